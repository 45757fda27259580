"""Quaternion and rotation-matrix conversions: the one place that talks to scipy's ``Rotation``.

Quaternions are scalar-first ``(w, x, y, z)`` everywhere in this project (as in MuJoCo and in
files); scipy is scalar-last by default, so every crossing passes ``scalar_first=True`` here and
nowhere else. A quaternion ``q`` and ``-q`` are the same rotation.
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


def quat_norm_deviation(q_wxyz: np.ndarray) -> np.ndarray:
    """``| |q| - 1 |`` for each quaternion, ``(..., 4) -> (...)``; NaN where ``q`` is not finite."""
    q = np.asarray(q_wxyz, dtype=float)
    return np.abs(np.linalg.norm(q, axis=-1) - 1.0)
