"""Limb lengths and sensor offsets (section 3), residual removal (section 3.4), unit scale (4)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import CalibrationError, CalibrationInputError, calibrate, remove_residual, unit_scale
from calibration.joint import joint_residual_vectors
from simbench.sim.synthetic import random_tree, simulate_motion


def test_limb_lengths_exact(linkage_exact):
    cap = linkage_exact
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    truth = cap.skeleton.segment_lengths()
    assert {(x.segment, x.joint_a, x.joint_b) for x in cal.lengths} == set(truth)
    for x in cal.lengths:
        # exact data: rounding only
        assert x.length == pytest.approx(truth[(x.segment, x.joint_a, x.joint_b)], abs=1e-9)


def test_branching_tree_lengths_and_offsets():
    sk = random_tree(10, np.random.default_rng(5))
    cap = simulate_motion(sk, n_frames=500, rate_hz=100.0, rng=np.random.default_rng(6))
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names, root="b0")
    truth = sk.segment_lengths()
    for x in cal.lengths:
        assert x.length == pytest.approx(truth[(x.segment, x.joint_a, x.joint_b)], abs=1e-9)
    joints = sk.joint_in_sensor_frames()
    for pl in cal.placements:
        for name, offset in zip(pl.joints, pl.offsets, strict=True):
            _parent, child = name.split("-")
            expected = joints[child][1] if pl.sensor == child else joints[child][0]
            assert_allclose(offset, expected, atol=1e-9)


def test_residual_removal_keeps_joints_together(linkage_noisy):
    cap = linkage_noisy
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    lp, lc = cal.joint_arrays()
    clean = remove_residual(cap.R_w_s, cap.p_w_s, cal.hierarchy, lp, lc)
    root = cal.hierarchy.root
    assert np.array_equal(clean[:, root], cap.p_w_s[:, root])
    worst_before = worst_after = 0.0
    for j in cal.joints:
        p, c = cap.names.index(j.parent), cap.names.index(j.child)
        before = joint_residual_vectors(
            cap.R_w_s[:, p],
            cap.p_w_s[:, p],
            cap.R_w_s[:, c],
            cap.p_w_s[:, c],
            j.fit.joint_in_parent,
            j.fit.joint_in_child,
        )
        after = joint_residual_vectors(
            cap.R_w_s[:, p],
            clean[:, p],
            cap.R_w_s[:, c],
            clean[:, c],
            j.fit.joint_in_parent,
            j.fit.joint_in_child,
        )
        worst_before = max(worst_before, np.abs(before).max())
        worst_after = max(worst_after, np.abs(after).max())
    assert worst_before > 1e-3  # the noisy data's joints do come apart
    assert worst_after < 1e-12  # rounding of metre-sized sums only


def test_residual_removal_is_identity_on_exact_data(linkage_exact):
    cap = linkage_exact
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    clean = remove_residual(cap.R_w_s, cap.p_w_s, cal.hierarchy, *cal.joint_arrays())
    assert_allclose(clean, cap.p_w_s, atol=1e-12)


def test_residual_removal_marks_missing_descendants(linkage_exact):
    cap = linkage_exact
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    R = cap.R_w_s.copy()
    arm = cap.names.index("upper_arm_l")
    R[10, arm] = np.nan
    clean = remove_residual(R, cap.p_w_s, cal.hierarchy, *cal.joint_arrays())
    fore = cap.names.index("forearm_l")
    assert np.isnan(clean[10, arm]).all() and np.isnan(clean[10, fore]).all()
    assert np.isfinite(np.delete(clean[10], [arm, fore], axis=0)).all()
    with pytest.raises(CalibrationInputError, match=r"joint_in_parent to have shape \(6, 3\)"):
        remove_residual(R, cap.p_w_s, cal.hierarchy, np.zeros((5, 3)), np.zeros((6, 3)))


def test_unit_scale_recovers_factor_and_spread():
    rng = np.random.default_rng(7)
    n, true_d, factor, sigma = 20_000, 0.565, 0.94, 0.005
    a = rng.normal(size=(n, 3))
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    b = a + u * true_d
    # the system reports lengths divided by the factor, plus noise on one sensor
    reported_a = a / factor
    reported_b = b / factor + rng.normal(0.0, sigma / factor, size=(n, 3))
    est = unit_scale(reported_a, reported_b, true_d)
    # 20,000 frames: the mean distance is known to ~sigma/sqrt(n) = 3.5e-5 m; 5e-4 is > 10 sigma
    assert est.scale == pytest.approx(factor, abs=5e-4)
    # the spread along the line of sight is the noise per component, sigma
    assert est.scaled_std == pytest.approx(sigma, rel=0.05)
    with pytest.raises(CalibrationInputError, match="positive length"):
        unit_scale(a, b, -1.0)
    with pytest.raises(CalibrationError, match="same place"):
        unit_scale(a, a, 1.0)
