"""``calibrate --follow`` trusts nothing about the file it follows (issue 45): it is read by the batch
reader's rules, tracked (truncated, replaced, rewritten: a clear stop), in bounded pieces under a
timeout that holds, and every time it reports is a frame's time stamp."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pytest

from simbench.cli import main
from simbench.cli.live import PRINT, LivePrinter
from simbench.errors import InputError
from simbench.experiments import live as live_mod
from simbench.experiments.live import follow
from simbench.io.follow import READ_BYTES, CsvFollower, FollowStopped, first_seen
from simbench.io.poses import CSV_COLUMNS, PoseRecording, write_pose_csv
from simbench.io.read import read_poses
from simbench.sim.synthetic import random_tree, simulate_motion

HEADER = ",".join(CSV_COLUMNS)


def _recording(n_frames: int = 600, n_sensors: int = 3, seed: int = 4) -> PoseRecording:
    skeleton = random_tree(n_sensors, np.random.default_rng(seed))
    cap = simulate_motion(skeleton, n_frames=n_frames, rate_hz=100.0, rng=np.random.default_rng(seed + 1))
    return PoseRecording(
        names=skeleton.names,
        time_s=np.arange(n_frames) / 100.0,
        R_w_s=cap.R_w_s,
        p_w_s=cap.p_w_s,
        valid=np.ones((n_frames, n_sensors), dtype=bool),
    )


@pytest.fixture
def until_caught_up(monkeypatch):
    """The follow ends (as at Ctrl-C) the first time it has nothing new to read."""

    def caught_up(_seconds):
        raise KeyboardInterrupt

    monkeypatch.setattr(live_mod.time, "sleep", caught_up)


def _updates(path, **kwargs) -> list:
    return list(follow(path, timeout_s=600.0, **kwargs))


def test_a_bom_quoted_header_and_a_sensor_missing_from_the_first_frame_read_as_the_batch_does(
    tmp_path, until_caught_up
):
    rec = _recording()
    plain = tmp_path / "plain.csv"
    write_pose_csv(plain, rec)
    lines = plain.read_text().splitlines()
    first = rec.names[0]
    # a byte-order mark, a quoted header and quoted names; the first sensor absent from frame 0
    body = [
        ",".join(f'"{cell}"' if k == 1 else cell for k, cell in enumerate(line.split(",")))
        for line in lines[1:]
        if not (line.startswith("0.0,") and line.split(",")[1] == first)
    ]
    path = tmp_path / "p.csv"
    path.write_bytes(
        b"\xef\xbb\xbf" + ("\n".join([",".join(f'"{c}"' for c in CSV_COLUMNS), *body]) + "\n").encode()
    )
    batch = read_poses(path)
    updates = _updates(path)
    final = updates[-1]
    assert final.kind == "final"
    assert final.calibrator.names == batch.names and final.calibrator.n_frames == batch.n_frames
    assert [u.kind for u in updates].count("stopped") == 1


def test_the_follower_names_a_truncated_replaced_rewritten_or_removed_file(tmp_path):
    rec = _recording(200)
    whole = tmp_path / "whole.csv"
    write_pose_csv(whole, rec)
    text = whole.read_bytes()

    def truncate(path):
        path.write_bytes(text[: len(text) // 3])

    def rotate(path):
        os.replace(path, path.with_suffix(".1"))
        path.write_bytes(text)

    other = tmp_path / "other.csv"
    write_pose_csv(other, _recording(400, seed=9))

    def rewrite(path):  # the logger restarted: another recording, longer than what was read
        path.write_bytes(other.read_bytes())

    for change, said in [
        (truncate, "truncated to"),
        (rotate, "replaced by another file"),
        (rewrite, "rewritten"),
    ]:
        path = tmp_path / f"{change.__name__}.csv"
        path.write_bytes(text[: len(text) // 2])
        follower = CsvFollower(path, 1.0)
        try:
            assert list(follower.frames())
            change(path)
            with pytest.raises(
                FollowStopped, match=rf"{path.name}: {said}.* while it was followed \(after line \d+"
            ):
                list(follower.frames())
        finally:
            follower.close()
    path = tmp_path / "removed.csv"
    path.write_bytes(text)
    follower = CsvFollower(path, 1.0)
    assert list(follower.frames())
    path.unlink()
    with pytest.raises(FollowStopped, match="removed while it was followed"):
        list(follower.frames())
    follower.close()


def test_a_follow_stopped_by_truncation_gives_its_final_table_then_exits_2(tmp_path, monkeypatch, capsys):
    rec = _recording(900)
    whole = tmp_path / "whole.csv"
    write_pose_csv(whole, rec)
    text = whole.read_bytes()
    path = tmp_path / "p.csv"
    path.write_bytes(text[: len(text) // 2])

    def truncate_then_wait(_seconds):  # the logger restarts its file while it is followed
        path.write_bytes(text[:100])

    monkeypatch.setattr(live_mod.time, "sleep", truncate_then_wait)
    code = main(["calibrate", str(path), "--follow", "--timeout", "600"])
    captured = capsys.readouterr()
    assert code == 2
    assert "simbench: stopped (" in captured.out and "truncated to 100 bytes" in captured.out
    assert "simbench final" in captured.out
    assert f"simbench: error: {path}: truncated to 100 bytes while it was followed" in captured.err


def test_times_are_the_frames_time_stamps_across_a_gap(tmp_path, until_caught_up):
    """A 5 s gap in the time stamps: the state's time and an alert's are the stamps', not a count
    of frames over the rate."""
    rec = _recording(900)
    stamps = rec.time_s + np.where(rec.time_s >= 3.0, 5.0, 0.0)
    path = tmp_path / "gap.csv"
    write_pose_csv(path, dataclasses.replace(rec, time_s=stamps))
    final = _updates(path, rate_hz=100.0)[-1]
    assert final.state.time_s == pytest.approx(stamps[-1])  # 13.99 s, not 8.99
    updates = live_mod._Updates(1.0)
    updates.stamps.extend(stamps.tolist())
    assert updates.at(450) == pytest.approx(stamps[450]) and updates.at(10**9) == pytest.approx(stamps[-1])


def test_a_backlog_is_read_in_bounded_pieces_and_the_timeout_holds(tmp_path, monkeypatch):
    rec = _recording(12_000, 3)
    path = tmp_path / "backlog.csv"
    write_pose_csv(path, rec)
    size = path.stat().st_size
    assert size > 2 * READ_BYTES
    follower = CsvFollower(path, 1.0)
    reads = 0
    while follower._offset < size:
        list(follower.frames())
        reads += 1
    follower.close()
    assert reads == -(-size // READ_BYTES)  # one piece of at most READ_BYTES a call
    ticks = iter(range(10**9))
    updates = list(follow(path, timeout_s=50.0, clock=lambda: float(next(ticks))))
    final = updates[-1]
    assert final.kind == "final"
    assert 40 <= final.calibrator.n_frames <= 60 + READ_BYTES // 100  # stopped at the 50th tick
    assert final.calibrator.n_frames < rec.n_frames // 2


def test_a_file_that_never_appears_is_said_and_exits_2(tmp_path, capsys):
    path = tmp_path / "later.csv"
    updates = follow(path, timeout_s=0.2)
    first = next(updates)
    assert first.kind == "waiting" and first.calibrator is None and "does not exist yet" in first.reason
    with pytest.raises(InputError, match=r"later\.csv: no such file \(waited 0\.2 s for it to appear\)"):
        list(updates)
    assert main(["calibrate", str(path), "--follow", "--timeout", "0.2"]) == 2
    captured = capsys.readouterr()
    assert "waiting (" in captured.out and "no such file" in captured.err


def test_each_line_is_flushed_as_it_is_printed():
    assert LivePrinter("x").out is PRINT and PRINT.keywords == {"flush": True}


def test_a_sensor_first_seen_after_the_start_is_named(tmp_path, until_caught_up):
    rec = _recording(300)
    path = tmp_path / "late.csv"
    write_pose_csv(path, rec)
    with path.open("a") as fh:
        fh.write("3.5,newcomer,0,0,0,1,0,0,0\n3.6,newcomer,0,0,0,1,0,0,0\n")
    with pytest.raises(
        InputError, match=r"line \d+: sensor 'newcomer' first appears at 3\.5 s, after the live"
    ):
        _updates(path)
    assert first_seen([(0.0, [("b", [], 2), ("a", [], 3)]), (0.1, [("c", [], 4), ("a", [], 5)])]) == (
        "b",
        "a",
        "c",
    )
    assert isinstance(Path(path), Path)
