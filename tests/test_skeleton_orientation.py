"""The skeleton-aware sourceless estimator (issue 15, part 1): on an analytic chain whose limbs
accelerate by more than 1 g, where the per-sample methods are tens of degrees off, it recovers
the orientations from accelerometer and magnetometer alone; heading is carried across a
magnetic disturbance; bad inputs are refused; the calibration JSON becomes its skeleton."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import simbench as sb
from calibration.errors import CalibrationInputError
from calibration.hierarchy import hierarchy_from_parents
from calibration.orientation import (
    Priors,
    Skeleton,
    disturbed_spans,
    orientation_errors,
    reference,
    skeleton_orientation,
    triad,
)
from calibration.orientation.skeleton import STARTS, _Problem
from calibration.orientation.world import measured_directions, quat_where
from calibration.rotations import quat_to_matrix, rotvec_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.calibration_json import calibration_to_dict, write_calibration_json
from simbench.io.dataset import write_dataset
from simbench.io.imu import ImuRecording, read_broad
from simbench.orient import calibrate_magnetometers, estimate, skeleton_from_calibration
from simbench.score import score_orientation

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
FIELD_W = np.array([0.0, 25.0, -43.3])  # ENU, uT: 50 uT, 60 degrees down
G = 9.81

# a three-segment chain: the root turns about its own origin (no acceleration); each joint in the
# parent's and the child's sensor frame, m
PARENT = np.array([-1, 0, 1])
LP = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.2, 0.0, 0.03]])
LC = np.array([[0.0, 0.0, 0.0], [-0.15, 0.02, 0.0], [-0.1, 0.0, 0.0]])
AMP = np.array([[0.6, 0.5, 0.4], [1.0, 0.6, 0.8], [0.9, 1.0, 0.5]])  # rad
FREQ = np.array([[0.31, 0.43, 0.27], [0.7, 0.55, 0.9], [0.8, 1.1, 0.65]])  # Hz


def chain_rotations(t: np.ndarray) -> np.ndarray:
    """``R_w_s`` ``(T, 3, 3, 3)``: each sensor's rotation vector a sum of sines."""
    v = AMP[None] * np.sin(2 * np.pi * FREQ[None] * t[:, None, None] + np.arange(3)[None, None, :])
    return rotvec_to_matrix(v)


def chain_positions(t: np.ndarray, rotations=chain_rotations) -> np.ndarray:
    """Sensor origins ``(T, 3, 3)`` by forward kinematics from the root at the origin, m."""
    R = rotations(t)
    p = np.zeros((t.size, 3, 3))
    for c in (1, 2):
        joint = p[:, PARENT[c]] + R[:, PARENT[c]] @ LP[c]
        p[:, c] = joint - R[:, c] @ LC[c]
    return p


def chain_session(rate_hz: float = 100.0, seconds: float = 20.0, rotations=chain_rotations):
    """Noise-free readings of the chain: the specific force from the exact acceleration (a
    five-point second derivative at 1 ms, error ~1e-10 m/s^2) and the Earth field."""
    t = np.arange(round(rate_hz * seconds)) / rate_hz
    R = rotations(t)
    h = 1e-3
    p = [chain_positions(t + k * h, rotations) for k in (-2, -1, 0, 1, 2)]
    a = (-p[0] + 16 * p[1] - 30 * p[2] + 16 * p[3] - p[4]) / (12 * h * h)
    acc = np.einsum("tkji,tkj->tki", R, a + np.array([0.0, 0.0, G]))
    mag = np.einsum("tkji,j->tki", R, FIELD_W)
    return t, R, acc, mag


def total_deg(q_est: np.ndarray, R_true: np.ndarray) -> np.ndarray:
    return np.rad2deg(orientation_errors(q_est, quat_where(R_true, np.ones(R_true.shape[:2], bool)))[..., 0])


REF = reference("enu", field_strength_ut=float(np.linalg.norm(FIELD_W)), inclination_deg=60.0, gravity=G)


def test_strong_accelerations_recovered_where_per_sample_methods_fail():
    _, R, acc, mag = chain_session()
    linear = np.abs(np.linalg.norm(acc, axis=-1) - G)
    assert linear.max() > G  # the limbs accelerate by more than 1 g
    per_sample = total_deg(triad(acc, mag, REF).q_w_s, R)
    est = skeleton_orientation(acc, mag, 100.0, Skeleton(PARENT, LP, LC))
    err = total_deg(est.q_w_s, R)
    assert est.ok.all() and np.isfinite(est.q_w_s).all()
    rms_triad = np.sqrt(np.mean(per_sample**2))
    rms = np.sqrt(np.mean(err**2))
    assert rms_triad > 30.0
    # the 20 Hz level low-passes at 8 Hz and slerps between its samples: most frames within a
    # degree; a span of about a second settles in a wrong minimum (the problem is not convex)
    assert np.median(err) < 1.0
    assert np.mean(err < 2.0) > 0.9
    assert rms < 0.15 * rms_triad
    # without the skeleton the same data give no such gain: the accelerations are unexplained
    alone = total_deg(skeleton_orientation(acc, mag, 100.0).q_w_s, R)
    assert np.median(alone) > 5 * np.median(err)


HINGE_P = np.array([0.0, 0.6, 0.8])  # the last joint's axis in its parent's (sensor 1's) frame
HINGE_Q = rotvec_to_matrix(np.array([0.3, -0.5, 0.2]))  # the child sensor's mounting on its segment


def hinged_rotations(t: np.ndarray) -> np.ndarray:
    """The chain with its last joint a hinge: ``R_2 = R_1 rot(a_p, theta(t)) Q``, so that
    ``R_2 a_c = R_1 a_p`` with ``a_c = Q^T a_p``."""
    R = chain_rotations(t)
    theta = 1.2 * np.sin(2 * np.pi * 0.9 * t) + 0.3
    R[:, 2] = R[:, 1] @ rotvec_to_matrix(theta[:, None] * HINGE_P) @ HINGE_Q
    return R


