"""Errors in the rotations: the bias they put into a joint fit, and its correction.

O'Brien's joint fit (:mod:`calibration.joint`) regresses ``b[f] = p_w_c[f] - p_w_p[f]`` on
``A[f] = [R_w_p[f], -R_w_c[f]]``. The rotations are measured too, and the noise on them is not
averaged out: with ``R = R_true exp([n]x)`` and ``n`` of variance ``sigma^2`` per component, the
measured ``A`` is, on average, the true one scaled by ``S = diag((1 - sigma_p^2) I, (1 - sigma_c^2) I)``
(``E exp([n]x) = (1 - sigma^2) I`` to second order), while ``A[f]^T A[f]`` keeps its identity
diagonal blocks (``R^T R = I`` whatever the noise). So the normal equations carry an extra
``F (I - S^2) ~ 2 F D`` on their diagonal (``D = diag(sigma_p^2 I, sigma_c^2 I)``, ``F`` frames)
that the truth does not: the classical errors-in-variables bias, which pulls the centre toward the
sensors' origins along the directions the motion determines weakly. Subtracting it
(the corrected least squares of Fuller 1987, ch. 2),

    (A^T A - 2 F D) x = A^T b,

and ``x = S y`` undoes the shrink (``N ~ S A0^T A0 S`` and ``A^T b ~ S A0^T b``, so ``y = S^-1 x``).
The shrink is ``sigma^2`` of the centre's distance (0.03 mm at 0.3 m for ``sigma`` = 0.01 rad),
but it lies along the best-determined direction (the sensors' offset, averaged over every frame),
where it was as large as the spread of the estimate in the tests. It matters when the
rotation noise is not small against the range of motion: Polhemus-class noise (0.15-0.6 degrees
at the sensors' ranges) and joints turned through a few degrees gave 6 mm median and 41 mm 90th
percentile errors with 20 % of the 95 % regions holding the truth; corrected, 2.2 and 8 mm and
91 % (``studies/methods.py``, small range, rotation noise only, 3 seeds).

**The noise level from the recording.** :func:`orientation_noise_variance` reads ``sigma^2`` off
the measured rotations themselves: the body-frame increments ``log(R[f]^T R[f+1])`` of smooth
motion differ from frame to frame by little, so their second difference (the third difference
of the orientation, variance ``20 sigma^2`` for white noise) is the noise. Its scale is taken
robustly per block of :data:`BLOCK_FRAMES` differences (the median absolute deviation, so a glitch
or a fast turn does not count) and averaged over blocks (the noise grows with the distance from
a magnetic tracker's source, so it changes over a session). Motion sampled coarsely also adds to
the differences; the fourth difference (variance ``70 sigma^2``) is less sensitive to it, and the
smaller of the two estimates is taken. Noise that the tracker filters (correlated from frame to
frame) is underestimated: the correction then removes less than the bias, never more.
"""

from __future__ import annotations

import math

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.rotations import matrix_to_rotvec

#: Differences per block of the robust scale estimate (1 s at 120 Hz).
BLOCK_FRAMES = 120

#: Fewest differences a block needs to count.
MIN_BLOCK_SAMPLES = 20

#: ``E[(d^k n)^2] / sigma^2`` for white noise ``n``: the k-th difference's variance (central
#: binomial coefficients ``C(2k, k)``) for the third and fourth differences used.
DIFFERENCE_GAIN = {3: 20.0, 4: 70.0}

#: Median absolute deviation to standard deviation for Gaussian noise.
MAD_TO_STD = 1.482602218505602

#: Largest rotation noise read off a recording, rad (3 degrees per component: ten times a magnetic
#: tracker's at the edge of its range). More than that between frames is motion that the
#: recording does not sample smoothly (or poses that are not a time series), not noise.
MAX_NOISE_RAD = 0.05

#: The corrected normal matrix must keep at least this share of the uncorrected one's information
#: along every determined direction; below it the noise swamps the motion there.
MIN_KEPT_INFORMATION = 0.1


