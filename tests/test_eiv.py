"""calibration.eiv: the rotation noise read off a recording, and the fit corrected for it.

Synthetic pairs of sensors joined at a known centre, moving smoothly (sums of sines at 0.1-0.6 Hz,
120 Hz), with world-frame rotation noise and position noise added: the exact truth is known, so
the bias of O'Brien's plain least squares under rotation noise, its removal, and the coverage of
the corrected fit's 95 % regions are measured against it.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.eiv import MAX_NOISE_RAD, orientation_noise_variance
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import fit_joint
from calibration.methods import estimate_obrien, estimate_obrien_eiv
from calibration.rotations import rotvec_to_matrix
from calibration.uncertainty import holds_truth, joint_covariance

RATE_HZ = 120.0
FRAMES = 2400
IN_PARENT = np.array([0.09, -0.08, -0.06])
IN_CHILD = np.array([0.02, 0.04, 0.21])


def smooth(rng: np.random.Generator, n: int, amplitude: float) -> np.ndarray:
    """``(n, 3)`` sums of three sines at 0.1-0.6 Hz, each of amplitude ``amplitude / 3``."""
    t = np.arange(n) / RATE_HZ
    f = rng.uniform(0.1, 0.6, (3, 3))
    phase = rng.uniform(0.0, 2.0 * np.pi, (3, 3))
    return (amplitude / 3) * np.sin(2.0 * np.pi * f * t[:, None, None] + phase).sum(axis=1)


def pair(rng: np.random.Generator, n: int, relative_rad: float) -> tuple[np.ndarray, ...]:
    """Exact ``(R_w_p, p_w_p, R_w_c, p_w_c)``: the parent turns through about 1.5 rad, the child
    relative to it through ``relative_rad`` (rotation-vector components)."""
    R_p = rotvec_to_matrix(smooth(rng, n, 1.5))
    p_p = smooth(rng, n, 0.3) + np.array([0.0, 0.0, 1.0])
    R_c = R_p @ rotvec_to_matrix(smooth(rng, n, relative_rad))
    p_c = np.einsum("fij,j->fi", R_p, IN_PARENT) + p_p - np.einsum("fij,j->fi", R_c, IN_CHILD)
    return R_p, p_p, R_c, p_c


def noisy(rng: np.random.Generator, poses, sigma_rad, noise_m: float) -> tuple[np.ndarray, ...]:
    """The poses with world-frame rotation noise (``sigma_rad`` per component: a scalar or one per
    frame) and position noise ``noise_m`` per axis."""
    R_p, p_p, R_c, p_c = poses
    n = p_p.shape[0]
    sigma = np.broadcast_to(np.asarray(sigma_rad, dtype=float), (n,))[:, None]
    return (
        rotvec_to_matrix(rng.normal(size=(n, 3)) * sigma) @ R_p,
        p_p + rng.normal(0.0, noise_m, (n, 3)),
        rotvec_to_matrix(rng.normal(size=(n, 3)) * sigma) @ R_c,
        p_c + rng.normal(0.0, noise_m, (n, 3)),
    )


# --------------------------------------------------------------------------------------------
# the noise level from the recording
# --------------------------------------------------------------------------------------------


def test_noise_variance_is_read_off_the_rotations():
    rng = np.random.default_rng(1)
    exact = pair(rng, FRAMES, 0.6)
    sigma = 0.004
    R = noisy(rng, exact, sigma, 0.0)[0]
    # 2400 frames, 20 blocks: the robust scale is within a few per cent (measured 0.99-1.02)
    assert orientation_noise_variance(R) == pytest.approx(sigma**2, rel=0.1)
    # smooth motion alone (1.5 rad at up to 0.6 Hz) is not noise: its third difference at 120 Hz
    # is about 1e-5 rad, a thousandth of the noise's variance
    assert orientation_noise_variance(exact[0]) < 1e-3 * sigma**2
    # noise that grows during the recording (a sensor moving away from a magnetic source): the mean
    # of its variance over the session, which is what the bias depends on
    ramp = np.linspace(0.002, 0.006, FRAMES)
    R = noisy(rng, exact, ramp, 0.0)[0]
    assert orientation_noise_variance(R) == pytest.approx(np.mean(ramp**2), rel=0.15)
    # frames left out (NaN or marked invalid) break the runs, not the estimate
    R = noisy(rng, exact, sigma, 0.0)[0]
    valid = np.ones(FRAMES, dtype=bool)
    valid[300:420] = False
    R[350] = np.nan
    assert orientation_noise_variance(R, valid) == pytest.approx(sigma**2, rel=0.1)


def test_noise_variance_refuses_what_is_not_a_smooth_time_series():
    rng = np.random.default_rng(2)
    with pytest.raises(
        CalibrationInputError, match=r"Expected R_w_s of shape \(frames, 3, 3\), got \(10, 3\)"
    ):
        orientation_noise_variance(np.zeros((10, 3)))
    R = pair(rng, 300, 0.6)[0]
    with pytest.raises(CalibrationInputError, match=r"Expected valid to have shape \(300,\), got \(299,\)"):
        orientation_noise_variance(R, np.ones(299, dtype=bool))
    with pytest.raises(CalibrationError, match="needs at least 5 frames, got 4"):
        orientation_noise_variance(R[:4])
    every_other = np.arange(300) % 2 == 0
    with pytest.raises(CalibrationError, match="needs at least 20 runs of 5 consecutive valid frames, got 0"):
        orientation_noise_variance(R, every_other)
    # a rotation sampled far too coarsely (here: independent random rotations) is not noise
    shuffled = rotvec_to_matrix(rng.normal(0.0, 1.0, (300, 3)))
    with pytest.raises(CalibrationError, match=f"more than {MAX_NOISE_RAD} rad is not tracker noise"):
        orientation_noise_variance(shuffled)


# --------------------------------------------------------------------------------------------
# the corrected fit
# --------------------------------------------------------------------------------------------


def test_plain_fit_is_biased_by_rotation_noise_and_the_corrected_one_is_not_and_covers():
    """Monte Carlo: 200 sessions (10 motions, new noise in each) of a joint turned through about
    6 degrees per axis, 0.34 degrees of rotation noise and 0.5 mm of position noise.

    Measured: the plain fit's mean error along the determined directions is 1-3 mm (4.3 of one
    session's standard deviations) and none of its 95 % regions holds the truth; corrected, the
    mean error is 0.23 standard deviations (what 200 sessions give by chance), the rms error
    1.2 mm against 5.7, and 95 % of the regions hold the truth.
    """
    runs, sigma = 200, 0.006
    motions = [pair(np.random.default_rng([5, m]), FRAMES, 0.1) for m in range(10)]
    errors: dict[str, list] = {"plain": [], "eiv": []}
    held: dict[str, list] = {"plain": [], "eiv": []}
    for run in range(runs):
        rng = np.random.default_rng([6, run])
        poses = noisy(rng, motions[run % 10], sigma, 5e-4)
        noise = (orientation_noise_variance(poses[0]), orientation_noise_variance(poses[2]))
        for name, given in (("plain", None), ("eiv", noise)):
            fit = fit_joint(*poses, orientation_noise_rad2=given)
            u = joint_covariance(*poses, fit)
            V = u.basis
            x = np.concatenate([fit.joint_in_parent - IN_PARENT, fit.joint_in_child - IN_CHILD])
            errors[name].append(V @ (V.T @ x))
            held[name] += holds_truth(u, IN_PARENT, IN_CHILD)

    def bias_in_spreads(e: np.ndarray) -> float:
        """The mean error's Mahalanobis length in the sessions' own spread: how many standard
        deviations of one session's estimate the bias is (what coverage suffers from)."""
        m, S = e.mean(axis=0), np.cov(e, rowvar=False)
        return float(np.sqrt(m @ np.linalg.solve(S, m)))

    plain, eiv = np.array(errors["plain"]), np.array(errors["eiv"])
    # measured 4.3 and 0.23; with no bias the mean of 200 sessions is sqrt(chi2_6) / sqrt(200)
    # spreads from zero by chance: 0.17 typically, 0.33 at the 99.9th percentile
    assert bias_in_spreads(plain) > 3.0
    assert bias_in_spreads(eiv) < 0.35
    assert np.sqrt(np.mean(np.sum(eiv**2, axis=1))) < 0.35 * np.sqrt(np.mean(np.sum(plain**2, axis=1)))
    assert np.mean(held["plain"]) < 0.5
    assert 0.91 <= np.mean(held["eiv"]) <= 0.98