def test_a_hinge_keeps_its_axis_common_to_both_sensors():
    _, R, acc, mag = chain_session(seconds=12.0, rotations=hinged_rotations)
    a_p = np.zeros((3, 3))
    a_c = np.zeros((3, 3))
    a_p[2], a_c[2] = HINGE_P, HINGE_Q.T @ HINGE_P
    assert np.allclose(R[:, 2] @ a_c[2], R[:, 1] @ a_p[2])  # the generator is a hinge
    hinge = Skeleton(PARENT, LP, LC, a_p, a_c)
    ball = Skeleton(PARENT, LP, LC)
    with_axis = skeleton_orientation(acc, mag, 100.0, hinge)
    without = skeleton_orientation(acc, mag, 100.0, ball)

    def axis_angle_deg(est):
        Rs = quat_to_matrix(est.q_w_s)
        u, v = Rs[:, 1] @ a_p[2], Rs[:, 2] @ a_c[2]
        return np.rad2deg(np.arccos(np.clip(np.sum(u * v, axis=-1), -1, 1)))

    # measured: the axes 0.16 degrees apart (median) with the hinge, 0.40 without; total RMSE
    # 0.55 against 0.85 degrees
    assert np.median(axis_angle_deg(with_axis)) < 0.5 * np.median(axis_angle_deg(without))
    e_with, e_without = total_deg(with_axis.q_w_s, R), total_deg(without.q_w_s, R)
    assert np.sqrt(np.mean(e_with**2)) < np.sqrt(np.mean(e_without**2)) < 2.0


def test_reference_from_the_roots_equals_the_true_one_when_the_root_is_still():
    _, _R, acc, mag = chain_session(seconds=8.0)
    sk = Skeleton(PARENT, LP, LC)
    from_data = skeleton_orientation(acc, mag, 100.0, sk)
    given = skeleton_orientation(acc, mag, 100.0, sk, ref=REF)
    assert np.max(orientation_errors(from_data.q_w_s, given.q_w_s)[..., 0]) < np.deg2rad(0.05)


def test_heading_carried_through_a_dipole_pass():
    """One sensor turning steadily about the vertical; for 2 s a magnet near it adds a field of
    60 % of the Earth's: the per-sample estimate follows the disturbed field, the disturbance
    weighting carries the heading across from the span's ends. The weighting sees the field
    strength only (the dip is measured against an accelerometer that limbs turn), so the magnet's
    field here has a part along the Earth's; one added at right angles changes the strength only
    to second order at the span's ends and is carried less well (measured: 19.8 degrees of
    heading in the span against TRIAD's 33.2)."""
    rate = 100.0
    t = np.arange(2000) / rate
    yaw = 0.4 * t  # rad
    v = np.stack([0.2 * np.sin(0.5 * t), 0.15 * np.cos(0.3 * t), yaw], axis=-1)
    R = rotvec_to_matrix(v)[:, None]
    acc = np.einsum("tkji,j->tki", R, np.array([0.0, 0.0, G]))
    field = np.broadcast_to(FIELD_W, (t.size, 3)).copy()
    span = (t >= 9.0) & (t < 11.0)
    ramp = np.sin(np.pi * (t[span] - 9.0) / 2.0) ** 2  # the magnet approaches and leaves
    toward = np.array([0.6, 0.5, -0.6]) / np.linalg.norm([0.6, 0.5, -0.6])  # across and along the field
    field[span] += 0.6 * np.linalg.norm(FIELD_W) * ramp[:, None] * toward
    mag = np.einsum("tkji,tj->tki", R, field)
    rng = np.random.default_rng(4)
    acc += rng.normal(scale=0.02, size=acc.shape)
    mag += rng.normal(scale=0.1, size=mag.shape)
    truth = quat_where(R, np.ones(R.shape[:2], bool))

    def heading_in_span(q):
        e = np.rad2deg(orientation_errors(q, truth)[:, 0, 1])
        return np.sqrt(np.mean(e[span] ** 2)), np.sqrt(np.mean(e[~span] ** 2))

    tri, _ = heading_in_span(triad(acc, mag, REF).q_w_s)
    assert tri > 10.0  # the disturbed field turns the per-sample heading
    carried = skeleton_orientation(acc, mag, rate, weigh_disturbance=True)
    inside, outside = heading_in_span(carried.q_w_s)
    assert inside < 0.3 * tri
    assert outside < 1.0
    # or the span found in the data, the magnetometer left out there
    spans, _ = disturbed_spans(mag[:, 0], rate)
    assert len(spans) == 1 and abs(spans[0][0] / rate - 9.0) < 0.6 and abs(spans[0][1] / rate - 11.0) < 0.6
    carry = np.zeros(mag.shape[:2], bool)
    carry[spans[0][0] : spans[0][1]] = True
    inside, outside = heading_in_span(skeleton_orientation(acc, mag, rate, carry=carry).q_w_s)
    assert inside < 0.3 * tri
    assert outside < 1.0
    # sb.orient reports the share of the samples left disturbed (nothing recalibrates a field
    # that changes in the world): the 2 s of 20 s, less the ramps' ends
    rec = ImuRecording(
        ("s",), t, acc, np.zeros_like(acc), mag, np.ones(mag.shape[:2], bool), truth, None, rate, "dipole"
    )
    share = sb.orient(rec).disturbed["s"]
    assert 0.05 < share <= 0.1


def test_gaps_and_bad_samples_come_back_nan_and_the_rest_is_estimated():
    _, _R, acc, mag = chain_session(seconds=6.0)
    acc = acc.copy()
    acc[100:130, 2] = np.nan
    valid = np.ones(acc.shape[:2], bool)
    valid[300:320, 1] = False
    est = skeleton_orientation(acc, mag, 100.0, Skeleton(PARENT, LP, LC), valid=valid)
    assert not est.ok[100:130, 2].any() and np.isnan(est.q_w_s[100:130, 2]).all()
    assert not est.ok[300:320, 1].any()
    assert est.ok.sum() == acc.shape[0] * 3 - 30 - 20
    assert np.isfinite(est.q_w_s[est.ok]).all()


