"""Recorded motions other than BVH drive a session: ``qpos`` series and rigid-body pose trajectories.

The expected poses are computed independently of the playback: MuJoCo's forward kinematics of the
same ``qpos`` on the model as read (no sensors, no driver), the pose CSV's own numbers, analytic
rates of a constant-rate motion.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench as sb
from calibration.rotations import quat_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.qpos import model_joints, write_qpos_npz
from simbench.io.recorded import fill_gaps, frame_grid
from simbench.sim.mjcf import compile_spec, read_spec
from simbench.sim.pose_model import read_broad_poses

RATE = 100.0
FRAMES = 200
BROAD_EXCERPT = str(
    Path(__file__).resolve().parent.parent / "simbench/data/broad_02_undisturbed_slow_rotation_B_60s.hdf5"
)


def _linkage_qpos() -> tuple[mujoco.MjModel, np.ndarray, np.ndarray]:
    """A smooth ``qpos`` series of the linkage: each ball joint turning through slow sines, the
    root moving and turning."""
    m = compile_spec(read_spec("linkage"), "linkage")
    t = np.arange(FRAMES) / RATE
    qpos = np.tile(m.qpos0, (FRAMES, 1))
    for k, (_name, kind, adr) in enumerate(model_joints(m)):
        rv = 0.4 * np.stack([np.sin(1.3 * t + k), np.cos(0.7 * t + 2 * k), np.sin(0.5 * t)], 1)
        q = Rotation.from_rotvec(rv).as_quat(scalar_first=True)
        if kind == "free":
            qpos[:, adr : adr + 3] = m.qpos0[adr : adr + 3] + 0.1 * np.stack([np.sin(t), t, np.cos(t) - 1], 1)
            qpos[:, adr + 3 : adr + 7] = q
        elif kind == "ball":
            qpos[:, adr : adr + 4] = q
    return m, qpos, t


def _body_poses(
    m: mujoco.MjModel, qpos: np.ndarray, bodies: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray]:
    """``(R_w_b, p_w_b)`` of named bodies by MuJoCo's forward kinematics of each ``qpos`` row."""
    d = mujoco.MjData(m)
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for b in bodies]
    R = np.empty((len(qpos), len(ids), 3, 3))
    p = np.empty((len(qpos), len(ids), 3))
    for f, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        R[f] = d.xmat[ids].reshape(-1, 3, 3)
        p[f] = d.xpos[ids]
    return R, p


@pytest.fixture(scope="module")
def linkage_npz(tmp_path_factory):
    m, qpos, t = _linkage_qpos()
    path = tmp_path_factory.mktemp("qpos") / "linkage.npz"
    write_qpos_npz(path, qpos, t, model="linkage")
    return path, m, qpos, t


def test_qpos_archive_round_trip_is_the_forward_kinematics(linkage_npz):
    path, m, qpos, _t = linkage_npz
    ds = sb.simulate(motion=str(path))  # the archive names its model
    assert ds.meta["model"] == "linkage" and ds.meta["playback"]["format"] == "qpos"
    assert ds.time_s.size == FRAMES and ds.meta["rate_hz"] == pytest.approx(RATE)
    R, p = _body_poses(m, qpos, ds.sensors)
    assert np.abs(quat_to_matrix(ds.truth.q_w_b) - R).max() < 1e-9
    assert np.abs(ds.truth.p_w_b - p).max() < 1e-9
    # the gyroscope's truth is the rate of those rotations (a central difference agrees to O(dt^2))
    R_w_s = quat_to_matrix(ds.truth.rigid.q_w_s)
    rel = np.einsum("fsji,fsjk->fsik", R_w_s[:-2], R_w_s[2:])
    w_fd = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape((*rel.shape[:2], 3)) * RATE / 2
    assert np.abs(ds.truth.rigid.gyro[1:-1] - w_fd).max() < 5e-3


