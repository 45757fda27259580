"""The Dataset container and its HDF5 file; exports to the pose CSV and the truth JSON."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.cli import main
from simbench.errors import InputError
from simbench.io.dataset import read_dataset, truth_calibration_dict, write_dataset
from simbench.sim.session import SessionConfig, run_session


@pytest.fixture(scope="module")
def session():
    # with tracker noise, dropouts and skin artefact, so measured, actual and bone-rigid all differ
    return run_session(
        SessionConfig(model="linkage", motion="walk", duration_s=2.0, seed=9, sensors="ascension-flock")
    )


def test_hdf5_round_trip_is_lossless(session, tmp_path):
    path = tmp_path / "run.h5"
    write_dataset(path, session)
    back = read_dataset(path)
    assert back.sensors == session.sensors
    assert np.array_equal(back.time_s, session.time_s)
    for name in ("p_w_s", "q_w_s", "valid", "acc", "gyro", "mag"):
        assert np.array_equal(getattr(back.measured, name), getattr(session.measured, name), equal_nan=True)
        assert np.array_equal(getattr(back.truth.rigid, name), getattr(session.truth.rigid, name))
        assert np.array_equal(getattr(back.truth.actual, name), getattr(session.truth.actual, name))
    for name in (
        "p_w_b",
        "q_w_b",
        "joint_w",
        "joint_in_parent",
        "joint_in_child",
        "single_axis",
        "p_b_s",
        "q_b_s",
    ):
        assert np.array_equal(getattr(back.truth, name), getattr(session.truth, name))
    assert np.array_equal(back.truth.axis_in_parent, session.truth.axis_in_parent, equal_nan=True)
    assert back.truth.parent == session.truth.parent and back.truth.child == session.truth.child
    assert back.meta["seed"] == 9 and back.meta["versions"]["mujoco"]
    assert not list(tmp_path.glob(".*.tmp"))


def test_truth_json_matches_truth(session):
    doc = truth_calibration_dict(session)
    assert doc["root"] == "chest" and doc["units"] == "m"
    lengths = sorted(round(x["length"] * 100, 6) for x in doc["limb_lengths"])
    assert lengths == [28.6, 31.4, 34.3, 39.0, 39.7]
    for k, j in enumerate(doc["joints"]):
        assert j["parent"] == session.truth.parent[k]
        assert_allclose(j["joint_in_child"], session.truth.joint_in_child[k])
        assert j["single_axis"] is False and j["axis_in_parent"] is None


def test_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_dataset(tmp_path / "none.h5")
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(InputError, match="not an HDF5 file"):
        read_dataset(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as fh:
        fh["x"] = 1
    with pytest.raises(InputError, match="not a simbench dataset"):
        read_dataset(other)


def test_failed_write_leaves_nothing(session, tmp_path, monkeypatch):
    path = tmp_path / "run.h5"
    path.write_text("old")

    def boom(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr("simbench.io.dataset._write_group", boom)
    with pytest.raises(RuntimeError):
        write_dataset(path, session)
    assert path.read_text() == "old"  # the old file is untouched
    assert not list(tmp_path.glob(".*.tmp"))


def test_simulate_then_calibrate_from_the_command_line(tmp_path, capsys):
    h5, csv, truth, cal = (tmp_path / n for n in ("run.h5", "run.csv", "truth.json", "cal.json"))
    code = main(
        [
            "simulate",
            "--model",
            "linkage",
            "--motion",
            "exercise",
            "--duration",
            "10",
            "--rate",
            "120",
            "--seed",
            "1",
            "-o",
            str(h5),
            "--csv",
            str(csv),
            "--truth-json",
            str(truth),
        ]
    )
    assert code == 0, capsys.readouterr().err
    for source in (h5, csv):
        assert main(["calibrate", str(source), "--json", str(cal), "--no-slip"]) == 0
        doc = json.loads(cal.read_text())
        exact = json.loads(truth.read_text())
        assert {j["child"]: j["parent"] for j in doc["joints"]} == {
            j["child"]: j["parent"] for j in exact["joints"]
        }
        got = {(x["segment"], x["joint_a"], x["joint_b"]): x["length"] for x in doc["limb_lengths"]}
        for x in exact["limb_lengths"]:
            # noise-free physics: exact to rounding (the CSV holds every digit)
            assert got[(x["segment"], x["joint_a"], x["joint_b"])] == pytest.approx(x["length"], abs=1e-9)
    capsys.readouterr()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--model", "robot"], "unknown model 'robot'"),
        (["--sensors-on", "chest,tail"], "no body 'tail'"),
        (["--motion", "dance"], "unknown motion 'dance'"),
        (["--rate", "5000"], "above the model's physics rate"),
        (["--duration", "0"], "argument --duration: expected a number > 0, got '0'"),
        (["--duration", "-3"], "argument --duration: expected a number > 0, got '-3'"),
        (["--sensors", "flock"], "unknown sensor preset 'flock'"),
    ],
)
def test_simulate_bad_input_exits_2(tmp_path, capsys, args, message):
    try:
        code = main(["simulate", *args, "-o", str(tmp_path / "x.h5"), "--duration", "1", *args])
    except SystemExit as exc:  # a value argparse refuses itself
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    assert not (tmp_path / "x.h5").exists()


def test_simulate_unwritable_output(tmp_path, capsys):
    code = main(["simulate", "--duration", "1", "-o", str(tmp_path / "missing" / "x.h5")])
    assert code == 2 and "does not exist" in capsys.readouterr().err


def test_a_large_datasets_poses_are_read_a_chunk_at_a_time_and_equal_the_whole_read(tmp_path, capsys):
    """``read_dataset_poses(in_memory=False)`` (what ``simbench calibrate`` takes for a dataset
    larger than IN_MEMORY_BYTES): h5py datasets of a temporary file, equal to the bit to
    ``Dataset.poses()``, notes and all, and the same calibration."""
    from calibration import calibrate
    from simbench.io.dataset import read_dataset_poses

    ds = run_session(SessionConfig(model="linkage", duration_s=20.0, seed=4, sensors="polhemus-liberty"))
    path = tmp_path / "d.h5"
    write_dataset(path, ds)
    whole = read_dataset(path).poses()
    assert not whole.valid.all() and whole.notes  # dropouts: NaN poses and a note to carry over
    assert isinstance(read_dataset_poses(path).R_w_s, np.ndarray)  # small: in memory
    lazy = read_dataset_poses(path, in_memory=False)
    assert isinstance(lazy.R_w_s, h5py.Dataset) and isinstance(lazy.p_w_s, h5py.Dataset)
    np.testing.assert_array_equal(np.asarray(lazy.R_w_s), whole.R_w_s)
    np.testing.assert_array_equal(np.asarray(lazy.p_w_s), whole.p_w_s)
    np.testing.assert_array_equal(lazy.valid, whole.valid)
    np.testing.assert_array_equal(lazy.time_s, whole.time_s)
    assert (lazy.names, lazy.source, lazy.notes) == (whole.names, whole.source, whole.notes)
    a = calibrate(whole.R_w_s, whole.p_w_s, whole.names, valid=whole.valid)
    b = calibrate(lazy.R_w_s, lazy.p_w_s, lazy.names, valid=lazy.valid)
    assert a.parent_of == b.parent_of
    for ja, jb in zip(a.joints, b.joints, strict=True):
        assert_allclose(jb.fit.joint_in_parent, ja.fit.joint_in_parent, rtol=0, atol=1e-12)
    # a sample marked valid with a zero quaternion: the same refusal as the whole read
    with h5py.File(path, "r+") as fh:
        f, k = np.argwhere(fh["measured/valid"][()])[1500]
        fh["measured/q_w_s"][f, k] = 0.0
    with pytest.raises(InputError) as whole_error:
        read_dataset(path)
    with pytest.raises(InputError) as lazy_error:
        read_dataset_poses(path, in_memory=False)
    assert str(lazy_error.value) == str(whole_error.value)
    assert "1 sample(s) marked valid without a finite position" in str(lazy_error.value)


def test_simbench_calibrate_takes_the_chunked_path_for_a_large_dataset(tmp_path, capsys, monkeypatch):
    """``simbench calibrate DATASET.h5`` above the in-memory size reads the poses a chunk at a time
    and prints exactly what the whole read gives."""
    import simbench.io.dataset as dataset_module

    ds = run_session(SessionConfig(model="linkage", duration_s=10.0, seed=5, sensors="polhemus-liberty"))
    path = tmp_path / "d.h5"
    write_dataset(path, ds)
    assert main(["calibrate", str(path)]) == 0
    whole = capsys.readouterr().out
    calls = []
    real = dataset_module.read_dataset_poses

    def spy(p, *, in_memory=None):
        rec = real(p, in_memory=in_memory)
        calls.append(type(rec.R_w_s))
        return rec

    monkeypatch.setattr(dataset_module, "IN_MEMORY_BYTES", 0)
    monkeypatch.setattr("simbench.io.read.read_dataset_poses", spy)
    assert main(["calibrate", str(path)]) == 0
    chunked = capsys.readouterr().out
    assert calls == [h5py.Dataset]
    drop_time = [line for line in whole.splitlines() if "calibrated in" not in line]
    assert drop_time == [line for line in chunked.splitlines() if "calibrated in" not in line]


def test_repeated_sensor_names_are_named_before_anything_that_depends_on_them(session):
    import dataclasses

    names = list(session.sensors)
    names[1] = names[0]
    with pytest.raises(InputError, match=rf"sensor names must be unique, repeated: \['{names[0]}'\]"):
        dataclasses.replace(session, sensors=tuple(names))
