"""Warnings a user can act on (issue 12, item 4): joints the motion hardly determines, joints whose
residual stands far above the others', and that the warnings reach the table, JSON and report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calibration import calibrate
from calibration.diagnostics import UNCERTAIN_FRACTION, block_jackknife, residual_outliers, rotation_ranges
from calibration.rotations import rotvec_to_matrix
from simbench.cli.table import format_table
from simbench.errors import InputError
from simbench.io.calibration_json import calibration_to_dict
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.report.dataset import dataset_report
from simbench.score import score

UNDETERMINED = "hardly determines its centre"
NOT_NEIGHBOURS = "probably not neighbours"


def two_segments(amplitude_deg: float, *, seed: int, n_frames: int = 3000, artefact_m: float = 0.004):
    """A parent and a child sensor joined at a ball joint, the child turning by up to
    ``amplitude_deg`` about three axes, with a smooth soft-tissue offset of the child sensor
    (about ``artefact_m`` rms per axis) and 0.5 mm white position noise.

    Returns ``(R_w_s (F, 2, 3, 3), p_w_s (F, 2, 3), joint_in_parent, joint_in_child)``, metres.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / 100.0
    freq = rng.uniform(0.2, 0.6, 3)
    phase = rng.uniform(0, 2 * np.pi, 3)
    rel = np.deg2rad(amplitude_deg) * np.sin(2 * np.pi * freq * t[:, None] + phase)  # (F, 3) rad
    body = np.stack([0.3 * np.sin(0.1 * t), 0.2 * np.cos(0.13 * t), 0.5 * np.sin(0.07 * t)], axis=1)
    R_p = rotvec_to_matrix(body)
    R_c = R_p @ rotvec_to_matrix(rel)
    l_p, l_c = np.array([0.02, 0.01, -0.2]), np.array([-0.01, 0.03, 0.22])
    p_p = np.stack([np.sin(0.2 * t), np.cos(0.17 * t), 0.9 + 0.1 * np.sin(0.3 * t)], axis=1)
    p_c = np.einsum("fij,j->fi", R_p, l_p) + p_p - np.einsum("fij,j->fi", R_c, l_c)
    # soft tissue: a smooth child-frame offset wandering on the time scale of the motion
    f_skin = rng.uniform(0.1, 0.5, (4, 3))
    ph_skin = rng.uniform(0, 2 * np.pi, (4, 3))
    skin = artefact_m / 2 * np.sin(2 * np.pi * f_skin[None] * t[:, None, None] + ph_skin).sum(axis=1)
    p_c = p_c + np.einsum("fij,fj->fi", R_c, skin) + rng.normal(0, 5e-4, (n_frames, 3))
    return np.stack([R_p, R_c], axis=1), np.stack([p_p, p_c], axis=1), l_p, l_c


def test_small_motion_is_reported_with_its_range_and_uncertainty():
    R, p, l_p, _ = two_segments(3.0, seed=1)
    cal = calibrate(R, p, ["pelvis", "thigh"], parent_of={"thigh": "pelvis"})
    found = [w for w in cal.warnings if UNDETERMINED in w]
    assert len(found) == 1 and "pelvis-thigh" in found[0]
    # the fit really is off by centimetres, which is what the warning is for
    assert np.linalg.norm(cal.joints[0].fit.joint_in_parent - l_p) > 0.01
    # +-3 degree sines about three axes: along any unit direction at most 2 x 3 x sqrt(3) degrees
    ranges = [float(x) for x in found[0].split("range ")[1].split(" deg")[0].split(", ")]
    assert len(ranges) == 3 and max(ranges) <= 6.0 * np.sqrt(3.0) and min(ranges) > 1.0
    assert "condition" in found[0]


def test_well_moved_joint_with_the_same_artefact_is_not_reported():
    R, p, l_p, _ = two_segments(40.0, seed=1)
    cal = calibrate(R, p, ["pelvis", "thigh"], parent_of={"thigh": "pelvis"})
    assert not [w for w in cal.warnings if UNDETERMINED in w]
    assert np.linalg.norm(cal.joints[0].fit.joint_in_parent - l_p) < 0.02


@pytest.mark.parametrize("scale", [1.0, 100.0, 1000.0, 1 / 0.0254])
def test_small_motion_decision_is_unit_free(scale):
    R, p, _, _ = two_segments(3.0, seed=2)
    cal = calibrate(R, p * scale, ["pelvis", "thigh"], parent_of={"thigh": "pelvis"})
    assert sum(UNDETERMINED in w for w in cal.warnings) == 1