def orientation_noise_variance(R_w_s: np.ndarray, valid: np.ndarray | None = None) -> float:
    """The variance of one sensor's rotation noise per rotation-vector component, rad^2.

    See the module docstring: robust (median absolute deviation) per block of third and fourth
    differences of the orientation, averaged over blocks, the smaller of the two.

    Args:
        R_w_s: ``(frames, 3, 3)`` the sensor's rotations, sensor to world.
        valid: optional ``(frames,)`` bool; only runs of consecutive valid, finite frames are used.

    Returns:
        ``sigma^2``, rad^2 (0 for exact rotations).

    Raises:
        CalibrationInputError: malformed arrays.
        CalibrationError: fewer than :data:`MIN_BLOCK_SAMPLES` runs of five consecutive usable
            frames, or differences larger than :data:`MAX_NOISE_RAD` of noise would give (the
            rotations are not a smoothly sampled time series).
    """
    R = np.asarray(R_w_s, dtype=float)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise CalibrationInputError(f"Expected R_w_s of shape (frames, 3, 3), got {R.shape}")
    n = R.shape[0]
    ok = np.isfinite(R).all(axis=(1, 2))
    if valid is not None:
        valid = np.asarray(valid)
        if valid.shape != (n,):
            raise CalibrationInputError(f"Expected valid to have shape ({n},), got {valid.shape}")
        ok &= valid.astype(bool)
    if n < 5:
        raise CalibrationError(f"The rotation noise needs at least 5 frames, got {n}")
    R0 = np.where(ok[:, None, None], R, np.eye(3))
    inc = matrix_to_rotvec(np.einsum("fji,fjk->fik", R0[:-1], R0[1:]))  # (n-1, 3) body increments
    estimates = []
    for k, gain in DIFFERENCE_GAIN.items():
        d = np.diff(inc, n=k - 1, axis=0)  # k-th difference of the orientation, (n - k, 3)
        good = np.lib.stride_tricks.sliding_window_view(ok, k + 1).all(axis=1)
        estimates.append(_blockwise_variance(d, good) / gain)
    if not all(np.isfinite(estimates)):
        raise CalibrationError(
            f"The rotation noise needs at least {MIN_BLOCK_SAMPLES} runs of 5 consecutive valid frames, "
            f"got {int(np.count_nonzero(np.lib.stride_tricks.sliding_window_view(ok, 5).all(axis=1)))}"
        )
    variance = float(min(estimates))
    if variance > MAX_NOISE_RAD**2:
        raise CalibrationError(
            f"The rotations change by {math.sqrt(variance):.3g} rad (rms, third difference scaled to "
            f"noise) from frame to frame beyond smooth motion; more than {MAX_NOISE_RAD} rad is not "
            "tracker noise: the rotations must be a time series that samples the motion smoothly "
            "(or give the noise variances)"
        )
    return variance


def corrected_normal_matrix(gram: np.ndarray, n_frames: int, noise_rad2: tuple[float, float]) -> np.ndarray:
    """``(6, 6)`` ``A^T A - 2 F D``: the normal matrix less the rotation noise's share.

    Args:
        gram: ``(6, 6)`` ``A^T A`` over ``n_frames`` frames.
        n_frames: ``F``, the frames summed.
        noise_rad2: ``(sigma_p^2, sigma_c^2)`` per rotation-vector component, rad^2.
    """
    return np.asarray(gram, dtype=float) - 2.0 * n_frames * noise_diagonal(noise_rad2)


def noise_diagonal(noise_rad2: tuple[float, float]) -> np.ndarray:
    """``(6, 6)`` ``D = diag(sigma_p^2 I, sigma_c^2 I)``, rad^2."""
    return np.diag(np.repeat(np.asarray(noise_rad2, dtype=float), 3))