def test_long_recordings_are_solved_in_segments_that_join():
    _, R, acc, mag = chain_session(seconds=30.0)
    sk = Skeleton(PARENT, LP, LC)
    whole = skeleton_orientation(acc, mag, 100.0, sk)
    cut = skeleton_orientation(acc, mag, 100.0, sk, segment_s=12.0)
    e_whole, e_cut = total_deg(whole.q_w_s, R), total_deg(cut.q_w_s, R)
    assert np.median(e_cut) < 1.0 and abs(np.median(e_cut) - np.median(e_whole)) < 0.2


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (
            dict(parent=np.array([-1, 0]), joint_in_parent=np.zeros((2, 3)), joint_in_child=np.zeros((3, 3))),
            "joint_in_child",
        ),
        (
            dict(
                parent=np.array([1, 0, -1]), joint_in_parent=np.zeros((3, 3)), joint_in_child=np.zeros((3, 3))
            ),
            "cycle",
        ),
        (
            dict(
                parent=np.array([-1, 0, 0]),
                joint_in_parent=np.full((3, 3), np.nan),
                joint_in_child=np.zeros((3, 3)),
            ),
            "finite",
        ),
        (
            dict(
                parent=np.array([-1, 5, 0]), joint_in_parent=np.zeros((3, 3)), joint_in_child=np.zeros((3, 3))
            ),
            "parent indices",
        ),
        (
            dict(
                parent=np.array([-1.0, 0.0, 0.0]),
                joint_in_parent=np.zeros((3, 3)),
                joint_in_child=np.zeros((3, 3)),
            ),
            "integers",
        ),
    ],
)
def test_bad_skeletons_are_refused(kwargs, match):
    with pytest.raises(CalibrationInputError, match=match):
        Skeleton(**kwargs)


def test_bad_hinge_axes_are_refused():
    zeros = np.zeros((3, 3))
    unit = np.array([[0, 0, 0], [0, 0, 1.0], [0, 0, 0]])
    with pytest.raises(CalibrationInputError, match="both"):
        Skeleton(PARENT, LP, LC, unit, None)
    with pytest.raises(CalibrationInputError, match="unit vectors"):
        Skeleton(PARENT, LP, LC, 2 * unit, unit)
    with pytest.raises(CalibrationInputError, match="unit vectors"):
        Skeleton(PARENT, LP, LC, unit, zeros)
    with pytest.raises(CalibrationInputError, match="root"):
        Skeleton(PARENT, LP, LC, np.roll(unit, -1, axis=0), np.roll(unit, -1, axis=0))
    with pytest.raises(CalibrationInputError, match="finite"):
        Skeleton(PARENT, LP, LC, unit * np.nan, unit)


def test_bad_inputs_are_refused():
    _, _, acc, mag = chain_session(seconds=2.0)
    with pytest.raises(CalibrationInputError, match="one shape"):
        skeleton_orientation(acc[..., :2], mag, 100.0)
    with pytest.raises(CalibrationInputError, match="rate_hz"):
        skeleton_orientation(acc, mag, 0.0)
    with pytest.raises(CalibrationInputError, match="skeleton has 2 sensors"):
        skeleton_orientation(acc, mag, 100.0, Skeleton(np.array([-1, 0]), np.zeros((2, 3)), np.zeros((2, 3))))
    with pytest.raises(CalibrationInputError, match="valid"):
        skeleton_orientation(acc, mag, 100.0, valid=np.ones((3, 3), bool))
    with pytest.raises(CalibrationInputError, match="carry"):
        skeleton_orientation(acc, mag, 100.0, carry=np.ones((3, 3), bool))


def test_a_calibration_json_becomes_the_skeleton(tmp_path):
    names = ("pelvis", "thigh", "shank", "extra")
    doc = {
        "units": "m",
        "joints": [
            {
                "parent": "pelvis",
                "child": "thigh",
                "joint_in_parent": [0.1, 0, 0],
                "joint_in_child": [0, 0.2, 0],
            },
            {
                "parent": "thigh",
                "child": "shank",
                "joint_in_parent": [0, -0.2, 0],
                "joint_in_child": [0, 0.21, 0],
            },
        ],
    }
    path = tmp_path / "cal.json"
    path.write_text(json.dumps(doc))
    sk = skeleton_from_calibration(path, names)
    assert sk.parent.tolist() == [-1, 0, 1, -1]  # the sensor the calibration leaves out is a root
    assert sk.joint_in_parent[2].tolist() == [0, -0.2, 0] and sk.joint_in_child[1].tolist() == [0, 0.2, 0]
    with pytest.raises(sb.InputError, match="sensors the data lacks"):
        skeleton_from_calibration(path, ("pelvis", "thigh"))
    path.write_text(json.dumps({**doc, "units": "mm"}))
    with pytest.raises(sb.InputError, match="units"):
        skeleton_from_calibration(path, names)
    knee = {
        **doc["joints"][1],
        "single_axis": True,
        "axis_in_parent": [0, 0, 2.0],
        "axis_in_child": [0, 1.0, 0],
    }
    path.write_text(json.dumps({**doc, "joints": [doc["joints"][0], knee]}))
    sk = skeleton_from_calibration(path, names)
    assert sk.hinges.tolist() == [2]
    assert sk.hinge_in_parent[2].tolist() == [0, 0, 1] and sk.hinge_in_child[2].tolist() == [0, 1, 0]
    path.write_text(json.dumps({**doc, "joints": [doc["joints"][0], {**knee, "axis_in_child": None}]}))
    with pytest.raises(sb.InputError, match="single-axis but its axis"):
        skeleton_from_calibration(path, names)
    cyc = {
        "units": "m",
        "joints": [*doc["joints"], {**doc["joints"][0], "parent": "shank", "child": "pelvis"}],
    }
    path.write_text(json.dumps(cyc))
    with pytest.raises(sb.InputError, match=r"not a tree|cycle"):
        skeleton_from_calibration(path, names)


