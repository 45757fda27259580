"""Two-vector solutions: TRIAD and the optimal weighted solution of Wahba's problem.

- :func:`triad`: TRIAD, the classic closed form; the accelerometer is the primary vector (it
  defines "up" exactly), the magnetometer only the heading.
- :func:`wahba`: ``min sum_i w_i |v_wi - R v_si|^2`` over the two observations. It has a closed
  form: the optimal rotation maps ``v_s1 x v_s2`` onto ``v_w1 x v_w2``, which leaves one angle
  about that axis, solved exactly (``method="closed"``, the default); ``method="svd"`` is the
  general SVD solution (Markley), kept as the reference.

Samples whose accelerometer and magnetometer are (nearly) parallel cannot be estimated and come
back as NaN, like every other unusable sample (:mod:`calibration.orientation.world`).
"""

from __future__ import annotations

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.orientation.world import Estimate, Reference, measured_directions, quat_where, reference
from calibration.rotations import axis_angle_to_matrix

#: Accelerometer and magnetometer directions closer than this (sin of the angle) are collinear.
MIN_SIN_ANGLE = 1e-3


def frame_from(v1: np.ndarray, v2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal triad ``(..., 3, 3)`` (columns v1, v1 x v2, v1 x (v1 x v2)) of unit ``v1`` and
    ``v2`` ``(..., 3)``, and ``(...)`` where the two are not collinear."""
    t2 = np.cross(v1, v2)
    s = np.linalg.norm(t2, axis=-1, keepdims=True)
    ok = np.isfinite(s[..., 0]) & (s[..., 0] > MIN_SIN_ANGLE)
    with np.errstate(invalid="ignore", divide="ignore"):
        t2 = t2 / np.where(s > 0, s, 1.0)
    t3 = np.cross(v1, t2)
    return np.stack([v1, t2, t3], axis=-1), ok


def _triad_matrices(a: np.ndarray, m: np.ndarray, ref: Reference) -> tuple[np.ndarray, np.ndarray]:
    """TRIAD rotations ``R_w_s`` ``(..., 3, 3)`` of unit directions, and where they are defined."""
    S, ok = frame_from(a, m)
    W, _ = frame_from(ref.up_w, ref.field_dir_w)
    return W @ np.swapaxes(S, -1, -2), ok


def triad(
    acc: np.ndarray, mag: np.ndarray, ref: Reference | None = None, *, valid: np.ndarray | None = None
) -> Estimate:
    """TRIAD orientation, the accelerometer as the primary vector.

    Args:
        acc: ``(..., 3)`` specific force in the sensor frame, m/s^2.
        mag: ``(..., 3)`` magnetic field in the sensor frame (any unit; only its direction counts).
        ref: the world's reference vectors (default ENU, 50 uT, 60 degrees).
        valid: optional ``(...)`` bool mask of usable samples.
    """
    ref = ref or reference()
    a, m, ok = measured_directions(acc, mag, ref, valid)
    R, ok_s = _triad_matrices(a, m, ref)
    ok &= ok_s
    return Estimate(quat_where(R, ok), ok, ref.frame)


def weights_array(weights: np.ndarray | tuple[float, float] | None, shape: tuple[int, ...]) -> np.ndarray:
    """``(*shape, 2)`` accelerometer and magnetometer weights (ones when ``None``), checked."""
    if weights is None:
        return np.ones((*shape, 2))
    w = np.broadcast_to(np.asarray(weights, dtype=float), (*shape, 2)).copy()
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise CalibrationInputError("weights must be finite and >= 0")
    return w


def _wahba_svd(a: np.ndarray, m: np.ndarray, w: np.ndarray, ok: np.ndarray, ref: Reference) -> np.ndarray:
    """Markley's SVD solution ``(..., 3, 3)`` of the attitude profile matrix ``B``."""
    B = w[..., 0, None, None] * ref.up_w[:, None] * a[..., None, :]
    B = B + w[..., 1, None, None] * ref.field_dir_w[:, None] * m[..., None, :]
    B = np.where(ok[..., None, None], B, np.eye(3))
    U, _, Vt = np.linalg.svd(B)
    d = np.linalg.det(U) * np.linalg.det(Vt)
    D = np.ones((*d.shape, 3))
    D[..., 2] = d
    return (U * D[..., None, :]) @ Vt


def _wahba_closed(
    a: np.ndarray, m: np.ndarray, w: np.ndarray, ref: Reference
) -> tuple[np.ndarray, np.ndarray]:
    """The two-observation closed form ``(..., 3, 3)``, and where it is defined.

    TRIAD with the accelerometer primary maps ``a -> up`` and ``a x m -> up x b`` exactly; the
    optimum also maps ``a x m -> up x b``, leaving one angle ``phi`` about
    ``n = (up x b) / |up x b|``.
    """
    b_w = ref.field_dir_w
    R0, ok = _triad_matrices(a, m, ref)
    W, _ = frame_from(ref.up_w, b_w)
    n = W[:, 1]
    c2 = np.einsum("...ij,...j->...i", R0, m)  # the magnetometer after R0, in the plane
    delta = np.arctan2(np.cross(b_w, c2) @ n, c2 @ b_w)
    phi = np.arctan2(-w[..., 1] * np.sin(delta), w[..., 0] + w[..., 1] * np.cos(delta))
    return axis_angle_to_matrix(np.broadcast_to(n, a.shape), phi) @ R0, ok


def wahba(
    acc: np.ndarray,
    mag: np.ndarray,
    ref: Reference | None = None,
    *,
    weights: np.ndarray | tuple[float, float] | None = None,
    valid: np.ndarray | None = None,
    method: str = "closed",
) -> Estimate:
    """The optimal weighted solution of Wahba's problem for the two measured directions.

    Args:
        acc: ``(..., 3)`` measured specific force in the sensor frame, m/s^2.
        mag: ``(..., 3)`` measured magnetic field in the sensor frame, uT.
        ref: reference vectors (default ENU).
        weights: ``(..., 2)`` or ``(2,)`` accelerometer and magnetometer weights (default equal).
        valid: optional ``(...)`` bool mask.
        method: ``"closed"`` (two-observation closed form, fast) or ``"svd"``.
    """
    ref = ref or reference()
    a, m, ok = measured_directions(acc, mag, ref, valid)
    w = weights_array(weights, a.shape[:-1])
    ok &= (w[..., 0] + w[..., 1]) > 0
    if method == "svd":
        R = _wahba_svd(a, m, w, ok, ref)
        ok &= np.isfinite(R).all(axis=(-1, -2))
    elif method == "closed":
        R, ok_s = _wahba_closed(a, m, w, ref)
        ok &= ok_s
    else:
        raise CalibrationInputError(f"method must be 'closed' or 'svd', got {method!r}")
    return Estimate(quat_where(R, ok), ok, ref.frame, weights=w)