def test_qpos_csv_plays_as_the_archive(linkage_npz, tmp_path):
    path, m, qpos, t = linkage_npz
    header, cols = ["time_s"], [t]
    for name, kind, adr in model_joints(m):
        suffix = {"free": ("x", "y", "z", "qw", "qx", "qy", "qz"), "ball": ("qw", "qx", "qy", "qz")}[kind]
        header += [f"{name}.{c}" for c in suffix]
        cols += [qpos[:, adr + i] for i in range(len(suffix))]
    csv = tmp_path / "linkage_qpos.csv"
    rows = np.stack(cols, 1)
    csv.write_text(
        ",".join(header) + "\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in rows) + "\n"
    )
    a = sb.simulate(motion=str(path))
    b = sb.simulate("linkage", str(csv))
    assert np.abs(a.truth.q_w_b - b.truth.q_w_b).max() < 1e-12
    assert np.abs(a.truth.rigid.acc - b.truth.rigid.acc).max() < 1e-9


def test_a_joint_left_out_stays_at_its_reference(tmp_path):
    m = compile_spec(read_spec("linkage"), "linkage")
    name, _kind, adr = next(j for j in model_joints(m) if j[1] == "ball")
    t = np.arange(50) / RATE
    q = Rotation.from_rotvec(np.outer(np.sin(t), [0.3, 0, 0])).as_quat(scalar_first=True)
    csv = tmp_path / "one.csv"
    csv.write_text(
        "time_s,"
        + ",".join(f"{name}.{c}" for c in ("qw", "qx", "qy", "qz"))
        + "\n"
        + "\n".join(",".join(map(repr, [float(ti), *map(float, qi)])) for ti, qi in zip(t, q, strict=True))
    )
    ds = sb.simulate("linkage", str(csv))
    full = np.tile(m.qpos0, (50, 1))
    full[:, adr : adr + 4] = q
    R, _ = _body_poses(m, full, ds.sensors)
    assert np.abs(quat_to_matrix(ds.truth.q_w_b) - R).max() < 1e-9


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time_s,nope\n0,1\n0.01,1\n", "name no coordinate of the model"),
        ("time_s,j1.qw\n0,1\n0.01,1\n", "needs columns"),
        ("time\n0\n", "no column 'time_s'"),
        ("time_s,j1.qw,j1.qx,j1.qy,j1.qz\n0,1,0,0,0\n0.01,1,0,0\n", "line 3: 4 fields"),
        ("time_s,j1.qw,j1.qx,j1.qy,j1.qz\n0,1,0,0,0\n0.01,nan,0,0,0\n", "line 3, column 'j1.qw'"),
        (
            "time_s,j1.qw,j1.qx,j1.qy,j1.qz\n0,1,0,0,0\n0.01,2,0,0,0\n",
            "line 3: joint 'j1''s quaternion has norm 2",
        ),
        (
            "time_s,j1.qw,j1.qx,j1.qy,j1.qz\n0,1,0,0,0\n0.01,1,0,0,0\n0.0149,1,0,0,0\n0.03,1,0,0,0\n",
            "line 4: time 0.0149 s is off the recording's frame grid",
        ),
    ],
)
def test_bad_qpos_csv_gets_one_line_naming_file_and_line(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text.replace("j1", _a_ball_joint()))
    with pytest.raises(InputError) as err:
        sb.simulate("linkage", str(path))
    assert str(path) in str(err.value) and message.replace("j1", _a_ball_joint()) in str(err.value)
    assert "\n" not in str(err.value)


