"""Rigid marker clusters: their poses from optical markers, and finding them automatically.

An optical system sees markers, not sensors. Three or more markers rigidly fixed to one segment
(a cluster) give that segment's pose at every frame by a least-squares rigid fit of the
cluster's reference shape onto the markers seen (Soderkvist and Wedin 1993; Kabsch 1976):
``min_R,t sum_k |R r_k + t - x_k|^2`` over the visible markers, solved by the SVD of the
centred cross-covariance with the reflection guard. The fit's rms residual measures how rigid the
cluster really is (skin moves markers against each other). Frames with fewer than three visible
markers of a cluster give no pose (marked missing, never interpolated).

:func:`find_clusters` finds clusters without a specification, from how steady each pair's distance
stays (its standard deviation over frames) with cuts at the largest gaps of a hierarchical tree
(no tolerance in metres), and sets apart groups that are steady only because they barely move.
Each group the cut gives is then tested for being one rigid body (:func:`rigid_parts`): a union of
two parts is kept only if fitting it as one body misfits the markers no more than the parts' own
misfit allows (an F test at a stated false-alarm rate), so two segments whose distances happen to
be as steady as a segment's own (a segment that lost a marker) are not merged. Where the parts are
too small for that test to tell, a cluster whose two main branches misfit as one far more than the
same union in subsets of the recording's other clusters is said to be doubtful
(:func:`doubtful_unions`): kept, and named.
Markers seen too little to judge (never, or with no other marker in :data:`MIN_FRAMES` frames)
are left out before the tree is built: they say nothing about rigidity.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import squareform

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.quantiles import f_ppf, mad_std, norm_ppf

#: Fewest frames in which two markers are seen together for their distance's spread to be judged
#: (a standard deviation of fewer than three samples says nothing about how steady it is).
MIN_FRAMES = 3

#: False-alarm rate of the rigidity test (:func:`rigid_parts`): two parts are split when the median
#: frame's misfit ratio is beyond what one rigid body with independent marker noise exceeds in one
#: frame in a thousand.
RIGID_FALSE_ALARM = 1e-3

#: False-alarm rate of the check of a cluster's top union against the recording's own clusters
#: (:func:`doubtful_unions`), per cluster judged.
DOUBT_FALSE_ALARM = 1e-3

#: Subsets of the other clusters drawn for that check, at most; fewer than :data:`DOUBT_MIN_NULL`
#: with a top union of the same sizes leave the cluster unjudged.
DOUBT_SUBSETS = 100
DOUBT_MIN_NULL = 20

#: Smallest cluster that check judges: a cluster of three splits into one marker and a pair,
#: whose misfit leaves one degree of freedom for the noise; the ratio's spread is then too wide
#: to tell anything.
DOUBT_MIN_SIZE = 4

#: Frames (evenly spaced) that check's misfit ratios are taken over, at most.
DOUBT_FRAMES = 200


@dataclass(frozen=True)
class ClusterFit:
    """Poses of one cluster over time.

    Attributes:
        R_w_c: ``(F, 3, 3)`` cluster frame to world (NaN where missing).
        p_w_c: ``(F, 3)`` cluster origin (the reference shape's centroid) in world, m.
        valid: ``(F,)`` a pose was fitted (at least 3 markers seen).
        rms_residual: ``(F,)`` rms distance of the visible markers from the fitted shape, m.
        reference: ``(K, 3)`` the cluster's shape in its own frame, m.
    """

    R_w_c: np.ndarray
    p_w_c: np.ndarray
    valid: np.ndarray
    rms_residual: np.ndarray
    reference: np.ndarray


def rigid_fit(reference: np.ndarray, markers: np.ndarray, visible: np.ndarray | None = None) -> ClusterFit:
    """Least-squares rigid fit of a reference shape to markers at every frame (vectorised).

    Args:
        reference: ``(K, 3)`` marker positions in the cluster frame, m (K >= 3).
        markers: ``(F, K, 3)`` measured marker positions in world, m (NaN where not seen).
        visible: optional ``(F, K)`` bool; markers with NaN are never visible.
    """
    ref = np.asarray(reference, dtype=float)
    x = np.asarray(markers, dtype=float)
    if ref.ndim != 2 or ref.shape[1] != 3 or ref.shape[0] < 3:
        raise CalibrationInputError(f"Expected a reference shape of shape (K >= 3, 3), got {ref.shape}")
    if x.ndim != 3 or x.shape[1:] != ref.shape:
        raise CalibrationInputError(f"Expected markers of shape (frames, {ref.shape[0]}, 3), got {x.shape}")
    w = np.isfinite(x).all(axis=2)
    if visible is not None:
        w &= np.asarray(visible, dtype=bool)
    n = w.sum(axis=1)
    ok = n >= 3
    wf = w.astype(float)[..., None]
    xz = np.where(w[..., None], x, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (xz * wf).sum(axis=1) / n[:, None]
        cr = (ref[None] * wf).sum(axis=1) / n[:, None]
    dx = (xz - cx[:, None]) * wf
    dr = (ref[None] - cr[:, None]) * wf
    H = np.einsum("fki,fkj->fij", dr, dx)  # reference -> world cross-covariance
    H = np.where(ok[:, None, None], H, np.eye(3))
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    D = np.ones((len(x), 3))
    D[:, 2] = d
    R = np.swapaxes(Vt, -1, -2) @ (D[:, :, None] * np.swapaxes(U, -1, -2))
    t = cx - np.einsum("fij,fj->fi", R, cr)
    fitted = np.einsum("fij,kj->fki", R, ref) + t[:, None]
    err = np.where(w, np.linalg.norm(fitted - xz, axis=2), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt((err**2).sum(axis=1) / n)
    # express the pose about the reference centroid: origin at the shape's centroid
    origin = ref.mean(axis=0)
    p = t + np.einsum("fij,j->fi", R, origin)
    R[~ok] = np.nan
    p[~ok] = np.nan
    rms[~ok] = np.nan
    return ClusterFit(R, p, ok, rms, ref - origin)


def reference_shape(markers: np.ndarray, iterations: int = 3) -> np.ndarray:
    """A cluster's shape in its own frame: generalised Procrustes over the complete frames.

    Args:
        markers: ``(F, K, 3)`` marker positions in world, m (NaN where not seen).

    Raises:
        CalibrationError: when no frame shows every marker of the cluster.
    """
    x = np.asarray(markers, dtype=float)
    full = np.isfinite(x).all(axis=(1, 2))
    if not full.any():
        raise CalibrationError("no frame shows every marker of the cluster: cannot define its shape")
    shape = x[np.flatnonzero(full)[0]] - x[np.flatnonzero(full)[0]].mean(axis=0)
    for _ in range(iterations):
        fit = rigid_fit(shape, x[full])
        local = np.einsum(
            "fji,fkj->fki", fit.R_w_c, x[full] - fit.p_w_c[:, None]
        )  # back to the cluster frame
        shape = np.mean(local, axis=0)
        shape -= shape.mean(axis=0)
    return shape


@dataclass(frozen=True)
class MarkerGroups:
    """Markers grouped automatically (:func:`find_clusters`).

    Attributes:
        clusters: marker index lists of the moving rigid clusters, each sorted, largest first.
        still: marker index lists of groups whose distances are steady but which rotate less than
            the still limit: rigidity not proven by motion (the body at rest, lab markers).
        left_out: ``{marker index: reason}`` for markers in no cluster and no still group.
        unseen: the markers of ``left_out`` seen too little to judge (:func:`unjudged_markers`),
            set aside before the cuts, sorted.
        residual_m: median rigidity residual of each cluster, then each still group, m.
        rotation_deg: 95th-percentile rotation from the mean orientation, same order, degrees.
        cut_m: ``(still/moving cut, cluster cut)`` on the distance spread, m.
        splits: ``(part, other part, F, limit)`` for each union the rigidity test refused
            (:func:`rigid_parts`): marker index lists, the median frame's misfit ratio and the
            F quantile it exceeded.
        doubtful: ``(part, other part, F, z, n)`` for each cluster that may be two bodies: its top
            union misfits far more than the same union in ``n`` subsets of the recording's other
            clusters (:func:`doubtful_unions`); kept as one cluster, and said.
    """

    clusters: list[list[int]]
    still: list[list[int]]
    left_out: dict[int, str]
    unseen: list[int]
    residual_m: list[float]
    rotation_deg: list[float]
    cut_m: tuple[float, float]
    splits: list[tuple[list[int], list[int], float, float]] = field(default_factory=list)
    doubtful: list[tuple[list[int], list[int], float, float, int]] = field(default_factory=list)


def distance_spread(markers: np.ndarray) -> np.ndarray:
    """``(M, M)`` standard deviation over frames of every pair's distance, m.

    ``inf`` for a pair seen together in fewer than :data:`MIN_FRAMES` frames. Each pair's
    distances are taken from their value in the first frame that shows both before the spread is
    computed, so a distance that never changes has a spread of exactly 0, not the rounding of
    its mean (whose differences of 1e-17 m would otherwise be the gaps the tree is cut at).
    """
    x = np.asarray(markers, dtype=float)
    d = np.linalg.norm(x[:, :, None] - x[:, None, :], axis=3)  # (F, M, M)
    first = np.argmax(np.isfinite(d), axis=0)  # (M, M) first frame showing both (0 if none)
    d -= np.take_along_axis(d, first[None], axis=0)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pairs
        spread = np.nanstd(d, axis=0)
    seen = np.isfinite(d).sum(axis=0)
    spread = np.where(seen >= MIN_FRAMES, spread, np.inf)
    np.fill_diagonal(spread, 0.0)
    return spread


def _spread_tree(spread: np.ndarray, members: np.ndarray) -> np.ndarray:
    """The complete-linkage tree (scipy's ``Z``) of ``members`` (two or more) on the distance
    spread. A pair never seen together (``inf``) counts as unsteady as the least steady pair
    seen: it is joined no earlier than every measured pair, yet makes no gap of its own (a larger
    stand-in would become the largest gap and cut the tree at the unseen pair instead of at the
    motion)."""
    sub = spread[np.ix_(members, members)]
    finite = np.isfinite(sub)
    top = sub[finite].max() if finite.any() else 1.0
    return linkage(squareform(np.where(finite, sub, top), checks=False), method="complete")


def _tree_nodes(Z: np.ndarray, members: np.ndarray) -> list[np.ndarray]:
    """Every node of the tree ``Z`` over ``members``, in scipy's numbering: the leaves, then each
    row's union of its two nodes (sorted marker indices)."""
    nodes: list[np.ndarray] = [members[[i]] for i in range(len(members))]
    for left, right, _, _ in Z:
        nodes.append(np.sort(np.concatenate([nodes[int(left)], nodes[int(right)]])))
    return nodes


def _largest_gap_groups(spread: np.ndarray, members: np.ndarray) -> tuple[list[np.ndarray], float]:
    """The spread's tree (:func:`_spread_tree`) cut at its largest ratio gap (unit-free)."""
    if len(members) < 2:
        return [members], np.inf
    Z = _spread_tree(spread, members)
    h = np.maximum(Z[:, 2], np.finfo(float).tiny)
    if len(h) < 2:
        return [members], np.inf
    k = int(np.argmax(h[1:] / h[:-1]))
    cut = float(np.sqrt(h[k] * h[k + 1]))
    labels = fcluster(Z, cut, criterion="distance")
    return [members[labels == v] for v in np.unique(labels)], cut


def _pose_dof(n: int) -> int:
    """Degrees of freedom of the pose of ``n`` markers (one point: 3; two: 5, no roll; more: 6)."""
    return 3 if n == 1 else 5 if n == 2 else 6


def _misfit(markers: np.ndarray) -> np.ndarray:
    """``(F,)`` sum of squared distances of the markers from their best rigid fit, each frame.

    Args:
        markers: ``(F, K, 3)`` marker positions seen in every frame, any length unit.

    One marker fits exactly; two fit all but their distance's change from its mean
    (``(d - mean d)^2 / 2``); three or more: the rigid fit of their reference shape.
    """
    k = markers.shape[1]
    if k == 1:
        return np.zeros(len(markers))
    if k == 2:
        d = np.linalg.norm(markers[:, 0] - markers[:, 1], axis=1)
        return (d - d.mean()) ** 2 / 2.0
    fit = rigid_fit(reference_shape(markers), markers)
    return fit.rms_residual**2 * k


def union_misfit_ratio(
    markers: np.ndarray, a: np.ndarray, b: np.ndarray, *, false_alarm: float = RIGID_FALSE_ALARM
) -> tuple[float, float] | None:
    """How much worse markers ``a`` and ``b`` fit as one rigid body than as two: ``(F, limit)``.

    In each frame that shows them all, the misfit added by fitting the union as one body, per
    degree of freedom given up, over the parts' own misfit per degree of freedom left:
    ``F = ((S_ab - S_a - S_b) / d1) / ((S_a + S_b) / d2)``, ``d1 = p_a + p_b - p_ab`` and
    ``d2 = 3 n_a - p_a + 3 n_b - p_b`` (``p`` the pose's degrees of freedom, :func:`_pose_dof`).
    For one rigid body with independent, equal, isotropic marker noise each frame's ``F`` follows
    F(d1, d2); skin noise is neither, so the test is on the median frame, against the quantile one
    body's frame exceeds with probability ``false_alarm``: a ratio of squared lengths, the same in
    any unit, with the noise scale taken from the parts themselves.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        a, b: marker indices of the two parts (disjoint).
        false_alarm: probability that one rigid body's frame exceeds the limit.

    Returns:
        ``(median F, limit)``, or ``None`` when it cannot be judged: fewer than
        :data:`MIN_FRAMES` frames show every marker, no degree of freedom is left in the parts
        (two single markers) or none is given up, or the union has no frame to define its shape.
    """
    both = np.concatenate([a, b])
    x = np.asarray(markers, dtype=float)[:, both]
    x = x[np.isfinite(x).all(axis=(1, 2))]
    n_a, n_b = len(a), len(b)
    d1 = _pose_dof(n_a) + _pose_dof(n_b) - _pose_dof(n_a + n_b)
    d2 = 3 * n_a - _pose_dof(n_a) + 3 * n_b - _pose_dof(n_b)
    if len(x) < MIN_FRAMES or d1 < 1 or d2 < 1:
        return None
    try:
        whole = _misfit(x)
        parts = _misfit(x[:, :n_a]) + _misfit(x[:, n_a:])
    except CalibrationError:
        return None
    # positions exact to rounding misfit by ~1e-16 of their size: not noise to scale the test by
    floor = (1e3 * np.finfo(float).eps * np.abs(x).max()) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        f = ((whole - parts) / d1) / np.maximum(parts / d2, floor)
    return float(np.nanmedian(f)), float(f_ppf(1.0 - false_alarm, d1, d2))


def rigid_parts(
    markers: np.ndarray, spread: np.ndarray, members: np.ndarray, *, false_alarm: float = RIGID_FALSE_ALARM
) -> tuple[list[np.ndarray], list[tuple[list[int], list[int], float, float]]]:
    """A group split into the largest parts that each move as one rigid body.

    The group's complete-linkage tree on the distance spread is walked from its leaves up: two
    branches are joined only when each is one body and :func:`union_misfit_ratio` finds their
    union no worse a rigid body than the two apart (median frame's F below its ``false_alarm``
    quantile; a union that cannot be judged is joined, as the distances alone joined it). The
    branches refused are the parts: a segment that lost markers is not merged into the next one
    because the distances between them are as steady as its own.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        spread: ``(M, M)`` distance spread (:func:`distance_spread`).
        members: marker indices of the group, sorted.
        false_alarm: the rigidity test's false-alarm rate per frame.

    Returns:
        The parts (sorted index arrays, in the tree's order) and, for each union refused,
        ``(part, other part, median F, limit)``.
    """
    if len(members) < 2:
        return [members], []
    Z = _spread_tree(spread, members)
    m = len(members)
    nodes = _tree_nodes(Z, members)
    whole: list[bool] = [True] * m  # each node one rigid body
    splits = []
    for left, right, _, _ in Z:
        i, j = int(left), int(right)
        a, b = nodes[i], nodes[j]
        ok = whole[i] and whole[j]
        if ok:
            test = union_misfit_ratio(markers, a, b, false_alarm=false_alarm)
            if test is not None and not test[0] <= test[1]:
                ok = False
                splits.append(([int(k) for k in a], [int(k) for k in b], *test))
        whole.append(ok)
    # the parts: the rigid nodes whose parent is not (or the root, if rigid)
    parent = np.full(len(nodes), -1)
    for row, (left, right, _, _) in enumerate(Z):
        parent[int(left)] = parent[int(right)] = m + row
    parts = [nodes[n] for n in range(len(nodes)) if whole[n] and (parent[n] < 0 or not whole[parent[n]])]
    return parts, splits


def _top_union(spread: np.ndarray, members: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two branches joined last in the spread tree of ``members`` (two or more)."""
    Z = _spread_tree(spread, members)
    nodes = _tree_nodes(Z, members)
    return nodes[int(Z[-1, 0])], nodes[int(Z[-1, 1])]


def _subsets(bodies: list[np.ndarray], size: int, most: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Up to ``most`` distinct subsets of ``size`` markers, each within one of ``bodies``, drawn
    evenly over all of them (all when there are no more)."""
    counts = np.array([math.comb(len(g), size) for g in bodies], dtype=float)
    if counts.sum() <= most:
        return [np.array(c) for g in bodies for c in itertools.combinations(sorted(g.tolist()), size)]
    seen: set[tuple[int, ...]] = set()
    out = []
    while len(out) < most:
        g = bodies[int(rng.choice(len(bodies), p=counts / counts.sum()))]
        key = tuple(sorted(rng.choice(g, size, replace=False).tolist()))
        if key not in seen:
            seen.add(key)
            out.append(np.array(key))
    return out


def doubtful_unions(
    markers: np.ndarray,
    spread: np.ndarray,
    clusters: list[np.ndarray],
    *,
    false_alarm: float = DOUBT_FALSE_ALARM,
    subsets: int = DOUBT_SUBSETS,
    frames: int = DOUBT_FRAMES,
    seed: int = 0,
) -> list[tuple[list[int], list[int], float, float, int]]:
    """Clusters that may be two bodies: each one's top union judged against the same union in the
    recording's other clusters.

    The rigidity test (:func:`rigid_parts`) takes its noise from the two parts alone, and with few
    markers in them (a segment that lost markers) its limit is so high that two segments pass as
    one. Here the reference is the recording itself, its skin motion and noise included. A part
    of another segment joins a cluster last, its distances to the rest being the least steady, so
    the union judged is the cluster's top union: its spread tree's two main branches
    (:func:`_top_union`), by the median frame's misfit ratio F (:func:`union_misfit_ratio`). The
    reference is the same construction on bodies known to be one: ``subsets`` subsets of as many
    markers of the *other* clusters (each subset within one cluster), whose own top union has
    parts of the same sizes -- the top union is the least rigid-looking split by construction,
    so random splits would not do (on simulated chains of 5-8 skin markers per segment, a
    reference of random splits flagged a cluster in 10 of 30 sets grouped right). ``log F`` of
    the reference is taken as normal (median and robust spread,
    :func:`calibration.quantiles.mad_std`); a cluster whose
    ``log F`` lies beyond its ``1 - false_alarm`` quantile, and above every reference value, is
    doubtful. A cluster is not judged with fewer than :data:`DOUBT_MIN_NULL` reference values
    (the others too small or too few), nor below :data:`DOUBT_MIN_SIZE` markers. Unit-free; the
    same ``seed`` gives the same result.

    Measured (``studies/cluster_doubt.py``, 30 seeds): simulated chains with 5-8 skin markers per
    segment, none of the 153 clusters of the whole sets doubtful and 1 of 153 sets with a segment
    cut to 2-3 markers; 94 of 122 planted unions (3 markers of one segment, 2 of the next)
    doubtful. Chains of 3-4 markers (``studies/cluster_finding.py``'s, 140 seeds): none. The real
    hip trial with each of its 73 markers lost, for the whole recording and for its second half
    (``studies/cluster_marker_loss.py``): both unions of two segments doubtful (F 21 against a
    reference median of 7 and a largest value of 10), none of the 131 cases grouped right.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        spread: ``(M, M)`` distance spread (:func:`distance_spread`).
        clusters: the rigid clusters (marker index arrays).
        false_alarm: the rate at which a cluster that is one body like the others is doubtful.
        subsets: subsets of the other clusters drawn per cluster judged, at most.
        frames: frames (evenly spaced) the misfit ratios are taken over, at most.
        seed: seeds the draw of the subsets.

    Returns:
        ``(part, other part, F, z, n)`` per doubtful cluster: ``z`` how many robust standard
        deviations its ``log F`` lies above the reference's median, ``n`` the reference values.
    """
    x = np.asarray(markers, dtype=float)
    x = x[:: max(1, -(-x.shape[0] // frames))]
    rng = np.random.default_rng(seed)
    limit = float(norm_ppf(1.0 - false_alarm))
    out = []
    for k, members in enumerate(clusters):
        members = np.asarray(members)
        others = [np.asarray(g) for j, g in enumerate(clusters) if j != k and len(g) >= len(members)]
        if len(members) < DOUBT_MIN_SIZE or not others:
            continue
        a, b = _top_union(spread, members)
        sizes = sorted((len(a), len(b)))
        alike = [
            ab
            for ab in (_top_union(spread, s) for s in _subsets(others, len(members), subsets, rng))
            if sorted((len(ab[0]), len(ab[1]))) == sizes
        ]
        if len(alike) < DOUBT_MIN_NULL:  # the trees alone tell: no misfit worked out in vain
            continue
        reference = [np.log(t[0]) for t in (union_misfit_ratio(x, *ab) for ab in alike) if t and t[0] > 0]
        test = union_misfit_ratio(x, a, b)
        if len(reference) < DOUBT_MIN_NULL or test is None or not test[0] > 0:
            continue
        scale = mad_std(np.array(reference))
        if not scale > 0:
            continue
        z = (np.log(test[0]) - float(np.median(reference))) / scale
        if z > limit and np.log(test[0]) > max(reference):
            out.append(([int(i) for i in a], [int(i) for i in b], float(test[0]), float(z), len(reference)))
    return out


def unjudged_markers(markers: np.ndarray) -> dict[int, str]:
    """``{marker index: reason}`` for markers seen too little to judge how steady their distances are.

    A marker is judged by its distances to the others, so it needs another marker seen in the
    same frames at least :data:`MIN_FRAMES` times; a marker never seen, or never long enough
    together with another, cannot be placed in any group (nor called moving).

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
    """
    seen = np.isfinite(np.asarray(markers, dtype=float)).all(axis=2)  # (F, M)
    together = seen.T.astype(np.int64) @ seen.astype(np.int64)  # (M, M) frames seen together
    np.fill_diagonal(together, 0)
    best = together.max(axis=1) if seen.shape[1] > 1 else np.zeros(seen.shape[1], dtype=np.int64)
    out = {}
    for k in np.flatnonzero(best < MIN_FRAMES):
        alone = int(seen[:, k].sum())
        out[int(k)] = (
            "not seen in any frame"
            if alone == 0
            else f"seen in {alone} frame(s), together with another marker in at most {int(best[k])}; "
            f"{MIN_FRAMES} needed to judge its distances"
        )
    return out


def _rotation_deg(markers: np.ndarray) -> tuple[float, float]:
    """A group's median rigid-fit residual (m) and 95th-percentile rotation from its mean (deg)."""
    shape = reference_shape(markers)
    fit = rigid_fit(shape, markers)
    R = fit.R_w_c[fit.valid]
    U, _, Vt = np.linalg.svd(R.mean(axis=0))  # chordal mean orientation
    R_mean = U @ Vt
    cos = (np.einsum("ij,fij->f", R_mean, R) - 1.0) / 2.0
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return float(np.nanmedian(fit.rms_residual)), float(np.percentile(angle, 95))


def find_clusters(markers: np.ndarray, *, still_deg: float = 10.0, min_size: int = 3) -> MarkerGroups:
    """Rigid marker clusters found from the steadiness of their distances, relative to motion.

    Two cuts, each at the largest ratio gap of a complete-linkage tree on the pairs' distance
    spread (standard deviation over frames), so no tolerance in metres is needed and the result
    is the same in any unit. The first cut, over all markers, separates groups that move against
    each other; a group of ``min_size`` or more whose rigid fit rotates less than ``still_deg``
    (95th percentile from its mean orientation) is *still*: its distances are steady because it
    barely moves, so its rigidity is not proven (a body at rest, lab markers); it is reported
    apart. The second cut, over the markers of the moving groups only, separates the segments
    (skin spread within a cluster, joint motion between clusters); each group it gives is then
    split into the parts that are each one rigid body (:func:`rigid_parts`), so that a segment
    whose distances to the next are as steady as its own (one that lost a marker) is not merged
    into it: a part too small to be a cluster is left out, named; a cluster that may still be two
    bodies is named in ``doubtful`` (:func:`doubtful_unions`). ``still_deg`` defaults to 10
    degrees: below that a joint centre is not determined (DESIGN.md, facts from real recordings).
    Markers seen too little to judge (:func:`unjudged_markers`) are left out before either cut,
    with the reason, so that a marker never seen does not decide where the tree is cut.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        still_deg: smallest rotation of a group that counts as moving, degrees.
        min_size: smallest cluster.
    """
    x = np.asarray(markers, dtype=float)
    if x.ndim != 3 or x.shape[2] != 3:
        raise CalibrationInputError(f"Expected markers of shape (frames, markers, 3), got {x.shape}")
    spread = distance_spread(x)
    left_out = unjudged_markers(x)
    unseen = sorted(left_out)
    everyone = np.setdiff1d(np.arange(x.shape[1]), list(left_out))
    first, cut1 = _largest_gap_groups(spread, everyone)
    still, stats = [], {}
    for g in first:
        if len(g) < min_size:
            continue
        try:
            stats[tuple(g)] = _rotation_deg(x[:, g])
        except CalibrationError:
            continue
        if stats[tuple(g)][1] < still_deg:
            still.append(g)
    pool = np.setdiff1d(everyone, np.concatenate(still)) if still else everyone
    second, cut2 = _largest_gap_groups(spread, pool) if len(pool) >= 2 * min_size else ([pool], np.inf)
    clusters, splits, split_off = [], [], set()
    rigid = []
    for g in second:
        parts, refused = rigid_parts(x, spread, g) if len(g) >= min_size else ([g], [])
        rigid += parts
        splits += refused
        if len(parts) > 1:
            split_off.update(tuple(p) for p in parts)
    for g in rigid:
        if len(g) < min_size:
            for k in g:
                left_out[int(k)] = (
                    f"moves; its group is not one rigid body, and the rigid part it is in has only "
                    f"{len(g) - 1} other marker(s)"
                    if tuple(g) in split_off
                    else f"moves, but steady with only {len(g) - 1} other marker(s)"
                )
            continue
        try:
            stats[tuple(g)] = _rotation_deg(x[:, g])
        except CalibrationError:
            for k in g:
                left_out[int(k)] = "its cluster is never seen whole in one frame"
            continue
        clusters.append(g)
    order = lambda gs: sorted((sorted(int(k) for k in g) for g in gs), key=lambda g: (-len(g), g[0]))  # noqa: E731
    clusters, still = order(clusters), order(still)
    groups = clusters + still
    doubtful = doubtful_unions(x, spread, [np.array(g) for g in clusters])
    return MarkerGroups(
        clusters=clusters,
        still=still,
        left_out=dict(sorted(left_out.items())),
        unseen=unseen,
        residual_m=[stats[tuple(g)][0] for g in groups],
        rotation_deg=[stats[tuple(g)][1] for g in groups],
        cut_m=(cut1, cut2),
        splits=splits,
        doubtful=doubtful,
    )


def group_markers(markers: np.ndarray, *, still_deg: float = 10.0, min_size: int = 3) -> list[list[int]]:
    """The moving rigid clusters of :func:`find_clusters`: marker index lists, largest first."""
    return find_clusters(markers, still_deg=still_deg, min_size=min_size).clusters
