"""Checks of a calibration that a user can act on: joints the motion hardly determines, joints
whose residual stands far above the others' (sensors that are probably not neighbours), and
joints that explain almost nothing of their sensors' motion (noise beyond any tracker's spec).

Both decisions are unit-free: the same recording in mm, cm, m or inches gives the same verdicts.

**Motion too small to locate a centre.** The joint fit ``A x = b`` (O'Brien eqs. 9-13) is only
as good as the relative rotation of the two sensors: a hip moved a few degrees gets a centre
decimetres off with a small residual, because residual errors that move with the joint (soft
tissue) shift the solution along the weakly determined directions. The white-noise covariance of
the normal equations misses that (the frames are not independent), so the standard error of the
centre is measured by the delete-one-block jackknife (:func:`block_jackknife`): the recording is
cut into :data:`JACKKNIFE_BLOCKS` contiguous blocks and the joint refitted without each in turn.
The error is compared with the rms distance between the two sensors (the scale of the segments
the joint links): a standard error above :data:`UNCERTAIN_FRACTION` of it (a 95 % interval
spanning most of that distance) is reported, with the range of relative rotation along each
principal axis in degrees and the fit's condition number. A noise-free joint has no spread
between blocks and is never reported, however small its motion. A fit that kept fewer than five
directions (the single-axis test of :mod:`calibration.joint` found the rotation too small for
more) has no located centre and is always reported, with the same figures.

The jackknife measures the centre's *variance*; errors that follow the joint angle (skin that
slides as the joint turns) bias it instead, and no spread between blocks shows them. The
functional-joint-centre literature gives the rule: the centre's error grows as the noise over the
range of motion, and a ball joint needs tens of degrees in at least two planes (Ehrig et al.
2006, J Biomech 39:2798, errors rising steeply below about 20 degrees; Camomilla et al. 2006,
J Biomech 39:1096; Begon et al. 2007, Gait Posture 25:353). It is applied with the data's own
noise (:func:`motion_bias_bounds`): the bound ``B = r_sys / phi`` of
:mod:`calibration.hinge` (``r_sys`` the residual less its white noise, read off its third
differences; ``phi`` the rms relative rotation, rad, of the least exercised direction the fit
keeps -- for a single-axis joint the one across its axis) is the most an error of the residual's
size that moves with the joint can shift the centre, in metres. A joint whose ``B`` exceeds
:data:`UNCERTAIN_FRACTION` of the sensors' distance is reported too (a ratio of lengths, and
independent of the recording's length: more frames of the same small motion do not help). The
advice fits the verdict: a joint judged single-axis is asked to flex more about its axis, never
to turn across it. A joint whose bound is large although its motion meets the literature's range
(:func:`well_moved`: the least exercised direction turns as much as a sinusoid of 20 degrees
peak to peak) is not short of
motion: its residual is too large for any joint of a body (a pair that is no joint, such as an
upper arm and a hand with the forearm between them missing, 128 mm rms on a real arm; or a marker
cluster joined across a joint), and it is reported as such instead.

**Residual far above the others.** A tree joint between two sensors that are not neighbours
(a hierarchy given wrong, or a sensor whose true neighbour is missing) leaves a residual many
times that of the real joints, whose residuals share the recording's noise. On the logarithm of
the rms residuals (a ratio test, so unit-free) each joint is compared with the median of the
*other* joints and their median absolute deviation: the modified z-score of Iglewicz and Hoaglin
(1993), ``0.6745 (x - median) / MAD``, flags values above 3.5. The log-MAD is floored at
``0.6745 log(RATIO_FLOOR) / 3.5`` so that joints of near-identical residuals (noise-free
simulation) do not make a small difference an outlier: a flagged joint always exceeds the
others' median by :data:`RATIO_FLOOR` or more. Residuals below :data:`NOISE_FREE_FRACTION` of
the sensors' median distance count as that much (noise-free data: 1e-15 m and 1e-13 m are both
exact, not a hundred times apart). With fewer than three other joints there is no spread to
measure; then a residual :data:`FEW_JOINTS_RATIO` times the largest other one is reported.

**A joint that explains nothing.** No joint at all (``x = 0``) leaves the sensors' own distance as
the residual, so a least-squares joint's rms residual never exceeds the sensors' rms distance.
One above :data:`UNEXPLAINED_FRACTION` of it (the joint explains less than three quarters of the
squared distance) is no joint of a body: skin and noise leave millimetres to centimetres on
segments of decimetres. It is noise beyond anything the sensors' spec allows, where every joint
is hit alike and none stands out from the others: a magnetic tracker metres from its
transmitter (its noise grows as the fourth power of the range; ``drop_noisy_frames`` leaves out
the frames that carry it, :mod:`calibration.frame_noise`), or poses that are not of one body.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.hinge import LITERATURE_RANGE_DEG, WELL_MOVED_RMS_RAD, bias_bounds, systematic_rms
from calibration.hinge import UNCERTAIN_FRACTION as HINGE_FRACTION
from calibration.joint import LOCATED_RANK
from calibration.pairs import PairStatistics, frame_residuals, pair_statistics, solve_pairs
from calibration.poses import CHUNK_FRAMES, iter_chunks
from calibration.rotations import matrix_to_rotvec

#: Report a joint whose centre's standard error, or the bound on its bias, exceeds this fraction
#: of the sensors' distance (:data:`calibration.hinge.UNCERTAIN_FRACTION`, re-exported).
UNCERTAIN_FRACTION = HINGE_FRACTION


#: Modified z-score (Iglewicz and Hoaglin 1993) above which a joint's log residual is an outlier.
OUTLIER_Z = 3.5

#: A flagged residual is at least this many times the median of the other joints' residuals.
RATIO_FLOOR = 3.0

#: With fewer than three other joints: ratio to the largest other residual that is reported.
FEW_JOINTS_RATIO = 10.0

#: Report a joint whose rms residual exceeds this fraction of its sensors' rms distance.
UNEXPLAINED_FRACTION = 0.5

#: Contiguous blocks of frames of the jackknife that measures a centre's standard error.
JACKKNIFE_BLOCKS = 20

#: Residuals below this fraction of the median sensor distance count as noise-free (0.3 mm at
#: 30 cm): far above rounding, below any tracker's noise.
NOISE_FREE_FRACTION = 1e-3

#: Percentiles bounding the reported range of relative rotation (robust to a few bad frames).
RANGE_PERCENTILES = (2.5, 97.5)


def fit_condition(singular_values: np.ndarray, rank: int) -> float:
    """``s_max / s_min`` of a joint fit over its ``rank`` kept directions (``inf`` if none)."""
    s = np.asarray(singular_values, dtype=float)
    if rank < 1 or not np.all(np.isfinite(s[:rank])) or s[rank - 1] <= 0.0:
        return float("inf")
    return float(s[0]) / float(s[rank - 1])


def block_jackknife(
    R_w_s: Any,
    p_w_s: Any,
    parent: np.ndarray,
    child: np.ndarray,
    rank: np.ndarray,
    *,
    valid: Any = None,
    n_blocks: int = JACKKNIFE_BLOCKS,
    chunk_frames: int = CHUNK_FRAMES,
) -> np.ndarray:
    """Standard error of each joint's centre by the delete-one-block jackknife.

    The recording is cut into ``n_blocks`` contiguous blocks of frames; each joint is fitted
    again without each block in turn (O'Brien eq. 13 from the blocks' normal equations, keeping
    the ``rank`` strongest directions of the full fit), and the spread of those fits gives the
    standard error. Errors correlated over times shorter than a block (soft tissue moving with
    the joint) enter it, unlike the white-noise covariance of the normal equations.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (sliceable along frames).
        p_w_s: ``(frames, sensors, 3)`` positions in world, any length unit.
        parent, child: ``(J,)`` sensor indices of the joints.
        rank: ``(J,)`` directions each joint's fit keeps.
        valid: optional ``(frames, sensors)`` bool.
        n_blocks: number of blocks.
        chunk_frames: frames per chunk.

    Returns:
        ``(J,)`` rms standard error of the centre, the larger of its location in the parent and
        in the child frame, in the positions' unit.
    """
    parent, child = np.asarray(parent, dtype=np.int64), np.asarray(child, dtype=np.int64)
    n_frames, n_j = int(R_w_s.shape[0]), parent.size
    blocks = np.zeros((n_blocks, n_j, 16))  # per block and joint: frames, R_p^T R_c, R_p^T b, R_c^T b
    for frames, R, p, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        block = np.arange(frames.start, frames.stop) * n_blocks // n_frames  # non-decreasing
        starts = np.flatnonzero(np.r_[True, block[1:] != block[:-1]])
        w = (ok[:, parent] & ok[:, child]).astype(float)  # (c, J)
        R_p, R_c = R[:, parent] * w[..., None, None], R[:, child] * w[..., None, None]
        b = p[:, child] - p[:, parent]
        # each frame's normal equations A^T A, A^T b with A = [R_p, -R_c]: the rotations make the
        # diagonal blocks w I, so only R_p^T R_c and the two R^T b are summed (a quarter of A^T A's
        # products), over the runs of frames of one block
        R_pt = R_p.swapaxes(-1, -2)
        sums = np.concatenate(
            [
                w[..., None],
                (R_pt @ R_c).reshape(*w.shape, 9),
                (R_pt @ b[..., None])[..., 0],
                (R_c.swapaxes(-1, -2) @ b[..., None])[..., 0],
            ],
            axis=-1,
        )  # (c, J, 16)
        blocks[block[starts]] += np.add.reduceat(sums, starts, axis=0)
    return jackknife_standard_error(blocks, rank)


def jackknife_block_sums(stats: PairStatistics, parent: np.ndarray, child: np.ndarray) -> np.ndarray:
    """``(K, J, 16)`` the per-block sums :func:`block_jackknife` makes in its pass over the data
    (frames, ``R_p^T R_c``, ``R_p^T b``, ``R_c^T b`` per block and joint), read off pair statistics
    that kept the blocks of :func:`calibration.pairs.jackknife_edges`
    (``pair_statistics(..., jackknife_blocks=K)``): no pass over the data. ``b = p_c - p_p`` does
    not change with the statistics' per-frame centring."""
    gram, cross, self_cross = stats.jackknife_gram, stats.jackknife_cross, stats.jackknife_self_cross
    count = stats.jackknife_count
    if gram is None or cross is None or self_cross is None or count is None:
        raise ValueError("these pair statistics kept no jackknife blocks")
    parent, child = np.asarray(parent, dtype=np.int64), np.asarray(child, dtype=np.int64)
    return np.concatenate(
        [
            count[:, parent, child].astype(float)[..., None],
            gram[:, parent, child].reshape(count.shape[0], parent.size, 9),
            cross[:, parent, child] - self_cross[:, parent, child],
            self_cross[:, child, parent] - cross[:, child, parent],
        ],
        axis=-1,
    )


