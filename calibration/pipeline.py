"""The whole calibration: from sensor poses to joints, hierarchy and skeleton.

Steps (O'Brien et al. 2000):

1. one pass over the data accumulates the normal equations of every sensor pair
   (:func:`calibration.pairs.pair_statistics`), with what the misfit tree's noise
   (:class:`calibration.pair_sums.ThirdDifferenceSums`) and the jackknife of the motion warnings
   (:func:`calibration.diagnostics.jackknife_block_sums`) need: no other pass over the data
   unless per-frame residuals are kept;
2. every pair's joint fit and residual follow from those (section 3.1);
3. the hierarchy is the minimum spanning tree of the pairs' misfits (residuals less their noise,
   :mod:`calibration.hierarchy`; ``hierarchy_method="mst"``: of the residuals, as in section 3.3),
   unless one is given;
4. the tree's joints are solved with single-axis detection (3.2), and their residuals are
   recomputed exactly from the data in a second pass (unless per-frame residuals are not
   wanted: the rms then comes from the normal equations where their rounding allows,
   :func:`calibration.pairs.rms_needs_data`);
5. limb lengths and sensor offsets follow from the joint locations.

Two options leave the default path untouched (neither runs unless asked for):

- ``robust="tukey"`` or ``"huber"``: the tree's joints are fitted by IRLS
  (:func:`calibration.robust.robust_fit_joint`) so that slip blocks and field-distortion bursts
  lose their pull, and an inferred hierarchy is the spanning tree of the robust pair misfits
  (:func:`calibration.robust.robust_pair_misfits`: one IRLS fit per pair of sensors, about 0.1 s
  each for 3000 frames). The residual matrix and loop candidates stay the least-squares ones.
- ``intervals=True``: every joint gets its covariance and 95 % regions
  (:func:`calibration.uncertainty.joint_covariance`, batch means) on the fit it used, and every
  limb length between two such joints its 95 % interval
  (:func:`calibration.uncertainty.segment_length_uncertainty`, the two fits' correlation
  included). For a robust fit the covariance is computed over its inlier frames only and is
  therefore *conditional on the inlier set*: it does not count the uncertainty of which frames
  were rejected, and it is centred on the robust centre (whose scores over the inliers need not
  sum to zero, which makes it slightly conservative).

- ``correct_rotation_noise=True``: the tree's joints are refitted by O'Brien's least squares
  corrected for the noise on the rotations (:mod:`calibration.eiv`: the errors-in-variables bias
  that pulls a centre toward the sensors along weakly exercised directions), each sensor's noise
  read off its own rotations (:func:`calibration.eiv.orientation_noise_variance`), with the same
  single-axis verdicts; the intervals are then the corrected fit's. Not with ``robust``.

All three hold each joint's pair of sensors in memory (``frames x 24`` floats) and, for a robust
inferred hierarchy, all the poses.

Memory is bounded by the chunk size (plus ``frames x joints`` floats when per-frame residuals
are kept), so the input may be an h5py dataset or a memory map larger than memory; by default
the per-frame residuals of such an input are kept only up to :data:`FRAME_RESIDUAL_BYTES`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calibration.diagnostics import (
    JACKKNIFE_BLOCKS,
    jackknife_block_sums,
    motion_bias_bounds,
    motion_warnings,
    residual_flagged,
    residual_warnings,
)
from calibration.eiv import orientation_noise_variance
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.frame_noise import noisy_frames
from calibration.hierarchy import (
    HIERARCHY_METHODS,
    LOOP_FACTOR,
    Hierarchy,
    hierarchy_from_parents,
    loop_candidates,
    misfit_weights,
    spanning_tree,
)
from calibration.joint import MIN_FRAMES, SINGLE_AXIS_RATIO, JointFit, fit_joint
from calibration.pair_noise import pair_noise_variance
from calibration.pairs import (
    PairSolutions,
    PairStatistics,
    frame_residuals,
    pair_fit_spectrum,
    pair_residual_matrix,
    pair_statistics,
    rms_needs_data,
    solve_pairs,
)
from calibration.poses import CHUNK_FRAMES, check_poses, check_rotations
from calibration.robust import LOSSES, RobustJointFit, robust_fit_joint, robust_pair_misfits
from calibration.robust import MIN_FRAMES as ROBUST_MIN_FRAMES
from calibration.skeleton import (
    SegmentLength,
    SensorPlacement,
    joint_arrays,
    joint_name,
    segment_lengths,
    sensor_placements,
)
from calibration.uncertainty import (
    JointUncertainty,
    LengthUncertainty,
    joint_covariance,
    segment_length_uncertainty,
)

#: By default, per-frame residuals of poses that are out of core (an h5py dataset, a memory map)
#: are kept only up to this many bytes (8 million residuals: a million frames of 8 joints).
FRAME_RESIDUAL_BYTES = 64 << 20


def default_keep_frame_residuals(R_w_s: Any, n_frames: int, n_joints: int) -> bool:
    """Whether ``calibrate`` keeps per-frame residuals when not told (``keep_frame_residuals``):
    always for in-memory arrays, for out-of-core poses up to :data:`FRAME_RESIDUAL_BYTES`."""
    in_memory = isinstance(R_w_s, np.ndarray) and not isinstance(R_w_s, np.memmap)
    return in_memory or 8 * n_frames * n_joints <= FRAME_RESIDUAL_BYTES


@dataclass(frozen=True)
class Joint:
    """A joint of the calibrated hierarchy.

    Attributes:
        parent: inboard sensor name.
        child: outboard sensor name.
        fit: the joint fit (locations in both sensor frames, residuals, diagnostics). For a
            robust fit: its centre, rank and axis, the per-frame residual norms of every frame
            and ``rms_residual`` over the inlier frames, with the least-squares fit's singular
            values and frame counts.
        uncertainty: the centre's covariance and 95 % regions
            (:func:`calibration.uncertainty.joint_covariance`) when intervals were asked for, else
            ``None``; for a robust fit, over its inlier frames (conditional on the inlier set).
        robust_fit: the IRLS fit (weights, inliers, scale) when the joint was fitted robustly,
            else ``None``.
    """

    parent: str
    child: str
    fit: JointFit
    uncertainty: JointUncertainty | None = None
    robust_fit: RobustJointFit | None = None

    @property
    def name(self) -> str:
        """``"parent-child"``."""
        return joint_name(self.parent, self.child)


@dataclass(frozen=True)
class Calibration:
    """Everything the calibration estimated.

    Attributes:
        names: sensor names, in input order.
        hierarchy: the tree (indices into ``names``).
        hierarchy_given: the tree was given, not inferred.
        joints: one per non-root sensor, parents before children.
        residual_matrix: ``(N, N)`` rms joint-fit residual of every sensor pair, metres
            (``inf`` on the diagonal and for pairs with too few common frames).
        loop_candidates: ``(sensor a, sensor b, residual)`` of pairs left out of the tree that fit
            as well as its joints (possible loop joints).
        lengths: distances between the joints of each segment.
        placements: each sensor's offsets to its segment's joints.
        warnings: plain-language notes on what the data could not determine or lacked.
        n_frames: frames in the input.
        missing: ``(N,)`` frames where each sensor's pose was missing or not finite.
        seconds: wall time of each step.
        hierarchy_method: how the tree was inferred (:data:`calibration.hierarchy.HIERARCHY_METHODS`;
            unused when the hierarchy was given).
        robust: the loss of the robust joint fits (``"tukey"``, ``"huber"``), or ``None`` for
            least squares.
        length_uncertainty: with intervals, one entry per ``lengths`` (same order): the length's
            95 % interval, or ``None`` where a joint of the segment has no uncertainty (or the
            centres coincide); empty without intervals.
        rotation_noise_rad2: ``{sensor: sigma^2}`` the rotation noise (rad^2, per component) the
            joints were corrected for (``correct_rotation_noise``), or ``None``.
        noisy_frames: ``(F, N)`` True where a valid pose was left out for its noise
            (``drop_noisy_frames``, :mod:`calibration.frame_noise`), or ``None`` when none was.
    """

    names: tuple[str, ...]
    hierarchy: Hierarchy
    hierarchy_given: bool
    joints: tuple[Joint, ...]
    residual_matrix: np.ndarray
    loop_candidates: tuple[tuple[str, str, float], ...]
    lengths: tuple[SegmentLength, ...]
    placements: tuple[SensorPlacement, ...]
    warnings: tuple[str, ...]
    n_frames: int
    missing: np.ndarray
    seconds: dict[str, float] = field(default_factory=dict)
    hierarchy_method: str = HIERARCHY_METHODS[0]
    robust: str | None = None
    length_uncertainty: tuple[LengthUncertainty | None, ...] = ()
    rotation_noise_rad2: dict[str, float] | None = None
    noisy_frames: np.ndarray | None = None

    @property
    def root(self) -> str:
        """Name of the root sensor."""
        return self.names[self.hierarchy.root]

    @property
    def parent_of(self) -> dict[str, str]:
        """``{child: parent}`` by name."""
        return {j.child: j.parent for j in self.joints}

    def joint_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(joint_in_parent, joint_in_child)``, each ``(N, 3)`` indexed by the child sensor.

        The row of the root is zero. This is the layout
        :func:`calibration.replay.remove_residual` takes.
        """
        return joint_arrays(
            self.names,
            [j.child for j in self.joints],
            np.array([j.fit.joint_in_parent for j in self.joints]).reshape(-1, 3),
            np.array([j.fit.joint_in_child for j in self.joints]).reshape(-1, 3),
        )


