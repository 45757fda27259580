"""Joint fits of every pair of sensors from a few matrix products over the data.

The per-pair SVD of :func:`calibration.joint.fit_joint` costs one pass over the data per pair.
Its normal equations need far less: for the pair ``(i, j)`` (``i`` parent, ``j`` child) with
``A[f] = [R_i[f], -R_j[f]]`` and ``b[f] = p_j[f] - p_i[f]`` (O'Brien eqs. 9-13)::

    A^T A = [[n I, -G_ij], [-G_ij^T, n I]]       G_ij = sum_f R_i^T R_j
    A^T b = [C_ij - D_ij, C_ji - D_ji]           C_ij = sum_f R_i^T p_j,  D_ij = sum_f R_i^T p_i
    b^T b = sum_f |p_j - p_i|^2

and every ``G``, ``C``, ``D`` and ``b^T b`` of all pairs together are blocks of four matrix
products over the pose array (:func:`pair_statistics`), read chunk by chunk so that memory stays
bounded however long the recording. Frames where a sensor's pose is missing enter through 0/1
weights, so each pair uses exactly the frames where both of its sensors are valid.

**Cancellation.** The residual from the normal equations, ``b^T b - (A^T b)^T x``, is a
difference of large numbers. Two guards keep it honest: positions are centred per frame on the
mean of the valid sensors before any product (``b`` is unchanged by a common shift, and the
sums then scale with the body's size, not with where it stands in the room), and the joints the
calibration keeps get their residual recomputed exactly from the data
(:func:`frame_residuals`). Measured against the per-pair SVD, the normal-equation residual of a
noise-free joint stays below about 1e-8 m.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.joint import MIN_FRAMES, SINGLE_AXIS_RATIO, Spectrum, determined_directions, read_spectrum
from calibration.poses import CHUNK_FRAMES, check_poses, iter_chunks


@dataclass(frozen=True)
class PairStatistics:
    """Sufficient statistics of O'Brien eq. 13 for every ordered pair of ``N`` sensors.

    Positions are centred per frame (see the module docstring). ``w_i[f]`` is 1 where sensor
    ``i`` is valid in frame ``f``, else 0; every sum runs over frames.

    Attributes:
        gram: ``(N, N, 3, 3)`` ``sum w_i w_j R_i^T R_j``, dimensionless.
        cross: ``(N, N, 3)`` ``sum w_i w_j R_i^T p_j``, metres.
        self_cross: ``(N, N, 3)`` ``sum w_i w_j R_i^T p_i``, metres.
        sq_dist: ``(N, N)`` ``sum w_i w_j |p_j - p_i|^2``, square metres.
        count: ``(N, N)`` frames where both sensors are valid.
        n_frames: frames in the recording.
    """

    gram: np.ndarray
    cross: np.ndarray
    self_cross: np.ndarray
    sq_dist: np.ndarray
    count: np.ndarray
    n_frames: int

    @property
    def n_sensors(self) -> int:
        """Number of sensors ``N``."""
        return int(self.count.shape[0])


_ROW = np.dtype((np.void, 24))  # one row of a 3x3 float64 matrix, moved as a unit


def _rows_by_world_axis(R: np.ndarray, out: np.ndarray) -> None:
    """Copy ``R[f, i, a, :]`` to ``out[f, a, i, :]`` (``(c, n, 3, 3) -> (c, 3, n, 3)``).

    Moving each 24-byte matrix row as one item is about twice as fast as numpy's element-wise
    strided copy; arrays whose rows are not contiguous take the plain path.
    """
    try:
        src = R.view(_ROW)[..., 0]
        dst = out.view(_ROW)[..., 0]
    except ValueError:
        np.copyto(out, R.transpose(0, 2, 1, 3))
        return
    np.copyto(dst, src.transpose(0, 2, 1))


def pair_statistics(
    R_w_s: Any, p_w_s: Any, *, valid: Any = None, chunk_frames: int = CHUNK_FRAMES
) -> PairStatistics:
    """Accumulate the normal equations of every sensor pair in one pass over the data.

    Chunks where every pose is valid take a fast path: one Gram matrix of ``[X | P]``, where
    the rows of ``X`` are the world-axis rows of every sensor's rotation and ``P`` the centred
    positions, holds all of ``G``, ``C``, ``D`` and ``b^T b``. Chunks with missing poses add
    the 0/1 weights of the module docstring.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (ndarray, h5py dataset or
            anything else sliceable along frames).
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres.
        valid: optional ``(frames, sensors)`` bool mask; non-finite poses are always invalid.
        chunk_frames: frames per chunk (memory is ``O(chunk_frames * sensors)``).

    Returns:
        The statistics of all pairs.
    """
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    m = 4 * n
    full = np.zeros((m, m))  # Gram of [X | P] over the chunks with every pose valid
    n_full = 0
    gram = np.zeros((3 * n, 3 * n))
    cross = np.zeros((3 * n, n))
    weighted_self = np.zeros((n, 3 * n))
    dot = np.zeros((n, n))
    weighted_sq = np.zeros((n, n))
    count = np.zeros((n, n))
    buf = np.empty((min(chunk_frames, max(n_frames, 1)), 3, m))
    mean_of_sensors = np.kron(np.ones((n, 1)) / n, np.eye(3))  # (3n, 3)
    for _, R, p, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        c = R.shape[0]
        XP = buf[:c]
        _rows_by_world_axis(R, XP[:, :, : 3 * n].reshape(c, 3, n, 3))
        if ok.all():
            centre = p.reshape(c, 3 * n) @ mean_of_sensors  # (c, 3) mean sensor position
            np.subtract(p.transpose(0, 2, 1), centre[:, :, None], out=XP[:, :, 3 * n :])
            flat = XP.reshape(3 * c, m)
            full += flat.T @ flat
            n_full += c
            continue
        w = ok.astype(float)
        centre = p.sum(axis=1) / np.maximum(w.sum(axis=1), 1.0)[:, None]
        pc = (p - centre[:, None, :]) * w[:, :, None]
        X = XP[:, :, : 3 * n].reshape(3 * c, 3 * n)
        P = pc.transpose(0, 2, 1).reshape(3 * c, n)
        gram += X.T @ X
        cross += X.T @ P
        Rtp = np.einsum("fiab,fia->fib", R, pc)  # R_i^T p_i per frame, (c, n, 3)
        weighted_self += w.T @ Rtp.reshape(c, 3 * n)
        dot += P.T @ P
        weighted_sq += w.T @ np.einsum("fia,fia->fi", pc, pc)
        count += w.T @ w
    if n_full:
        fx = full[: 3 * n, 3 * n :]
        gram += full[: 3 * n, : 3 * n]
        cross += fx
        own = fx.reshape(n, 3, n)[np.arange(n), :, np.arange(n)]  # (n, 3): sum R_i^T p_i
        weighted_self += own.reshape(1, 3 * n)
        fp = full[3 * n :, 3 * n :]
        dot += fp
        weighted_sq += np.diagonal(fp)[None, :]
        count += n_full
    sq_i = weighted_sq.T  # [i, j] = sum w_i w_j |p_i|^2
    return PairStatistics(
        gram=gram.reshape(n, 3, n, 3).transpose(0, 2, 1, 3),
        cross=cross.reshape(n, 3, n).transpose(0, 2, 1),
        self_cross=weighted_self.reshape(n, n, 3).transpose(1, 0, 2),
        sq_dist=sq_i + sq_i.T - 2.0 * dot,
        count=np.rint(count).astype(np.int64),
        n_frames=n_frames,
    )


@dataclass(frozen=True)
class PairSolutions:
    """Joint fits of a batch of ``P`` sensor pairs solved from their normal equations.

    Attributes:
        parent: ``(P,)`` parent sensor index of each pair.
        child: ``(P,)`` child sensor index.
        joint_in_parent: ``(P, 3)`` metres.
        joint_in_child: ``(P, 3)`` metres.
        rms_residual: ``(P,)`` metres; ``inf`` where the pair has fewer than 3 common frames.
        singular_values: ``(P, 6)`` descending, as the SVD of ``A`` would give them.
        right_vectors: ``(P, 6, 6)`` right singular vectors as columns.
        n_frames: ``(P,)`` frames both sensors are valid.
    """

    parent: np.ndarray
    child: np.ndarray
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    rms_residual: np.ndarray
    singular_values: np.ndarray
    right_vectors: np.ndarray
    n_frames: np.ndarray


def solve_pairs(
    stats: PairStatistics,
    parent: np.ndarray,
    child: np.ndarray,
    *,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
) -> PairSolutions:
    """Solve the joint fits of the given pairs from their normal equations (batched).

    Gives the same joint, residual and singular values as :func:`calibration.joint.fit_joint`
    on the same frames (the same truncation of undetermined directions), without touching the
    data again.

    Args:
        stats: from :func:`pair_statistics`.
        parent: ``(P,)`` parent sensor indices.
        child: ``(P,)`` child sensor indices.
        single_axis_ratio: see :mod:`calibration.joint`.
    """
    parent = np.asarray(parent, dtype=np.int64)
    child = np.asarray(child, dtype=np.int64)
    n_pairs = parent.shape[0]
    counts = stats.count[parent, child].astype(float)
    normal = np.zeros((n_pairs, 6, 6))
    eye = np.eye(3)
    normal[:, :3, :3] = counts[:, None, None] * eye
    normal[:, 3:, 3:] = counts[:, None, None] * eye
    g = stats.gram[parent, child]
    normal[:, :3, 3:] = -g
    normal[:, 3:, :3] = -g.transpose(0, 2, 1)
    rhs = np.concatenate(
        [
            stats.cross[parent, child] - stats.self_cross[parent, child],
            stats.cross[child, parent] - stats.self_cross[child, parent],
        ],
        axis=1,
    )
    eigval, eigvec = np.linalg.eigh(normal)
    eigval, eigvec = eigval[:, ::-1], eigvec[:, :, ::-1]  # descending, like the SVD
    s = np.sqrt(np.clip(eigval, 0.0, None))
    keep = determined_directions(s, single_axis_ratio)  # O'Brien 3.2
    proj = np.einsum("pki,pk->pi", eigvec, rhs)  # V^T (A^T b)
    safe = np.where(keep, eigval, 1.0)
    coef = np.where(keep, proj / safe, 0.0)
    x = np.einsum("pik,pk->pi", eigvec, coef)
    sq_res = stats.sq_dist[parent, child] - np.sum(np.where(keep, proj * proj / safe, 0.0), axis=1)
    usable = counts >= MIN_FRAMES
    rms = np.full(n_pairs, np.inf)
    rms[usable] = np.sqrt(np.clip(sq_res[usable], 0.0, None) / counts[usable])
    return PairSolutions(
        parent=parent,
        child=child,
        joint_in_parent=x[:, :3],
        joint_in_child=x[:, 3:],
        rms_residual=rms,
        singular_values=s,
        right_vectors=eigvec,
        n_frames=stats.count[parent, child],
    )


def pair_residual_matrix(
    stats: PairStatistics, *, single_axis_ratio: float = SINGLE_AXIS_RATIO
) -> np.ndarray:
    """The rms joint-fit residual of every pair of sensors (O'Brien section 3.3's edge weights).

    Returns:
        ``(N, N)`` symmetric, metres; ``inf`` on the diagonal and for pairs with fewer than 3
        frames in common.
    """
    n = stats.n_sensors
    i, j = np.triu_indices(n, k=1)
    sol = solve_pairs(stats, i, j, single_axis_ratio=single_axis_ratio)
    out = np.full((n, n), np.inf)
    out[i, j] = sol.rms_residual
    out[j, i] = sol.rms_residual
    return out


def frame_residuals(
    R_w_s: Any,
    p_w_s: Any,
    parent: np.ndarray,
    child: np.ndarray,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    *,
    valid: Any = None,
    chunk_frames: int = CHUNK_FRAMES,
    keep_frames: bool = True,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Exact residual norms of given joints, computed from the data chunk by chunk.

    The residual vectors of all joints are two matrix products per chunk: the flattened
    rotations ``(chunk, 9 N)`` times a matrix holding each joint's ``+joint_in_parent`` and
    ``-joint_in_child``, plus the positions ``(chunk, 3 N)`` times a +1/-1 selection.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres.
        parent, child: ``(J,)`` sensor indices of each joint.
        joint_in_parent, joint_in_child: ``(J, 3)`` joint centres in each sensor frame, metres.
        valid: optional ``(frames, sensors)`` bool mask.
        chunk_frames: frames per chunk.
        keep_frames: also return the per-frame residuals (``frames x J`` floats).

    Returns:
        ``(rms, per_frame)``: ``(J,)`` rms over the frames where both sensors are valid
        (NaN if none), and ``(frames, J)`` residual norms with NaN where a sensor is invalid
        (``None`` unless ``keep_frames``), metres.
    """
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    parent = np.asarray(parent, dtype=np.int64)
    child = np.asarray(child, dtype=np.int64)
    lp = np.asarray(joint_in_parent, dtype=float).reshape(-1, 3)
    lc = np.asarray(joint_in_child, dtype=float).reshape(-1, 3)
    n_joints = parent.shape[0]
    rot = np.zeros((n, 3, 3, n_joints, 3))  # [sensor, a, b, joint, a']: R[a, b] l[b] into row a
    pos = np.zeros((n, 3, n_joints, 3))  # +1 / -1 selection of the two sensors' positions
    for k in range(n_joints):
        for a in range(3):
            rot[parent[k], a, :, k, a] += lp[k]
            rot[child[k], a, :, k, a] -= lc[k]
            pos[parent[k], a, k, a] += 1.0
            pos[child[k], a, k, a] -= 1.0
    rot = rot.reshape(9 * n, 3 * n_joints)
    pos = pos.reshape(3 * n, 3 * n_joints)
    sum_xyz = np.kron(np.eye(n_joints), np.ones((3, 1)))  # (3J, J): adds each joint's x, y, z
    total = np.zeros(n_joints)
    used = np.zeros(n_joints)
    per_frame = np.full((n_frames, n_joints), np.nan) if keep_frames else None
    for frames, R, p, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        c = R.shape[0]
        r = R.reshape(c, 9 * n) @ rot
        r += p.reshape(c, 3 * n) @ pos
        sq = np.square(r, out=r) @ sum_xyz  # (c, J) squared norms
        both = ok[:, parent] & ok[:, child]
        if both.all():
            total += sq.sum(axis=0)
            used += c
        else:
            sq[~both] = np.nan
            total += np.where(both, sq, 0.0).sum(axis=0)
            used += both.sum(axis=0)
        if per_frame is not None:
            per_frame[frames] = np.sqrt(sq)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.where(used > 0, np.sqrt(total / np.maximum(used, 1)), np.nan)
    return rms, per_frame


def pair_fit_spectrum(sol: PairSolutions, k: int, single_axis_ratio: float = SINGLE_AXIS_RATIO) -> Spectrum:
    """The :class:`calibration.joint.Spectrum` of pair ``k`` of a batch solution."""
    return read_spectrum(sol.singular_values[k], sol.right_vectors[k], single_axis_ratio)