def jackknife_standard_error(blocks: np.ndarray, rank: np.ndarray) -> np.ndarray:
    """:func:`block_jackknife`'s standard errors from its ``(K, J, 16)`` per-block sums (frames,
    ``R_p^T R_c``, ``R_p^T b``, ``R_c^T b``) and each joint's ``rank``."""
    n_blocks, n_j = blocks.shape[:2]
    ata = np.zeros((n_blocks, n_j, 6, 6))
    eye = np.eye(3)
    ata[..., :3, :3] = ata[..., 3:, 3:] = blocks[..., :1, None] * eye
    ata[..., :3, 3:] = -blocks[..., 1:10].reshape(n_blocks, n_j, 3, 3)
    ata[..., 3:, :3] = np.swapaxes(ata[..., :3, 3:], -1, -2)
    atb = np.concatenate([blocks[..., 10:13], -blocks[..., 13:16]], axis=-1)
    full_ata, full_atb = ata.sum(axis=0), atb.sum(axis=0)
    out = np.full(n_j, np.nan)
    rank = np.asarray(rank, dtype=np.int64)
    _, vecs = np.linalg.eigh(full_ata)
    for r in np.unique(rank):  # the joints of one rank together
        js = np.flatnonzero(rank == r)
        keep = vecs[js][:, :, ::-1][:, :, :r]  # (j, 6, r) the strongest directions of each full fit
        left = full_ata[js] - ata[:, js]  # (blocks, j, 6, 6): each block left out
        m = np.swapaxes(keep, -1, -2) @ left @ keep  # (blocks, j, r, r)
        v = ((full_atb[js] - atb[:, js])[..., None, :] @ keep)[..., 0, :]  # (blocks, j, r)
        try:
            x = np.linalg.solve(m, v[..., None])[..., 0]
        except np.linalg.LinAlgError:  # one joint at a time, as the batch failed
            x = np.stack([_left_out_fits(m[:, q], v[:, q]) for q in range(js.size)], axis=1)
        x = (x[..., None, :] @ np.swapaxes(keep, -1, -2))[..., 0, :]  # (blocks, j, 6)
        dev = x - x.mean(axis=0)
        var = (n_blocks - 1) / n_blocks * np.sum(dev**2, axis=0)  # (j, 6) jackknife variance per coordinate
        out[js] = np.sqrt(np.maximum(var[:, :3].sum(axis=1), var[:, 3:].sum(axis=1)))
    return out


