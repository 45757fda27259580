"""Quaternion and rotation-matrix conversions: the one place that talks to scipy's ``Rotation``.

Quaternions are scalar-first ``(w, x, y, z)`` everywhere in this project (as in MuJoCo and in
files); scipy is scalar-last by default, so every crossing passes ``scalar_first=True`` here and
nowhere else. A quaternion ``q`` and ``-q`` are the same rotation.

Also the two plain-numpy pieces the orientation estimators build on in their inner loops:
:func:`skew` (the cross-product matrix) and :func:`axis_angle_to_matrix` (Rodrigues).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from calibration.errors import CalibrationInputError

#: A quaternion whose norm is further than this from 1 is reported when it is normalised.
UNIT_TOLERANCE = 1e-3


def quat_to_matrix(q_wxyz: np.ndarray) -> np.ndarray:
    """Rotation matrices of scalar-first quaternions.

    Args:
        q_wxyz: ``(..., 4)`` quaternions ``(w, x, y, z)``; need not be unit (they are
            normalised), must not be zero.

    Returns:
        ``(..., 3, 3)`` rotation matrices ``R`` such that ``v_w = R @ v_s`` when ``q`` is the
        quaternion of ``R_w_s``.
    """
    q = np.asarray(q_wxyz, dtype=float)
    if q.shape[-1:] != (4,):
        raise CalibrationInputError(f"Expected quaternions of shape (..., 4), got {q.shape}")
    flat = q.reshape(-1, 4)
    if flat.shape[0] == 0:
        return np.zeros((*q.shape[:-1], 3, 3))
    norms = np.linalg.norm(flat, axis=1)
    if np.any(norms == 0.0):
        raise CalibrationInputError(
            f"{int(np.sum(norms == 0.0))} zero quaternion(s): a rotation needs a non-zero quaternion"
        )
    matrices = Rotation.from_quat(flat, scalar_first=True).as_matrix()
    return matrices.reshape(*q.shape[:-1], 3, 3)


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Scalar-first unit quaternions of rotation matrices, with ``w >= 0``.

    Args:
        R: ``(..., 3, 3)`` rotation matrices.

    Returns:
        ``(..., 4)`` quaternions ``(w, x, y, z)``, canonical sign (``w >= 0``).
    """
    R = np.asarray(R, dtype=float)
    if R.shape[-2:] != (3, 3):
        raise CalibrationInputError(f"Expected rotation matrices of shape (..., 3, 3), got {R.shape}")
    flat = R.reshape(-1, 3, 3)
    if flat.shape[0] == 0:
        return np.zeros((*R.shape[:-2], 4))
    q = Rotation.from_matrix(flat).as_quat(canonical=True, scalar_first=True)
    return q.reshape(*R.shape[:-2], 4)


