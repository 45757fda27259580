"""Wide tracker exports (issue 8): round trips, Euler and units, repeated samples, bad files."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.cli import main
from simbench.errors import InputError
from simbench.io.poses import PoseRecording
from simbench.io.wide_csv import read_wide_csv, read_wide_spec, write_wide_csv

SPEC = """
[wide]
time = "Time"
units = "{units}"
orientation = "{orientation}"
euler = "ZYX"
angle_units = "deg"
repeated = "{repeated}"
"""


def spec_file(tmp_path, names, orientation="quaternion", units="cm", repeated="drop"):
    text = SPEC.format(units=units, orientation=orientation, repeated=repeated)
    for k, name in enumerate(names):
        o = (
            [f"S{k}_Q{i}" for i in range(4)]
            if orientation == "quaternion"
            else [f"S{k}_A{i}" for i in range(3)]
        )
        text += (
            f"[wide.sensors.{name}]\nposition = {[f'S{k}_X', f'S{k}_Y', f'S{k}_Z']}\n{orientation} = {o}\n"
        )
    path = tmp_path / "spec.toml"
    path.write_text(text.replace("'", '"'))
    return read_wide_spec(path)


@pytest.fixture(scope="module")
def recording(linkage_noisy_wide):
    cap = linkage_noisy_wide
    return PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones(cap.p_w_s.shape[:2], bool))


@pytest.fixture(scope="module")
def linkage_noisy_wide():
    from simbench.sim.synthetic import linkage, simulate_motion

    return simulate_motion(
        linkage(), n_frames=600, rate_hz=120.0, rng=np.random.default_rng(5), position_noise_m=0.002
    )


@pytest.mark.parametrize("orientation", ["quaternion", "euler"])
def test_round_trip(tmp_path, recording, orientation):
    spec = spec_file(tmp_path, recording.names, orientation=orientation)
    path = tmp_path / "wide.csv"
    write_wide_csv(path, recording, spec)
    back = read_wide_csv(path, spec)
    assert back.names == recording.names and back.valid.all()
    assert_allclose(back.p_w_s, recording.p_w_s, rtol=1e-13, atol=1e-15)  # cm back to metres
    assert_allclose(back.R_w_s, recording.R_w_s, atol=1e-12)


def test_repeated_samples_dropped(tmp_path, recording):
    spec = spec_file(tmp_path, recording.names)
    p = recording.p_w_s.copy()
    R = recording.R_w_s.copy()
    p[11, 2], R[11, 2] = p[10, 2], R[10, 2]  # the tracker repeated sensor 2's sample
    rec = PoseRecording(recording.names, recording.time_s, R, p, recording.valid)
    path = tmp_path / "w.csv"
    write_wide_csv(path, rec, spec)
    back = read_wide_csv(path, spec)
    assert not back.valid[11, 2] and back.valid[10, 2] and back.valid[11, [0, 1, 3, 4, 5]].all()
    assert any("1 repeated samples" in n for n in back.notes)
    kept = read_wide_csv(path, spec_file(tmp_path, recording.names, repeated="keep"))
    assert kept.valid.all()


def test_calibrate_reads_wide_files(tmp_path, recording, capsys):
    spec_path = tmp_path / "spec.toml"
    spec = spec_file(tmp_path, recording.names, orientation="euler", units="mm")
    path = tmp_path / "w.csv"
    write_wide_csv(path, recording, spec)
    assert main(["calibrate", str(path), "--wide", str(spec_path), "--no-slip"]) == 0
    out = capsys.readouterr().out
    assert "read 600 frames of 6 sensors (euler orientation, positions in mm)" in out
    assert "chest -> head" in out


def test_bad_wide_input(tmp_path, recording):
    spec = spec_file(tmp_path, recording.names)
    path = tmp_path / "w.csv"
    write_wide_csv(path, recording, spec)
    text = path.read_text().splitlines()
    (tmp_path / "cols.csv").write_text("\n".join([text[0].replace("S0_X", "X0"), *text[1:]]) + "\n")
    with pytest.raises(InputError, match=r"missing columns \['S0_X'\]"):
        read_wide_csv(tmp_path / "cols.csv", spec)
    (tmp_path / "num.csv").write_text(
        "\n".join([text[0], text[1].replace(text[1].split(",")[1], "abc", 1), *text[2:]])
    )
    with pytest.raises(InputError, match=r"line 2: column 'S0_X' is not a number: 'abc'"):
        read_wide_csv(tmp_path / "num.csv", spec)
    bad_spec = tmp_path / "bad.toml"
    sensor = '[wide.sensors.a]\nposition = ["x","y","z"]\nquaternion = ["w","i","j","k"]\n'
    bad_spec.write_text('[wide]\ntime = "Time"\nunits = "furlong"\n' + sensor)
    with pytest.raises(InputError, match="unknown units 'furlong'"):
        read_wide_spec(bad_spec)
    bad_spec.write_text(
        '[wide]\nunits = "m"\n[wide.sensors.a]\nposition = ["x","y","z"]\nquaternion = ["w","i","j","k"]\n'
    )
    with pytest.raises(InputError, match="give a time column"):
        read_wide_spec(bad_spec)


def test_read_recordings_become_datasets(tmp_path, recording):
    from simbench.io.dataset import dataset_from_poses, read_dataset, write_dataset

    spec = spec_file(tmp_path, recording.names)
    path = tmp_path / "w.csv"
    write_wide_csv(path, recording, spec)
    ds = dataset_from_poses(read_wide_csv(path, spec))
    write_dataset(tmp_path / "w.h5", ds)
    back = read_dataset(tmp_path / "w.h5").poses()
    assert back.names == recording.names and back.valid.all()
    assert_allclose(back.p_w_s, recording.p_w_s, rtol=1e-13, atol=1e-15)
    assert_allclose(back.R_w_s, recording.R_w_s, atol=1e-12)