def test_a_calibration_json_carries_the_joints_ranges(tmp_path, monkeypatch):
    """``simbench calibrate --json`` writes each joint's range of motion in its poses (as
    ``with_ranges`` finds it, read a chunk at a time or whole alike); ``--skeleton`` reads it
    back; a malformed range is refused naming the file and the joint."""
    ds = sb.simulate(model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=6, seed=5)
    data = tmp_path / "s.h5"
    write_dataset(data, ds)
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(data), "--json", str(cal), "--no-slip"]) == 0
    poses = ds.poses()
    sk = skeleton_from_calibration(cal, tuple(poses.names))
    expected = sk.with_ranges(poses.R_w_s, poses.valid)
    monkeypatch.setattr("calibration.orientation.skeleton.RANGE_CHUNK", 7)
    chunked = sk.with_ranges(poses.R_w_s, poses.valid)
    assert sk.ranged.tolist() == expected.ranged.tolist() == sk.children.tolist()
    for other in (expected, chunked):
        np.testing.assert_allclose(sk.range_rad[sk.children], other.range_rad[sk.children], rtol=1e-9)
        np.testing.assert_allclose(sk.range_centre, other.range_centre, atol=1e-9)
    doc = json.loads(cal.read_text())
    doc["joints"][0]["range"]["radius_deg"] = -3
    cal.write_text(json.dumps(doc))
    with pytest.raises(
        sb.InputError, match=r"cal.json: not a calibration JSON: joints\[0\]: expected 'range'"
    ):
        skeleton_from_calibration(cal, tuple(poses.names))