def orthonormal_to_quat(R: np.ndarray) -> np.ndarray:
    """Scalar-first quaternions (``w >= 0``) of *exactly orthonormal* rotation matrices, fast.

    Shepperd's method, vectorised in numpy: about five times faster than scipy's
    ``Rotation.from_matrix`` (which first projects each matrix onto the nearest rotation) on
    large batches. Use it only for matrices built orthonormal (products and frames of unit
    vectors); :func:`matrix_to_quat` is the general conversion.

    Args:
        R: ``(..., 3, 3)`` rotation matrices.

    Returns:
        ``(..., 4)`` unit quaternions ``(w, x, y, z)``.
    """
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty((*R.shape[:-2], 4))
    # each branch divides by the largest of 4 w^2, 4 x^2, 4 y^2, 4 z^2 (well conditioned)
    for branch in range(4):
        sel = k == branch
        if not np.any(sel):
            continue
        r = R[sel]
        if branch == 0:
            s = np.sqrt(1.0 + r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]) * 2
            q[sel] = np.stack(
                [
                    0.25 * s,
                    (r[:, 2, 1] - r[:, 1, 2]) / s,
                    (r[:, 0, 2] - r[:, 2, 0]) / s,
                    (r[:, 1, 0] - r[:, 0, 1]) / s,
                ],
                axis=-1,
            )
        elif branch == 1:
            s = np.sqrt(1.0 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2]) * 2
            q[sel] = np.stack(
                [
                    (r[:, 2, 1] - r[:, 1, 2]) / s,
                    0.25 * s,
                    (r[:, 0, 1] + r[:, 1, 0]) / s,
                    (r[:, 0, 2] + r[:, 2, 0]) / s,
                ],
                axis=-1,
            )
        elif branch == 2:
            s = np.sqrt(1.0 + r[:, 1, 1] - r[:, 0, 0] - r[:, 2, 2]) * 2
            q[sel] = np.stack(
                [
                    (r[:, 0, 2] - r[:, 2, 0]) / s,
                    (r[:, 0, 1] + r[:, 1, 0]) / s,
                    0.25 * s,
                    (r[:, 1, 2] + r[:, 2, 1]) / s,
                ],
                axis=-1,
            )
        else:
            s = np.sqrt(1.0 + r[:, 2, 2] - r[:, 0, 0] - r[:, 1, 1]) * 2
            q[sel] = np.stack(
                [
                    (r[:, 1, 0] - r[:, 0, 1]) / s,
                    (r[:, 0, 2] + r[:, 2, 0]) / s,
                    (r[:, 1, 2] + r[:, 2, 1]) / s,
                    0.25 * s,
                ],
                axis=-1,
            )
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rotvec_to_matrix(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrices of rotation vectors (axis times angle in rad), ``(..., 3) -> (..., 3, 3)``."""
    v = np.asarray(rotvec, dtype=float)
    if v.shape[-1:] != (3,):
        raise CalibrationInputError(f"Expected rotation vectors of shape (..., 3), got {v.shape}")
    flat = v.reshape(-1, 3)
    if flat.shape[0] == 0:
        return np.zeros((*v.shape[:-1], 3, 3))
    return Rotation.from_rotvec(flat).as_matrix().reshape(*v.shape[:-1], 3, 3)


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad) of rotation matrices, ``(..., 3, 3) -> (..., 3)``."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    if flat.shape[0] == 0:
        return np.zeros((*R.shape[:-2], 3))
    return Rotation.from_matrix(flat).as_rotvec().reshape(*R.shape[:-2], 3)


def euler_to_matrix(sequence: str, angles: np.ndarray, *, degrees: bool) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of Euler angles ``(..., 3)`` in scipy's convention:
    uppercase ``sequence`` (e.g. ``"ZYX"``) for intrinsic rotations, lowercase for extrinsic."""
    a = np.asarray(angles, dtype=float)
    if a.shape[-1:] != (3,):
        raise CalibrationInputError(f"Expected Euler angles of shape (..., 3), got {a.shape}")
    flat = a.reshape(-1, 3)
    if flat.shape[0] == 0:
        return np.zeros((*a.shape[:-1], 3, 3))
    try:
        R = Rotation.from_euler(sequence, flat, degrees=degrees).as_matrix()
    except ValueError as exc:
        raise CalibrationInputError(f"Euler sequence {sequence!r}: {exc}") from None
    return R.reshape(*a.shape[:-1], 3, 3)


def matrix_to_euler(sequence: str, R: np.ndarray, *, degrees: bool) -> np.ndarray:
    """Euler angles ``(..., 3)`` of rotation matrices ``(..., 3, 3)`` (scipy's convention)."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    if flat.shape[0] == 0:
        return np.zeros((*R.shape[:-2], 3))
    return Rotation.from_matrix(flat).as_euler(sequence, degrees=degrees).reshape(*R.shape[:-2], 3)


def quat_norm_deviation(q_wxyz: np.ndarray) -> np.ndarray:
    """``| |q| - 1 |`` for each quaternion, ``(..., 4) -> (...)``; NaN where ``q`` is not finite."""
    q = np.asarray(q_wxyz, dtype=float)
    return np.abs(np.linalg.norm(q, axis=-1) - 1.0)


def skew(u: np.ndarray) -> np.ndarray:
    """Cross-product matrices ``[u]x`` (``[u]x v == u x v``), ``(..., 3) -> (..., 3, 3)``."""
    K = np.zeros((*u.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2] = -u[..., 2], u[..., 1]
    K[..., 1, 0], K[..., 1, 2] = u[..., 2], -u[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -u[..., 1], u[..., 0]
    return K


def axis_angle_to_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: ``(..., 3, 3)`` rotations by ``angle`` (``(...)``, rad) about unit ``axis``
    (``(..., 3)``). A zero axis gives the identity; no normalisation, no input checks (it serves
    the estimators' inner loops)."""
    K = skew(axis)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)