def test_no_noise_is_the_plain_fit_and_exact_data_are_recovered():
    rng = np.random.default_rng(3)
    poses = noisy(rng, pair(rng, FRAMES, 0.6), 0.003, 5e-4)
    plain, zero = fit_joint(*poses), fit_joint(*poses, orientation_noise_rad2=(0.0, 0.0))
    assert_allclose(zero.joint_in_parent, plain.joint_in_parent, rtol=0, atol=0)
    assert zero.orientation_noise_rad2 == (0.0, 0.0)
    u_plain, u_zero = joint_covariance(*poses, plain), joint_covariance(*poses, zero)
    assert_allclose(u_zero.cov, u_plain.cov, rtol=1e-12, atol=0)
    # exact time series: the noise read off them is (nearly) nil and the truth comes back
    exact = pair(rng, FRAMES, 0.6)
    est = estimate_obrien_eiv(*exact)
    assert est.method == "obrien-eiv" and max(est.fit.orientation_noise_rad2) < 1e-9
    assert_allclose(est.joint_in_parent, IN_PARENT, atol=1e-6)
    assert_allclose(est.joint_in_child, IN_CHILD, atol=1e-6)
    # the variances given are the ones used, and they move the centre (the plain fit is biased)
    given = estimate_obrien_eiv(*poses, orientation_noise_rad2=(9e-6, 9e-6))
    assert given.fit.orientation_noise_rad2 == (9e-6, 9e-6)
    assert not np.allclose(given.joint_in_parent, estimate_obrien(*poses).joint_in_parent, atol=1e-5)


def test_bad_noise_variances_are_named():
    rng = np.random.default_rng(4)
    poses = pair(rng, 600, 0.6)
    for bad, match in (
        ((1e-6,), r"two finite variances >= 0 \(rad\^2\), got \(1e-06,\)"),
        ((1e-6, -1e-6), r"two finite variances >= 0"),
        ((1e-6, float("nan")), r"two finite variances >= 0"),
        ("ab", r"as \(parent, child\) variances in rad\^2, got 'ab'"),
        (0.001, r"as \(parent, child\) variances in rad\^2, got 0.001"),
        ((0.3, 0.3), r"is a variance in rad\^2 .* pass sigma\*\*2, not sigma or degrees"),
    ):
        with pytest.raises(CalibrationInputError, match=match):
            fit_joint(*poses, orientation_noise_rad2=bad)
    # more noise than the motion carries information: refused, not a wild centre
    small = pair(rng, 600, 0.01)
    with pytest.raises(CalibrationError, match="the joint turns too little for its noise to be corrected"):
        fit_joint(*small, orientation_noise_rad2=(0.01, 0.01))
