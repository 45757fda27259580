"""Physics-simulated capture sessions (issue 3): models, programs, truth, determinism, errors."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import calibrate
from calibration.rotations import matrix_to_rotvec, quat_to_matrix
from calibration.skeleton import segment_lengths
from simbench.errors import InputError
from simbench.sim.models import EARTH_FIELD_UT, load_capture_model
from simbench.sim.physics import SETTLE_S, initial_state
from simbench.sim.programs import BUILTIN_PROGRAMS, joint_targets, root_pose
from simbench.sim.session import SessionConfig, plan_session, run_session

MODELS = ("linkage", "humanoid", "dm_control:humanoid_CMU")


@pytest.fixture(scope="module")
def capture_models():
    return {name: load_capture_model(name) for name in MODELS}


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("motion", BUILTIN_PROGRAMS)
def test_every_model_runs_every_program_without_warning(capture_models, model, motion):
    if motion == "gait" and model != "humanoid":
        with pytest.raises(InputError, match="motion 'gait' needs the humanoid's ball joints"):
            run_session(SessionConfig(model=model, motion=motion, duration_s=2.0), capture_models[model])
        return
    ds = run_session(SessionConfig(model=model, motion=motion, duration_s=2.0, seed=3), capture_models[model])
    assert ds.meta["mujoco_warnings"] == {}
    assert ds.measured.p_w_s.shape == (240, len(ds.sensors), 3)
    assert np.isfinite(ds.measured.p_w_s).all() and np.isfinite(ds.measured.acc).all()
    assert_allclose(ds.time_s, np.arange(240) / 120.0, atol=1e-9)
    if motion != "static":
        assert np.ptp(ds.truth.rigid.p_w_s, axis=0).max() > 0.05


@pytest.mark.parametrize("model", MODELS)
def test_static_settles(capture_models, model):
    ds = run_session(SessionConfig(model=model, motion="static", duration_s=4.0), capture_models[model])
    # nothing asked to move: after settling under gravity the body hangs still
    assert np.ptp(ds.truth.joint_w[-60:], axis=0).max() < 0.01
    assert ds.meta["mujoco_warnings"] == {}


def test_same_seed_same_dataset_other_seed_differs(capture_models, fresh_physics):
    cm = capture_models["linkage"]
    a = run_session(SessionConfig(motion="walk", duration_s=1.0, seed=5), cm)
    b = run_session(SessionConfig(motion="walk", duration_s=1.0, seed=5), cm)
    c = run_session(SessionConfig(motion="walk", duration_s=1.0, seed=6), cm)
    assert np.array_equal(a.measured.p_w_s, b.measured.p_w_s)
    assert np.array_equal(a.measured.acc, b.measured.acc)
    assert not np.array_equal(a.measured.p_w_s, c.measured.p_w_s)
    # frozen, and no memory shared between datasets
    assert not a.measured.p_w_s.flags.writeable
    assert not np.shares_memory(a.measured.p_w_s, b.measured.p_w_s)


def test_readings_are_mujocos_sensors_at_the_sample_times(capture_models):
    """Replay the same controls with a plain mj_step loop: every sample equals MuJoCo's data."""
    cm = load_capture_model("linkage")
    config = SessionConfig(motion="exercise", duration_s=0.25, seed=2)
    ds = run_session(config, cm)
    plan = plan_session(config, cm)
    program, phases = plan.program, plan.root_phases
    m = cm.model
    d = initial_state(cm, joint_targets(program, cm, np.zeros(1))[0])
    p0, q0 = d.mocap_pos[0].copy(), d.mocap_quat[0].copy()
    k = ds.meta["steps_per_sample"]
    for _ in range(round(SETTLE_S / m.opt.timestep)):  # settle holding the first set-points
        mujoco.mj_step(m, d)
    d.time = 0.0
    site = cm.site_ids[3]
    for step in range(ds.time_s.size * k):
        t = np.array([step * m.opt.timestep])
        d.ctrl[:] = joint_targets(program, cm, t)[0]
        pos, quat = root_pose(program, p0, q0, t, phases)
        d.mocap_pos[0], d.mocap_quat[0] = pos[0], quat[0]
        mujoco.mj_step(m, d)  # sensors are evaluated at the start of the step
        if step % k == 0:
            f = step // k
            assert_allclose(
                ds.measured.p_w_s[f, 3], d.sensordata[cm.adr["site_pos"][3] + np.arange(3)], atol=1e-12
            )
            assert_allclose(ds.measured.acc[f, 3], d.sensordata[cm.adr["acc"][3] + np.arange(3)], atol=1e-9)
    assert site >= 0


