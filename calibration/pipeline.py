"""The whole calibration: from sensor poses to joints, hierarchy and skeleton.

Steps (O'Brien et al. 2000):

1. one pass over the data accumulates the normal equations of every sensor pair
   (:func:`calibration.pairs.pair_statistics`);
2. every pair's joint fit and residual follow from those (section 3.1);
3. the hierarchy is the minimum spanning tree of the residuals, unless one is given (3.3);
4. the tree's joints are solved with single-axis detection (3.2), and their residuals are
   recomputed exactly from the data in a second pass (unless per-frame residuals are not
   wanted);
5. limb lengths and sensor offsets follow from the joint locations.

Memory is bounded by the chunk size (plus ``frames x joints`` floats when per-frame residuals
are kept), so the input may be an h5py dataset or a memory map larger than memory.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hierarchy import (
    LOOP_FACTOR,
    Hierarchy,
    hierarchy_from_parents,
    loop_candidates,
    spanning_tree,
)
from calibration.joint import MIN_FRAMES, SINGLE_AXIS_RATIO, JointFit
from calibration.pairs import (
    CHUNK_FRAMES,
    check_poses,
    frame_residuals,
    pair_fit_spectrum,
    pair_residual_matrix,
    pair_statistics,
    solve_pairs,
)
from calibration.skeleton import (
    SegmentLength,
    SensorPlacement,
    joint_arrays,
    joint_name,
    segment_lengths,
    sensor_placements,
)


@dataclass(frozen=True)
class Joint:
    """A joint of the calibrated hierarchy.

    Attributes:
        parent: inboard sensor name.
        child: outboard sensor name.
        fit: the joint fit (locations in both sensor frames, residuals, diagnostics).
    """

    parent: str
    child: str
    fit: JointFit

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
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
    loop_factor: float = LOOP_FACTOR,
    chunk_frames: int = CHUNK_FRAMES,
    keep_frame_residuals: bool = True,
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
        single_axis_ratio: see :mod:`calibration.joint`.
        loop_factor: see :func:`calibration.hierarchy.loop_candidates`.
        chunk_frames: frames per chunk.
        keep_frame_residuals: compute each joint's per-frame residual exactly in a second pass
            over the data and keep it (``frames x joints`` floats). When False there is no
            second pass and the rms residual comes from the normal equations (within about
            1e-8 m of the exact value, see :mod:`calibration.pairs`).

    Raises:
        CalibrationInputError: malformed arrays or options.
        CalibrationError: the data cannot be calibrated (fewer than 3 frames, one sensor,
            sensors that share no usable frames).
    """
    t0 = time.perf_counter()
    n_frames, n = check_poses(R_w_s, p_w_s, valid)
    names = tuple(str(x) for x in names)
    if len(names) != n:
        raise CalibrationInputError(f"Expected {n} sensor names, got {len(names)}")
    if len(set(names)) != n:
        dup = sorted({x for x in names if names.count(x) > 1})
        raise CalibrationInputError(f"sensor names must be unique, repeated: {dup}")
    if n < 2:
        raise CalibrationError(f"calibration needs at least 2 sensors, got {n} ({list(names)})")
    if n_frames < MIN_FRAMES:
        raise CalibrationError(f"calibration needs at least {MIN_FRAMES} frames, got {n_frames}")
    if not 0.0 < single_axis_ratio < 1.0:
        raise CalibrationInputError(f"single_axis_ratio must be in (0, 1), got {single_axis_ratio}")
    if root is not None and root not in names:
        raise CalibrationInputError(f"root {root!r} is not a sensor; sensors are {list(names)}")
    seconds: dict[str, float] = {}

    stats = pair_statistics(R_w_s, p_w_s, valid=valid, chunk_frames=chunk_frames)
    missing = n_frames - np.diagonal(stats.count).astype(np.int64)
    usable_frames = int(np.max(np.diagonal(stats.count)))
    if np.max(stats.count - np.diag(np.diagonal(stats.count))) < MIN_FRAMES:
        raise CalibrationError(
            f"no pair of sensors has {MIN_FRAMES} frames where both poses are valid "
            f"(frames: {n_frames}, most valid frames of one sensor: {usable_frames})"
        )
    t1 = time.perf_counter()
    seconds["pair_statistics"] = t1 - t0

    residual = pair_residual_matrix(stats, single_axis_ratio=single_axis_ratio)
    index = {name: k for k, name in enumerate(names)}
    if parent_of is not None:
        tree = hierarchy_from_parents(parent_of, names, root=root)
    else:
        tree = spanning_tree(residual, root=None if root is None else index[root], names=names)
    t2 = time.perf_counter()
    seconds["hierarchy"] = t2 - t1

    pairs = tree.joints
    par = np.array([p for p, _ in pairs], dtype=np.int64)
    chi = np.array([c for _, c in pairs], dtype=np.int64)
    sol = solve_pairs(stats, par, chi, single_axis_ratio=single_axis_ratio)
    too_few = [f"{names[p]}-{names[c]}" for k, (p, c) in enumerate(pairs) if sol.n_frames[k] < MIN_FRAMES]
    if too_few:
        raise CalibrationError(
            f"joints with fewer than {MIN_FRAMES} frames where both sensors are valid: {too_few}"
        )
    if keep_frame_residuals:
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
    else:
        rms, per_frame = sol.rms_residual, None
    t3 = time.perf_counter()
    seconds["joints"] = t3 - t2

    joints = []
    warnings: list[str] = []
    for k, (p, c) in enumerate(pairs):
        spec = pair_fit_spectrum(sol, k, single_axis_ratio)
        fit = JointFit(
            joint_in_parent=sol.joint_in_parent[k].copy(),
            joint_in_child=sol.joint_in_child[k].copy(),
            rms_residual=float(rms[k]),
            frame_residual=None if per_frame is None else per_frame[:, k].copy(),
            singular_values=sol.singular_values[k].copy(),
            rank=spec.rank,
            single_axis=spec.single_axis,
            axis_in_parent=spec.axis_in_parent,
            axis_in_child=spec.axis_in_child,
            n_frames=int(sol.n_frames[k]),
            n_dropped=n_frames - int(sol.n_frames[k]),
        )
        joint = Joint(names[p], names[c], fit)
        joints.append(joint)
        if fit.single_axis:
            warnings.append(
                f"joint {joint.name}: single-axis in this motion (axis in {names[p]} frame "
                f"{np.round(fit.axis_in_parent, 3).tolist()}); its location along the axis is the "
                "minimum-norm point, not a measured one"
            )
        elif fit.rank < 5:
            warnings.append(
                f"joint {joint.name}: the sensors hardly rotate relative to each other "
                f"(rank {fit.rank} of 6); the motion does not determine this joint"
            )
        if fit.n_dropped:
            warnings.append(
                f"joint {joint.name}: {fit.n_dropped} of {n_frames} frames dropped "
                "(a pose missing or not finite)"
            )
    for k in np.flatnonzero(missing):
        warnings.append(f"sensor {names[k]}: pose missing or not finite in {missing[k]} of {n_frames} frames")
    loops = tuple(
        (names[a], names[b], r) for a, b, r in loop_candidates(residual, tree, loop_factor=loop_factor)
    )
    for a, b, r in loops:
        warnings.append(
            f"pair {a}-{b} left out of the hierarchy fits as well as its joints "
            f"(rms {r * 1e3:.3g} mm): a loop joint, or sensors the motion does not tell apart"
        )
    lp = np.array([j.fit.joint_in_parent for j in joints]).reshape(-1, 3)
    lc = np.array([j.fit.joint_in_child for j in joints]).reshape(-1, 3)
    t4 = time.perf_counter()
    seconds["skeleton"] = t4 - t3
    seconds["total"] = t4 - t0
    return Calibration(
        names=names,
        hierarchy=tree,
        hierarchy_given=parent_of is not None,
        joints=tuple(joints),
        residual_matrix=residual,
        loop_candidates=loops,
        lengths=tuple(segment_lengths(names, pairs, lp, lc)),
        placements=tuple(sensor_placements(names, pairs, lp, lc)),
        warnings=tuple(warnings),
        n_frames=n_frames,
        missing=missing,
        seconds=seconds,
    )