def test_orient_on_a_simulated_session_with_its_calibrated_skeleton(tmp_path, capsys):
    """The whole path: simulate, calibrate the tracker poses to a JSON, orient with it."""
    ds = sb.simulate(model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=20, seed=11)
    data = tmp_path / "s.h5"
    write_dataset(data, ds)
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(data), "--json", str(cal), "--no-slip"]) == 0
    capsys.readouterr()
    # the command line on a short session of the same sensors (the estimate itself is checked below)
    short = tmp_path / "short.h5"
    few = sb.simulate(model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=4, seed=11)
    write_dataset(short, few)
    assert main(["orient", str(short), "--skeleton", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "method: skeleton (15 joints, 1 root(s); ranges of motion on 15)" in out
    with_skeleton = sb.orient(ds, skeleton=cal)
    alone = sb.orient(ds)
    per_sample = sb.orient(ds, method="fontaine")
    assert with_skeleton.method == "skeleton"
    # measured (20 s): 1.8 degrees against Fontaine's 23.9 and 13.6 without the skeleton (30 s:
    # 1.6, 22.4, 9.8; a 12 s session is worse: its first seconds, violent from the first frame,
    # are a large share)
    assert with_skeleton.score.total_rmse_deg < 0.3 * per_sample.score.total_rmse_deg
    assert with_skeleton.score.total_rmse_deg < alone.score.total_rmse_deg
    rec = few.imu()
    assert estimate(rec, "skeleton").q_enu.shape == (*rec.acc.shape[:2], 4)
    assert main(["orient", str(short), "--method", "triad", "--skeleton", str(cal)]) == 2
    assert "--skeleton is for --method skeleton" in capsys.readouterr().err


def test_gait_is_found_by_mixing_the_starts():
    """A person walking (the ``gait`` program): from the per-sample start the legs settle tens of
    degrees off; the coarse starts find them, and the mix of all starts window by window, by the
    cost they share, is better than the one start (module docstring, several starts)."""
    ds = sb.simulate(model="humanoid", motion="gait", sensors="mems-industrial", duration_s=20, seed=3)
    rec = ds.imu()
    tree = hierarchy_from_parents(ds.truth.parent_of, ds.sensors)
    skeleton = Skeleton(np.asarray(tree.parent), *ds.truth_joint_arrays())
    errors = {}
    for name, starts in (("one", ((),)), ("mixed", STARTS)):
        est = skeleton_orientation(rec.acc, rec.mag, rec.rate_hz, skeleton, valid=rec.valid, starts=starts)
        e = orientation_errors(est.q_w_s, rec.q_true)[..., 0]
        errors[name] = float(np.rad2deg(np.sqrt(np.nanmean(e**2))))
    # measured (seed 3, 20 s): one start 15.3 degrees, mixed 4.2; the issue's target is 8
    assert errors["mixed"] <= 8.0, errors
    assert errors["mixed"] < 0.6 * errors["one"], errors


def test_sensors_on_their_own_move_with_a_bounded_speed():
    """Without a skeleton every sensor is on its own: its linear acceleration integrates to a
    velocity with a prior (``Priors.lone_speed``), not a white prior on the acceleration that
    calls every sustained acceleration a tilt. On a walking humanoid's pelvis and arms, each
    estimated alone, that more than halves the error (module docstring)."""
    ds = sb.simulate(
        model="humanoid", motion="gait", sensors="mems-industrial", duration_s=10, rate_hz=50.0, seed=3
    )
    rec = ds.imu()
    pick = [
        rec.names.index(n) for n in ("pelvis", "forearm_l", "hand_l", "upper_arm_r", "forearm_r", "hand_r")
    ]
    errors = {}
    for name, priors in (("white", Priors(lone_speed=None)), ("velocity", Priors())):
        est = skeleton_orientation(
            rec.acc[:, pick], rec.mag[:, pick], rec.rate_hz, valid=rec.valid[:, pick], priors=priors
        )
        e = orientation_errors(est.q_w_s, rec.q_true[:, pick])[..., 0]
        errors[name] = float(np.rad2deg(np.sqrt(np.nanmean(e**2))))
    # measured: white 34.7 degrees, velocity 15.2 (all 16 sensors: 33.4 and 19.2, each on its own)
    assert errors["velocity"] < 0.5 * errors["white"], errors


@pytest.mark.skipif(
    not SHARED_DATA.is_dir(), reason="../shared/data (BROAD trials) not beside the repository"
)
def test_broad_trials_at_hand_meet_the_issue_targets():
    """The default gyro-free estimator on the two real BROAD trials at hand, against TRIAD on the
    same calibrated magnetometer: at most 0.8 x undisturbed (02), 0.6 x beside a magnet (30)."""
    for stem, target in (
        ("broad_02_undisturbed_slow_rotation_B", 0.8),
        ("broad_30_disturbed_stationary_magnet_C", 0.6),
    ):
        rec, _ = calibrate_magnetometers(read_broad(SHARED_DATA / f"{stem}.hdf5"))
        total = {
            m: score_orientation(estimate(rec, m).q_enu, rec.q_true, rec.names, rec.evaluate).per_sensor[
                "imu"
            ]["total_deg"]
            for m in ("skeleton", "triad")
        }
        # measured: 02 0.38 x (3.3 against 8.9 degrees), 30 0.23 x (21.6 against 93.9)
        assert total["skeleton"] <= target * total["triad"], (stem, total)


def test_the_lone_speed_prior_from_the_command_line_and_the_api(tmp_path, capsys):
    """``--lone-speed`` and ``priors=`` reach the estimator, say so in the header, and are
    refused for the methods that have no such prior."""
    few = sb.simulate(model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=3, seed=11)
    short = tmp_path / "short.h5"
    write_dataset(short, few)
    capsys.readouterr()
    assert main(["orient", str(short), "--lone-speed", "1.5"]) == 0
    assert "(no skeleton: each sensor on its own, speed prior 1.5 m/s)" in capsys.readouterr().out
    assert main(["orient", str(short), "--method", "triad", "--lone-speed", "1.5"]) == 2
    assert "--lone-speed is for --method skeleton, not triad" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: a speed must be > 0
        main(["orient", str(short), "--lone-speed", "0"])
    assert "--lone-speed" in capsys.readouterr().err
    default = sb.orient(few, calibrate_mag=False)
    white = sb.orient(few, calibrate_mag=False, priors=Priors(lone_speed=None))
    assert not np.allclose(default.q_w_s, white.q_w_s, equal_nan=True)
    with pytest.raises(InputError, match="priors are used by the skeleton method only"):
        sb.orient(few, method="triad", priors=Priors())
    with pytest.raises(CalibrationInputError, match="lone_speed must be > 0"):
        Priors(lone_speed=-1.0)


def test_ranges_from_poses_and_a_joint_held_inside_its_range():
    """``with_ranges`` finds a joint's cone (centre and radius) from poses that sweep it, and a
    solve with the ranges still recovers the noise-free chain (the truth lies inside them)."""
    _, R, acc, mag = chain_session(seconds=10.0)
    skeleton = Skeleton(PARENT, LP, LC).with_ranges(R)
    assert np.isinf(skeleton.range_rad[0]) and skeleton.ranged.tolist() == [1, 2]
    for c in (1, 2):
        rel = np.swapaxes(R[:, PARENT[c]], -1, -2) @ R[:, c]
        cos = (np.einsum("ij,fij->f", skeleton.range_centre[c], rel) - 1) / 2
        # every pose inside, one on the surface
        assert np.rad2deg(np.arccos(np.clip(cos, -1, 1)).max()) == pytest.approx(
            np.rad2deg(skeleton.range_rad[c])
        )
    est = skeleton_orientation(acc, mag, 100.0, skeleton, REF)
    # measured: 0.75 degrees RMS, as without the ranges (10 s; the first seconds dominate)
    assert np.sqrt(np.nanmean(total_deg(est.q_w_s, R) ** 2)) < 1.0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"range_rad": np.ones(3)}, "both"),
        ({"range_centre": np.broadcast_to(np.eye(3), (3, 3, 3)), "range_rad": np.ones(2)}, "range_rad as"),
        ({"range_centre": np.broadcast_to(2 * np.eye(3), (3, 3, 3)), "range_rad": np.ones(3)}, "rotation"),
        ({"range_centre": np.broadcast_to(np.eye(3), (3, 3, 3)), "range_rad": np.zeros(3)}, "> 0"),
    ],
)
def test_bad_ranges_are_refused(kwargs, match):
    with pytest.raises(CalibrationInputError, match=match):
        Skeleton(PARENT, LP, LC, **kwargs)
    with pytest.raises(CalibrationInputError, match="R_w_s"):
        Skeleton(PARENT, LP, LC).with_ranges(np.zeros((5, 2, 3, 3)))


def test_each_tree_of_a_forest_is_estimated_as_if_it_were_alone():
    """Two chains in one recording share no residual: each sensor's estimate is the one its own
    tree gives alone, whatever else the file holds (and the solve is the cheaper for it: the
    banded solve's cost goes as the cube of the sensors solved together)."""
    _, R1, acc1, mag1 = chain_session(seconds=6.0)
    _, R2, acc2, mag2 = chain_session(seconds=6.0, rotations=hinged_rotations)
    # the second chain first, so that the trees interleave in neither the input nor the output
    acc = np.concatenate([acc2, acc1], axis=1)
    mag = np.concatenate([mag2, mag1], axis=1)
    forest = Skeleton(
        np.concatenate([PARENT, np.where(PARENT >= 0, PARENT + 3, -1)]),
        np.concatenate([LP, LP]),
        np.concatenate([LC, LC]),
    )
    assert [sorted(t.tolist()) for t in forest.trees()] == [[0, 1, 2], [3, 4, 5]]
    both = skeleton_orientation(acc, mag, 100.0, forest, REF)
    alone = [
        skeleton_orientation(a, m, 100.0, Skeleton(PARENT, LP, LC), REF)
        for a, m in ((acc2, mag2), (acc1, mag1))
    ]
    np.testing.assert_array_equal(both.q_w_s, np.concatenate([e.q_w_s for e in alone], axis=1))
    assert both.iterations == sum(e.iterations for e in alone)
    assert np.median(total_deg(both.q_w_s, np.concatenate([R2, R1], axis=1))) < 1.0