def test_rotation_range_of_a_known_motion():
    # child turning +-10 degrees about one axis, sinusoidally: the 2.5-97.5 percentile range of a
    # sine of amplitude A is 2 A sin(pi/2 * 0.95) = 1.9938 A, the other axes zero
    t = np.linspace(0, 10, 20001)
    angle = np.deg2rad(10.0) * np.sin(2 * np.pi * t)
    R_p = rotvec_to_matrix(np.tile([0.3, -0.2, 1.0], (t.size, 1)))
    R_c = R_p @ rotvec_to_matrix(angle[:, None] * np.array([0.0, 0.6, 0.8]))
    R = np.stack([R_p, R_c], axis=1)
    got = rotation_ranges(R, np.array([0]), np.array([1]))[0]
    # tolerance: the sampled sine's percentiles, 20001 samples (a few 1e-3 degrees)
    np.testing.assert_allclose(got, [20.0 * np.sin(np.pi / 2 * 0.95), 0.0, 0.0], atol=0.01)


def test_noise_free_small_motion_has_zero_jackknife_error():
    R, p, l_p, l_c = two_segments(2.0, seed=3, artefact_m=0.0)
    p[:, 1] = np.einsum("fij,j->fi", R[:, 0], l_p) + p[:, 0] - np.einsum("fij,j->fi", R[:, 1], l_c)
    se = block_jackknife(R, p, np.array([0]), np.array([1]), np.array([6]))
    assert se[0] < 1e-9  # exact data: every block's fit is the same joint to rounding
    cal = calibrate(R, p, ["a", "b"], parent_of={"b": "a"})
    assert not [w for w in cal.warnings if UNDETERMINED in w]


def test_jackknife_error_matches_the_normal_equations_on_white_noise():
    # white noise: the jackknife must agree with sigma * sqrt(diag((A^T A)^-1)); its own sampling
    # error with 20 blocks is about 1/sqrt(2 * 19) = 16 % relative, so 50 % is three of those
    R, p, _, _ = two_segments(30.0, seed=4, artefact_m=0.0)
    se = block_jackknife(R, p, np.array([0]), np.array([1]), np.array([6]))[0]
    A = np.concatenate([R[:, 0], -R[:, 1]], axis=2).reshape(-1, 6)
    cov = 5e-4**2 * np.linalg.inv(A.T @ A)  # 0.5 mm noise per axis on the child position
    expected = np.sqrt(max(np.trace(cov[:3, :3]), np.trace(cov[3:, 3:])))
    assert se == pytest.approx(expected, rel=0.5)


def test_jackknife_is_the_same_over_chunks_that_cut_blocks_and_missing_frames():
    R, p, _, _ = two_segments(30.0, seed=5, artefact_m=0.002)
    valid = np.random.default_rng(5).random(p.shape[:2]) > 0.05
    args = (R, p, np.array([0]), np.array([1]), np.array([6]))
    whole = block_jackknife(*args, valid=valid, chunk_frames=R.shape[0])
    assert np.isfinite(whole).all() and whole[0] > 0
    for chunk in (7, 333):  # chunks that end inside blocks, and blocks inside chunks
        np.testing.assert_allclose(block_jackknife(*args, valid=valid, chunk_frames=chunk), whole, rtol=1e-9)


def test_residual_outlier_test_is_a_ratio_test():
    r = np.array([5.0, 6.0, 4.5, 5.5, 50.0])
    for scale in (1.0, 1e-3, 39.37):
        flagged = residual_outliers(r * scale)
        assert [k for k, _, _ in flagged] == [4]
        # the others' median of log residuals: the geometric mean of the middle two, 5 and 5.5
        assert flagged[0][2] == pytest.approx(50.0 / np.sqrt(5.0 * 5.5), rel=1e-12)
    assert residual_outliers(np.array([5.0, 6.0, 4.5, 5.5, 12.0])) == []  # twice: not an outlier
    # noise-free joints: 1e-15 and 1e-13 are both exact, not a hundred times apart
    assert residual_outliers(np.array([1e-15, 2e-16, 3e-15, 1e-13, 5e-16]), floor=1e-4) == []
    # two joints: no spread to measure, only a tenfold ratio counts
    assert [k for k, _, _ in residual_outliers(np.array([5.0, 60.0]))] == [1]
    assert residual_outliers(np.array([5.0, 40.0])) == []


