"""Sensor configurations applied to simulated sessions (issue 4): presets, skin, field, errors."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import calibrate, detect_slip
from calibration.rotations import quat_to_matrix
from calibration.skeleton import segment_lengths
from simbench.errors import InputError
from simbench.sim.sensor_config import load_sensor_config, preset_names
from simbench.sim.session import SessionConfig, load_session_model, run_session


def session(tmp_path, toml: str | None = None, preset: str = "ideal", **kw):
    sensors = preset
    if toml is not None:
        path = tmp_path / f"s{abs(hash(toml))}.toml"
        path.write_text(toml)
        sensors = str(path)
    config = SessionConfig(sensors=sensors, **{"duration_s": 5.0, "seed": 1, **kw})
    return run_session(config, load_session_model(config))


def test_presets_load():
    assert set(preset_names()) >= {
        "ideal",
        "ascension-flock",
        "polhemus-liberty",
        "mems-consumer",
        "mems-industrial",
        "skin-paper-human",
    }
    for name in preset_names():
        assert load_sensor_config(name).name == name


def test_ideal_measures_the_truth_exactly(tmp_path):
    ds = session(tmp_path)
    for name in ("p_w_s", "q_w_s", "acc", "gyro", "mag"):
        assert np.array_equal(getattr(ds.measured, name), getattr(ds.truth.actual, name))
        assert np.array_equal(getattr(ds.truth.actual, name), getattr(ds.truth.rigid, name))
    assert ds.measured.valid.all()


def test_sensors_do_not_change_the_motion_and_are_seeded(tmp_path):
    ideal = session(tmp_path)
    flock = session(tmp_path, preset="ascension-flock")
    again = session(tmp_path, preset="ascension-flock")
    other = session(tmp_path, preset="ascension-flock", seed=2)
    assert np.array_equal(ideal.truth.rigid.p_w_s, flock.truth.rigid.p_w_s)  # same physics
    assert np.array_equal(flock.measured.p_w_s, again.measured.p_w_s, equal_nan=True)
    assert not np.array_equal(flock.measured.p_w_s, other.measured.p_w_s, equal_nan=True)
    # positions are reported in the Flock's units: metres / 0.94, plus noise of millimetres
    ratio = np.linalg.norm(flock.measured.p_w_s, axis=2) / np.linalg.norm(flock.truth.actual.p_w_s, axis=2)
    assert np.median(ratio) == pytest.approx(1 / 0.94, rel=2e-3)


def test_imu_preset_noise_level(tmp_path):
    ds = session(tmp_path, preset="mems-industrial")
    diff = ds.measured.acc - ds.truth.actual.acc
    # white noise 0.000588 x sqrt(120 Hz) = 6.4e-3 m/s^2 on top of constant biases: take the
    # spread of first differences, sqrt(2) x the white noise
    assert np.std(np.diff(diff, axis=0)) / np.sqrt(2) == pytest.approx(0.000588 * np.sqrt(120), rel=0.05)


def test_mount_slip_grows_as_stiffness_falls(tmp_path):
    slips = []
    for k in (20000.0, 2000.0, 200.0):
        ds = session(tmp_path, f"[skin]\nmount_stiffness_n_per_m = {k}\n", motion="walk")
        slips.append(np.sqrt(np.mean(np.sum((ds.truth.actual.p_w_s - ds.truth.rigid.p_w_s) ** 2, axis=2))))
    assert slips[0] < slips[1] < slips[2]
    assert slips[0] > 0  # the physics moves the sensor on its mount
    assert ds.meta["mujoco_warnings"] == {}


def test_soft_tissue_artefact_on_one_sensor(tmp_path):
    ds = session(tmp_path, "[skin]\nsta_by_sensor = { forearm_l = 0.03 }\n")
    move = np.linalg.norm(ds.truth.actual.p_w_s - ds.truth.rigid.p_w_s, axis=2)
    k = ds.sensors.index("forearm_l")
    assert np.delete(move, k, axis=1).max() == 0.0
    assert 0.005 < np.sqrt(np.mean(move[:, k] ** 2)) < 0.05  # centimetres, following the motion
    assert np.ptp(move[:, k]) > 0.005


def test_slip_event_found_by_the_detector(tmp_path):
    toml = '[[skin.slip]]\nsensor = "forearm_r"\ntime_s = 6.0\noffset_m = [0.0, 0.03, 0.0]\n'
    ds = session(tmp_path, toml, duration_s=12.0)
    k = ds.sensors.index("forearm_r")
    R_b = quat_to_matrix(ds.truth.q_w_b[:, k])
    offset = np.einsum("fji,fj->fi", R_b, ds.truth.actual.p_w_s[:, k] - ds.truth.rigid.p_w_s[:, k])
    assert_allclose(offset[ds.time_s < 5.999], 0.0, atol=1e-12)
    after = offset[ds.time_s > 6.051]  # the slip takes 50 ms
    assert_allclose(after, np.tile([0.0, 0.03, 0.0], (len(after), 1)), atol=1e-12)
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, parent_of=ds.truth.parent_of)
    j = next(j for j in cal.joints if j.child == "forearm_r")
    p = ds.sensors.index(j.parent)
    rep = detect_slip(
        rec.R_w_s[:, p],
        rec.p_w_s[:, p],
        rec.R_w_s[:, k],
        rec.p_w_s[:, k],
        j.fit.joint_in_parent,
        j.fit.joint_in_child,
        window=120,
        rate_hz=rec.rate_hz,
    )
    assert len(rep.events) == 1 and abs(ds.time_s[rep.events[0].frame] - 6.0) < 0.1
    assert rep.events[0].sensor_frame == "child"


def test_joint_laxity_moves_the_joint_centre(tmp_path):
    ds = session(tmp_path, "[skin]\nlaxity_by_joint = { forearm_l = 0.01 }\n")
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, parent_of=ds.truth.parent_of)
    rms = {j.child: j.fit.rms_residual for j in cal.joints}
    assert rms["forearm_l"] > 5e-4  # the lax elbow's centre wanders (up to ~1 cm per radian)
    assert max(v for c, v in rms.items() if c != "forearm_l") < 1e-9  # ideal joints stay exact


def test_magnetic_disturbance_is_local(tmp_path):
    toml = "[[magnetic.disturbance]]\nposition = [0.0, 0.0, 1.2]\nmoment_am2 = [0.0, 0.0, 1.0]\n"
    ds = session(tmp_path, toml, motion="static")
    earth = np.einsum("fsji,j->fsi", quat_to_matrix(ds.truth.actual.q_w_s), [0.0, 25.0, -43.30127018922193])
    extra = np.linalg.norm(ds.truth.actual.mag - earth, axis=2).mean(axis=0)
    dist = np.linalg.norm(ds.truth.actual.p_w_s - [0.0, 0.0, 1.2], axis=2).mean(axis=0)
    near, far = np.argmin(dist), np.argmax(dist)
    assert extra[near] > 5.0 and extra[far] < extra[near] / 10  # strong near it, weak far
    assert_allclose(extra * dist**3, (extra * dist**3)[0], rtol=1.0)  # same order once d^3 is removed


def test_calibration_error_grows_with_position_noise(tmp_path):
    errors = []
    for sigma in (0.0, 0.003, 0.012):
        toml = f"[tracker]\nposition_noise_m = {sigma}\ntransmitter_pos = [0.0, -0.8, 1.0]\n"
        errs = []
        for seed in (1, 2):
            ds = session(tmp_path, toml, seed=seed, duration_s=10.0)
            rec = ds.poses()
            cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, parent_of=ds.truth.parent_of)
            index = {n: k for k, n in enumerate(ds.sensors)}
            joints = [(index[a], index[b]) for a, b in zip(ds.truth.parent, ds.truth.child, strict=True)]
            truth = {
                (x.segment, x.joint_a, x.joint_b): x.length
                for x in segment_lengths(
                    ds.sensors, joints, ds.truth.joint_in_parent, ds.truth.joint_in_child
                )
            }
            errs += [abs(x.length - truth[(x.segment, x.joint_a, x.joint_b)]) for x in cal.lengths]
        errors.append(np.mean(errs))
    assert errors[0] < 1e-9  # exact without noise
    assert errors[1] > 10 * errors[0] and errors[2] > 2 * errors[1]  # ~x4 noise, clearly more error


def test_dropouts_are_marked_and_calibration_copes(tmp_path):
    ds = session(tmp_path, "[tracker]\ndropout_rate = 0.05\n")
    missing = ~ds.measured.valid
    assert 0.03 < missing.mean() < 0.07
    assert np.isnan(ds.measured.p_w_s[missing]).all()
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    assert cal.parent_of == ds.truth.parent_of or {frozenset(e) for e in cal.parent_of.items()} == {
        frozenset(e) for e in ds.truth.parent_of.items()
    }
    assert all(j.fit.n_dropped > 0 for j in cal.joints)


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ("[tracker]\nnoise = 1\n", r"tracker: unknown keys \['noise'\]"),
        (
            "[tracker]\nposition_noise_m = -0.1\n",
            "tracker: TrackerConfig.position_noise_m must be a finite number >= 0",
        ),
        ("[imu]\naccel_range = 'big'\n", "imu.accel_range: expected a number"),
        ("[skin]\nsta_by_sensor = { tail = 0.01 }\n", r"skin.sta_by_sensor names \['tail'\]"),
        ("[magnetic]\ninclination_deg = 120\n", r"inclination_deg must be in \[-90, 90\]"),
        (
            "[[tracker.distortion]]\nradius_m = 0\n",
            r"tracker.distortion\[0\]: distortion.radius_m must be > 0",
        ),
        ("colour = 'red'\n", r"unknown keys \['colour'\]"),
        ("[skin\n", "not valid TOML"),
    ],
)
def test_bad_configurations_name_the_key(tmp_path, toml, message):
    with pytest.raises(InputError, match=message):
        session(tmp_path, toml)


def test_unknown_preset(tmp_path):
    with pytest.raises(InputError, match="unknown sensor preset 'flock'"):
        session(tmp_path, preset="flock")
