"""The pose CSV of docs/conventions.md: round trip, units, and every kind of bad input."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.errors import InputError
from simbench.io.poses import PoseRecording, read_pose_csv, write_pose_csv

HEADER = "time,sensor,x,y,z,qw,qx,qy,qz\n"


def recording(cap, valid=None):
    valid = np.ones(cap.p_w_s.shape[:2], dtype=bool) if valid is None else valid
    R = np.where(valid[..., None, None], cap.R_w_s, np.nan)
    p = np.where(valid[..., None], cap.p_w_s, np.nan)
    return PoseRecording(cap.names, cap.time_s, R, p, valid, source="test")


def test_round_trip_is_lossless(linkage_noisy, tmp_path):
    rec = recording(linkage_noisy)
    path = tmp_path / "poses.csv"
    write_pose_csv(path, rec)
    back = read_pose_csv(path)
    assert back.names == rec.names
    assert np.array_equal(back.time_s, rec.time_s)
    assert np.array_equal(back.p_w_s, rec.p_w_s)  # repr of a float64 reads back exactly
    # quaternion -> matrix -> quaternion -> matrix: a few ulp
    assert_allclose(back.R_w_s, rec.R_w_s, atol=1e-15)
    assert back.valid.all() and back.notes == ()


@pytest.mark.parametrize(("units", "factor"), [("cm", 100.0), ("mm", 1000.0), ("in", 1 / 0.0254)])
def test_units_converted_to_metres(linkage_exact, tmp_path, units, factor):
    rec = recording(linkage_exact)
    path = tmp_path / "p.csv"
    write_pose_csv(path, rec, units=units)
    back = read_pose_csv(path, units=units)
    assert_allclose(back.p_w_s, rec.p_w_s, rtol=1e-14)
    first = path.read_text().splitlines()[1].split(",")
    assert float(first[2]) == pytest.approx(rec.p_w_s[0, 0, 0] * factor, rel=1e-14)


def test_missing_poses_are_marked_and_reported(linkage_exact, tmp_path):
    valid = np.ones(linkage_exact.p_w_s.shape[:2], dtype=bool)
    valid[3:7, 2] = False
    path = tmp_path / "p.csv"
    write_pose_csv(path, recording(linkage_exact, valid))
    back = read_pose_csv(path)
    assert np.array_equal(back.valid, valid)
    assert np.isnan(back.p_w_s[3:7, 2]).all()
    assert any("upper_arm_l: no row in 4 of 800 frames" in n for n in back.notes)


def write(tmp_path, text, name="in.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


ROW_A = "0.0,a,0,0,0,1,0,0,0\n"
ROW_B = "0.0,b,1,0,0,1,0,0,0\n"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty"),
        ("\n\n", "the file is empty"),
        (HEADER, "no data rows after the header"),
        ("time,sensor,x,y,z,qw,qx,qy\n" + ROW_A, r"line 1: missing columns \['qz'\]"),
        (HEADER + "0.0,a,0,0,0,1,0,0\n", "line 2: expected 9 fields, got 8"),
        (HEADER + "0.0,a,0,zero,0,1,0,0,0\n", "line 2: column 'y' is not a number: 'zero'"),
        (HEADER + ROW_A + "nan,b,0,0,0,1,0,0,0\n", "line 3: time is not finite"),
        (HEADER + "0.0, ,0,0,0,1,0,0,0\n", "line 2: empty sensor name"),
        (HEADER + ROW_A + ROW_B + ROW_A, r"line 4: sensor 'a' appears twice at time 0.0 \(also on line 2\)"),
        (HEADER + ROW_A + "0.0,b,1,0,0,0,0,0,0\n", "line 3: zero quaternion"),
        ("time,sensor,x,y,z,qw,qx,qy,qz,x\n" + ROW_A, r"columns repeated in the header: \['x'\]"),
    ],
)
def test_bad_files_name_file_and_line(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=message) as info:
        read_pose_csv(path)
    assert str(path) in str(info.value)


def test_unknown_units_and_missing_file(tmp_path):
    with pytest.raises(InputError, match="unknown units 'ft': expected one of m, cm, mm, in"):
        read_pose_csv(write(tmp_path, HEADER + ROW_A), units="ft")
    with pytest.raises(InputError, match="cannot read"):
        read_pose_csv(tmp_path / "nope.csv")


def test_repairs_are_reported(tmp_path):
    text = (
        "sensor,time,qw,qx,qy,qz,x,y,z,extra\n"  # any column order, extra columns ignored
        "a,0.0,2,0,0,0,0,0,0,foo\n"
        "b,0.0,1,0,0,0,1,0,0,foo\n"
        "a,0.1,1,0,0,0,nan,0,0,foo\n"
        "b,0.1,1.0000001,0,0,0,1,0,0,foo\n"
    )
    rec = read_pose_csv(write(tmp_path, text))
    assert rec.names == ("a", "b")
    assert rec.valid.tolist() == [[True, True], [False, True]]
    assert_allclose(rec.R_w_s[0, 0], np.eye(3), atol=1e-15)  # |q| = 2 normalised
    assert any("1 quaternion(s) off unit norm" in n and "line 2" in n for n in rec.notes)
    assert any("sensor a: 1 row(s) with NaN or inf" in n for n in rec.notes)


def test_frames_sorted_by_time(tmp_path):
    text = HEADER + "0.2,a,2,0,0,1,0,0,0\n0.1,a,1,0,0,1,0,0,0\n0.1,b,1,0,0,1,0,0,0\n0.2,b,1,0,0,1,0,0,0\n"
    rec = read_pose_csv(write(tmp_path, text))
    assert rec.time_s.tolist() == [0.1, 0.2]
    assert rec.p_w_s[:, 0, 0].tolist() == [1.0, 2.0]


def stamped_csv(tmp_path, times, name="stamps.csv"):
    """Two sensors at the given frame times, standing still."""
    rows = [HEADER]
    for t in times:
        rows.append(f"{float(t)!r},a,0,0,0,1,0,0,0\n{float(t)!r},b,1,0,0,1,0,0,0\n")
    return write(tmp_path, "".join(rows), name)


def test_bursty_time_stamps_give_the_rate_from_count_over_span(tmp_path):
    # a 240 Hz tracker whose logger stamps four samples 2 microseconds apart, then waits: the
    # median step is 2 us (500 kHz), the true rate 240 Hz
    k = np.arange(960)
    times = (k // 4) * (4 / 240.0) + (k % 4) * 2e-6
    rec = read_pose_csv(stamped_csv(tmp_path, times))
    span = times[-1] - times[0]
    assert rec.rate_hz == pytest.approx((times.size - 1) / span, rel=1e-12)
    assert rec.rate_hz == pytest.approx(240.0, rel=0.01)  # 959 steps over 239 bursts of 4/240 s
    note = next(n for n in rec.notes if "bursts" in n)
    assert "720 of 959 steps" in note and "count over the span" in note


def test_regular_time_stamps_keep_the_median_step(tmp_path):
    rng = np.random.default_rng(3)
    times = np.arange(600) / 120.0 + rng.uniform(-1e-3, 1e-3, 600)  # 120 Hz with 1 ms jitter
    times[300:] += 2.0  # and a 2 s gap, which the median step ignores
    rec = read_pose_csv(stamped_csv(tmp_path, times))
    assert rec.rate_hz == pytest.approx(1.0 / np.median(np.diff(times)), rel=1e-12)
    assert rec.rate_hz == pytest.approx(120.0, rel=0.02)
    assert not [n for n in rec.notes if "bursts" in n]


def test_bursty_note_reaches_every_recording_once():
    k = np.arange(40)
    t = (k // 4) * 0.1 + (k % 4) * 1e-6
    R = np.tile(np.eye(3), (40, 1, 1, 1))
    p = np.zeros((40, 1, 3))
    rec = PoseRecording(("a",), t, R, p, np.ones((40, 1), bool), notes=("read by hand",))
    assert rec.notes[0] == "read by hand" and sum("bursts" in n for n in rec.notes) == 1
    again = PoseRecording(rec.names, rec.time_s, rec.R_w_s, rec.p_w_s, rec.valid, notes=rec.notes)
    assert again.notes == rec.notes  # built from a bursty recording's notes: not repeated


def messy_csv(tmp_path, *, blank_lines=False, name="messy.csv"):
    """Three sensors over 60 frames, rows shuffled within and across frames, with gaps, NaN rows,
    off-norm quaternions, an extra column and CRLF line ends; optionally blank lines."""
    rng = np.random.default_rng(11)
    rows = []
    for f in range(60):
        for s in ("hip", "knee", "ankle"):
            if rng.random() < 0.1:
                continue  # a missing row
            q = rng.normal(size=4)
            q *= (1.0 + rng.choice([0.0, 0.01])) / np.linalg.norm(q)
            x = rng.normal(size=3) * 100.0
            if rng.random() < 0.05:
                x[1] = np.nan
            rows.append(",".join([repr(f / 120.0), s, *map(repr, map(float, [*x, *q])), "z"]))
    order = np.argsort(np.arange(len(rows)) + rng.normal(0, 4, len(rows)))  # locally shuffled
    lines = [HEADER.strip() + ",extra"] + [rows[k] for k in order]
    if blank_lines:
        lines = [line for row in lines for line in (row, "")]
    return write(tmp_path, "\r\n".join(lines) + "\r\n", name)


def same_recording(a, b):
    assert a.names == b.names and a.notes == b.notes
    assert np.array_equal(a.time_s, b.time_s) and np.array_equal(a.valid, b.valid)
    assert np.array_equal(np.asarray(a.R_w_s), np.asarray(b.R_w_s), equal_nan=True)
    assert np.array_equal(np.asarray(a.p_w_s), np.asarray(b.p_w_s), equal_nan=True)


@pytest.mark.parametrize("in_memory", [True, False])
def test_fast_and_exact_readers_agree_in_memory_and_on_disk(tmp_path, monkeypatch, in_memory):
    """pyarrow's reader, the csv module's, arrays and the temporary HDF5 store all give the same
    recording; small blocks and chunks put frames across block and slab boundaries."""
    import h5py

    from simbench.io import csv_blocks

    path = messy_csv(tmp_path)
    reference = read_pose_csv(path, units="mm", in_memory=True)
    assert reference.valid.sum() > 100 and (~reference.valid).sum() > 5
    assert any("off unit norm" in n for n in reference.notes)
    monkeypatch.setattr(csv_blocks, "BLOCK_BYTES", 1 << 10)  # pyarrow's smallest useful block
    monkeypatch.setattr(csv_blocks, "BLOCK_ROWS", 7)
    monkeypatch.setattr(csv_blocks, "CHUNK_FRAMES", 4)
    fast = read_pose_csv(path, units="mm", in_memory=in_memory)
    assert isinstance(fast.R_w_s, np.ndarray if in_memory else h5py.Dataset)
    same_recording(fast, reference)
    exact = []
    monkeypatch.setattr(
        csv_blocks, "exact_blocks", lambda *a, f=csv_blocks.exact_blocks: exact.append(1) or f(*a)
    )
    read_pose_csv(path, in_memory=in_memory)
    assert not exact  # the fast reader read the file
    blank = read_pose_csv(
        messy_csv(tmp_path, blank_lines=True, name="blank.csv"), units="mm", in_memory=in_memory
    )
    # blank lines send the file to the exact reader; only the line numbers in the notes differ
    assert exact
    assert blank.notes != reference.notes
    same_recording(
        blank,
        PoseRecording(
            *[getattr(reference, k) for k in ("names", "time_s", "R_w_s", "p_w_s", "valid")],
            source=blank.source,
            notes=blank.notes,
        ),
    )


@pytest.mark.parametrize(
    ("bad", "line", "message"),
    [
        ("0.25,knee,0,0,0,1,0,0,0", 41, r"sensor 'knee' appears twice at time 0.25 \(also on line 7\)"),
        ("0.3,hip,0,0,0,0,0,0,0", 41, "zero quaternion"),
        ("inf,hip,0,0,0,1,0,0,0", 41, "time is not finite"),
        ("0.3, ,0,0,0,1,0,0,0", 41, "empty sensor name"),
        ("0.3,hip,0,0,zero,1,0,0,0", 41, "column 'z' is not a number: 'zero'"),
        ("0.3,hip,0,0,0,1,0,0", 41, "expected 9 fields, got 8"),
    ],
)
def test_errors_deep_in_a_file_name_their_line_across_blocks(tmp_path, monkeypatch, bad, line, message):
    from simbench.io import csv_blocks

    monkeypatch.setattr(csv_blocks, "BLOCK_BYTES", 1 << 10)
    monkeypatch.setattr(csv_blocks, "BLOCK_ROWS", 5)
    rows = [f"{f / 8!r},{s},0,0,0,1,0,0,0" for f in range(20) for s in ("hip", "knee")]
    rows.insert(line - 2, bad)
    path = write(tmp_path, HEADER + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match=rf"line {line}: {message}"):
        read_pose_csv(path, in_memory=False)


def test_calibration_of_a_recording_on_disk_equals_in_memory(linkage_noisy, tmp_path):
    from simbench.api import calibrate

    path = tmp_path / "poses.csv"
    write_pose_csv(path, recording(linkage_noisy))
    disk, memory = read_pose_csv(path, in_memory=False), read_pose_csv(path, in_memory=True)
    a, b = calibrate(disk), calibrate(memory)
    assert a.parent_of == b.parent_of and len(a.joints) == 5
    for ja, jb in zip(a.joints, b.joints, strict=True):
        assert np.array_equal(ja.fit.joint_in_parent, jb.fit.joint_in_parent)
        assert np.array_equal(ja.fit.frame_residual, jb.fit.frame_residual)


def test_quaternions_far_from_unit_norm_are_normalised_without_overflow(tmp_path):
    text = HEADER + "0,a,0,0,0,1e200,0,0,0\n0,b,0,0,0,0,1e-320,0,0\n"  # |q| beyond and below float64
    rec = read_pose_csv(write(tmp_path, text))
    assert_allclose(rec.R_w_s[0, 0], np.eye(3), atol=1e-15)
    assert_allclose(rec.R_w_s[0, 1], np.diag([1.0, -1.0, -1.0]), atol=1e-15)  # 180 deg about x
    assert "2 quaternion(s) off unit norm" in rec.notes[0] and "1e+200 on line 2" in rec.notes[0]


def test_times_in_milliseconds_are_named(tmp_path):
    """A 120 Hz recording stamped in ms read as s: steps of 8.3 s (0.12 Hz) get a note; the same
    in seconds none."""
    from simbench.io.read import read_poses

    times = np.arange(300) / 120.0
    assert not [n for n in read_poses(stamped_csv(tmp_path, times)).notes if "in seconds" in n]
    rec = read_poses(stamped_csv(tmp_path, 1000 * times))
    assert any("time steps of 8.333 s" in n and "milliseconds" in n for n in rec.notes)


def test_a_last_line_cut_short_is_noted(linkage_exact, tmp_path):
    """A writer stopped in the middle of the last line leaves a number cut short, which reads as a
    shorter number: the file not ending with a line end is the one sign, and it is noted."""
    cap = linkage_exact
    path = tmp_path / "poses.csv"
    write_pose_csv(
        path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones(cap.p_w_s.shape[:2], bool))
    )
    whole = read_pose_csv(path)
    assert not any("line end" in n for n in whole.notes)
    text = path.read_bytes()
    assert text.endswith(b"\n")
    path.write_bytes(text[:-4])  # the last quaternion component cut short
    cut = read_pose_csv(path)
    assert any("does not end with a line end: its last line may be cut short" in n for n in cut.notes)
    assert cut.n_frames == whole.n_frames
    path.write_bytes(text.replace(b"\n", b"\r\n"))  # Windows line ends end the file too
    assert not any("line end" in n for n in read_pose_csv(path).notes)