def test_a_skeleton_cut_to_a_tree_keeps_its_joints_and_refuses_an_orphan():
    sk = Skeleton(PARENT, LP, LC)
    part = sk.permuted(np.array([0, 1]))
    np.testing.assert_array_equal(part.parent, [-1, 0])
    np.testing.assert_array_equal(part.joint_in_child, LC[:2])
    with pytest.raises(CalibrationInputError, match="parents"):
        sk.permuted(np.array([1, 2]))
    with pytest.raises(CalibrationInputError, match="distinct"):
        sk.permuted(np.array([0, 0, 1]))


def test_a_calibration_in_memory_is_the_skeleton_its_json_gives(tmp_path):
    """``sb.orient(ds, skeleton=sb.calibrate(ds))``: the calibration in memory gives the skeleton its
    JSON gives (tree, joints, hinges), and anything else is refused by name."""
    ds = sb.simulate(model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=2, seed=11)
    cal = sb.calibrate(ds)
    path = tmp_path / "cal.json"
    write_calibration_json(path, calibration_to_dict(cal))
    names = ds.imu().names
    from_memory, from_file = skeleton_from_calibration(cal, names), skeleton_from_calibration(path, names)
    for field in dataclasses.fields(from_file):
        a, b = getattr(from_memory, field.name), getattr(from_file, field.name)
        assert (a is None and b is None) or np.array_equal(a, b), field.name
    assert (from_memory.parent >= 0).sum() == 15
    run = sb.orient(ds, skeleton=cal)
    assert run.method == "skeleton" and np.isfinite(run.q_w_s).all()
    with pytest.raises(sb.InputError, match=r"expected a Skeleton, a Calibration .* got int"):
        sb.orient(ds, skeleton=42)
    # a calibration document is read as its JSON would be: a malformed one is named
    with pytest.raises(
        sb.InputError, match=r'the calibration given: not a calibration JSON: expected .* "joints" list'
    ):
        sb.orient(ds, skeleton={"joints": "none"})
    # the checks a file gets: a centre that is not finite is named, not solved with
    first = cal.joints[0]
    lost = dataclasses.replace(first, fit=dataclasses.replace(first.fit, joint_in_parent=np.full(3, np.nan)))
    broken = dataclasses.replace(cal, joints=[lost, *cal.joints[1:]])
    with pytest.raises(sb.InputError, match=r"the calibration given: .*joints\[0\].*joint_in_parent"):
        skeleton_from_calibration(broken, names)


def test_the_solve_runs_blas_on_one_thread(monkeypatch):
    """The banded solves' blocks are small: a threaded BLAS only slows them (twice as slow on two
    cores, :data:`~calibration.orientation.skeleton.BLAS_THREADS`), whatever the caller set."""
    import calibration.orientation.skeleton as sk

    seen: list[int] = []
    solve = sk._solve_tree

    def recording(*args, **kwargs):
        seen.extend(x["num_threads"] for x in threadpool_info() if x["user_api"] == "blas")
        return solve(*args, **kwargs)

    monkeypatch.setattr(sk, "_solve_tree", recording)
    rng = np.random.default_rng(0)
    acc = rng.normal(size=(200, 2, 3)) + np.array([0.0, 0.0, 9.81])
    mag = rng.normal(size=(200, 2, 3)) + np.array([20.0, 0.0, -40.0])
    with threadpool_limits(limits=2, user_api="blas"):
        # as the caller has them: 2, or 1 for a BLAS built single-threaded (opensim brings one, so
        # a process that has run an OpenSim test holds three BLAS libraries, one of them that)
        before = [(x["filepath"], x["num_threads"]) for x in threadpool_info() if x["user_api"] == "blas"]
        skeleton_orientation(acc, mag, 100.0)
        after = [(x["filepath"], x["num_threads"]) for x in threadpool_info() if x["user_api"] == "blas"]
    assert seen and set(seen) == {1}
    assert 2 in {n for _, n in before}
    assert after == before  # the caller's setting is back