def _left_out_fits(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(blocks, r)`` one joint's fits with each block left out, from ``m`` ``(blocks, r, r)`` and
    ``v`` ``(blocks, r)``; least squares where a block's removal leaves a direction unseen."""
    try:
        return np.linalg.solve(m, v[..., None])[..., 0]
    except np.linalg.LinAlgError:
        return np.array([np.linalg.lstsq(m[b], v[b], rcond=None)[0] for b in range(m.shape[0])])


def rotation_ranges(
    R_w_s: Any,
    parent: np.ndarray,
    child: np.ndarray,
    *,
    valid: Any = None,
    chunk_frames: int = CHUNK_FRAMES,
) -> np.ndarray:
    """Range of relative rotation of each given sensor pair along its principal axes.

    Two passes of chunks: the first sums the relative rotations ``R_w_p^T R_w_c``, the second
    takes the rotation vector of each frame's relative rotation about their chordal mean (the
    sum projected onto the rotations).

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (sliceable along frames;
            non-finite entries are missing poses).
        parent, child: ``(J,)`` sensor indices of the pairs.
        valid: optional ``(frames, sensors)`` bool; each pair uses the frames where both are.
        chunk_frames: frames per chunk.

    Returns:
        ``(J, 3)`` extent of the relative rotation (parent to child) about its mean along its
        principal axes, largest first: the spread between the 2.5th and 97.5th percentiles of the
        rotation vectors' components, degrees; NaN for a pair with no common frame.
    """
    parent, child = np.asarray(parent, dtype=np.int64), np.asarray(child, dtype=np.int64)
    n_frames, n = int(R_w_s.shape[0]), int(R_w_s.shape[1])
    p_w_s = np.broadcast_to(0.0, (n_frames, n, 3))  # positions play no part; iter_chunks wants them
    total = np.zeros((parent.size, 3, 3))
    used = np.zeros((n_frames, parent.size), dtype=bool)
    for frames, R, _, ok in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        used[frames] = ok[:, parent] & ok[:, child]
        rel = np.einsum("fjki,fjkl->fjil", R[:, parent], R[:, child])  # R_p^T R_c
        total += np.einsum("fj,fjil->jil", used[frames], rel)
    u, _, vt = np.linalg.svd(total)
    u[np.linalg.det(u @ vt) < 0.0, :, 2] *= -1.0  # the nearest rotation, not a reflection
    mean = u @ vt
    vectors = np.zeros((n_frames, parent.size, 3))
    for frames, R, _, _ in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        rel = np.einsum("fjki,fjkl->fjil", R[:, parent], R[:, child])
        off_mean = np.einsum("jki,fjkl->fjil", mean, rel)  # mean^T R_p^T R_c
        vectors[frames] = matrix_to_rotvec(_nearest_rotation(off_mean))
    ranges = np.full((parent.size, 3), np.nan)
    for k in range(parent.size):
        if used[:, k].any():
            ranges[k] = _principal_ranges(np.rad2deg(vectors[used[:, k], k]))
    return ranges


def _nearest_rotation(R: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations; zeroed (invalid) entries become the identity."""
    zero = ~np.any(R.reshape(*R.shape[:-2], 9) != 0.0, axis=-1)
    return np.where(zero[..., None, None], np.eye(3), R)


def _principal_ranges(vectors: np.ndarray) -> np.ndarray:
    """``(3,)`` percentile extent of ``(frames, 3)`` vectors along their principal axes, descending."""
    centred = vectors - np.median(vectors, axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    along = centred @ vt.T
    lo, hi = np.percentile(along, RANGE_PERCENTILES, axis=0)
    return np.sort(hi - lo)[::-1]


def residual_outliers(rms_residual: np.ndarray, floor: float = 0.0) -> list[tuple[int, float, float]]:
    """Joints whose rms residual stands far above the other joints' (module docstring).

    Args:
        rms_residual: ``(J,)`` rms residual of each joint, any length unit (non-negative).
        floor: residuals below it count as equal to it (the precision of the data, same unit).

    Returns:
        ``(joint index, modified z-score, ratio to the others' median)`` of each flagged joint;
        the z-score is NaN where fewer than three other joints leave no spread to measure (the
        ratio is then to the largest other residual).
    """
    r = np.asarray(rms_residual, dtype=float)
    finite = np.isfinite(r) & (r >= 0.0)
    if r.size < 2 or not finite.any() or np.max(r[finite]) == 0.0:
        return []
    floor = max(floor, np.max(r[finite]) * 1e-12)  # exact zeros (noise-free joints) stay comparable
    logr = np.log(np.maximum(np.where(finite, r, np.nan), floor))
    out = []
    for k in np.flatnonzero(finite):
        others = np.delete(logr, k)
        others = others[np.isfinite(others)]
        if others.size == 0:
            continue
        if others.size < 3:
            ratio = float(np.exp(logr[k] - np.max(others)))
            if ratio > FEW_JOINTS_RATIO:
                out.append((int(k), float("nan"), ratio))
            continue
        med = float(np.median(others))
        mad = max(float(np.median(np.abs(others - med))), 0.6745 * np.log(RATIO_FLOOR) / OUTLIER_Z)
        z = 0.6745 * (logr[k] - med) / mad
        ratio = float(np.exp(logr[k] - med))
        if z > OUTLIER_Z and ratio > RATIO_FLOOR:
            out.append((int(k), float(z), ratio))
    return out


def motion_bias_bounds(fits: list[Any], white_variance: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's bias bound along its least exercised located direction (module docstring).

    Args:
        fits: :class:`calibration.joint.JointFit` of the joints.
        white_variance: ``(J,)`` the white-noise variance of each joint's residual
            (:mod:`calibration.pair_noise`), m^2; ``None``: unknown, the whole residual counts.

    Returns:
        ``(bound, phi)``: ``(J,)`` ``B = r_sys / phi`` in metres, and ``(J,)`` ``phi`` the rms
        relative rotation (rad) of the direction it is taken along: the weakest kept one
        (:func:`calibration.hinge.bias_bounds`), the fifth for a single-axis joint (across the
        axis, whose own direction is not located), NaN for a joint with fewer than 5 directions.
    """
    n_j = len(fits)
    white = np.zeros(n_j) if white_variance is None else np.asarray(white_variance, dtype=float)
    bound, phi = np.full(n_j, np.nan), np.full(n_j, np.nan)
    for k, fit in enumerate(fits):
        if fit.rank < LOCATED_RANK:
            continue
        r_sys = systematic_rms(fit.rms_residual, white[k], fit.n_frames)
        j = fit.rank - 1
        bound[k] = float(bias_bounds(r_sys, fit.singular_values, fit.n_frames)[j])
        phi[k] = float(np.sqrt(2.0) * fit.singular_values[j] / np.sqrt(max(fit.n_frames, 1)))
    return bound, phi


def motion_warnings(
    R_w_s: Any,
    p_w_s: Any,
    names: tuple[str, ...],
    pairs: list[tuple[int, int]],
    fits: list[Any],
    separation: np.ndarray,
    *,
    valid: Any = None,
    chunk_frames: int = CHUNK_FRAMES,
    block_sums: np.ndarray | None = None,
    white_variance: np.ndarray | None = None,
    reported: frozenset[int] = frozenset(),
) -> list[str]:
    """Warnings for joints whose centre the motion hardly determines (module docstring): a
    jackknife standard error or a bias bound above :data:`UNCERTAIN_FRACTION` of the distance.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres.
        names: sensor names.
        pairs: ``(parent, child)`` sensor indices of the joints.
        fits: their :class:`calibration.joint.JointFit` (singular values, rank, residual). A
            fit that kept fewer than 5 directions is always reported (its centre is not located).
        separation: ``(J,)`` typical distance between each joint's sensors, metres.
        valid, chunk_frames: as for :func:`rotation_ranges`.
        block_sums: ``(JACKKNIFE_BLOCKS, J, 16)`` the jackknife's per-block sums of the joints
            when they are at hand (:func:`jackknife_block_sums`); else the jackknife makes its own
            pass over the data.
        white_variance: ``(J,)`` white-noise variance of each joint's residual, m^2, for the bias
            bound (:func:`motion_bias_bounds`); ``None``: the whole residual counts as systematic.
        reported: joints (indices into ``pairs``) whose residual :func:`residual_warnings` reports
            already: a well moved one is not reported twice as a pair that is no joint.
    """
    par = np.array([p for p, _ in pairs], dtype=np.int64)
    chi = np.array([c for _, c in pairs], dtype=np.int64)
    rank = np.array([fit.rank for fit in fits])
    unc = np.full(len(fits), np.inf)  # fewer than 5 directions kept: the centre is not located
    checked = np.flatnonzero(rank >= LOCATED_RANK)
    if checked.size:
        if block_sums is not None:
            unc[checked] = jackknife_standard_error(block_sums[:, checked], rank[checked])
        else:
            args = (par[checked], chi[checked], rank[checked])
            unc[checked] = block_jackknife(R_w_s, p_w_s, *args, valid=valid, chunk_frames=chunk_frames)
    bound, phi = motion_bias_bounds(fits, white_variance)
    limit = UNCERTAIN_FRACTION * np.asarray(separation, dtype=float)
    flagged = [k for k in range(len(fits)) if unc[k] > limit[k] or bound[k] > limit[k]]
    if not flagged:
        return []
    ranges = rotation_ranges(R_w_s, par[flagged], chi[flagged], valid=valid, chunk_frames=chunk_frames)
    out = []
    for k, rng in zip(flagged, ranges, strict=True):
        fit, sep = fits[k], float(separation[k])
        if unc[k] <= limit[k] and well_moved(phi[k]):
            if k in reported:
                continue
            out.append(_residual_too_large(names[par[k]], names[chi[k]], fit, rng, float(bound[k]), sep))
            continue
        how = (
            f"the data determine only {fit.rank} of its 6 directions (condition "
            f"{fit_condition(fit.singular_values, 6):.3g})"
            if fit.rank < LOCATED_RANK
            else f"fit condition {fit_condition(fit.singular_values, fit.rank):.3g}, centre standard "
            f"error {unc[k] * 1e3:.3g} mm by block jackknife ({100 * unc[k] / sep:.0f} % of the "
            f"{sep * 1e3:.3g} mm between the sensors), bias bound {bound[k] * 1e3:.3g} mm "
            f"({100 * bound[k] / sep:.0f} %: the residual's systematic part over the "
            f"{np.rad2deg(phi[k]):.2g} deg rms rotation of its least exercised direction)"
        )
        out.append(
            f"joint {names[par[k]]}-{names[chi[k]]}: the motion hardly determines its centre: relative "
            f"rotation range {', '.join(f'{x:.1f}' for x in rng)} deg along its principal axes; "
            f"{how}; residual {fit.rms_residual * 1e3:.3g} mm rms. "
            f"{motion_advice(fit, bool(bound[k] > limit[k]))}"
        )
    return out


def well_moved(phi_rad: float) -> bool:
    """The literature's range of motion (module docstring) is met along the direction a bias bound
    is taken along: its rms rotation ``phi_rad`` (:func:`motion_bias_bounds`) is at least that of a
    sinusoid spanning :data:`LITERATURE_RANGE_DEG` peak to peak (``range / (2 sqrt 2)``, 7.1
    degrees). For a ball joint that direction is the least exercised, so both planes are met."""
    return bool(np.isfinite(phi_rad) and phi_rad >= WELL_MOVED_RMS_RAD)


def _residual_too_large(parent: str, child: str, fit: Any, rng: np.ndarray, bound: float, sep: float) -> str:
    """The warning for a joint whose bias bound is large although it moved well: its residual,
    not its motion, is what cannot place the centre (module docstring)."""
    return (
        f"joint {parent}-{child}: residual {fit.rms_residual * 1e3:.3g} mm rms is too large for its "
        f"motion to place a centre: bias bound {bound * 1e3:.3g} mm ({100 * bound / sep:.0f} % of the "
        f"{sep * 1e3:.3g} mm between the sensors) although it turned through "
        f"{', '.join(f'{x:.1f}' for x in rng)} deg along its principal axes. {parent} and {child} are "
        "probably not neighbours (a segment between them missing: check the hierarchy), or one of "
        "them is not one rigid body (a marker cluster joined across a joint: check the clusters)"
    )


def motion_advice(fit: Any, across_too: bool = False) -> str:
    """What to record for a joint the motion hardly determines, fitting its verdict: a joint
    judged single-axis is not asked to turn in two or more directions. ``across_too``: its
    motion about the axis is too small as well (:func:`motion_bias_bounds`), too small to tell a
    hinge from a ball joint that barely moved."""
    if fit.single_axis:
        out = (
            "It is judged single-axis: the axis is what the data give, its centre along the axis is "
            "not measured (the point nearest both sensors is reported)"
        )
        if across_too:
            out += (
                f", and it turned too little about the axis to place the axis itself: record it "
                f"through tens of degrees (at least {LITERATURE_RANGE_DEG:.0f}) about its axis (a ball "
                "joint that barely moved, across the axis as well)"
            )
        return out
    return (
        f"Record this joint moving through tens of degrees (at least {LITERATURE_RANGE_DEG:.0f}, "
        "Ehrig et al. 2006) in two or more directions"
    )


def _outliers(rms_residual: np.ndarray, separation: np.ndarray) -> list[tuple[int, float, float]]:
    """:func:`residual_outliers` at the precision floor of the sensors' median distance."""
    floor = NOISE_FREE_FRACTION * float(np.nanmedian(separation)) if np.size(separation) else 0.0
    return residual_outliers(rms_residual, floor if np.isfinite(floor) else 0.0)


class JointResiduals(NamedTuple):
    """How well given joints fit a recording's poses (any estimator's joints).

    Attributes:
        rms: ``(J,)`` root mean square over frames of the residual's norm (O'Brien eq. 13), in
            the positions' unit; NaN for a joint with no frame where both sensors are seen.
        max: ``(J,)`` the largest residual norm, same unit.
        best: ``(J,)`` the least rms residual any centre leaves on the same frames (O'Brien's
            least-squares fit of the pair), same unit.
        separation: ``(J,)`` rms distance between the joint's two sensors, same unit.
        frames: ``(J,)`` frames where both sensors are seen.
    """

    rms: np.ndarray
    max: np.ndarray
    best: np.ndarray
    separation: np.ndarray
    frames: np.ndarray


def joint_residuals(
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
) -> JointResiduals:
    """The residual of joints located by any method, over a recording, beside the least residual
    any centre leaves (the least-squares fit of each pair, O'Brien eqs. 9-13): one pass for the
    pairs' statistics, one for the exact residuals of both (:func:`calibration.pairs.frame_residuals`).

    The same figures O'Brien's calibration reports for its own joints, for centres found some
    other way, so that :func:`estimate_warnings` judges every estimator's joints alike.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` positions in world, any length unit.
        parent: ``(J,)`` parent sensor index of each joint.
        child: ``(J,)`` child sensor index of each joint.
        joint_in_parent: ``(J, 3)`` centres in the parent sensor's frame, the positions' unit.
        joint_in_child: ``(J, 3)`` centres in the child sensor's frame, the same unit.
        valid: optional ``(frames, sensors)`` bool, False where a pose is missing.
        chunk_frames: frames worked on at a time.
        keep_frames: keep the per-frame residuals for the largest (``frames x 2 J`` floats, as
            :func:`calibration.pipeline.default_keep_frame_residuals` decides for O'Brien's);
            without them ``max`` is NaN.
    """
    par = np.asarray(parent, dtype=np.int64).reshape(-1)
    chi = np.asarray(child, dtype=np.int64).reshape(-1)
    lp = np.asarray(joint_in_parent, dtype=float).reshape(-1, 3)
    lc = np.asarray(joint_in_child, dtype=float).reshape(-1, 3)
    if not len(par) == len(chi) == len(lp) == len(lc):
        raise CalibrationInputError(
            f"Expected one parent, child and two centres per joint, got {len(par)} parents, {len(chi)} "
            f"children, {len(lp)} and {len(lc)} centres"
        )
    stats = pair_statistics(R_w_s, p_w_s, valid=valid, chunk_frames=chunk_frames, third_differences=False)
    fit = solve_pairs(stats, par, chi)
    # theirs and the least-squares centres, residuals exact from the data (not the normal equations)
    rms, per_frame = frame_residuals(
        R_w_s,
        p_w_s,
        np.concatenate([par, par]),
        np.concatenate([chi, chi]),
        np.concatenate([lp, np.nan_to_num(fit.joint_in_parent)]),
        np.concatenate([lc, np.nan_to_num(fit.joint_in_child)]),
        valid=valid,
        chunk_frames=chunk_frames,
        keep_frames=keep_frames,
    )
    j = len(par)
    count = stats.count[par, chi].astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        separation = np.sqrt(stats.sq_dist[par, chi] / count)
    top = np.full(j, np.nan)
    if per_frame is not None and per_frame.shape[0]:
        seen = count > 0
        top[seen] = np.nanmax(per_frame[:, :j][:, seen], axis=0)
    best = np.where(np.isfinite(fit.rms_residual), np.minimum(rms[j:], rms[:j]), np.nan)
    return JointResiduals(rms[:j], top, best, separation, count.astype(np.int64))


def estimate_warnings(
    names: tuple[str, ...], pairs: list[tuple[int, int]], residuals: JointResiduals, unit_m: float = 1.0
) -> list[str]:
    """:func:`residual_warnings` for joints located by any method, told apart by the cause.

    A joint the rules of :func:`residual_flagged` report whose least-squares centre on the same
    poses they would not report is the estimate's fault, not the data's: it is said so, with what
    the least-squares centre leaves. Where the least-squares centres are reported too, the data's
    warning is given as O'Brien's calibration gives it.

    Args:
        names: sensor names.
        pairs: ``(parent, child)`` sensor indices of the joints.
        residuals: :func:`joint_residuals` of the joints.
        unit_m: metres per unit of the residuals (the warnings state millimetres).
    """
    rms, best, sep = (
        np.asarray(x, dtype=float) * unit_m for x in (residuals.rms, residuals.best, residuals.separation)
    )
    theirs, least = residual_flagged(rms, sep), residual_flagged(best, sep)
    out = []
    for k in sorted(theirs - least):
        p, c = pairs[k]
        out.append(
            f"joint {names[p]}-{names[c]}: residual {rms[k] * 1e3:.3g} mm rms ({sep[k] * 1e3:.3g} mm between "
            f"the sensors), where the least-squares centre of the same poses leaves {best[k] * 1e3:.3g} mm: "
            "the estimate does not fit these poses (a method that fits less of the motion, such as a sphere "
            "fit of the child's position alone, or centres in the wrong sensor's frame or another unit)"
        )
    return out + residual_warnings(names, pairs, rms, sep, only=theirs & least)


def residual_flagged(rms_residual: np.ndarray, separation: np.ndarray) -> frozenset[int]:
    """The joints :func:`residual_warnings` reports (indices)."""
    sep, rms = np.asarray(separation, dtype=float), np.asarray(rms_residual, dtype=float)
    unexplained = np.flatnonzero((sep > 0) & (rms > UNEXPLAINED_FRACTION * sep))
    return frozenset(k for k, _, _ in _outliers(rms, sep)) | frozenset(int(k) for k in unexplained)


def residual_warnings(
    names: tuple[str, ...],
    pairs: list[tuple[int, int]],
    rms_residual: np.ndarray,
    separation: np.ndarray,
    *,
    only: frozenset[int] | None = None,
) -> list[str]:
    """Warnings for joints whose residual stands far above the others', and for joints that
    explain little of their sensors' distance (module docstring).

    Args:
        names: sensor names.
        pairs: ``(parent, child)`` sensor indices of the joints.
        rms_residual: ``(J,)`` their rms residuals, metres.
        separation: ``(J,)`` the rms distance between each joint's sensors, metres.
        only: warn of these joints (indices) alone, judged among all; ``None``: all.
    """
    out = []
    for k, z, ratio in _outliers(rms_residual, separation):
        if only is not None and k not in only:
            continue
        p, c = pairs[k]
        test = "the largest other joint's"
        if not np.isnan(z):
            test = f"the other joints' median (modified z {z:.3g})"
        out.append(
            f"joint {names[p]}-{names[c]}: residual {rms_residual[k] * 1e3:.3g} mm rms is {ratio:.3g} "
            f"times {test}: {names[p]} and {names[c]} are probably not neighbours (check the "
            "hierarchy, or a sensor between them that is missing), or one of them moved on the body "
            "(see the slip events)"
        )
    for k, (p, c) in enumerate(pairs):
        if only is not None and k not in only:
            continue
        if separation[k] > 0 and rms_residual[k] > UNEXPLAINED_FRACTION * separation[k]:
            out.append(
                f"joint {names[p]}-{names[c]}: residual {rms_residual[k] * 1e3:.3g} mm rms is "
                f"{rms_residual[k] / separation[k]:.2g} of the sensors' own rms distance "
                f"({separation[k] * 1e3:.3g} mm): the joint explains almost nothing of their motion. "
                "These poses are far noisier than any tracker's spec (a magnetic tracker metres from "
                "its transmitter: leave out the noisiest frames, --drop-noisy-frames, or "
                "drop_noisy_frames=True in Python) or are not of one body"
            )
    return out
