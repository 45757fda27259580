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
calibration keeps get their residual recomputed exactly from the data (:func:`frame_residuals`)
wherever the normal equations' rounding bound could exceed 1e-9 of the sensors' distance
(:func:`rms_needs_data`: in practice only noise-free joints). Measured against the per-pair SVD,
the normal-equation residual of a noise-free joint stays below about 1e-8 m.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.hinge import (
    biased_directions,
    block_edges,
    critical_t,
    hinge_verdict,
    precise_directions,
    score_t,
    score_variance,
    systematic_rms,
    testable_directions,
)
from calibration.joint import MIN_FRAMES, SINGLE_AXIS_RATIO, Spectrum, determined_directions, read_spectrum
from calibration.pair_sums import PairSums, ThirdDifferenceSums, block_results, lay_out
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
        block_gram, block_cross, block_self_cross, block_count: ``(B, ...)`` the same sums over
            each of the ``B`` blocks of :func:`calibration.hinge.block_edges` (for the
            batch-means variance of the single-axis test).
        jackknife_gram, jackknife_cross, jackknife_self_cross, jackknife_count: ``(K, ...)`` the
            same sums over each of the ``K`` blocks of :func:`jackknife_edges` (for
            :func:`calibration.diagnostics.block_jackknife`), when asked for; else ``None``.
        third_differences: the sums of the third-differenced poses (the misfit hierarchy's
            noise, :class:`calibration.pair_sums.ThirdDifferenceSums`), when asked for.
    """

    gram: np.ndarray
    cross: np.ndarray
    self_cross: np.ndarray
    sq_dist: np.ndarray
    count: np.ndarray
    n_frames: int
    block_gram: np.ndarray
    block_cross: np.ndarray
    block_self_cross: np.ndarray
    block_count: np.ndarray
    jackknife_gram: np.ndarray | None = None
    jackknife_cross: np.ndarray | None = None
    jackknife_self_cross: np.ndarray | None = None
    jackknife_count: np.ndarray | None = None
    third_differences: ThirdDifferenceSums | None = None

    @property
    def n_sensors(self) -> int:
        """Number of sensors ``N``."""
        return int(self.count.shape[0])


def pair_statistics(
    R_w_s: Any,
    p_w_s: Any,
    *,
    valid: Any = None,
    chunk_frames: int = CHUNK_FRAMES,
    jackknife_blocks: int = 0,
    third_differences: bool = True,
) -> PairStatistics:
    """Accumulate the normal equations of every sensor pair in one pass over the data.

    Chunks where every pose is valid take a fast path: one Gram matrix of ``[X | P]``, where
    the rows of ``X`` are the world-axis rows of every sensor's rotation and ``P`` the centred
    positions, holds all of ``G``, ``C``, ``D`` and ``b^T b``. Chunks with missing poses add
    the 0/1 weights of the module docstring. The sums are kept per block of frames
    (:func:`calibration.hinge.block_edges`) for the single-axis test; the products are the same.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (ndarray, h5py dataset or
            anything else sliceable along frames).
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres.
        valid: optional ``(frames, sensors)`` bool mask; non-finite poses are always invalid.
        chunk_frames: frames per chunk (memory is ``O(chunk_frames * sensors)``).
        jackknife_blocks: also keep the sums over this many blocks of :func:`jackknife_edges`
            (0: not).
        third_differences: also sum the third-differenced poses (the residuals' white noise: the
            misfit hierarchy's, and the single-axis verdict's effect size of
            :mod:`calibration.hinge`, which without them is not applied), in the same pass.

    Returns:
        The statistics of all pairs.
    """
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    edges = block_edges(n_frames)
    jack = jackknife_edges(n_frames, jackknife_blocks) if jackknife_blocks else edges
    # one PairSums per piece of the two block divisions together; each block sums its pieces
    cuts_all = np.union1d(edges, jack)
    sums = [PairSums(n) for _ in range(max(len(cuts_all) - 1, 1))]
    d3 = ThirdDifferenceSums(n) if third_differences else None
    buf = np.empty((min(chunk_frames, max(n_frames, 1)), 3, 4 * n))
    for frames, R, p, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        cuts = np.clip(cuts_all, frames.start, frames.stop) - frames.start
        pieces = [(k, cuts[k], cuts[k + 1]) for k in np.flatnonzero(np.diff(cuts) > 0)]
        if ok.all():  # laid out once for all pieces and the third differences
            XP = lay_out(R, p, buf[: R.shape[0]])
            for k, lo, hi in pieces:
                sums[k].add_laid_out(XP[lo:hi])
            if d3 is not None:
                d3.add(R, p, ok, laid_out=XP)
            continue
        for k, lo, hi in pieces:
            sums[k].add(R[lo:hi], p[lo:hi], ok[lo:hi], buf[: hi - lo])
        if d3 is not None:
            d3.add(R, p, ok)
    stats = statistics_of_stacked(block_results(sums, np.searchsorted(cuts_all, edges)), n_frames)
    extra: dict[str, Any] = {"third_differences": d3}
    if jackknife_blocks:
        gram, cross, self_cross, _, count = block_results(sums, np.searchsorted(cuts_all, jack))
        extra.update(
            jackknife_gram=gram, jackknife_cross=cross, jackknife_self_cross=self_cross, jackknife_count=count
        )
    return dataclasses.replace(stats, **extra)


def jackknife_edges(n_frames: int, n_blocks: int) -> np.ndarray:
    """``(n_blocks + 1,)`` frame indices cutting ``n_frames`` frames into the contiguous blocks of
    :func:`calibration.diagnostics.block_jackknife`: frame ``f`` is in block ``f * n_blocks // n_frames``."""
    k = np.arange(n_blocks + 1, dtype=np.int64)
    return -(-k * int(n_frames) // n_blocks)


def statistics_of_blocks(blocks: list[tuple[np.ndarray, ...]], n_frames: int) -> PairStatistics:
    """The pair statistics of consecutive blocks of frames, from each block's
    :meth:`calibration.pair_sums.PairSums.result` ``(gram, cross, self_cross, sq_dist, count)``
    (shared with :mod:`calibration.streaming`); ``n_frames`` frames in all."""
    stacked = tuple(np.stack(x) for x in zip(*blocks, strict=True))
    return statistics_of_stacked(stacked, n_frames)


def statistics_of_stacked(blocks: tuple[np.ndarray, ...], n_frames: int) -> PairStatistics:
    """:func:`statistics_of_blocks` from the blocks' sums stacked, each ``(B, ...)``."""
    gram, cross, self_cross, sq_dist, count = blocks
    return PairStatistics(
        gram=gram.sum(axis=0),
        cross=cross.sum(axis=0),
        self_cross=self_cross.sum(axis=0),
        sq_dist=sq_dist.sum(axis=0),
        count=count.sum(axis=0),
        n_frames=n_frames,
        block_gram=gram,
        block_cross=cross,
        block_self_cross=self_cross,
        block_count=count,
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
        keep: ``(P, 6)`` bool, the directions the data determine (:mod:`calibration.hinge`).
        t_statistic: ``(P, 6)`` ``|t|`` of each direction's test (NaN when untestable).
    """

    parent: np.ndarray
    child: np.ndarray
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    rms_residual: np.ndarray
    singular_values: np.ndarray
    right_vectors: np.ndarray
    n_frames: np.ndarray
    keep: np.ndarray
    t_statistic: np.ndarray


def solve_pairs(
    stats: PairStatistics,
    parent: np.ndarray,
    child: np.ndarray,
    *,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
) -> PairSolutions:
    """Solve the joint fits of the given pairs from their normal equations (batched).

    Gives the same joint, residual, singular values and single-axis verdict as
    :func:`calibration.joint.fit_joint` on the same frames (the test of :mod:`calibration.hinge`
    takes its block scores from the per-block normal equations), without touching the data
    again.

    Args:
        stats: from :func:`pair_statistics`.
        parent: ``(P,)`` parent sensor indices.
        child: ``(P,)`` child sensor indices.
        single_axis_ratio: the hard floor of :mod:`calibration.joint`.
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
    proj = np.einsum("pki,pk->pi", eigvec, rhs)  # V^T (A^T b)
    floor_keep = determined_directions(s, single_axis_ratio)  # O'Brien 3.2, hard floor
    scores = _block_scores(stats, parent, child, eigvec, _min_norm(eigvec, eigval, proj, floor_keep))
    block_counts = stats.block_count[:, parent, child].T  # (P, B)
    var = score_variance(scores, block_counts)
    t, t_crit = score_t(proj, var), critical_t(block_counts)
    with np.errstate(invalid="ignore", divide="ignore"):
        ball_rms = np.sqrt(
            np.clip(_sq_residual(stats, parent, child, eigval, proj, floor_keep), 0, None) / counts
        )
    precise = precise_directions(var, eigval, t_crit, ball_rms)
    biased = None
    if stats.third_differences is not None:  # the effect size of calibration.hinge needs the noise
        x_ball = _min_norm(eigvec, eigval, proj, floor_keep)
        white = stats.third_differences.noise_variance(parent, child, x_ball[:, :3], x_ball[:, 3:])
        with np.errstate(invalid="ignore", divide="ignore"):
            separation = np.sqrt(stats.sq_dist[parent, child] / counts)
        biased = biased_directions(systematic_rms(ball_rms, white, counts), s, counts, separation, proj)
    keep = hinge_verdict(floor_keep, t, t_crit, testable_directions(s, counts), precise, biased)
    x = _min_norm(eigvec, eigval, proj, keep)
    sq_res = _sq_residual(stats, parent, child, eigval, proj, keep)
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
        keep=keep,
        t_statistic=t,
    )


#: Bound on the rounding error of a residual from the normal equations (``b^T b`` less the
#: explained part), in units of ``eps * b^T b`` (``eps`` the float64 epsilon): measured at most
#: 9 on noise-free joints of 3,000 to 200,000 frames, also 10 km from the origin.
NORMAL_EQUATION_ROUNDING = 1000.0

#: A residual from the normal equations stands for the exact one when its rounding bound is below
#: this fraction of the sensors' rms distance (1e-9 m at a metre, 3e-10 m at 30 cm).
RMS_TOLERANCE = 1e-9


def rms_needs_data(stats: PairStatistics, sol: PairSolutions) -> np.ndarray:
    """``(P,)`` bool: the pairs of ``sol`` whose rms residual from the normal equations may be
    further from the exact one (a pass over the data, :func:`frame_residuals`) than
    :data:`RMS_TOLERANCE` times the sensors' rms distance.

    Its squared rms ``r^2`` is within ``d = NORMAL_EQUATION_ROUNDING * eps * b^T b / n`` of the
    exact value, so the rms lies in ``[sqrt(r^2 - d), sqrt(r^2 + d)]``: for any noisy joint that
    interval is far below a nanometre (``d / 2 r``), and only joints at the rounding floor of
    the normal equations (noise-free data, residuals below about 0.1 mm) need the data.
    """
    counts = np.maximum(sol.n_frames.astype(float), 1.0)
    msd = stats.sq_dist[sol.parent, sol.child] / counts  # mean |b|^2, the sensors' squared distance
    d = NORMAL_EQUATION_ROUNDING * np.finfo(float).eps * msd
    r2 = np.where(np.isfinite(sol.rms_residual), sol.rms_residual, 0.0) ** 2
    width = np.sqrt(r2 + d) - np.sqrt(np.clip(r2 - d, 0.0, None))
    return np.isfinite(sol.rms_residual) & (width > RMS_TOLERANCE * np.sqrt(msd))


def _sq_residual(
    stats: PairStatistics,
    parent: np.ndarray,
    child: np.ndarray,
    eigval: np.ndarray,
    proj: np.ndarray,
    keep: np.ndarray,
) -> np.ndarray:
    """``(P,)`` sum of squared residuals of the solutions over the kept directions (``b^T b`` minus
    the explained part), length squared."""
    explained = np.where(keep, proj * proj / np.where(keep, eigval, 1.0), 0.0)
    return stats.sq_dist[parent, child] - np.sum(explained, axis=1)


def _min_norm(eigvec: np.ndarray, eigval: np.ndarray, proj: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``(P, 6)`` least-squares solutions over the kept directions, zero along the others."""
    coef = np.where(keep, proj / np.where(keep, eigval, 1.0), 0.0)
    return np.einsum("pik,pk->pi", eigvec, coef)


def _block_scores(
    stats: PairStatistics, parent: np.ndarray, child: np.ndarray, eigvec: np.ndarray, x: np.ndarray
) -> np.ndarray:
    """``(P, B, 6)`` per block, ``v_j . A_b^T (A_b x - b_b)``: the normal equations' gradient of
    each block along each direction (:func:`calibration.hinge.score_t`)."""
    cnt = stats.block_count[:, parent, child].astype(float)[..., None]  # (B, P, 1)
    g = stats.block_gram[:, parent, child]  # (B, P, 3, 3)
    xp, xc = x[:, :3], x[:, 3:]
    top = cnt * xp - np.einsum("bpij,pj->bpi", g, xc)
    top -= stats.block_cross[:, parent, child] - stats.block_self_cross[:, parent, child]
    bottom = cnt * xc - np.einsum("bpji,pj->bpi", g, xp)
    bottom -= stats.block_cross[:, child, parent] - stats.block_self_cross[:, child, parent]
    grad = np.concatenate([top, bottom], axis=2)  # (B, P, 6)
    return np.einsum("pkj,bpk->pbj", eigvec, grad)


def pair_residual_matrix(
    stats: PairStatistics,
    *,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
    solutions: PairSolutions | None = None,
) -> np.ndarray:
    """The rms joint-fit residual of every pair of sensors (O'Brien section 3.3's edge weights).

    Args:
        stats: from :func:`pair_statistics`.
        single_axis_ratio: the hard floor of :mod:`calibration.joint`.
        solutions: the pairs ``numpy.triu_indices(N, k=1)`` already solved (:func:`solve_pairs`
            with this ``single_axis_ratio``), when at hand.

    Returns:
        ``(N, N)`` symmetric, metres; ``inf`` on the diagonal and for pairs with fewer than 3
        frames in common.
    """
    n = stats.n_sensors
    i, j = np.triu_indices(n, k=1)
    sol = solutions
    if sol is None:
        sol = solve_pairs(stats, i, j, single_axis_ratio=single_axis_ratio)
    out = np.full((n, n), np.inf)
    out[i, j] = sol.rms_residual
    out[j, i] = sol.rms_residual
    return out


def residual_operators(
    n: int, parent: np.ndarray, child: np.ndarray, joint_in_parent: np.ndarray, joint_in_child: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The two matrices that give the residual vectors of ``J`` joints from a chunk of poses.

    With the ``c`` frames' rotations laid out by world axis, ``X[f, a, (s, b)] = R[f, s, a, b]``
    (``(3 c, 3 N)``, as :func:`calibration.pair_sums.lay_out` lays them out) and the positions
    likewise, ``P[f, a, s] = p[f, s, a]`` (``(3 c, N)``), ``X @ rot + P @ pos`` is ``(3 c, J)``: row
    ``(f, a)`` holds component ``a`` of each joint's residual ``R_p l_p + p_p - R_c l_c - p_c``
    (O'Brien eq. 8). Each column of ``rot`` has only the two centres of its joint, so this costs
    a third of a product with the flattened ``(c, 9 N)`` rotations.

    Args:
        n: number of sensors ``N``.
        parent: ``(J,)`` parent sensor index of each joint.
        child: ``(J,)`` child sensor index of each joint.
        joint_in_parent: ``(J, 3)`` joint centres in the parent sensor frame, metres.
        joint_in_child: ``(J, 3)`` joint centres in the child sensor frame, metres.

    Returns:
        ``rot`` ``(3 N, J)`` (lengths) and ``pos`` ``(N, J)`` (+1 / -1 selections).
    """
    lp = np.asarray(joint_in_parent, dtype=float).reshape(-1, 3)
    lc = np.asarray(joint_in_child, dtype=float).reshape(-1, 3)
    parent, child = np.asarray(parent, dtype=np.int64), np.asarray(child, dtype=np.int64)
    joints = np.arange(parent.size)
    rot = np.zeros((n, 3, parent.size))  # [sensor, b, joint]
    pos = np.zeros((n, parent.size))
    np.add.at(rot, (parent, slice(None), joints), lp)
    np.add.at(rot, (child, slice(None), joints), -lc)
    np.add.at(pos, (parent, joints), 1.0)
    np.add.at(pos, (child, joints), -1.0)
    return rot.reshape(3 * n, parent.size), pos


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

    The residual vectors of all joints are one matrix product per chunk: the rotations laid out
    by world axis ``(3 chunk, 3 N)`` and the positions ``(3 chunk, N)`` (side by side, as
    :func:`calibration.pair_sums.lay_out` lays them out) times a matrix holding each joint's
    ``+joint_in_parent`` and ``-joint_in_child`` over a +1/-1 selection (:func:`residual_operators`).

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres.
        parent: ``(J,)`` parent sensor index of each joint.
        child: ``(J,)`` child sensor index of each joint.
        joint_in_parent: ``(J, 3)`` joint centres in the parent sensor frame, metres.
        joint_in_child: ``(J, 3)`` joint centres in the child sensor frame, metres.
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
    n_joints = parent.shape[0]
    rot, pos = residual_operators(n, parent, child, joint_in_parent, joint_in_child)
    total = np.zeros(n_joints)
    used = np.zeros(n_joints)
    # joint-major, so that each joint's series is one contiguous row (calibrate hands out views)
    per_frame = np.full((n_joints, n_frames), np.nan) if keep_frames else None
    # [X | P] as the pair statistics lay it out: the positions' per-frame centring cancels in
    # p_p - p_c, so one product per chunk gives every joint's residual
    operator = np.concatenate([rot, pos])  # (4N, J)
    XP = np.empty((min(chunk_frames, max(n_frames, 1)), 3, 4 * n))
    for frames, R, p, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        c = R.shape[0]
        r = (lay_out(R, p, XP[:c]).reshape(3 * c, 4 * n) @ operator).reshape(c, 3, n_joints)
        sq = np.einsum("faj,faj->fj", r, r)  # (c, J) squared norms
        both = ok[:, parent] & ok[:, child]
        if both.all():
            total += sq.sum(axis=0)
            used += c
        else:
            sq[~both] = np.nan
            total += np.where(both, sq, 0.0).sum(axis=0)
            used += both.sum(axis=0)
        if per_frame is not None:
            per_frame[:, frames] = np.sqrt(sq).T
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.where(used > 0, np.sqrt(total / np.maximum(used, 1)), np.nan)
    return rms, None if per_frame is None else per_frame.T


def pair_fit_spectrum(sol: PairSolutions, k: int, single_axis_ratio: float = SINGLE_AXIS_RATIO) -> Spectrum:
    """The :class:`calibration.joint.Spectrum` of pair ``k`` of a batch solution (the verdict
    was made in :func:`solve_pairs`; ``single_axis_ratio`` is kept for callers)."""
    return read_spectrum(sol.singular_values[k], sol.right_vectors[k], single_axis_ratio, sol.keep[k])