def test_ideal_readings_agree_with_finite_differences_of_true_poses(capture_models):
    cm = capture_models["linkage"]
    ds = run_session(SessionConfig(motion="exercise", duration_s=3.0, rate_hz=1200.0, seed=4), cm)
    t = ds.truth.rigid
    h = 1.0 / 1200.0
    R = quat_to_matrix(t.q_w_s)
    # magnetometer: the Earth field seen in the sensor frame, exactly
    assert_allclose(t.mag, np.einsum("fsji,j->fsi", R, EARTH_FIELD_UT), atol=1e-9)
    # accelerometer: R^T (d2p/dt2 - g); central differences at the physics step
    a_w = (t.p_w_s[2:] - 2 * t.p_w_s[1:-1] + t.p_w_s[:-2]) / h**2
    expected = np.einsum("fsji,fsj->fsi", R[1:-1], a_w - np.array([0.0, 0.0, -9.81]))
    err = np.abs(expected - t.acc[1:-1])
    # second differences of positions after the implicit integrator: O(h) off; 2 % of the range
    assert np.percentile(err, 99) < 0.02 * np.abs(t.acc).max()
    # gyro: the rotation from one sample to the next, in the sensor frame, over h
    w_fd = matrix_to_rotvec(np.einsum("fsji,fsjk->fsik", R[:-1], R[1:])) / h
    err_w = np.abs(w_fd - t.gyro[:-1])
    assert np.percentile(err_w, 99) < 0.02 * np.abs(t.gyro).max()


@pytest.mark.parametrize("model", ["linkage", "humanoid"])
def test_noise_free_session_calibrates_exactly(capture_models, model):
    # the paper's 45 s: each joint gets about 3 s of its own
    ds = run_session(
        SessionConfig(model=model, motion="exercise", duration_s=45.0, seed=1), capture_models[model]
    )
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, root=ds.sensors[0])
    assert cal.parent_of == ds.truth.parent_of
    index = {name: k for k, name in enumerate(ds.sensors)}
    joints = [(index[p], index[c]) for p, c in zip(ds.truth.parent, ds.truth.child, strict=True)]
    truth = {
        (x.segment, x.joint_a, x.joint_b): x.length
        for x in segment_lengths(ds.sensors, joints, ds.truth.joint_in_parent, ds.truth.joint_in_child)
    }
    assert len(cal.lengths) == len(truth)
    for x in cal.lengths:
        # MuJoCo's joints are exact: the issue asks 1e-6 m; rounding gives ~1e-14
        assert x.length == pytest.approx(truth[(x.segment, x.joint_a, x.joint_b)], abs=1e-6), x
    if model == "linkage":
        lengths = sorted(round(x.length * 100, 6) for x in cal.lengths)
        assert lengths == [28.6, 31.4, 34.3, 39.0, 39.7]  # the paper's linkage, cm


def test_cmu_single_axis_knees_flagged(capture_models):
    ds = run_session(
        SessionConfig(model="dm_control:humanoid_CMU", motion="exercise", duration_s=60.0, seed=0),
        capture_models["dm_control:humanoid_CMU"],
    )
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, parent_of=ds.truth.parent_of)
    fits = {j.child: j.fit for j in cal.joints}
    for knee in ("ltibia", "rtibia"):
        assert fits[knee].single_axis
        truth_axis = ds.truth.axis_in_parent[ds.truth.child.index(knee)]
        assert abs(fits[knee].axis_in_parent @ truth_axis) > 1 - 1e-9
    for hip in ("lfemur", "rfemur"):  # three hinges through one point: a ball joint
        assert not fits[hip].single_axis and fits[hip].rank == 6
    assert ds.truth.single_axis[ds.truth.child.index("ltibia")]


def test_bad_configurations(capture_models, tmp_path):
    with pytest.raises(InputError, match="unknown model 'robot'"):
        load_capture_model("robot")
    with pytest.raises(InputError, match="no body 'tail'"):
        load_capture_model("linkage", sensor_bodies=["chest", "tail"])
    with pytest.raises(InputError, match="joined by the joints of exactly one body"):
        load_capture_model("linkage", sensor_bodies=["chest", "forearm_l"])
    with pytest.raises(InputError, match="duration must be > 0"):
        SessionConfig(duration_s=0.0)
    with pytest.raises(InputError, match="above the model's physics rate 1200 Hz"):
        run_session(SessionConfig(rate_hz=2000.0, duration_s=1.0), capture_models["linkage"])
    with pytest.raises(InputError, match="unknown motion 'dance'"):
        run_session(SessionConfig(motion="dance", duration_s=1.0), capture_models["linkage"])
    program = tmp_path / "p.toml"
    program.write_text(
        "[[phase]]\nstart_s = 0\nend_s = 1\n[phase.joints.knee]\namplitude_rad = [1]\nfrequency_hz = [1]\n"
    )
    with pytest.raises(InputError, match="has no joint 'knee'"):
        run_session(SessionConfig(motion=str(program), duration_s=1.0), capture_models["linkage"])


def test_user_program_from_toml(capture_models, tmp_path):
    program = tmp_path / "wave.toml"
    program.write_text(
        'name = "wave"\nroot = "still"\n[[phase]]\nstart_s = 0.0\nend_s = 2.0\n'
        "[phase.joints.shoulder_l]\namplitude_rad = [0.0, 0.0, 0.8]\nfrequency_hz = [0.5, 0.5, 1.0]\n"
    )
    ds = run_session(SessionConfig(motion=str(program), duration_s=2.0), capture_models["linkage"])
    assert ds.meta["program"] == "wave"
    moved = np.ptp(ds.truth.rigid.p_w_s, axis=0).max(axis=1)
    names = list(ds.sensors)
    # the left arm moves, the rest (root still, other joints held) barely does
    assert moved[names.index("forearm_l")] > 0.1
    assert moved[names.index("forearm_r")] < 0.25 * moved[names.index("forearm_l")]
