"""The per-pair joint fit (O'Brien eqs. 8-13) and single-axis detection (section 3.2)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import SINGLE_AXIS_RATIO, CalibrationError, CalibrationInputError, fit_joint
from calibration.joint import determined_directions
from calibration.rotations import rotvec_to_matrix
from simbench.sim.synthetic import HINGE, chain, linkage, simulate_motion
from tests.helpers import pair_arrays


def test_noise_free_joints_recovered_exactly(linkage_exact):
    truth = linkage_exact.skeleton.joint_in_sensor_frames()
    for child, parent in linkage_exact.skeleton.parent_of.items():
        fit = fit_joint(*pair_arrays(linkage_exact, parent, child))
        lp, lc = truth[child]
        # exact data: the only error is rounding of metre-sized numbers (~1e-15)
        assert_allclose(fit.joint_in_parent, lp, atol=1e-9)
        assert_allclose(fit.joint_in_child, lc, atol=1e-9)
        assert fit.rms_residual < 1e-12
        assert fit.rank == 6 and not fit.single_axis
        assert fit.n_frames == 800 and fit.n_dropped == 0


def test_matches_plain_least_squares(linkage_noisy):
    Rp, pp, Rc, pc = pair_arrays(linkage_noisy, "chest", "upper_arm_l")
    fit = fit_joint(Rp, pp, Rc, pc)
    A = np.concatenate([Rp, -Rc], axis=2).reshape(-1, 6)
    x, *_ = np.linalg.lstsq(A, (pc - pp).ravel(), rcond=None)
    # full rank: the SVD solution is the least-squares one, up to rounding
    assert_allclose(fit.joint_in_parent, x[:3], atol=1e-12)
    assert_allclose(fit.joint_in_child, x[3:], atol=1e-12)
    r = (A @ x - (pc - pp).ravel()).reshape(-1, 3)
    assert fit.rms_residual == pytest.approx(np.sqrt(np.mean(np.sum(r * r, axis=1))), rel=1e-12)
    assert_allclose(fit.frame_residual, np.linalg.norm(r, axis=1), atol=1e-12)


@pytest.fixture(scope="module")
def hinge_capture():
    return simulate_motion(
        chain([0.4, 0.3], [HINGE, "ball"]), n_frames=600, rate_hz=100.0, rng=np.random.default_rng(4)
    )


def test_hinge_detected_with_axis_in_both_frames(hinge_capture):
    sk = hinge_capture.skeleton
    fit = fit_joint(*pair_arrays(hinge_capture, "s0", "s1"))
    assert fit.single_axis and fit.rank == 5
    axis_body = np.array(sk.segments[1].axis)
    axis_p = rotvec_to_matrix(np.array(sk.segments[0].sensor_rotvec)).T @ axis_body
    axis_c = rotvec_to_matrix(np.array(sk.segments[1].sensor_rotvec)).T @ axis_body
    # exact hinge data: the axis is recovered to rounding (up to sign, same sign in both frames)
    sign = np.sign(fit.axis_in_parent @ axis_p)
    assert_allclose(fit.axis_in_parent, sign * axis_p, atol=1e-9)
    assert_allclose(fit.axis_in_child, sign * axis_c, atol=1e-9)
    # the fitted point lies on the true axis ...
    lp, _lc = sk.joint_in_sensor_frames()["s1"]
    along = fit.joint_in_parent - lp
    assert np.linalg.norm(along - (along @ axis_p) * axis_p) < 1e-9
    assert fit.rms_residual < 1e-12
    # ... and is the minimum-norm one: orthogonal to the null vector [axis_p; axis_c]
    assert abs(fit.joint_in_parent @ axis_p + fit.joint_in_child @ axis_c) < 1e-9
    # the ball joint further down is not flagged
    assert not fit_joint(*pair_arrays(hinge_capture, "s1", "s2")).single_axis


def test_verdict_and_solution_do_not_depend_on_length_unit(hinge_capture):
    for parent, child in (("s0", "s1"), ("s1", "s2")):
        Rp, pp, Rc, pc = pair_arrays(hinge_capture, parent, child)
        in_m = fit_joint(Rp, pp, Rc, pc)
        in_cm = fit_joint(Rp, 100.0 * pp, Rc, 100.0 * pc)
        assert in_m.single_axis == in_cm.single_axis
        assert_allclose(in_m.singular_values, in_cm.singular_values, rtol=1e-12)
        assert_allclose(100.0 * in_m.joint_in_parent, in_cm.joint_in_parent, rtol=1e-9, atol=1e-9)


def test_weak_ratio_is_half_the_off_axis_angle():
    """The documented reading of s_min/s_max: about half the rms rotation off the weakest axis."""
    rng = np.random.default_rng(1)
    n = 4000
    for theta in (0.01, 0.1):
        rotvec = np.zeros((n, 3))
        rotvec[:, 2] = rng.uniform(-1.2, 1.2, n)
        rotvec[:, :2] = rng.normal(0.0, theta / np.sqrt(2), (n, 2))
        Rp = rotvec_to_matrix(rng.normal(size=(n, 3)))
        Rc = Rp @ rotvec_to_matrix(rotvec)
        pp = rng.normal(size=(n, 3))
        pc = pp + np.einsum("fij,j->fi", Rp, [0.1, 0.2, 0.3]) - np.einsum("fij,j->fi", Rc, [0.0, 0.1, 0.0])
        fit = fit_joint(Rp, pp, Rc, pc)
        assert fit.weak_ratio == pytest.approx(theta / 2, rel=0.1)
        # exact positions: even 0.3 degrees off the axis pin the centre along it (the ratio is
        # reported, the verdict comes from the residual's noise, calibration.hinge)
        assert theta / 2 > SINGLE_AXIS_RATIO and not fit.single_axis and fit.rank == 6


def test_error_shrinks_as_frames_grow():
    truth = linkage().joint_in_sensor_frames()["upper_arm_l"][0]
    errors = []
    for n_frames in (250, 1000, 4000):
        e = []
        for seed in range(6):
            cap = simulate_motion(
                linkage(),
                n_frames=n_frames,
                rate_hz=120.0,
                rng=np.random.default_rng(seed),
                position_noise_m=0.003,
            )
            fit = fit_joint(*pair_arrays(cap, "chest", "upper_arm_l"))
            e.append(np.linalg.norm(fit.joint_in_parent - truth))
        errors.append(np.mean(e))
    # least squares: error ~ 1/sqrt(frames), so x16 frames should roughly quarter it
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.5 * errors[0]
    assert errors[0] < 0.01  # a few-mm noise gives a joint well under a centimetre off


@pytest.mark.parametrize("batch", [(), (1,), (3, 1, 2)])
def test_single_axis_rule_is_vectorised(batch):
    rng = np.random.default_rng(3)
    s = -np.sort(-rng.uniform(0.0, 1.0, (*batch, 6)), axis=-1)
    flat = s.reshape(-1, 6)
    flat[::2, 5] = 0.4 * SINGLE_AXIS_RATIO * flat[::2, 0]  # below the floor in every other row
    if flat.shape[0] > 1:
        flat[1] = 0.0  # a fit with no determined direction at all
    keep = determined_directions(s, SINGLE_AXIS_RATIO)
    assert keep.shape == s.shape
    # the rule row by row, as O'Brien 3.2 states it
    for row, mask in zip(flat, keep.reshape(-1, 6), strict=True):
        expect = (row >= SINGLE_AXIS_RATIO * row[0]) if row[0] > 0 else np.zeros(6, dtype=bool)
        np.testing.assert_array_equal(mask, expect)
    assert not keep.reshape(-1, 6)[0, 5]


def test_rigid_pair_is_not_determined():
    rng = np.random.default_rng(2)
    R = rotvec_to_matrix(rng.normal(size=(50, 3)))
    p = rng.normal(size=(50, 3))
    fit = fit_joint(R, p, R, p + np.einsum("fij,j->fi", R, [0.1, 0.0, 0.0]))
    assert fit.rank == 3 and not fit.single_axis
    assert fit.rms_residual < 1e-12


def test_nonfinite_frames_dropped(linkage_noisy):
    Rp, pp, Rc, pc = (a.copy() for a in pair_arrays(linkage_noisy, "chest", "head"))
    pp[5] = np.nan
    Rc[17, 0, 0] = np.inf
    fit = fit_joint(Rp, pp, Rc, pc)
    keep = np.ones(len(pp), dtype=bool)
    keep[[5, 17]] = False
    ref = fit_joint(Rp[keep], pp[keep], Rc[keep], pc[keep])
    assert fit.n_dropped == 2 and fit.n_frames == len(pp) - 2
    assert_allclose(fit.joint_in_parent, ref.joint_in_parent, atol=1e-13)
    assert np.isnan(fit.frame_residual[[5, 17]]).all()
    assert fit.rms_residual == pytest.approx(ref.rms_residual, rel=1e-12)


def test_bad_input():
    R = np.tile(np.eye(3), (2, 1, 1))
    p = np.zeros((2, 3))
    with pytest.raises(CalibrationError, match="at least 3 frames"):
        fit_joint(R, p, R, p)
    with pytest.raises(CalibrationInputError, match=r"Expected p_w_p to have shape \(frames, 3\)"):
        fit_joint(R, np.zeros((2, 4)), R, p)
    with pytest.raises(CalibrationInputError, match="Expected R_w_c to have 2 frames"):
        fit_joint(R, p, np.tile(np.eye(3), (3, 1, 1)), p)