def test_normal_equations_equal_those_of_a_finite_difference_jacobian():
    """``J^T J`` (LAPACK's lower band) and ``J^T r`` as the solver assembles them from the
    residuals' blocks equal those of ``J`` differenced numerically, on a problem with every
    residual: field, a body root, a lone sensor's velocity, joints (two sharing a parent), a
    hinge, a range (beyond it), smoothness; and some samples unusable."""
    from calibration.orientation.skeleton import _normal_equations, _Problem

    rng = np.random.default_rng(5)
    f = 6
    parent = np.array([-1, 0, 1, -1, 0])  # 3: a lone sensor; 0: a root with two children
    lp, lc = rng.normal(scale=0.2, size=(2, 5, 3))
    axis = np.zeros((5, 3))
    axis[2] = [0.0, 0.6, 0.8]
    centre = np.broadcast_to(np.eye(3), (5, 3, 3)).copy()
    centre[1] = rotvec_to_matrix(np.array([0.2, -0.1, 0.3]))
    sk = Skeleton(parent, lp, lc, axis, axis, centre, np.array([np.inf, 0.3, np.inf, np.inf, np.inf]))
    use = rng.random((f, 5)) > 0.15
    mag_dir = rng.normal(size=(f, 5, 3))
    mag_dir /= np.linalg.norm(mag_dir, axis=-1, keepdims=True)
    acc = rng.normal(scale=3.0, size=(f, 5, 3)) + np.array([0.0, 0.0, G])
    problem = _Problem(
        np.where(use[..., None], acc, 0.0),
        np.where(use[..., None], mag_dir, 0.0),
        use,
        0.05,
        sk,
        REF,
        Priors(),
    )
    assert problem.lone.tolist() == [3] and sk.hinges.tolist() == [2] and sk.ranged.tolist() == [1]
    R = rotvec_to_matrix(rng.normal(scale=1.0, size=(f, 5, 3)))
    V = rng.normal(size=(f, 1, 3))
    nb = problem.blocks_per_frame
    r, groups = problem.residuals(R, V, jacobian=True)
    ab, g = _normal_equations(r, groups, f, nb, {})

    def perturbed(x: np.ndarray) -> np.ndarray:
        d = x.reshape(f, nb, 3)
        return problem.residuals(rotvec_to_matrix(d[:, :5]) @ R, V + d[:, 5:])

    h = 1e-6
    eye = np.eye(3 * f * nb)
    J = np.stack([(perturbed(h * e) - perturbed(-h * e)) / (2 * h) for e in eye], axis=1)
    A = np.zeros((3 * f * nb,) * 2)
    for d in range(ab.shape[0]):
        j = np.arange(3 * f * nb - d)
        A[j + d, j] = ab[d, : j.size]
    A = np.tril(A) + np.tril(A, -1).T
    scale = np.abs(J.T @ J).max()
    np.testing.assert_allclose(A, J.T @ J, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(g, J.T @ r, rtol=0, atol=1e-7 * np.abs(J.T @ r).max())
    assert ab.flags.f_contiguous  # what LAPACK reads without a copy


def band_to_dense(ab: np.ndarray) -> np.ndarray:
    """The symmetric matrix of LAPACK's lower band ``ab`` ``(u + 1, n)``."""
    n = ab.shape[1]
    A = np.zeros((n, n))
    for d in range(ab.shape[0]):
        j = np.arange(n - d)
        A[j + d, j] = ab[d, : j.size]
    return np.tril(A) + np.tril(A, -1).T


def test_the_humanoid_s_unknowns_are_placed_in_a_narrower_band():
    """The 16-sensor humanoid's tree in reverse Cuthill-McKee's order joins sensors 4 places
    apart; the search places every joint's two sensors within 2 (its torso has 4 joints, so 2
    is the least)."""
    from calibration.orientation.skeleton import _band_slots

    parent = np.array([-1, 0, 1, 2, 2, 4, 5, 2, 7, 8, 0, 10, 11, 0, 13, 14])
    sk = Skeleton(parent, np.zeros((16, 3)), np.zeros((16, 3)))
    (tree,) = sk.trees()
    own = sk.permuted(tree)
    c = own.children
    assert np.abs(c - own.parent[c]).max() == 4
    slots = _band_slots(own)
    assert sorted(slots) == list(range(16))
    assert np.abs(slots[c] - slots[own.parent[c]]).max() == 2
    assert _band_slots(Skeleton.none(3)).tolist() == [0, 1, 2]  # no joints: nothing to narrow


def test_the_unknowns_placed_otherwise_give_the_same_normal_equations_and_steps():
    """The band's order of the unknowns is the linear algebra's alone: with the sensors placed
    in reverse, ``J^T J`` and ``J^T r`` are the same entries in other places, and the solver's
    iterations end where they did (to rounding)."""
    from calibration.orientation.skeleton import _levenberg_marquardt, _normal_equations

    rng = np.random.default_rng(3)
    f = 8
    parent = np.array([-1, 0, 1, -1, 0])
    lp, lc = rng.normal(scale=0.2, size=(2, 5, 3))
    use = rng.random((f, 5)) > 0.1
    mag_dir = rng.normal(size=(f, 5, 3))
    mag_dir /= np.linalg.norm(mag_dir, axis=-1, keepdims=True)
    acc = rng.normal(scale=3.0, size=(f, 5, 3)) + np.array([0.0, 0.0, G])

    def problem(slot):
        args = (np.where(use[..., None], acc, 0.0), np.where(use[..., None], mag_dir, 0.0), use, 0.05)
        return _Problem(*args, Skeleton(parent, lp, lc), REF, Priors(), slot=slot)

    R = rotvec_to_matrix(rng.normal(scale=0.5, size=(f, 5, 3)))
    V = rng.normal(size=(f, 1, 3))
    plain, placed = problem(None), problem(np.array([4, 3, 2, 1, 0]))
    nb = plain.blocks_per_frame
    assert placed.slot.tolist() == [4, 3, 2, 1, 0, 5]  # the lone sensor's velocity after them
    ab, g = _normal_equations(*plain.residuals(R, V, jacobian=True), f, nb, {})
    A = band_to_dense(ab)
    ab_p, g_p = _normal_equations(*placed.residuals(R, V, jacobian=True), f, nb, {})
    A_p = band_to_dense(ab_p)
    # unknown (t, k, i) sits at (t, slot[k], i)
    where = (np.arange(f)[:, None, None] * nb + placed.slot[None, :, None]) * 3 + np.arange(3)
    where = where.reshape(-1)
    np.testing.assert_array_equal(A_p[np.ix_(where, where)], A)  # the same sums, other places
    np.testing.assert_array_equal(g_p[where], g)
    R1, V1, it1, cost1 = _levenberg_marquardt(plain, R, V, 5)
    R2, V2, it2, cost2 = _levenberg_marquardt(placed, R, V, 5)
    # a backward-stable solve's relative error is at most about cond(A) eps (here 1.5e-8; measured
    # 1e-12 in R): the two orders differ by rounding alone
    tol = np.linalg.cond(A) * np.finfo(float).eps
    assert it1 == it2 and cost2 == pytest.approx(cost1, rel=tol)
    np.testing.assert_allclose(R2, R1, rtol=0, atol=tol)
    np.testing.assert_allclose(V2, V1, rtol=0, atol=tol * np.abs(V1).max())


def test_the_starts_are_mixed_sensor_by_sensor_and_the_costs_shared_among_them():
    """Two solutions of the analytic chain, each with a different sensor turned 90 degrees
    about the vertical over the whole recording: no one window of either is right everywhere,
    but sensor by sensor each is right in one, and the mix takes each sensor from there. The
    per-sensor costs add up to the problem's cost."""
    from calibration.orientation.skeleton import _mixed, _Problem, _sensor_costs

    _, R, acc, mag = chain_session(seconds=4.0)
    problem = _Problem(
        acc,
        mag / np.linalg.norm(mag, axis=-1, keepdims=True),
        np.ones(R.shape[:2], bool),
        0.01,
        Skeleton(PARENT, LP, LC),
        REF,
        Priors(),
    )
    V = np.zeros((R.shape[0], 0, 3))
    turn = rotvec_to_matrix(np.array([0.0, 0.0, np.pi / 2]))
    root_wrong, leaf_wrong = R.copy(), R.copy()
    root_wrong[:, 0] = turn @ R[:, 0]
    leaf_wrong[:, 2] = turn @ R[:, 2]
    costs = _sensor_costs(problem, leaf_wrong, V)
    r = problem.residuals(leaf_wrong, V)
    assert costs.sum() == pytest.approx(r @ r, rel=1e-12)
    assert costs[:, 2].sum() > 100 * costs[:, 0].sum()  # the leaf's wrong residuals are its own
    mixed, _ = _mixed(problem, [(root_wrong, V), (leaf_wrong, V)], window=50)
    np.testing.assert_array_equal(mixed, R)


def test_a_clipped_accelerometer_axis_is_filled_from_the_joints():
    _, R, acc, mag = chain_session()
    top = 1.4 * G  # the tip clips a quarter of its samples, the others none
    held = np.clip(acc, -top, top)
    clipped = np.abs(acc) > top
    assert 0.2 < clipped[:, 2].any(axis=-1).mean() < 0.3 and not clipped[:, :2].any()
    skeleton = Skeleton(PARENT, LP, LC)
    # at the true orientations the filled axes are the true specific force, the rest as given
    _, m_dir, use = measured_directions(held, mag, REF, None)
    problem = _Problem(held, m_dir, use, 0.01, skeleton, REF, Priors(), clipped)
    f = problem.filled(R, np.zeros((acc.shape[0], 0, 3)))
    assert np.abs(held - acc)[clipped].max() > 5.0
    assert np.abs(f - acc)[clipped].max() < 0.05  # measured 0.018 m/s^2 (the joints' finite differences)
    np.testing.assert_array_equal(f[~clipped], held[~clipped])
    # the estimate: filled against held at the range
    filled = total_deg(skeleton_orientation(held, mag, 100.0, skeleton, acc_clipped=clipped).q_w_s, R)
    as_held = total_deg(skeleton_orientation(held, mag, 100.0, skeleton).q_w_s, R)
    at = clipped.any(axis=-1)
    # measured: 1.6 degrees overall (5.3 held), 2.9 where it clips (8.9)
    assert np.sqrt(np.mean(filled**2)) < 0.5 * np.sqrt(np.mean(as_held**2))
    assert np.sqrt(np.mean(filled[at] ** 2)) < 0.5 * np.sqrt(np.mean(as_held[at] ** 2))
    # nothing clipped: the same estimate as without the mask; a mask of another shape refused
    short = slice(0, 300)
    none = np.zeros(acc[short].shape, dtype=bool)
    plain = skeleton_orientation(acc[short], mag[short], 100.0, skeleton).q_w_s
    np.testing.assert_array_equal(
        skeleton_orientation(acc[short], mag[short], 100.0, skeleton, acc_clipped=none).q_w_s, plain
    )
    with pytest.raises(CalibrationInputError, match=r"acc_clipped of shape \(300, 3, 3\), got \(300, 3\)"):
        skeleton_orientation(acc[short], mag[short], 100.0, skeleton, acc_clipped=none[..., 0])


def test_with_clipped_axes_the_gradient_is_that_of_the_cost_with_them_filled():
    """The clipped axes filled at every ``R``, ``V`` make the cost a function of them alone; its
    gradient is ``J^T r`` with the fill held (the envelope theorem: each fill minimises its
    sensor's rows), here for a root, a joint's child and a lone sensor clipped, no two of them
    sharing a row."""
    from calibration.orientation.skeleton import _normal_equations, _Problem

    rng = np.random.default_rng(7)
    f = 6
    parent = np.array([-1, 0, 1, -1, 0])
    lp, lc = rng.normal(scale=0.2, size=(2, 5, 3))
    sk = Skeleton(parent, lp, lc)
    use = np.ones((f, 5), dtype=bool)
    mag_dir = rng.normal(size=(f, 5, 3))
    mag_dir /= np.linalg.norm(mag_dir, axis=-1, keepdims=True)
    acc = rng.normal(scale=3.0, size=(f, 5, 3)) + np.array([0.0, 0.0, G])
    clipped = np.zeros((f, 5, 3), dtype=bool)
    clipped[1:-1, [0, 2, 3], 0] = True
    acc[clipped] = np.sign(acc[clipped]) * 0.01  # a low range: each fill is what its rows ask
    problem = _Problem(acc, mag_dir, use, 0.05, sk, REF, Priors(), clipped)
    R = rotvec_to_matrix(rng.normal(scale=1.0, size=(f, 5, 3)))
    V = rng.normal(size=(f, 1, 3))
    nb = problem.blocks_per_frame
    r, groups = problem.residuals(R, V, jacobian=True)
    _, g = _normal_equations(r, groups, f, nb, {})
    filled = problem.filled(R, V)
    assert (np.abs(filled[clipped]) > 0.01).mean() > 0.4  # most above the range: not held there

    def half_cost(x: np.ndarray) -> float:
        d = x.reshape(f, nb, 3)
        res = problem.residuals(rotvec_to_matrix(d[:, :5]) @ R, V + d[:, 5:])
        return 0.5 * float(res @ res)

    h = 1e-6
    eye = np.eye(3 * f * nb)
    fd = np.array([(half_cost(h * e) - half_cost(-h * e)) / (2 * h) for e in eye])
    np.testing.assert_allclose(g, fd, rtol=0, atol=1e-6 * np.abs(fd).max())
    # held at the range instead, the gradient is another
    held = _Problem(acc, mag_dir, use, 0.05, sk, REF, Priors())
    r_held, groups_held = held.residuals(R, V, jacobian=True)
    _, g_held = _normal_equations(r_held, groups_held, f, nb, {})
    assert np.abs(g_held - fd).max() > 1e-2 * np.abs(fd).max()