def check_noise(noise_rad2: object) -> tuple[float, float]:
    """``(sigma_p^2, sigma_c^2)`` as floats, or a clear error for anything else."""
    try:
        pair = tuple(float(v) for v in noise_rad2)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise CalibrationInputError(
            f"Expected orientation_noise_rad2 as (parent, child) variances in rad^2, got {noise_rad2!r}"
        ) from None
    if len(pair) != 2 or not all(np.isfinite(pair)) or min(pair) < 0.0:
        raise CalibrationInputError(
            f"Expected orientation_noise_rad2 as two finite variances >= 0 (rad^2), got {noise_rad2!r}"
        )
    if max(pair) > 0.1:
        raise CalibrationInputError(
            f"orientation_noise_rad2 {pair} is a variance in rad^2 (0.1 rad^2 is 18 degrees of noise): "
            "pass sigma**2, not sigma or degrees"
        )
    return pair  # type: ignore[return-value]


def corrected_solution(
    gram: np.ndarray, rhs: np.ndarray, basis: np.ndarray, n_frames: int, noise_rad2: tuple[float, float]
) -> np.ndarray:
    """``(6,)`` the corrected least-squares centre in the determined directions.

    ``x = S V (V^T N V)^-1 V^T A^T b`` with ``N`` from :func:`corrected_normal_matrix` and ``S``
    the rotations' mean shrink (module docstring).

    Args:
        gram: ``(6, 6)`` ``A^T A``.
        rhs: ``(6,)`` ``A^T b``, metres.
        basis: ``(6, k)`` orthonormal determined directions ``V``.
        n_frames: frames summed.
        noise_rad2: ``(sigma_p^2, sigma_c^2)``, rad^2.

    Raises:
        CalibrationError: the correction leaves less than :data:`MIN_KEPT_INFORMATION` of the
            information along a determined direction (the noise swamps the motion there).
    """
    V = np.asarray(basis, dtype=float)
    plain = V.T @ gram @ V
    kept = V.T @ corrected_normal_matrix(gram, n_frames, noise_rad2) @ V
    w = np.linalg.eigvalsh(np.linalg.solve(plain, kept)) if V.shape[1] else np.ones(1)
    if np.min(w) < MIN_KEPT_INFORMATION:
        raise CalibrationError(
            f"The rotation noise (variances {noise_rad2[0]:.3g}, {noise_rad2[1]:.3g} rad^2) leaves "
            f"{max(float(np.min(w)), 0.0):.0%} of the motion's information along a determined direction "
            f"(needs {MIN_KEPT_INFORMATION:.0%}): the joint turns too little for its noise to be corrected"
        )
    y = V @ np.linalg.solve(kept, V.T @ rhs)
    return np.repeat(1.0 - np.asarray(noise_rad2, dtype=float), 3) * y  # x = S y


def _blockwise_variance(d: np.ndarray, good: np.ndarray) -> float:
    """Mean over blocks of the per-axis robust variance (MAD squared) of the good rows of ``d``
    (blocks with every row good at once; the others one by one)."""
    out = []
    n_full = d.shape[0] // BLOCK_FRAMES
    whole = good[: n_full * BLOCK_FRAMES].reshape(n_full, BLOCK_FRAMES).all(axis=1)
    x = d[: n_full * BLOCK_FRAMES].reshape(n_full, BLOCK_FRAMES, d.shape[1])[whole]
    if x.shape[0]:
        mad = np.median(np.abs(x - np.median(x, axis=1, keepdims=True)), axis=1) * MAD_TO_STD
        out += list(np.mean(mad**2, axis=1))
    for start in [BLOCK_FRAMES * k for k in np.flatnonzero(~whole)] + [n_full * BLOCK_FRAMES]:
        y = d[start : start + BLOCK_FRAMES][good[start : start + BLOCK_FRAMES]]
        if y.shape[0] >= MIN_BLOCK_SAMPLES:
            mad = np.median(np.abs(y - np.median(y, axis=0)), axis=0) * MAD_TO_STD
            out.append(float(np.mean(mad**2)))
    return float(np.mean(out)) if out else float("nan")