def test_simulated_linkage_raises_no_warning(linkage_noisy):
    cap = linkage_noisy
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=cap.skeleton.parent_of)
    assert not [w for w in cal.warnings if UNDETERMINED in w or NOT_NEIGHBOURS in w]


def test_non_neighbours_forced_by_a_given_hierarchy_are_reported(linkage_noisy):
    cap = linkage_noisy
    wrong = dict(cap.skeleton.parent_of, forearm_l="chest")  # skips the left elbow's segment
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=wrong)
    found = [w for w in cal.warnings if NOT_NEIGHBOURS in w]
    assert len(found) == 1 and found[0].startswith("joint chest-forearm_l:")


@pytest.mark.parametrize(("model", "sensors"), [("linkage", "ascension-flock"), ("linkage", "skin-markers")])
def test_simulated_exercise_sessions_raise_no_warning(model, sensors):
    sb = pytest.importorskip("simbench")
    ds = sb.simulate(model=model, motion="exercise", sensors=sensors, duration_s=20, seed=1)
    rec = ds.poses()
    for parent_of in (ds.truth.parent_of, None):
        cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, parent_of=parent_of)
        assert not [w for w in cal.warnings if UNDETERMINED in w or NOT_NEIGHBOURS in w], cal.warnings


def test_humanoid_joints_that_barely_move_under_skin_are_reported_not_silent():
    # the humanoid's exercise turns wrists, ankles and a shoulder 10-20 degrees with under 10 in
    # a second plane; under the skin preset their centres are off by 2-6 cm (issue 42: the bias
    # bound). Every joint off by more than the warnings' limit is reported; none is a non-joint.
    sb = pytest.importorskip("simbench")
    ds = sb.simulate(model="humanoid", motion="exercise", sensors="skin-paper-human", duration_s=20, seed=1)
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, parent_of=ds.truth.parent_of)
    assert not [w for w in cal.warnings if NOT_NEIGHBOURS in w]
    reported = {w.split(":")[0].split()[1] for w in cal.warnings if UNDETERMINED in w}
    index = {n: k for k, n in enumerate(rec.names)}
    for j in score(cal, ds).joints:
        a, b = (index[x] for x in j.name.split("-"))
        sep = float(np.sqrt(np.nanmean(np.sum((rec.p_w_s[:, b] - rec.p_w_s[:, a]) ** 2, axis=1))))
        if max(j.centre_error_in_parent_m, j.centre_error_in_child_m) > UNCERTAIN_FRACTION * sep:
            assert j.name in reported, (j.name, reported)
    assert 1 <= len(reported) <= 8  # measured 6 of 15


def test_warnings_reach_the_table_the_json_and_the_report(tmp_path):
    R, p, _, _ = two_segments(3.0, seed=1)
    valid = np.ones((R.shape[0], 2), bool)
    rec = PoseRecording(("pelvis", "thigh"), np.arange(R.shape[0]) / 100.0, R, p, valid)
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    warning = next(w for w in cal.warnings if UNDETERMINED in w)
    assert warning in format_table(rec, cal, [])
    assert warning in calibration_to_dict(cal)["warnings"]
    path = tmp_path / "poses.csv"
    write_pose_csv(path, rec)
    # its one joint not located: the report is refused (as calibrate refuses it), saying why
    with pytest.raises(InputError, match=r"no joint centre is determined.*pelvis-thigh: 3 of 6"):
        dataset_report(path, tmp_path / "refused")
    # with a trunk that turns well on the same pelvis (same parent motion), the report is written
    # and the thigh's warning reaches it
    R2, p2, _, _ = two_segments(40.0, seed=2)
    assert np.array_equal(R2[:, 0], R[:, 0]) and np.array_equal(p2[:, 0], p[:, 0])
    three = PoseRecording(
        ("pelvis", "thigh", "trunk"),
        rec.time_s,
        np.concatenate([R, R2[:, 1:]], axis=1),
        np.concatenate([p, p2[:, 1:]], axis=1),
        np.ones((R.shape[0], 3), bool),
    )
    write_pose_csv(path, three)
    paths = dataset_report(path, tmp_path / "report")
    assert "## Warnings" in paths["md"].read_text() and UNDETERMINED in paths["md"].read_text()
    assert any(UNDETERMINED in w for w in json.loads(paths["json"].read_text())["warnings"])