def _a_ball_joint() -> str:
    m = compile_spec(read_spec("linkage"), "linkage")
    return next(n for n, k, _ in model_joints(m) if k == "ball")


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"time_s": np.arange(3.0)}, "no array 'qpos'"),
        ({"qpos": np.zeros((3, 2)), "rate_hz": 10.0}, "qpos has 2 columns; the model has nq"),
        (
            {"qpos": np.zeros((3, 4)), "joints": np.array(["nope"]), "rate_hz": 10.0},
            "joints ['nope'] are not",
        ),
        ({"qpos": np.full((3, 1), np.nan), "rate_hz": 10.0}, "qpos[0, 0] is nan"),
        ({"qpos": np.zeros((3, 27))}, "give 'time_s'"),
    ],
)
def test_bad_qpos_archive_gets_one_line_naming_the_file(tmp_path, arrays, message):
    path = tmp_path / "bad.npz"
    np.savez(path, **arrays)
    with pytest.raises(InputError) as err:
        sb.simulate("linkage", str(path))
    assert str(path) in str(err.value) and message in str(err.value)


def test_a_qpos_series_without_a_model_asks_for_one(tmp_path):
    path = tmp_path / "nomodel.npz"
    np.savez(path, qpos=np.zeros((3, 4)), rate_hz=10.0)
    with pytest.raises(InputError, match="plays on a model: give one"):
        sb.simulate(motion=str(path))


def _pose_csv(path, t, p, q, names=("a", "b"), drop=()):
    lines = ["time,sensor,x,y,z,qw,qx,qy,qz"]
    for f in range(t.size):
        if f in drop:
            continue
        for k, n in enumerate(names):
            lines.append(",".join([repr(float(t[f])), n, *(repr(float(x)) for x in (*p[f, k], *q[f, k]))]))
    path.write_text("\n".join(lines) + "\n")


def _spinning_pair(frames: int = FRAMES):
    """Two bodies: ``a`` turning about world z at 1.5 rad/s on a 0.3 m circle (its x axis along the
    radius), ``b`` still and tilted."""
    t = np.arange(frames) / RATE
    w, r = 1.5, 0.3
    p = np.zeros((frames, 2, 3))
    p[:, 0] = np.stack([r * np.cos(w * t), r * np.sin(w * t), np.full(frames, 1.0)], 1)
    p[:, 1] = [0.5, -0.2, 0.8]
    q = np.zeros((frames, 2, 4))
    q[:, 0] = Rotation.from_rotvec(np.outer(w * t, [0, 0, 1])).as_quat(scalar_first=True)
    q[:, 1] = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_quat(scalar_first=True)
    return t, p, q, w, r


