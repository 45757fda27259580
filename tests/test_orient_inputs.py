"""Sourceless orientation on damaged or mislabelled inputs: readings of exactly zero, zero
reference quaternions, a missing gyroscope, NaN bursts, options that do not apply, a rate label
far too low. Each gives a clear error or an honest result, never an internal error or a score
of nothing."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.orientation import fit_magnetometer, mahony, orientation_errors, reference
from calibration.orientation import skeleton as skeleton_module
from calibration.orientation.disturbance import smooth_vectors
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.imu import read_broad
from simbench.orient import estimate


def _trial(path: Path, frames: int = 600, rate: float = 100.0, **replace: np.ndarray) -> Path:
    """A BROAD-like trial: a sensor turning about a tilted axis in a 48 uT field (ENU, 60 degrees
    down), exact readings, a unit reference; ``replace`` overrides datasets."""
    t = np.arange(frames) / rate
    angle = 0.8 * np.sin(2 * np.pi * 0.5 * t)
    axis = np.array([0.3, 0.2, 0.93]) / np.linalg.norm([0.3, 0.2, 0.93])
    q = np.column_stack([np.cos(angle / 2), np.sin(angle / 2)[:, None] * axis])
    from calibration.rotations import quat_to_matrix

    R = quat_to_matrix(q)
    g_w = np.array([0.0, 0.0, 9.81])
    b_w = 48.0 * np.array([0.0, np.cos(np.deg2rad(60)), -np.sin(np.deg2rad(60))])
    data = {
        "imu_acc": np.einsum("fji,j->fi", R, g_w),
        "imu_gyr": np.gradient(angle, t)[:, None] * axis,
        "imu_mag": np.einsum("fji,j->fi", R, b_w),
        "opt_quat": q,
        "movement": np.ones(frames, bool),
    }
    data.update(replace)
    with h5py.File(path, "w") as fh:
        for k, v in data.items():
            fh[k] = v
        fh.attrs["sampling_rate"] = rate
    return path


def test_a_magnetometer_that_reads_zero_is_no_reading(tmp_path, capsys):
    with pytest.raises(CalibrationError, match="at least"):
        fit_magnetometer(np.zeros((500, 3)))
    path = _trial(tmp_path / "zero_mag.hdf5", imu_mag=np.zeros((600, 3)))
    rec = read_broad(path)
    assert not rec.valid.any()
    assert any("reads exactly zero" in n for n in rec.notes)
    assert main(["orient", str(path)]) == 2
    err = capsys.readouterr().err
    assert "no usable accelerometer and magnetometer samples" in err and "reads exactly zero" in err
    assert "magnetometers calibrated" not in err  # the reader's notes, not the calibration's
    assert "internal error" not in err


def test_zero_reference_quaternions_are_not_scored(tmp_path, capsys):
    q = np.tile([1.0, 0.0, 0.0, 0.0], (4, 1))
    q0 = q.copy()
    q0[1] = 0.0
    err = orientation_errors(q, q0)
    assert np.isnan(err[1]).all() and np.isfinite(err[[0, 2, 3]]).all()
    assert np.isnan(orientation_errors(q0, q)[1]).all()
    # neither needs unit length: a scaled quaternion is the same rotation
    assert np.allclose(orientation_errors(3 * q, q), 0.0)
    quat = read_broad(_trial(tmp_path / "ok.hdf5")).q_true[:, 0]
    quat[::2] = 0.0
    path = _trial(tmp_path / "q.hdf5", opt_quat=quat)
    assert any("300 reference quaternions of zero" in n for n in read_broad(path).notes)
    assert main(["orient", str(path), "--method", "triad"]) == 0
    row = [x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("imu ")][-1]
    assert row.split()[-1] == "300"  # the samples scored: the 300 with a reference


def test_a_gyro_that_is_not_there_leaves_the_gyro_aided_methods_without_estimates(tmp_path):
    gyro = np.full((600, 3), np.nan)
    path = _trial(tmp_path / "nogyro.hdf5", imu_gyr=gyro)
    rec = read_broad(path)
    assert any("NaN gyroscope" in n for n in rec.notes)
    for method in ("mahony", "vqf"):
        run = estimate(rec, method)
        assert not run.ok.any() and np.isnan(run.q_enu).all(), method
    # a burst: the rest estimated, the burst not
    gyro = read_broad(_trial(tmp_path / "ok.hdf5")).gyro[:, 0]
    gyro[200:230] = np.nan
    acc = read_broad(_trial(tmp_path / "ok.hdf5")).acc
    est = mahony(acc, gyro[:, None], read_broad(_trial(tmp_path / "ok.hdf5")).mag, 100.0, reference())
    assert not est.ok[200:230].any() and est.ok[:200].all() and est.ok[230:].all()


def test_nan_bursts_do_not_stop_the_weighted_wahba(tmp_path):
    acc = read_broad(_trial(tmp_path / "ok.hdf5")).acc[:, 0]
    acc[100:120] = np.nan
    acc[300] = np.inf
    rec = read_broad(_trial(tmp_path / "burst.hdf5", imu_acc=acc))
    run = estimate(rec, "wahba")
    assert not run.ok[100:120].any() and not run.ok[300].any()
    assert run.ok[:100].all() and np.isfinite(run.q_enu[:100]).all()


def test_smoothing_options_that_cannot_apply_are_refused(tmp_path, capsys):
    rec = read_broad(_trial(tmp_path / "ok.hdf5"))
    with pytest.raises(InputError, match="skeleton method"):
        estimate(rec, "skeleton", smooth_hz=1.0)
    assert main(["orient", str(tmp_path / "ok.hdf5"), "--smooth-hz", "1"]) == 2
    assert "--smooth-hz is for the per-sample and gyro-aided methods" in capsys.readouterr().err
    with pytest.raises(CalibrationInputError, match="too low a low-pass"):
        smooth_vectors(rec.acc, 100.0, 1e-9)
    assert main(["orient", str(tmp_path / "ok.hdf5"), "--method", "triad", "--smooth-hz", "1e-9"]) == 2
    err = capsys.readouterr().err
    assert "too low a low-pass" in err and "internal error" not in err


def test_a_rate_label_far_too_low_does_not_cut_the_recording_into_tiny_solves(monkeypatch):
    """2,000 samples labelled 0.01 Hz (a 120 s segment would be one sample, cut into 250 solves
    of 8): the segments hold at least MIN_SEGMENT_FRAMES samples each."""
    spans = []
    original = skeleton_module._solve_span

    def counted(data, setup):
        spans.append(data.acc.shape[0])
        return original(data, setup)

    monkeypatch.setattr(skeleton_module, "_solve_span", counted)
    frames = 2000
    acc = np.tile([0.0, 0.0, 9.81], (frames, 1, 1))
    mag = np.tile([0.0, 24.0, -41.6], (frames, 1, 1))
    est = skeleton_module.skeleton_orientation(acc, mag, 0.01, starts=((),))
    assert est.ok.all()
    assert len(spans) <= -(-frames // (skeleton_module.MIN_SEGMENT_FRAMES - 1)) + 1
    assert min(spans[:-1]) >= skeleton_module.MIN_SEGMENT_FRAMES  # the last holds what is left


def test_follow_refuses_a_file_that_is_not_a_pose_csv(tmp_path, capsys):
    h5 = _trial(tmp_path / "trial.h5")
    assert main(["calibrate", str(h5), "--follow", "--timeout", "1"]) == 2
    assert "--follow calibrates a pose CSV" in capsys.readouterr().err
    binary = tmp_path / "binary.csv"
    binary.write_bytes(h5.read_bytes())
    assert main(["calibrate", str(binary), "--follow", "--timeout", "1"]) == 2
    err = capsys.readouterr().err
    assert "not a pose CSV" in err and "internal error" not in err


def test_readings_in_other_units_are_named(tmp_path):
    ok = read_broad(_trial(tmp_path / "ok.hdf5"))
    assert not [n for n in ok.notes if "median magnitude" in n]
    in_g = read_broad(_trial(tmp_path / "g.hdf5", imu_acc=ok.acc[:, 0] / 9.81))
    assert any("accelerometer's median magnitude is 1," in n and "in m/s^2?" in n for n in in_g.notes)
    in_nt = read_broad(_trial(tmp_path / "nt.hdf5", imu_mag=ok.mag[:, 0] * 1000))
    assert any("magnetometer's median magnitude is 4.8e+04" in n and "in uT?" in n for n in in_nt.notes)
    fast = np.tile([0.0, 0.0, 20.0], (600, 1))  # 20 rad/s, a fast turn: fine
    assert not [n for n in read_broad(_trial(tmp_path / "f.hdf5", imu_gyr=fast)).notes if "gyroscope" in n]
    in_deg = read_broad(_trial(tmp_path / "d.hdf5", imu_gyr=np.rad2deg(fast)))
    assert any("99th-percentile rate is 1146" in n and "in rad/s?" in n for n in in_deg.notes)


def test_a_movement_mask_of_numbers_and_a_rate_of_several_values(tmp_path):
    move = np.ones(600)
    move[:100] = np.nan  # no sample to score there
    move[100:150] = 0.0
    rec = read_broad(_trial(tmp_path / "m.hdf5", movement=move))
    assert rec.evaluate.dtype == bool and rec.evaluate.sum() == 450 and not rec.evaluate[:150].any()
    path = _trial(tmp_path / "r.hdf5")
    with h5py.File(path, "a") as fh:
        fh.attrs["sampling_rate"] = [100.0, 200.0]
    with pytest.raises(InputError, match="sampling_rate must be a finite number"):
        read_broad(path)


def test_a_dataset_s_imu_is_valid_where_its_readings_are_and_its_rate_is_checked():
    import dataclasses

    import simbench as sb
    from simbench.orient import vqf_offline

    ds = sb.simulate(
        model="linkage", motion="exercise", duration_s=2.0, rate_hz=120.0, sensors="mems-industrial", seed=1
    )
    # every tracker pose lost: the IMU's samples are still good
    blind = dataclasses.replace(
        ds, measured=dataclasses.replace(ds.measured, valid=np.zeros_like(ds.measured.valid))
    )
    rec = blind.imu()
    assert rec.valid.all() and estimate(rec, "triad").ok.all()
    for bad in (float("nan"), -5.0, 0.0, "abc"):
        with pytest.raises(InputError, match="sample rate"):
            dataclasses.replace(ds, meta={**ds.meta, "rate_hz": bad}).imu()
    with pytest.raises(InputError, match="time stamps step at 120 Hz"):
        dataclasses.replace(ds, meta={**ds.meta, "rate_hz": 1e9}).imu()
    good = ds.imu()
    with pytest.raises(InputError, match="sample rate of a finite number"):
        estimate(dataclasses.replace(good, rate_hz=float("nan")), "vqf")
    with pytest.raises(InputError, match="rate_hz a finite number"):  # VQF's C++ assert would end the process
        vqf_offline(good.acc, good.gyro, good.mag, -1.0)
