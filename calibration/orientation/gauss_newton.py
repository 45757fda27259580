"""Fontaine et al.'s estimator: Gauss-Newton on the gravity and Earth-field residuals.

Minimise the quadratic error between the measured (normalised) accelerometer and magnetometer
vectors and those modelled from gravity and the Earth field, ``E(R) = w_a |a_s - R^T u_w|^2 +
w_m |m_s - R^T b_w|^2``, iteratively. The paper iterates on Euler angles; here Gauss-Newton
updates a rotation vector on the current estimate, ``R <- R exp([d]x)``, which has no gimbal
lock (Euler-angle Jacobians are singular at +-90 degrees pitch, where a tracker on a limb spends
real time). Started from TRIAD; with normalised vectors its minimum is the weighted Wahba
solution, reached in 2-4 iterations. The weights come from
:class:`calibration.orientation.disturbance.Weighting`, optionally with weighted temporal
smoothing (:func:`calibration.orientation.disturbance.weighted_smooth`).
"""

from __future__ import annotations

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.orientation.disturbance import Weighting, weighted_smooth
from calibration.orientation.two_vector import triad
from calibration.orientation.world import (
    MIN_NORM_FRACTION,
    Estimate,
    Reference,
    check_vectors,
    quat_where,
    reference,
    unit_vectors,
)
from calibration.rotations import axis_angle_to_matrix, quat_to_matrix, skew


def _solve3(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Solve batched 3x3 systems by the adjugate (vectorised; LAPACK per matrix is slow)."""
    c0 = np.cross(H[..., :, 1], H[..., :, 2])
    c1 = np.cross(H[..., :, 2], H[..., :, 0])
    c2 = np.cross(H[..., :, 0], H[..., :, 1])
    det = np.sum(H[..., :, 0] * c0, axis=-1)
    adj = np.stack([c0, c1, c2], axis=-2)  # rows: inverse's rows times det
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("...ij,...j->...i", adj, g) / det[..., None]


def _smoothed_inputs(
    acc: np.ndarray,
    mag: np.ndarray,
    w: np.ndarray,
    ref: Reference,
    valid: np.ndarray | None,
    rate_hz: float,
    temporal_hz: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The measured directions smoothed over time, weighted by ``w`` ``(F, ..., 2)``, rescaled to
    ``g`` and ``|B|``; NaN where a sample was not usable."""
    usable = np.isfinite(acc).all(axis=-1) & np.isfinite(mag).all(axis=-1)
    if valid is not None:
        usable &= np.asarray(valid, dtype=bool)
    wa = np.where(usable, np.nan_to_num(w[..., 0]), 0.0)
    wm = np.where(usable, np.nan_to_num(w[..., 1]), 0.0)
    a_dir, _ = unit_vectors(acc, MIN_NORM_FRACTION * ref.gravity)
    m_dir, _ = unit_vectors(mag, MIN_NORM_FRACTION * ref.field_strength)
    acc = ref.gravity * weighted_smooth(np.nan_to_num(a_dir), wa, rate_hz, temporal_hz)
    mag = ref.field_strength * weighted_smooth(np.nan_to_num(m_dir), wm, rate_hz, temporal_hz)
    acc[~usable] = np.nan
    mag[~usable] = np.nan
    return acc, mag


def _gauss_newton(
    R: np.ndarray,
    a: np.ndarray,
    m: np.ndarray,
    w: np.ndarray,
    ok: np.ndarray,
    ref: Reference,
    *,
    max_iter: int,
    tol_rad: float,
) -> tuple[np.ndarray, int]:
    """Iterate ``R <- R exp([d]x)`` from ``R`` ``(..., 3, 3)``; return it and the iterations."""
    up = ref.up_w
    b_w = ref.field_dir_w
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 - kept for the report
        ua = np.einsum("...ji,j->...i", R, up)  # modelled vectors in the sensor frame, R^T v
        um = np.einsum("...ji,j->...i", R, b_w)
        ra, rm = a - ua, m - um
        # r(d) ~ r - [u]x d for R <- R exp([d]x): normal equations of the weighted residuals
        Ka, Km = skew(ua), skew(um)
        H = (
            w[..., 0, None, None] * np.swapaxes(Ka, -1, -2) @ Ka
            + w[..., 1, None, None] * np.swapaxes(Km, -1, -2) @ Km
        )
        g = w[..., 0, None] * np.einsum("...ji,...j->...i", Ka, ra) + w[..., 1, None] * np.einsum(
            "...ji,...j->...i", Km, rm
        )
        d = _solve3(H, g)
        d = np.where(ok[..., None] & np.isfinite(d), d, 0.0)
        angle = np.linalg.norm(d, axis=-1)
        axis = np.divide(d, angle[..., None], out=np.zeros_like(d), where=angle[..., None] > 0)
        R = R @ axis_angle_to_matrix(axis, angle)
        if not np.any(angle > tol_rad):
            break
    return R, iterations


def fontaine(
    acc: np.ndarray,
    mag: np.ndarray,
    ref: Reference | None = None,
    *,
    weighting: Weighting | None = None,
    valid: np.ndarray | None = None,
    max_iter: int = 20,
    tol_rad: float = 1e-12,
    rate_hz: float | None = None,
    temporal_hz: float | None = None,
) -> Estimate:
    """Fontaine et al.'s iterative estimator (module docstring), Gauss-Newton on a rotation vector.

    Args:
        acc: ``(..., 3)`` measured specific force in the sensor frame, m/s^2; with
            ``temporal_hz``, frames first.
        mag: ``(..., 3)`` measured magnetic field in the sensor frame, uT, shaped as ``acc``.
        ref: reference vectors (default ENU, 50 uT, 60 degrees).
        weighting: disturbance weighting, or ``None`` for equal fixed weights.
        valid: optional ``(...)`` bool mask.
        max_iter: Gauss-Newton iterations at most.
        tol_rad: stop when every update is smaller than this, rad.
        rate_hz: sample rate, Hz (needed with ``temporal_hz``).
        temporal_hz: weighted zero-phase smoothing
            (:func:`calibration.orientation.disturbance.weighted_smooth`) of the measured
            directions with this cutoff before the fit: a sample whose accelerometer (or
            magnetometer) is disturbed takes that direction from its undisturbed neighbours. With
            two vectors per sample the weights alone only share the error between them; over
            time they decide whose direction to trust. Zero phase: no lag.
    """
    ref = ref or reference()
    acc, mag = check_vectors(acc, mag)
    w = weighting.weights(acc, mag, ref) if weighting is not None else np.ones((*acc.shape[:-1], 2))
    if temporal_hz is not None:
        if rate_hz is None:
            raise CalibrationInputError("temporal_hz needs rate_hz")
        acc, mag = _smoothed_inputs(acc, mag, w, ref, valid, rate_hz, temporal_hz)
    start = triad(acc, mag, ref, valid=valid)
    ok = start.ok
    a, _ = unit_vectors(acc, MIN_NORM_FRACTION * ref.gravity)
    m, _ = unit_vectors(mag, MIN_NORM_FRACTION * ref.field_strength)
    w = np.where(ok[..., None], w, 0.0)
    R = quat_to_matrix(np.where(ok[..., None], start.q_w_s, [1.0, 0.0, 0.0, 0.0]))
    R, iterations = _gauss_newton(R, a, m, w, ok, ref, max_iter=max_iter, tol_rad=tol_rad)
    return Estimate(quat_where(R, ok), ok, ref.frame, weights=w, iterations=iterations)