def calibrate(
    R_w_s: Any,
    p_w_s: Any,
    names: Sequence[str],
    *,
    valid: Any = None,
    parent_of: Mapping[str, str] | None = None,
    root: str | None = None,
    hierarchy_method: str = HIERARCHY_METHODS[0],
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
    loop_factor: float = LOOP_FACTOR,
    chunk_frames: int = CHUNK_FRAMES,
    keep_frame_residuals: bool | None = None,
    robust: str | None = None,
    intervals: bool = False,
    correct_rotation_noise: bool = False,
    drop_noisy_frames: bool = False,
) -> Calibration:
    """Estimate joints, hierarchy, limb lengths and sensor placement from sensor poses.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world; an ndarray or anything
            sliceable along frames (h5py dataset, memory map).
        p_w_s: ``(frames, sensors, 3)`` sensor positions in world, metres.
        names: ``sensors`` unique sensor names.
        valid: optional ``(frames, sensors)`` bool, False where a pose is missing; non-finite
            poses are always treated as missing. Each pair uses the frames where both of its
            sensors are valid.
        parent_of: a known hierarchy ``{child: parent}``; inferred when ``None``.
        root: root sensor name; with no hierarchy given, chosen by the rule of
            :mod:`calibration.hierarchy` when ``None``.
        hierarchy_method: with no hierarchy given, the edge weights of the spanning tree:
            ``"misfit"`` (residual less its noise) or ``"mst"`` (O'Brien's residual); see
            :mod:`calibration.hierarchy`.
        single_axis_ratio: see :mod:`calibration.joint`.
        loop_factor: see :func:`calibration.hierarchy.loop_candidates`.
        chunk_frames: frames per chunk.
        keep_frame_residuals: compute each joint's per-frame residual exactly in a second pass
            over the data and keep it (``frames x joints`` floats). When False there is no
            second pass: the rms residual comes from the normal equations, or for a joint at
            their rounding floor (noise-free data) from a pass over its two sensors; either way
            within 1e-9 m of the exact value (:func:`calibration.pairs.rms_needs_data`). ``None``
            (the default): kept, unless the poses are out of core (not in-memory arrays: an h5py
            dataset, a memory map) and the residuals would take more than
            :data:`FRAME_RESIDUAL_BYTES`, so that a large file is calibrated in memory that does
            not grow with its length.
        robust: ``"tukey"`` or ``"huber"`` (:data:`calibration.robust.LOSSES`) to fit the joints by
            IRLS and infer the hierarchy from robust pair misfits (module docstring); ``None``
            (the default) for least squares.
        intervals: give every joint a covariance with 95 % regions and every limb length a 95 %
            interval (module docstring); for a robust fit they are conditional on its inliers.
        correct_rotation_noise: refit the tree's joints corrected for the rotations' noise
            (module docstring); a joint whose motion is too small for its noise keeps the plain
            fit, with a warning.
        drop_noisy_frames: leave out each sensor's frames whose position noise drowns its
            others (:mod:`calibration.frame_noise`: a magnetic tracker far from its
            transmitter), with a warning; False keeps every valid frame.

    Raises:
        CalibrationInputError: malformed arrays or options.
        CalibrationError: the data cannot be calibrated (fewer than 3 frames, one sensor,
            sensors that share no usable frames); with ``correct_rotation_noise``, a sensor whose
            rotations give no noise level (too few consecutive frames, or not a time series).
    """
    t0 = time.perf_counter()
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    check_rotations(R_w_s, valid)
    names = checked_names(names, n)
    if keep_frame_residuals is None:
        keep_frame_residuals = default_keep_frame_residuals(R_w_s, n_frames, n - 1)
    _check_options(names, n_frames, single_axis_ratio=single_axis_ratio, root=root)
    if hierarchy_method not in HIERARCHY_METHODS:
        raise CalibrationInputError(
            f"hierarchy_method must be one of {list(HIERARCHY_METHODS)}, got {hierarchy_method!r}"
        )
    if robust is not None and robust not in LOSSES:
        raise CalibrationInputError(f"robust must be None or one of {list(LOSSES)}, got {robust!r}")
    if robust is not None and correct_rotation_noise:
        raise CalibrationInputError(
            "robust and correct_rotation_noise cannot be combined: the correction is for least squares"
        )
    noisy = None
    if drop_noisy_frames:
        base = np.ones((n_frames, n), dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
        noisy = noisy_frames(p_w_s, base, chunk_frames)
        if noisy.mask.any():
            valid = base & ~noisy.mask
        else:
            noisy = None
    # the third differences always: the single-axis verdict's effect size (calibration.hinge)
    # and the motion warnings' bias bound need the residuals' white noise, the misfit tree too
    stats, missing = _pair_statistics(
        R_w_s, p_w_s, valid=valid, chunk_frames=chunk_frames, third_differences=True
    )
    if noisy is not None:  # a pose left out for its noise is not missing
        missing = missing - noisy.mask.sum(axis=0)
    t1 = time.perf_counter()

    every_pair = solve_pairs(stats, *np.triu_indices(n, k=1), single_axis_ratio=single_axis_ratio)
    residual = pair_residual_matrix(stats, single_axis_ratio=single_axis_ratio, solutions=every_pair)
    if parent_of is not None:
        tree = hierarchy_from_parents(parent_of, names, root=root)
    elif robust is not None:
        misfits = robust_pair_misfits(
            R_w_s, p_w_s, valid=valid, loss=robust, single_axis_ratio=single_axis_ratio
        )
        if not np.isfinite(misfits.residual[np.triu_indices(n, k=1)]).any():
            raise CalibrationError(
                f"a robust fit ({robust}) needs at least {ROBUST_MIN_FRAMES} frames where both poses of "
                "a pair are valid; no pair of sensors has them"
            )
        weights = misfits.weights(hierarchy_method)
        tree = spanning_tree(weights, root=None if root is None else names.index(root), names=names)
    else:
        weights = residual
        if hierarchy_method == "misfit":
            noise = _pair_noise_matrix(R_w_s, p_w_s, valid, stats, every_pair, chunk_frames)
            weights = misfit_weights(residual, noise)
        tree = spanning_tree(weights, root=None if root is None else names.index(root), names=names)
    t2 = time.perf_counter()

    sol, rms, per_frame = _solve_joints(
        R_w_s, p_w_s, valid, stats, tree, names, single_axis_ratio, chunk_frames, keep_frame_residuals
    )
    t3 = time.perf_counter()

    pairs = tree.joints
    joints = [
        solved_joint(names, sol, k, rms, per_frame, n_frames, single_axis_ratio) for k in range(len(pairs))
    ]
    refine_s = 0.0
    refit = robust is not None or correct_rotation_noise
    noise: dict[str, float] = {}
    refit_warnings: list[str] = []
    if refit or intervals:
        t_refine = time.perf_counter()
        if correct_rotation_noise:
            noise = _rotation_noise(R_w_s, valid, names, {s for pair in pairs for s in pair})
        joints = [
            _refined_joint(
                R_w_s,
                p_w_s,
                valid,
                joint,
                names,
                robust=robust,
                intervals=intervals,
                keep_frame_residuals=keep_frame_residuals,
                single_axis_ratio=single_axis_ratio,
                noise=(noise[joint.parent], noise[joint.child]) if noise else None,
                warnings=refit_warnings,
            )
            for joint in joints
        ]
        refine_s = time.perf_counter() - t_refine
    loops = tuple(
        (names[a], names[b], r) for a, b, r in loop_candidates(residual, tree, loop_factor=loop_factor)
    )
    warnings = fit_warnings(joints, names, missing, loops, n_frames, noisy=noisy is not None) + refit_warnings
    if noisy is not None:
        warnings += noisy.warnings(names)
    par = np.array([p for p, _ in pairs], dtype=np.int64)
    chi = np.array([c for _, c in pairs], dtype=np.int64)
    white = joint_white_variance(stats, par, chi, joints)
    warnings += _diagnostic_warnings(R_w_s, p_w_s, valid, stats, names, pairs, joints, chunk_frames, white)
    if intervals:  # the bias bound beside the variance-based regions
        bound, _ = motion_bias_bounds([j.fit for j in joints], white)
        joints = [
            j
            if j.uncertainty is None
            else dataclasses.replace(j, uncertainty=dataclasses.replace(j.uncertainty, bias_bound_m=float(b)))
            for j, b in zip(joints, bound, strict=True)
        ]
    lp, lc = sol.joint_in_parent, sol.joint_in_child  # (J, 3) in the order of the tree's joints
    if refit:
        lp = np.array([j.fit.joint_in_parent for j in joints]).reshape(-1, 3)
        lc = np.array([j.fit.joint_in_child for j in joints]).reshape(-1, 3)
    lengths = tuple(segment_lengths(names, pairs, lp, lc))
    length_unc = _length_uncertainties(lengths, joints) if intervals else ()
    t4 = time.perf_counter()
    seconds = {"pair_statistics": t1 - t0, "hierarchy": t2 - t1, "joints": t3 - t2, "skeleton": t4 - t3}
    if refit or intervals:  # the refits and intervals, out of the skeleton's time
        seconds["skeleton"] -= refine_s
        seconds["refits_and_intervals"] = refine_s
    seconds["total"] = t4 - t0
    return Calibration(
        names=names,
        hierarchy=tree,
        hierarchy_given=parent_of is not None,
        joints=tuple(joints),
        residual_matrix=residual,
        loop_candidates=loops,
        lengths=lengths,
        placements=tuple(sensor_placements(names, pairs, lp, lc)),
        warnings=tuple(warnings),
        n_frames=n_frames,
        missing=missing,
        seconds=seconds,
        hierarchy_method=hierarchy_method,
        robust=robust,
        length_uncertainty=length_unc,
        rotation_noise_rad2=noise or None,
        noisy_frames=None if noisy is None else noisy.mask,
    )


def checked_names(names: Sequence[str], n: int) -> tuple[str, ...]:
    """``names`` as a tuple of ``n`` unique strings, or an input error (shared with
    :mod:`calibration.streaming`)."""
    names = tuple(str(x) for x in names)
    if len(names) != n:
        raise CalibrationInputError(f"Expected {n} sensor names, got {len(names)}")
    if len(set(names)) != n:
        dup = sorted({x for x in names if names.count(x) > 1})
        raise CalibrationInputError(f"sensor names must be unique, repeated: {dup}")
    return names


def _check_options(
    names: tuple[str, ...], n_frames: int, *, single_axis_ratio: float, root: str | None
) -> None:
    """Refuse data too small to calibrate and options out of range."""
    if len(names) < 2:
        raise CalibrationError(f"calibration needs at least 2 sensors, got {len(names)} ({list(names)})")
    if n_frames < MIN_FRAMES:
        raise CalibrationError(f"calibration needs at least {MIN_FRAMES} frames, got {n_frames}")
    if not 0.0 < single_axis_ratio < 1.0:
        raise CalibrationInputError(f"single_axis_ratio must be in (0, 1), got {single_axis_ratio}")
    if root is not None and root not in names:
        raise CalibrationInputError(f"root {root!r} is not a sensor; sensors are {list(names)}")


def _pair_statistics(
    R_w_s: Any, p_w_s: Any, *, valid: Any, chunk_frames: int, third_differences: bool
) -> tuple[PairStatistics, np.ndarray]:
    """The statistics of every pair (with the jackknife's blocks, and the third differences when
    asked for: all in one pass over the data) and the ``(N,)`` frames each sensor's pose is
    missing in.

    Raises:
        CalibrationError: no pair of sensors shares :data:`MIN_FRAMES` valid frames.
    """
    stats = pair_statistics(
        R_w_s,
        p_w_s,
        valid=valid,
        chunk_frames=chunk_frames,
        jackknife_blocks=JACKKNIFE_BLOCKS,
        third_differences=third_differences,
    )
    per_sensor = np.diagonal(stats.count)
    missing = stats.n_frames - per_sensor.astype(np.int64)
    if np.max(stats.count - np.diag(per_sensor)) < MIN_FRAMES:
        raise CalibrationError(
            f"no pair of sensors has {MIN_FRAMES} frames where both poses are valid "
            f"(frames: {stats.n_frames}, most valid frames of one sensor: {int(np.max(per_sensor))})"
        )
    return stats, missing


def _pair_noise_matrix(  # positional: one private caller
    R_w_s: Any, p_w_s: Any, valid: Any, stats: PairStatistics, every_pair: PairSolutions, chunk_frames: int
) -> np.ndarray:
    """``(N, N)`` noise variance of every pair's residual (:mod:`calibration.pair_noise`), square
    metres, at each pair's joint solved from the statistics (``every_pair``: the pairs of
    ``numpy.triu_indices(N, k=1)``): a quadratic form in the joint from the statistics' third
    differences when they were kept, else one more pass over the data."""
    n = stats.n_sensors
    i, j = every_pair.parent, every_pair.child
    lp, lc = every_pair.joint_in_parent, every_pair.joint_in_child
    if stats.third_differences is not None:
        nu = stats.third_differences.noise_variance(i, j, lp, lc)
    else:
        nu = pair_noise_variance(R_w_s, p_w_s, i, j, lp, lc, valid=valid, chunk_frames=chunk_frames)
    out = np.zeros((n, n))
    out[i, j] = nu
    out[j, i] = nu
    return out


def _solve_joints(  # positional: one private caller, whose call then fits on a line
    R_w_s: Any,
    p_w_s: Any,
    valid: Any,
    stats: PairStatistics,
    tree: Hierarchy,
    names: tuple[str, ...],
    single_axis_ratio: float,
    chunk_frames: int,
    keep_frame_residuals: bool,
) -> tuple[PairSolutions, np.ndarray, np.ndarray | None]:
    """Solve the tree's joints; their ``(J,)`` rms residuals and ``(frames, J)`` per-frame
    residuals (exact, from a second pass over the data, when ``keep_frame_residuals``), metres.

    Raises:
        CalibrationError: a joint's sensors share fewer than :data:`MIN_FRAMES` valid frames.
    """
    pairs = tree.joints
    par = np.array([p for p, _ in pairs], dtype=np.int64)
    chi = np.array([c for _, c in pairs], dtype=np.int64)
    sol = solve_pairs(stats, par, chi, single_axis_ratio=single_axis_ratio)
    too_few = [f"{names[p]}-{names[c]}" for k, (p, c) in enumerate(pairs) if sol.n_frames[k] < MIN_FRAMES]
    if too_few:
        raise CalibrationError(
            f"joints with fewer than {MIN_FRAMES} frames where both sensors are valid: {too_few}"
        )
    if not keep_frame_residuals:
        # from the normal equations where their rounding is far below a nanometre; the others
        # (noise-free joints at the normal equations' floor) exactly, in a pass over the data
        rms = sol.rms_residual.copy()
        exact = rms_needs_data(stats, sol)
        if exact.any():
            k = np.flatnonzero(exact)
            rms[k], _ = frame_residuals(
                R_w_s,
                p_w_s,
                par[k],
                chi[k],
                sol.joint_in_parent[k],
                sol.joint_in_child[k],
                valid=valid,
                chunk_frames=chunk_frames,
                keep_frames=False,
            )
        return sol, rms, None
    rms, per_frame = frame_residuals(
        R_w_s,
        p_w_s,
        par,
        chi,
        sol.joint_in_parent,
        sol.joint_in_child,
        valid=valid,
        chunk_frames=chunk_frames,
    )
    return sol, rms, per_frame


def solved_joint(
    names: tuple[str, ...],
    sol: PairSolutions,
    k: int,
    rms: np.ndarray,
    per_frame: np.ndarray | None,
    n_frames: int,
    single_axis_ratio: float,
) -> Joint:
    """Joint ``k`` of the solved batch, with its spectrum read, its own copies of the small arrays
    and a view of its per-frame residuals (``per_frame`` ``(frames, joints)`` or ``None``);
    ``rms`` ``(joints,)`` metres. Shared with :mod:`calibration.streaming`."""
    spec = pair_fit_spectrum(sol, k, single_axis_ratio)
    fit = JointFit(
        joint_in_parent=sol.joint_in_parent[k].copy(),
        joint_in_child=sol.joint_in_child[k].copy(),
        rms_residual=float(rms[k]),
        # a view: each joint's row of one joint-major array (a copy would double frames x joints)
        frame_residual=None if per_frame is None else per_frame[:, k],
        singular_values=sol.singular_values[k].copy(),
        rank=spec.rank,
        single_axis=spec.single_axis,
        axis_in_parent=spec.axis_in_parent,
        axis_in_child=spec.axis_in_child,
        n_frames=int(sol.n_frames[k]),
        n_dropped=n_frames - int(sol.n_frames[k]),
        weakest_t=float(sol.t_statistic[k, 5]),
    )
    return Joint(names[sol.parent[k]], names[sol.child[k]], fit)


def _pair_arrays(
    R_w_s: Any, p_w_s: Any, valid: Any, parent: int, child: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """``(R_w_p, p_w_p, R_w_c, p_w_c, valid)`` of one pair of sensors, read into memory."""
    arrays = tuple(np.asarray(a[:, k], dtype=float) for k in (parent, child) for a in (R_w_s, p_w_s))
    both = None if valid is None else np.asarray(valid[:, parent], bool) & np.asarray(valid[:, child], bool)
    return (*arrays, both)


def _refined_joint(
    R_w_s: Any,
    p_w_s: Any,
    valid: Any,
    joint: Joint,
    names: tuple[str, ...],
    *,
    robust: str | None,
    intervals: bool,
    keep_frame_residuals: bool,
    single_axis_ratio: float,
    noise: tuple[float, float] | None,
    warnings: list[str],
) -> Joint:
    """The joint refitted robustly (when ``robust``) or corrected for the rotation noise ``noise``
    (``(parent, child)`` variances, rad^2), and given its uncertainty (when ``intervals``); a
    correction that cannot be made leaves the plain fit and adds to ``warnings``."""
    R_w_p, p_w_p, R_w_c, p_w_c, both = _pair_arrays(
        R_w_s, p_w_s, valid, names.index(joint.parent), names.index(joint.child)
    )
    fit, rob, unc = joint.fit, None, None
    if robust is not None:
        rob = robust_fit_joint(
            R_w_p, p_w_p, R_w_c, p_w_c, valid=both, loss=robust, single_axis_ratio=single_axis_ratio
        )
        fit = _robust_joint_fit(rob, joint.fit, keep_frame_residuals)
    elif noise is not None:
        try:
            fit = fit_joint(
                R_w_p,
                p_w_p,
                R_w_c,
                p_w_c,
                valid=both,
                single_axis_ratio=single_axis_ratio,
                orientation_noise_rad2=noise,
            )
        except CalibrationError as err:
            warnings.append(f"{joint.name}: not corrected for rotation noise ({err})")
        else:
            if not keep_frame_residuals:
                fit = dataclasses.replace(fit, frame_residual=None)
    if intervals:
        if rob is None:
            unc = joint_covariance(R_w_p, p_w_p, R_w_c, p_w_c, fit, valid=both)
        else:  # over the inliers: conditional on the inlier set (module docstring)
            unc = joint_covariance(
                R_w_p, p_w_p, R_w_c, p_w_c, _inlier_fit(rob, R_w_p, R_w_c), valid=rob.inlier
            )
    return Joint(joint.parent, joint.child, fit, uncertainty=unc, robust_fit=rob)


def _rotation_noise(R_w_s: Any, valid: Any, names: tuple[str, ...], used: set[int]) -> dict[str, float]:
    """``{name: sigma^2}`` each used sensor's rotation noise, rad^2, read off its own rotations.

    Raises:
        CalibrationError: a sensor's rotations give no noise level (the sensor is named).
    """
    out = {}
    for k in sorted(used):
        mask = None if valid is None else np.asarray(valid[:, k], dtype=bool)
        try:
            out[names[k]] = orientation_noise_variance(np.asarray(R_w_s[:, k], dtype=float), mask)
        except CalibrationError as err:
            raise CalibrationError(
                f"correcting for rotation noise: sensor {names[k]!r}: {err} "
                "(calibrate without the correction)"
            ) from None
    return out


def _robust_joint_fit(rob: RobustJointFit, ls: JointFit, keep_frame_residuals: bool) -> JointFit:
    """The robust fit as a :class:`JointFit`: its centre, rank, axis, residuals (rms over the
    inliers), with the least-squares fit's spectrum and frame counts."""
    return JointFit(
        joint_in_parent=rob.joint_in_parent.copy(),
        joint_in_child=rob.joint_in_child.copy(),
        rms_residual=rob.rms_residual,
        frame_residual=rob.frame_residual if keep_frame_residuals else None,
        singular_values=ls.singular_values.copy(),
        rank=rob.rank,
        single_axis=rob.single_axis,
        axis_in_parent=rob.axis_in_parent,
        axis_in_child=rob.axis_in_child,
        n_frames=ls.n_frames,
        n_dropped=ls.n_dropped,
        weakest_t=ls.weakest_t,
    )


def _inlier_fit(rob: RobustJointFit, R_w_p: np.ndarray, R_w_c: np.ndarray) -> JointFit:
    """The robust centre as a fit of its inlier frames alone (their spectrum and counts), which
    :func:`calibration.uncertainty.joint_covariance` takes with ``valid=rob.inlier``."""
    inl = rob.inlier
    A = np.concatenate([R_w_p[inl], -R_w_c[inl]], axis=2).reshape(-1, 6)  # O'Brien eq. 12
    s = np.linalg.svd(np.linalg.qr(A, mode="r"), compute_uv=False)
    n = int(np.count_nonzero(inl))
    return JointFit(
        joint_in_parent=rob.joint_in_parent,
        joint_in_child=rob.joint_in_child,
        rms_residual=rob.rms_residual,
        frame_residual=None,
        singular_values=s,
        rank=rob.rank,
        single_axis=rob.single_axis,
        axis_in_parent=rob.axis_in_parent,
        axis_in_child=rob.axis_in_child,
        n_frames=n,
        n_dropped=inl.shape[0] - n,
    )


def _length_uncertainties(
    lengths: Sequence[SegmentLength], joints: Sequence[Joint]
) -> tuple[LengthUncertainty | None, ...]:
    """Each limb length's interval from its two joints' uncertainties (``None`` where one lacks it)."""
    by_name = {j.name: j for j in joints}
    out: list[LengthUncertainty | None] = []
    for x in lengths:
        a, b = by_name[x.joint_a], by_name[x.joint_b]
        if a.uncertainty is None or b.uncertainty is None:
            out.append(None)
            continue
        part_a = "child" if a.child == x.segment else "parent"
        part_b = "child" if b.child == x.segment else "parent"
        try:
            out.append(segment_length_uncertainty(a.uncertainty, part_a, b.uncertainty, part_b))
        except CalibrationInputError:  # the two centres coincide
            out.append(None)
    return tuple(out)


def fit_warnings(
    joints: Sequence[Joint],
    names: tuple[str, ...],
    missing: np.ndarray,
    loops: Sequence[tuple[str, str, float]],
    n_frames: int,
    *,
    noisy: bool = False,
) -> list[str]:
    """Plain-language notes that the joint fits and statistics alone give (no pass over the data;
    the batch and the streaming calibration share them): single-axis joints, dropped frames,
    missing poses, loop joints (joints the motion hardly determines: :func:`_diagnostic_warnings`).

    Args:
        joints: the tree's joints.
        names: ``(N,)`` sensor names.
        missing: ``(N,)`` frames each sensor's pose was missing in.
        loops: ``(sensor a, sensor b, rms residual m)`` pairs left out of the tree that fit as well.
        n_frames: frames in the recording.
        noisy: frames were left out for their noise too (:mod:`calibration.frame_noise`).
    """
    warnings: list[str] = []
    why = "a pose missing or not finite" + (", or left out for its noise" if noisy else "")
    for joint in joints:
        fit = joint.fit
        if fit.single_axis:
            warnings.append(
                f"joint {joint.name}: single-axis in this motion (axis in {joint.parent} frame "
                f"{np.round(fit.axis_in_parent, 3).tolist()}); its location along the axis is the "
                "minimum-norm point, not a measured one"
            )
        if fit.n_dropped:
            warnings.append(f"joint {joint.name}: {fit.n_dropped} of {n_frames} frames dropped ({why})")
    for k in np.flatnonzero(missing):
        warnings.append(f"sensor {names[k]}: pose missing or not finite in {missing[k]} of {n_frames} frames")
    for a, b, r in loops:
        warnings.append(
            f"pair {a}-{b} left out of the hierarchy fits as well as its joints "
            f"(rms {r * 1e3:.3g} mm): a loop joint, or sensors the motion does not tell apart"
        )
    return warnings


def joint_white_variance(
    stats: PairStatistics, parent: np.ndarray, child: np.ndarray, joints: Sequence[Joint]
) -> np.ndarray | None:
    """``(J,)`` the white-noise variance of each joint's residual at its fitted centre, m^2, from
    the statistics' third differences (:mod:`calibration.pair_noise`); ``None`` without them."""
    if stats.third_differences is None or not len(joints):
        return None
    fits = [j.fit for j in joints]
    lp = np.array([f.joint_in_parent for f in fits]).reshape(-1, 3)
    lc = np.array([f.joint_in_child for f in fits]).reshape(-1, 3)
    return stats.third_differences.noise_variance(parent, child, lp, lc)


def _diagnostic_warnings(  # positional: one private caller
    R_w_s: Any,
    p_w_s: Any,
    valid: Any,
    stats: PairStatistics,
    names: tuple[str, ...],
    pairs: Sequence[tuple[int, int]],
    joints: Sequence[Joint],
    chunk_frames: int,
    white: np.ndarray | None,
) -> list[str]:
    """Joints the motion hardly determines, and residuals far above the others'
    (:mod:`calibration.diagnostics`); the sensors' rms distance comes from the statistics,
    ``white`` ``(J,)`` is each joint's residual white-noise variance (m^2) or ``None``."""
    pairs = [(int(p), int(c)) for p, c in pairs]
    count = np.array([stats.count[p, c] for p, c in pairs], dtype=float)
    sq = np.array([stats.sq_dist[p, c] for p, c in pairs], dtype=float)
    separation = np.sqrt(sq / np.maximum(count, 1.0))
    fits = [j.fit for j in joints]
    par, chi = (np.array([x[k] for x in pairs], dtype=np.int64) for k in (0, 1))
    block_sums = None if stats.jackknife_count is None else jackknife_block_sums(stats, par, chi)
    warnings = motion_warnings(
        R_w_s,
        p_w_s,
        names,
        pairs,
        fits,
        separation,
        valid=valid,
        chunk_frames=chunk_frames,
        block_sums=block_sums,
        white_variance=white,
        reported=residual_flagged(np.array([f.rms_residual for f in fits]), separation),
    )
    rms = np.array([f.rms_residual for f in fits])
    return warnings + residual_warnings(names, pairs, rms, separation)
