"""A BVH clip drives a capture session: its own MJCF skeleton, its motion played back exactly.

The clips are written here (small, a few seconds) with the chain of ``tests/test_bvh.py``: the
expected poses come from the file's numbers composed independently of the reader and the model.
"""

from __future__ import annotations

import dataclasses
import re

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench as sb
from calibration.rotations import quat_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.bvh import Y_UP_TO_Z_UP, read_bvh
from simbench.sim.bvh_model import DENSITY_KG_M3, bvh_mjcf, capsule_radius
from simbench.sim.sensor_config import load_sensor_config
from tests.test_bvh import ORDERS, _bvh

C = Y_UP_TO_Z_UP
FRAME_TIME = 0.01
ROOT_OFFSET_CM = np.array([1.0, 90.0, -2.0])  # the hips' OFFSET in test_bvh's clip


def _smooth_clip(frames: int = 300) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Angles (deg) and root path (cm) of a smooth clip: slow sines, well below the cutoff."""
    t = np.arange(frames) * FRAME_TIME
    angles = {
        name: np.stack(
            [40 * np.sin(np.pi * t + i), 30 * np.sin(2 * np.pi * 0.7 * t + i), 60 * np.sin(0.9 * t)], 1
        )
        for i, name in enumerate(ORDERS)
    }
    root = np.stack([20 * np.sin(t), 10 * t, 5 * np.cos(t)], 1)
    return angles, root


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    angles, root = _smooth_clip()
    path = tmp_path_factory.mktemp("bvh") / "clip.bvh"
    path.write_text(_bvh(angles, root, FRAME_TIME))
    return path, angles, root


@pytest.fixture(scope="module")
def spin(tmp_path_factory):
    """Constant rates: the hips turn about the vertical (BVH's y) at 90 deg/s, the chest about its
    own x at 60 deg/s, the head still; the root does not translate."""
    frames = 300
    t = np.arange(frames) * FRAME_TIME
    zero = np.zeros(frames)
    angles = {  # ORDERS: hips ZXY, chest XYZ, head YZX
        "hips": np.stack([zero, zero, 90.0 * t], 1),
        "chest": np.stack([60.0 * t, zero, zero], 1),
        "head": np.zeros((frames, 3)),
    }
    path = tmp_path_factory.mktemp("bvh") / "spin.bvh"
    path.write_text(_bvh(angles, np.zeros((frames, 3)), FRAME_TIME))
    return path


@pytest.fixture(scope="module")
def played(clip):
    return sb.simulate(motion=str(clip[0]), sensors="mems-industrial", seed=3)


def _elementary(axis: str, deg: np.ndarray) -> np.ndarray:
    return Rotation.from_euler(axis.lower(), deg, degrees=True).as_matrix()


def test_truth_is_the_file_exactly(clip, played):
    _, angles, root = clip
    ds = played
    assert ds.sensors == ("hips", "chest", "head") and ds.meta["model"] == "bvh"
    assert ds.time_s.size == 300 and ds.meta["rate_hz"] == pytest.approx(100.0)
    np.testing.assert_allclose(ds.time_s, np.arange(300) * FRAME_TIME, atol=1e-12)
    assert ds.meta["mujoco_warnings"] == {} and ds.meta["playback"]["resampled"] is False
    R_w_b = quat_to_matrix(ds.truth.q_w_b)
    # each joint's rotation, its frame into its parent's, back to the file's Euler angles (rad)
    up = {"chest": 0, "head": 1}
    for k, name in enumerate(ds.sensors):
        R = R_w_b[:, k] if k == 0 else np.einsum("fji,fjk->fik", R_w_b[:, up[name]], R_w_b[:, k])
        back = Rotation.from_matrix(C.T @ R @ C).as_euler(ORDERS[name], degrees=False)
        diff = np.angle(np.exp(1j * (back - np.deg2rad(angles[name]))))
        assert np.abs(diff).max() < 1e-6, name
    # the root path: the file's OFFSET plus its position channels, cm -> m, y up -> z up
    expected = (ROOT_OFFSET_CM + root) @ C.T / 100
    assert np.abs(ds.truth.p_w_b[:, 0] - expected).max() < 1e-6


def test_skeleton_model_loads_without_warnings_and_has_the_stated_masses(clip):
    motion = read_bvh(clip[0])
    m = mujoco.MjModel.from_xml_string(bvh_mjcf(motion))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for _ in range(10):
        mujoco.mj_step(m, d)
    assert all(w.number == 0 for w in d.warning)
    assert [m.body(b).name for b in range(1, m.nbody)] == list(motion.names)
    kinds = [int(m.jnt_type[j]) for j in range(m.njnt)]
    assert kinds == [mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL, mujoco.mjtJoint.mjJNT_BALL]
    np.testing.assert_allclose(m.body_pos[2], motion.offset_m[1], atol=1e-15)
    # the head: one capsule to its End Site, radius by the stated rule, water density
    length = float(np.linalg.norm(motion.end_sites_m["head"][0]))
    r = capsule_radius(length)
    mass = DENSITY_KG_M3 * (np.pi * r * r * length + 4 / 3 * np.pi * r**3)
    assert m.body_mass[3] == pytest.approx(mass, rel=1e-9)
    assert all(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"sensor_{n}") >= 0 for n in motion.names)


def test_imu_session_orientation_truth_is_the_forward_kinematics(clip, played):
    ds = played
    motion = read_bvh(clip[0])
    R_w_j, p_w_j = motion.world()
    R_b_s = quat_to_matrix(ds.truth.q_b_s)
    R_w_s = quat_to_matrix(ds.truth.rigid.q_w_s)
    assert np.abs(R_w_s - R_w_j @ R_b_s[None]).max() < 1e-12
    p_w_s = p_w_j + np.einsum("fsab,sb->fsa", R_w_j, ds.truth.p_b_s)
    assert np.abs(ds.truth.rigid.p_w_s - p_w_s).max() < 1e-12
    # the IMU measured something, with its noise: near the truth, not equal to it
    err = ds.measured.gyro - ds.truth.actual.gyro
    assert 0 < np.abs(err).mean() < 0.05
    # the gyroscope's truth is the rate of the file's rotations (a central difference of them agrees
    # to its own error, O(dt^2))
    rel = np.einsum("fsji,fsjk->fsik", R_w_s[:-2], R_w_s[2:])
    w_fd = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(-1, 3, 3) / (2 * FRAME_TIME)
    assert np.abs(ds.truth.rigid.gyro[1:-1] - w_fd).max() < 0.02


def test_constant_rate_rotation_gives_the_known_rates(spin):
    ds = sb.simulate(motion=str(spin))
    # the head never turns in its parent: welded to the chest, no joint and no sensor of its own
    assert ds.sensors == ("hips", "chest")
    w_hips, w_chest = np.deg2rad(90.0), np.deg2rad(60.0)
    R_w_b = quat_to_matrix(ds.truth.q_w_b)
    R_b_s = quat_to_matrix(ds.truth.q_b_s)
    # body frames: the hips turn about world z, the chest about its own x on top of that
    w_b = np.zeros((ds.time_s.size, 2, 3))
    w_b[:, 0] = [0.0, 0.0, w_hips]
    w_b[:, 1] = np.einsum("fji,j->fi", R_w_b[:, 1], [0.0, 0.0, w_hips])
    w_b[:, 1, 0] += w_chest
    expected = np.einsum("sji,fsj->fsi", R_b_s, w_b)
    # the smoothing's accuracy (simbench.sim.playback): measured 2.9e-6 rad/s at the clip's ends,
    # 5.2e-7 rad/s a window away from them (rates of 1.6 rad/s, cutoff 6 Hz, 29-frame window)
    gyro_error = np.abs(ds.truth.rigid.gyro - expected).max(axis=(1, 2))
    window = ds.meta["playback"]["window_frames"]
    assert gyro_error.max() < 5e-6 and gyro_error[window:-window].max() < 1e-6, gyro_error
    # the hips' accelerometer: centripetal about the vertical axis through the hips, and gravity
    R_w_s = quat_to_matrix(ds.truth.rigid.q_w_s[:, 0])
    r = ds.truth.rigid.p_w_s[:, 0] - ds.truth.p_w_b[:, 0]
    a_w = -(w_hips**2) * r * [1.0, 1.0, 0.0] - mujoco.MjModel.from_xml_string("<mujoco/>").opt.gravity
    expected_acc = np.einsum("fji,fj->fi", R_w_s, a_w)
    # measured 3.8e-6 m/s^2 of about 10 (the smoothed rate squared, and its derivative, not exactly 0)
    assert np.abs(ds.truth.rigid.acc[:, 0] - expected_acc).max() < 1e-5


def test_another_rate_resamples_the_smoothed_motion(clip, played):
    ds = sb.simulate(motion=str(clip[0]), rate_hz=200.0, duration_s=2.0)
    assert ds.meta["playback"]["resampled"] is True and ds.time_s.size == 400
    np.testing.assert_allclose(ds.time_s[-1], 399 / 200, atol=1e-12)
    # every other sample falls on a frame: the smoothed motion there is near the recorded one
    R = quat_to_matrix(ds.truth.q_w_b[::2])
    R0 = quat_to_matrix(played.truth.q_w_b[:200])
    angle = Rotation.from_matrix(np.einsum("fsji,fsjk->fsik", R0, R).reshape(-1, 3, 3)).magnitude()
    assert angle.max() < 1e-3
    assert np.abs(ds.truth.rigid.gyro[::2] - played.truth.rigid.gyro[:200]).max() < 1e-3


def test_bad_inputs_are_clear_errors(clip, tmp_path):
    path = str(clip[0])
    with pytest.raises(InputError, match="its own skeleton: leave the model at its default or give 'bvh'"):
        sb.simulate(model="humanoid", motion=path)
    with pytest.raises(InputError, match=r"not the rate 10 Hz.*cannot be resampled.*above 12 Hz"):
        sb.simulate(motion=path, rate_hz=10.0)
    with pytest.raises(InputError, match=r"the clip lasts 300 frames.*at most 3 s"):
        sb.simulate(motion=path, duration_s=5.0)
    ideal = load_sensor_config("ideal")
    with_play = dataclasses.replace(ideal, joints=dataclasses.replace(ideal.joints, play_m=0.001))
    with pytest.raises(
        InputError, match=r"joint play moves by contact physics.*sets every joint kinematically"
    ):
        sb.simulate(motion=path, sensors=with_play)
    with pytest.raises(InputError, match="does not exist"):
        sb.simulate(motion=str(tmp_path / "none.bvh"))
    with pytest.raises(InputError, match=r"give a \.bvh motion"):
        sb.SessionConfig(model="bvh", motion="exercise")


def test_cli_simulate_motion_bvh_writes_a_dataset(clip, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "clip.bvh").write_text(clip[0].read_text())
    assert main(["simulate", "--motion", "clip.bvh", "--sensors", "mems-industrial", "-o", "out.h5"]) == 0
    out = capsys.readouterr().out
    assert "model bvh, motion bvh:clip.bvh" in out and "300 at 100 Hz   played back" in out
    ds = sb.read_dataset(tmp_path / "out.h5")
    assert ds.sensors == ("hips", "chest", "head") and ds.time_s.size == 300
    code = main(["simulate", "--motion", "clip.bvh", "--model", "linkage", "-o", "x.h5"])
    err = capsys.readouterr().err
    assert code != 0 and re.search("own skeleton", err), err
    # lengths in metres: the skeleton is a hundred times larger
    argv = ["simulate", "--motion", "clip.bvh", "--motion-units", "m", "--duration", "1", "-o", "m.h5"]
    assert main(argv) == 0
    big = sb.read_dataset(tmp_path / "m.h5")
    np.testing.assert_allclose(big.truth.p_w_b[:, 0], ds.truth.p_w_b[:100, 0] * 100, rtol=1e-12, atol=1e-12)
