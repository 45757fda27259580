"""Pose arrays read chunk by chunk: shape checks and the frames each sensor is valid in.

A pose array is anything sliceable along frames (ndarray, h5py dataset, memory map), so that a
recording larger than memory is read a chunk at a time and never copied whole.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from calibration.errors import CalibrationInputError

#: Frames read and multiplied at a time: big enough for BLAS, small enough for the cache.
CHUNK_FRAMES = 1024


def check_poses(R_w_s: Any, p_w_s: Any, valid: Any = None) -> tuple[int, int]:
    """Check the shapes of a pose array (anything sliceable on frames: ndarray, h5py, memmap).

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` sensor positions in world, metres.
        valid: optional ``(frames, sensors)`` bool, False where a pose is missing.

    Returns:
        ``(frames, sensors)``.
    """
    for name, x in (("R_w_s", R_w_s), ("p_w_s", p_w_s), ("valid", valid)):
        if x is not None and not hasattr(x, "shape"):
            raise CalibrationInputError(
                f"Expected {name} as an array (ndarray, h5py dataset, memmap), got a {type(x).__name__}"
            )
    R_shape, p_shape = tuple(R_w_s.shape), tuple(p_w_s.shape)
    if len(R_shape) != 4 or R_shape[2:] != (3, 3):
        raise CalibrationInputError(f"Expected R_w_s to have shape (frames, sensors, 3, 3), got {R_shape}")
    if p_shape != (*R_shape[:2], 3):
        raise CalibrationInputError(
            f"Expected p_w_s to have shape ({R_shape[0]}, {R_shape[1]}, 3) to match R_w_s, got {p_shape}"
        )
    if valid is not None and tuple(valid.shape) != R_shape[:2]:
        raise CalibrationInputError(f"Expected valid to have shape {R_shape[:2]}, got {tuple(valid.shape)}")
    return R_shape[0], R_shape[1]


#: Frames sampled by :func:`check_rotations` (evenly spaced; a pose array may be larger than
#: memory) and how far from orthonormal with determinant +1 a matrix may be and count as a rotation
#: (a tracker's matrices stored in single precision, or rounded in a file, are within 1e-6).
ROTATION_SAMPLE_FRAMES = 64
ROTATION_TOLERANCE = 1e-2


def check_rotations(R_w_s: Any, valid: Any = None) -> None:
    """Refuse rotations that are mostly not rotations (all zeros, a scaled matrix, a reflection,
    a mix-up of fields), judged on :data:`ROTATION_SAMPLE_FRAMES` evenly spaced frames' finite,
    valid matrices: when more than half of them are not. Once per recording, at the entry
    (:func:`calibration.pipeline.calibrate`), after :func:`check_poses`; not on every pass.

    Raises:
        CalibrationInputError: naming how many of the sampled matrices are not rotations.
    """
    n_frames = R_w_s.shape[0]
    if n_frames == 0:
        return
    idx = np.unique(np.linspace(0, n_frames - 1, min(ROTATION_SAMPLE_FRAMES, n_frames)).astype(int))
    R = np.asarray(R_w_s[idx], dtype=float).reshape(-1, 3, 3)
    use = np.isfinite(R).all(axis=(1, 2))
    if valid is not None:
        use &= np.asarray(valid[idx], dtype=bool).reshape(-1)
    R = R[use]
    if R.shape[0] == 0:
        return
    off = np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max(axis=(1, 2))
    bad = (off > ROTATION_TOLERANCE) | (np.linalg.det(R) < 0)
    if bad.sum() * 2 > R.shape[0]:
        raise CalibrationInputError(
            f"Expected R_w_s to hold rotation matrices (orthonormal, determinant +1), but {int(bad.sum())} "
            f"of {R.shape[0]} sampled poses are not (largest |R^T R - I| {off.max():.3g})"
        )


def iter_chunks(
    R_w_s: Any, p_w_s: Any, valid: Any = None, *, chunk_frames: int = CHUNK_FRAMES
) -> Iterator[tuple[slice, np.ndarray, np.ndarray, np.ndarray]]:
    """Yield ``(frames, R, p, ok)`` chunk by chunk, with invalid poses zeroed.

    ``ok`` is ``(chunk, sensors)`` bool: the pose is finite and not marked invalid. Where every
    pose of a chunk is valid, ``R`` and ``p`` may be read-only views of the caller's arrays;
    otherwise they are copies with zeros where not ``ok``, so that no NaN reaches a matrix
    product. The caller's data are never modified.
    """
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    if chunk_frames < 1:
        raise CalibrationInputError(f"chunk_frames must be at least 1, got {chunk_frames}")
    ones9, ones3 = np.ones(9), np.ones(3)
    for start in range(0, n_frames, chunk_frames):
        frames = slice(start, min(start + chunk_frames, n_frames))
        R = np.asarray(R_w_s[frames], dtype=float)
        p = np.asarray(p_w_s[frames], dtype=float)
        c = R.shape[0]
        # NaN and inf survive a sum (rotation entries cannot overflow it): one cheap pass
        ok = np.isfinite(R.reshape(c * n, 9) @ ones9) & np.isfinite(p.reshape(c * n, 3) @ ones3)
        ok = ok.reshape(c, n)
        if valid is not None:
            ok &= np.asarray(valid[frames], dtype=bool)
        if not ok.all():
            R = np.where(ok[:, :, None, None], R, 0.0)
            p = np.where(ok[:, :, None], p, 0.0)
        yield frames, R, p, ok