def test_pose_csv_bodies_follow_the_recorded_poses_with_the_analytic_readings(tmp_path):
    t, p, q, w, r = _spinning_pair()
    path = tmp_path / "poses.csv"
    _pose_csv(path, t, p, q)
    ds = sb.simulate(motion=str(path))
    assert ds.meta["model"] == "poses" and ds.sensors == ("a", "b")
    assert np.abs(ds.truth.rigid.p_w_s - p).max() < 1e-12
    assert np.abs(quat_to_matrix(ds.truth.rigid.q_w_s) - quat_to_matrix(q)).max() < 1e-12
    # a: rate w about its own z; specific force: centripetal -w^2 r along its own x, gravity up its z
    g = -mujoco.MjModel.from_xml_string("<mujoco/>").opt.gravity[2]
    window = ds.meta["playback"]["window_frames"]
    inner = slice(window, -window)
    np.testing.assert_allclose(
        ds.truth.rigid.gyro[inner, 0], np.tile([0, 0, w], (FRAMES - 2 * window, 1)), atol=1e-6
    )
    np.testing.assert_allclose(
        ds.truth.rigid.acc[inner, 0], np.tile([-w * w * r, 0, g], (FRAMES - 2 * window, 1)), atol=1e-5
    )
    # b: still, gravity only, in its tilted frame
    np.testing.assert_allclose(ds.truth.rigid.gyro[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(
        ds.truth.rigid.acc[:, 1], np.tile(quat_to_matrix(q[0, 1]).T @ [0, 0, g], (FRAMES, 1)), atol=1e-9
    )


def test_dropped_frames_are_filled_and_counted(tmp_path):
    t, p, q, _w, _r = _spinning_pair()
    path = tmp_path / "gaps.csv"
    _pose_csv(path, t, p, q, drop=(50, 51, 52, 120))
    ds = sb.simulate(motion=str(path))
    assert ds.time_s.size == FRAMES and ds.meta["playback"]["frames_filled"] == 4
    # the filled frames: spherical interpolation of a constant-rate turn is the turn itself
    assert np.abs(quat_to_matrix(ds.truth.rigid.q_w_s) - quat_to_matrix(q)).max() < 1e-9
    assert np.abs(ds.truth.rigid.p_w_s[:, 1] - p[:, 1]).max() < 1e-12


def test_fill_gaps_slerps_rotations_and_interpolates_positions():
    valid = np.array([True, False, False, True, False])
    q0, q1 = Rotation.from_rotvec([0, 0, 0]), Rotation.from_rotvec([0, 0, 0.9])
    v = np.zeros((5, 7))
    v[0, :3], v[3, :3] = [0, 0, 0], [3, 6, 9]
    v[0, 3:], v[3, 3:] = q0.as_quat(scalar_first=True), q1.as_quat(scalar_first=True)
    out = fill_gaps(v, valid, slice(3, 7))
    np.testing.assert_allclose(out[:4, :3], [[0, 0, 0], [1, 2, 3], [2, 4, 6], [3, 6, 9]], atol=1e-12)
    np.testing.assert_allclose(out[4, :3], [3, 6, 9])  # held at the end
    angles = Rotation.from_quat(out[:, 3:], scalar_first=True).as_rotvec()[:, 2]
    np.testing.assert_allclose(angles, [0, 0.3, 0.6, 0.9, 0.9], atol=1e-12)


def test_frame_grid_places_dropped_frames_and_refuses_off_grid_stamps():
    t = np.array([0.0, 0.01, 0.03, 0.04, 0.0500004])
    period, frame = frame_grid(t, "x.csv")
    assert period == pytest.approx(0.01, rel=1e-4) and frame.tolist() == [0, 1, 3, 4, 5]
    with pytest.raises(InputError, match=r"x.csv, line 5: time 0.025 s is off"):
        frame_grid(np.array([0.0, 0.01, 0.02, 0.025, 0.04]), "x.csv")
    with pytest.raises(InputError, match=r"x.csv, line 4: time 0.005 s does not follow"):
        frame_grid(np.array([0.0, 0.01, 0.005]), "x.csv")


def test_broad_optical_pose_drives_the_one_imu():
    poses = read_broad_poses(BROAD_EXCERPT)
    ds = sb.simulate(motion=BROAD_EXCERPT)
    assert ds.sensors == ("imu",) and ds.meta["model"] == "poses"
    assert ds.time_s.size == poses.n_frames and ds.meta["rate_hz"] == pytest.approx(2000 / 7)
    ok = poses.valid[:, 0]
    assert ds.meta["playback"]["frames_filled"] == int((~ok).sum()) > 0
    assert np.abs(ds.truth.rigid.p_w_s[ok, 0] - poses.p_w_s[ok, 0]).max() < 1e-12
    assert np.abs(quat_to_matrix(ds.truth.rigid.q_w_s[ok, 0]) - poses.R_w_s[ok, 0]).max() < 1e-12


def test_a_file_without_an_optical_pose_is_named(tmp_path):
    import h5py

    path = tmp_path / "imu_only.hdf5"
    with h5py.File(path, "w") as fh:
        fh["imu_acc"] = np.zeros((10, 3))
        fh.attrs["sampling_rate"] = 100.0
    with pytest.raises(InputError, match=r"imu_only.hdf5: expected BROAD.s optical pose .* .opt_quat."):
        sb.simulate(motion=str(path))


def test_a_motion_that_brings_its_bodies_refuses_another_model(tmp_path):
    t, p, q, *_ = _spinning_pair(20)
    path = tmp_path / "poses.csv"
    _pose_csv(path, t, p, q)
    with pytest.raises(InputError, match="moves its own bodies"):
        sb.simulate("humanoid", str(path))
    with pytest.raises(InputError, match="model 'poses' is the bodies of a pose trajectory"):
        sb.simulate("poses", "exercise")


def test_cli_simulates_each_source_from_a_temporary_folder(tmp_path, monkeypatch, linkage_npz, capsys):
    t, p, q, *_ = _spinning_pair()
    _pose_csv(tmp_path / "poses.csv", t, p, q)
    monkeypatch.chdir(tmp_path)
    for motion, extra in (
        (str(linkage_npz[0]), []),
        ("poses.csv", []),
        (BROAD_EXCERPT, ["--duration", "5"]),
    ):
        assert (
            main(["simulate", "--motion", motion, "--sensors", "mems-industrial", "-o", "out.h5", *extra])
            == 0
        )
        out = capsys.readouterr().out
        assert "played back" in out and "wrote out.h5" in out
        ds = sb.read("out.h5")
        assert np.isfinite(ds.measured.gyro).all()


def test_c3d_marker_clusters_move_bodies_rigidly_with_the_segments_they_ride(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    truth = sb.simulate("linkage", "exercise", duration_s=3, markers=True, seed=2)
    from simbench.io.dataset import write_dataset

    write_dataset("d.h5", truth)
    assert main(["export", "d.h5", "--c3d", "m.c3d"]) == 0
    ds = sb.simulate(motion="m.c3d")
    assert ds.meta["model"] == "poses" and ds.time_s.size == truth.time_s.size
    R_true = quat_to_matrix(truth.truth.q_w_b)
    R_c3d = quat_to_matrix(ds.truth.rigid.q_w_s)
    for k, cluster in enumerate(ds.sensors):
        segment = truth.sensors.index(cluster.split("_M")[0])
        # a cluster of ideal markers is fixed on its segment: their relative pose does not change
        rel = np.einsum("fji,fjk->fik", R_true[:, segment], R_c3d[:, k])
        assert np.abs(rel - rel[0]).max() < 1e-5, cluster
        r = np.einsum(
            "fji,fj->fi", R_true[:, segment], ds.truth.rigid.p_w_s[:, k] - truth.truth.p_w_b[:, segment]
        )
        assert np.abs(r - r[0]).max() < 1e-5, cluster


def test_a_study_varies_sensors_on_a_recorded_motion(tmp_path):
    from simbench.experiments import study as st
    from simbench.experiments import sweep as sw
    from tests.test_bvh import _bvh
    from tests.test_bvh_session import FRAME_TIME, _smooth_clip

    angles, root = _smooth_clip(400)
    (tmp_path / "clip.bvh").write_text(_bvh(angles, root, FRAME_TIME))
    path = tmp_path / "study.toml"
    path.write_text(
        'name = "recorded"\nseed = 1\nseeds_per_cell = 2\nestimators = ["calibration"]\n'
        'metrics = ["joint_centre_error_m"]\n[base]\nmotion = "clip.bvh"\nsensors = "ascension-flock"\n'
        '[sampling]\nkind = "grid"\n[[parameter]]\nname = "sensors.tracker.position_noise_m"\nunit = "mm"\n'
        "values = [0.0, 12.0]\n"
    )
    study = st.load_study(path)
    base = st.base_session(study)
    assert (
        base.model == "bvh" and base.rate_hz == pytest.approx(100.0) and base.duration_s == pytest.approx(4.0)
    )
    data = sw.run_study(study, tmp_path / "out", workers=1).to_pydict()
    noise = np.array(data["sensors.tracker.position_noise_m"])
    err = np.array(data["joint_centre_error_m"])
    assert len(err) == 4 and np.isfinite(err).all()
    assert err[noise > 0].mean() > 2.0 * err[noise == 0].mean()


def test_a_sprung_mount_rings_on_a_recorded_motion_as_the_analytic_oscillator(tmp_path):
    import dataclasses

    from simbench.sim.sensor_config import load_sensor_config

    # one body shaken along world x at 2 Hz, 2 cm amplitude, not turning
    rate, frames, f_hz, amp = 200.0, 800, 2.0, 0.02
    t = np.arange(frames) / rate
    p = np.zeros((frames, 1, 3))
    p[:, 0, 0] = amp * np.sin(2 * np.pi * f_hz * t)
    p[:, 0, 2] = 1.0
    q = np.tile([1.0, 0, 0, 0], (frames, 1, 1))
    path = tmp_path / "shake.csv"
    _pose_csv(path, t, p, q, names=("box",))
    k, mass, zeta = 2000.0, 0.03, 0.3
    ideal = load_sensor_config("ideal")
    skin = dataclasses.replace(
        ideal.skin, mount_stiffness_n_per_m=k, mount_damping_ratio=zeta, mount_mass_kg=mass
    )
    sensors = dataclasses.replace(ideal, skin=skin, name="mounted")
    ds = sb.simulate(motion=str(path), sensors=sensors, motion_cutoff_hz=10.0)
    rel = ds.truth.actual.p_w_s[:, 0] - ds.truth.rigid.p_w_s[:, 0]
    # base-excited oscillator: x'' + 2 zeta w0 x' + w0^2 x = -a_base; steady state after ~10/(zeta w0)
    w0, w = np.sqrt(k / mass), 2 * np.pi * f_hz
    gain = w * w * amp / np.hypot(w0 * w0 - w * w, 2 * zeta * w0 * w)
    phase = np.arctan2(2 * zeta * w0 * w, w0 * w0 - w * w)
    expected_x = gain * np.sin(w * t - phase)
    settled = t > 0.5
    end = t < t[-1] - 0.3  # the smoothing's one-sided window at the end
    sel = settled & end
    assert np.abs(rel[sel, 0] - expected_x[sel]).max() < 0.02 * gain
    # gravity sags the mount by g / w0^2 (0.15 mm)
    g = -mujoco.MjModel.from_xml_string("<mujoco/>").opt.gravity[2]
    np.testing.assert_allclose(rel[sel, 2], -g / w0**2, rtol=0.01)
    assert np.abs(rel[sel, 1]).max() < 1e-9


def test_a_mount_with_a_rotational_spring_stays_stable_on_a_recorded_skeleton(tmp_path):
    import dataclasses

    from simbench.sim.sensor_config import load_sensor_config
    from tests.test_roles import cmu_bvh

    path = tmp_path / "cmu.bvh"
    path.write_text(cmu_bvh(240))
    ideal = load_sensor_config("ideal")
    skin = dataclasses.replace(
        ideal.skin, mount_stiffness_n_per_m=2000.0, mount_rot_stiffness_nm_per_rad=0.5, mount_mass_kg=0.03
    )
    ds = sb.simulate(motion=str(path), sensors=dataclasses.replace(ideal, skin=skin, name="rot"))
    # the explicit step was unstable here (a mount turning about a pivot off its centre of mass has a
    # mode far faster than its springs alone): the implicit springs keep it on the bone, within mm
    off = np.linalg.norm(ds.truth.actual.p_w_s - ds.truth.rigid.p_w_s, axis=2)
    assert np.isfinite(ds.truth.actual.acc).all() and 1e-5 < off.max() < 0.005


def test_qpos_csv_errors_name_the_files_own_lines_past_blank_ones(tmp_path):
    ball = _a_ball_joint()
    path = tmp_path / "blank.csv"
    path.write_text(
        f"time_s,{ball}.qw,{ball}.qx,{ball}.qy,{ball}.qz\n\n0,1,0,0,0\n\n0.01,1,0,0,0\n0.01,1,0,0,0\n"
    )
    with pytest.raises(InputError, match=r"blank.csv, line 6: time 0.01 s does not follow 0.01 s"):
        sb.simulate("linkage", str(path))


def test_what_a_reader_noticed_reaches_the_dataset(tmp_path):
    ds = sb.simulate(motion=BROAD_EXCERPT)
    assert any("without an optical pose" in n for n in ds.meta["playback"]["notes"])
