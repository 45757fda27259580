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
Each group the cut gives is then tested for being one rigid body (:func:`rigid_parts`), two
ways. A union of two parts is kept only if fitting it as one body misfits the markers no more
than the parts' own misfit allows (an F test at a stated false-alarm rate), so two segments whose
distances happen to be as steady as a segment's own (a segment that lost a marker) are not merged;
and only if the distances between the parts vary no more than those within them
(:func:`spread_excess`: the median log spread of the pairs between against that of the pairs
within, in units of the scatter of the recording's own clusters' pairs, :func:`spread_noise`,
against the quantile of the same construction on one body, :data:`SPREAD_NULL`), so that two
markers -- no pose -- are not joined to the next segment's cluster because the misfit test has too
few degrees of freedom to refuse them. Where the parts are too small for the misfit test to tell,
a cluster whose two main branches misfit as one far more than the same union in subsets of the
recording's other clusters (:func:`doubtful_unions`), or whose top union's spread excess is beyond
the 1 in 100 quantile, is said to be doubtful: kept, and named.
Markers seen too little to judge (never, or with no other marker in :data:`MIN_FRAMES` frames)
are left out before the tree is built: they say nothing about rigidity. So are markers exactly
rigid with each other (:func:`exact_groups`): landmarks a probing-based export computes from a
cluster's pose, whose spread of zero would otherwise be the tree's largest gap.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.sparse.csgraph import connected_components
from scipy.spatial.distance import squareform

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.quantiles import MAD_TO_SIGMA, f_ppf, mad_std, norm_ppf, t_ppf

#: Fewest frames in which two markers are seen together for their distance's spread to be judged
#: (a standard deviation of fewer than three samples says nothing about how steady it is).
MIN_FRAMES = 3

#: False-alarm rate of the rigidity test (:func:`rigid_parts`): two parts are split when the median
#: frame's misfit ratio is beyond what one rigid body with independent marker noise exceeds in one
#: frame in a thousand.
RIGID_FALSE_ALARM = 1e-3

#: Fewest blocks the burst test (:func:`burst_excess`) judges a union over: fewer give no scale.
BURST_MIN_BLOCKS = 12

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

#: A pair of markers whose distance spread is below this fraction of the recording's marker noise
#: (:func:`exact_groups`) is exactly rigid: three orders of magnitude steadier than its markers
#: are seen. No two measured markers are (on 16 real C3D files of biobuddy, the kinetics toolkit
#: and pyomeca the steadiest measured pair is at 0.06 of that noise); landmarks a probing export
#: computes from one cluster's pose are (the kinetics toolkit's racing trial: 9e-5 to 1.7e-4 of it,
#: the rounding of its single-precision values).
ZERO_SPREAD = 1e-3

#: False-alarm rate of the spread test (:func:`spread_excess`, :func:`spread_limit`): the rate at
#: which the top union of one rigid body whose pairs' log spreads scatter like independent normal
#: draws exceeds its limit.
SPREAD_FALSE_ALARM = 1e-3

#: False-alarm rate of the spread test for a union of a cluster (``min_size`` markers or more) and
#: a branch too small to be one (two markers, or one): refusing it wrongly leaves that branch's
#: markers out and the cluster whole, while joining it wrongly puts another segment's markers into
#: the cluster's pose -- two markers give no pose of their own and are never to be joined to a
#: neighbour on weak evidence.
SPREAD_SMALL = 1e-2

#: The rate at which a cluster kept whole is said to be doubtful by the spread test (its top union
#: beyond this quantile of one body's, within :data:`SPREAD_FALSE_ALARM`'s), per cluster.
SPREAD_DOUBT = 1e-2

#: Upper quantiles (0.99, 0.999) of the spread test's statistic (:func:`spread_excess`, in units of
#: the pairs' robust standard deviation) at the top union of one rigid body, by the sizes of the two
#: branches ``(smaller, larger)``: the median log spread of the pairs between the branches less that
#: of the pairs within them, when the complete-linkage tree is built on log spreads that are
#: independent standard normal draws. The tree joins the least steady pairs last, so even one body's
#: top union has its between pairs above its within pairs (by 1.3 for branches of 1 and 2 markers
#: on average, 0.4 for 8 and 8): the limit must be that of the same construction, not that of a
#: plain difference of medians. Monte Carlo, 400,000 sets of each size from 3 to 10 markers and
#: 60,000 from 11 to 16 (``scripts/cluster_spread_null.py``, seed 20240601, 284 s on two cores);
#: sizes drawn fewer than 5,000 times left out.
SPREAD_NULL: dict[tuple[int, int], tuple[float, float]] = {
    (1, 2): (3.34, 4.15),  # 400000 draws
    (1, 3): (2.80, 3.48),  # 186903 draws
    (1, 4): (2.27, 2.74),  # 94060 draws
    (1, 5): (2.19, 2.61),  # 48988 draws
    (1, 6): (1.98, 2.32),  # 26068 draws
    (1, 7): (1.94, 2.33),  # 14182 draws
    (1, 8): (1.76, 2.06),  # 8018 draws
    (2, 2): (2.60, 3.17),  # 213097 draws
    (2, 3): (2.21, 2.70),  # 305940 draws
    (2, 4): (1.95, 2.38),  # 221388 draws
    (2, 5): (1.71, 2.06),  # 156175 draws
    (2, 6): (1.52, 1.84),  # 111445 draws
    (2, 7): (1.39, 1.66),  # 80320 draws
    (2, 8): (1.29, 1.58),  # 57972 draws
    (2, 9): (1.19, 1.48),  # 6415 draws
    (3, 3): (1.99, 2.39),  # 129624 draws
    (3, 4): (1.77, 2.13),  # 217757 draws
    (3, 5): (1.59, 1.89),  # 170496 draws
    (3, 6): (1.39, 1.67),  # 133534 draws
    (3, 7): (1.28, 1.54),  # 104347 draws
    (3, 8): (1.17, 1.38),  # 12314 draws
    (3, 9): (1.09, 1.30),  # 9730 draws
    (3, 10): (1.01, 1.22),  # 7618 draws
    (3, 11): (0.96, 1.12),  # 6068 draws
    (4, 4): (1.57, 1.87),  # 103877 draws
    (4, 5): (1.42, 1.69),  # 178128 draws
    (4, 6): (1.30, 1.54),  # 152930 draws
    (4, 7): (1.18, 1.38),  # 19498 draws
    (4, 8): (1.07, 1.28),  # 16446 draws
    (4, 9): (1.00, 1.18),  # 13833 draws
    (4, 10): (0.94, 1.10),  # 11882 draws
    (4, 11): (0.88, 1.03),  # 9968 draws
    (4, 12): (0.83, 0.98),  # 8490 draws
    (5, 5): (1.32, 1.58),  # 80053 draws
    (5, 6): (1.21, 1.43),  # 21377 draws
    (5, 7): (1.13, 1.36),  # 18803 draws
    (5, 8): (1.02, 1.20),  # 16574 draws
    (5, 9): (0.98, 1.16),  # 14425 draws
    (5, 10): (0.91, 1.07),  # 12378 draws
    (5, 11): (0.85, 1.02),  # 10801 draws
    (6, 6): (1.12, 1.32),  # 10236 draws
    (6, 7): (1.05, 1.24),  # 18312 draws
    (6, 8): (0.98, 1.17),  # 16417 draws
    (6, 9): (0.93, 1.10),  # 14915 draws
    (6, 10): (0.85, 1.00),  # 13221 draws
    (7, 7): (0.98, 1.21),  # 8548 draws
    (7, 8): (0.94, 1.08),  # 15952 draws
    (7, 9): (0.87, 1.01),  # 14583 draws
    (8, 8): (0.88, 1.05),  # 7654 draws
}


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
        splits: each union the rigidity tests refused (:class:`Refusal`, :func:`rigid_parts`):
            the two parts, the statistic and the limit it exceeded, and which test.
        doubtful: ``(part, other part, F, z, n)`` for each cluster that may be two bodies: its top
            union misfits far more than the same union in ``n`` subsets of the recording's other
            clusters (:func:`doubtful_unions`); kept as one cluster, and said.
        doubtful_spread: each cluster kept whole whose top union's spread test lies beyond the
            :data:`SPREAD_DOUBT` quantile (:class:`Refusal` with that quantile as the limit):
            perhaps two bodies, kept as one, and said.
        doubtful_partner: each cluster that may hold a marker of a pair left out (:class:`Partner`,
            :func:`pair_partners`): kept, and said.
        virtual: groups of markers exactly rigid with each other (:func:`exact_groups`): landmarks
            computed from a cluster's pose, set aside before the cuts (their markers are in
            ``left_out`` too), sorted.
        virtual_with: for each virtual group, the index in ``clusters + still`` of the group it
            moves with (the one whose pairs with it are steadiest, if the spread test finds them
            one body: :func:`spread_excess`), or ``None``.
        virtual_spread: for each virtual group, the largest distance spread of its pairs, in the
            markers' unit.
        marker_noise: the recording's marker noise :func:`exact_groups` measured against, in the
            markers' unit.
        noise: the scatter of the clusters' own spreads the spread test used (:func:`spread_noise`),
            or ``None`` (no cluster of three markers to take it from).
    """

    clusters: list[list[int]]
    still: list[list[int]]
    left_out: dict[int, str]
    unseen: list[int]
    residual_m: list[float]
    rotation_deg: list[float]
    cut_m: tuple[float, float]
    splits: list[Refusal] = field(default_factory=list)
    doubtful: list[tuple[list[int], list[int], float, float, int]] = field(default_factory=list)
    doubtful_spread: list[Refusal] = field(default_factory=list)
    doubtful_partner: list[Partner] = field(default_factory=list)
    virtual: list[list[int]] = field(default_factory=list)
    virtual_with: list[int | None] = field(default_factory=list)
    virtual_spread: list[float] = field(default_factory=list)
    marker_noise: float = math.nan
    noise: SpreadNoise | None = None


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
        a: marker indices of the first part.
        b: marker indices of the second part (disjoint from ``a``).
        false_alarm: probability that one rigid body's frame exceeds the limit.

    Returns:
        ``(median F, limit)``, or ``None`` when it cannot be judged: fewer than
        :data:`MIN_FRAMES` frames show every marker, no degree of freedom is left in the parts
        (two single markers) or none is given up, or the union has no frame to define its shape.
    """
    frames = union_misfit_frames(markers, a, b)
    if frames is None:
        return None
    added, parts, d1, d2 = frames
    f = (added / d1) / (parts / d2)
    return float(np.nanmedian(f)), float(f_ppf(1.0 - false_alarm, d1, d2))


def union_misfit_frames(
    markers: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """Each frame's misfit of :func:`union_misfit_ratio`, in time order: ``(added, parts, d1, d2)``.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        a: marker indices of the first part.
        b: marker indices of the second part (disjoint from ``a``).

    Returns:
        ``(n,)`` the misfit added by fitting the union as one body (``S_ab - S_a - S_b``) and the
        parts' own misfit (``S_a + S_b``), squared length units, in each of the ``n`` frames that
        show every marker, and the degrees of freedom ``d1``, ``d2`` of their ratio; ``None`` when
        it cannot be judged (as :func:`union_misfit_ratio`).
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
    return whole - parts, np.maximum(parts, floor), d1, d2


def correlation_frames(series: np.ndarray) -> int:
    """Frames over which a series stays correlated: the first lag at which its autocorrelation
    falls below ``1/e`` (at least 1). Skin moves markers smoothly, so a misfit's frames are not
    independent draws; blocks of a few such lengths are about as independent as frames of white
    noise would be."""
    y = np.asarray(series, dtype=float)
    y = y[np.isfinite(y)]
    y = y - np.median(y) if len(y) else y
    n = len(y)
    if n < 4 or not np.any(y):
        return 1
    spectrum = np.fft.rfft(y, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[:n]
    acf /= acf[0]
    below = np.flatnonzero(acf < math.exp(-1.0))
    return max(1, int(below[0])) if len(below) else n


def burst_excess(
    added: np.ndarray, parts: np.ndarray, *, false_alarm: float = RIGID_FALSE_ALARM
) -> tuple[float, float] | None:
    """Whether a union misfits far worse in some stretch of the recording than in the rest:
    ``(z, limit)``.

    A joint that turns during a part of the recording only (an exercise that moves each joint in
    turn) leaves the median frame's misfit that of one body, and the distance spread over the
    whole recording diluted; its frames misfit by far more than the others. Each frame's misfit
    added by the union (``added``, :func:`union_misfit_frames`) is taken over the parts' own
    misfit pooled over the recording (its median: one frame's, with a few degrees of freedom,
    scatters too widely to compare stretches by); the log of that ratio is cut into blocks of
    twice the correlation length of the parts' own misfit (:func:`correlation_frames`: skin motion
    is smooth, frames are not independent draws, and one body's misfit is what sets that length);
    ``z`` is the largest block mean's distance above the block means' median, in units of their
    robust standard deviation (:func:`calibration.quantiles.mad_std`): unit-free, the scale taken
    from the recording's own blocks. The limit is Student's t quantile at ``false_alarm`` shared
    over the blocks (Bonferroni), with one degree of freedom fewer than blocks: the scale is
    estimated from those few blocks themselves (with the normal quantile, a chain of 5-8 skin
    markers a segment had one cluster split in 30 sets). One body's largest block exceeds it
    with probability about ``false_alarm``, if the block means are normal about their median.

    Args:
        added: ``(n,)`` per-frame misfits of the union in time order (:func:`union_misfit_frames`).
        parts: ``(n,)`` per-frame misfits of the parts, the same frames.
        false_alarm: the rate at which one body's union exceeds the limit.

    Returns:
        ``None`` with fewer than :data:`BURST_MIN_BLOCKS` blocks, or no scale.
    """
    added, parts = np.asarray(added, dtype=float), np.asarray(parts, dtype=float)
    level = float(np.median(parts))
    if not level > 0:
        return None
    logs = np.log(np.maximum(added, 1e-12 * level) / level)
    length = 2 * correlation_frames(np.log(parts))
    blocks = len(logs) // length
    if blocks < BURST_MIN_BLOCKS:
        return None
    means = logs[: blocks * length].reshape(blocks, length).mean(axis=1)
    scale = mad_std(means)
    if not scale > 0:
        return None
    z = float((means.max() - np.median(means)) / scale)
    return z, float(t_ppf(1.0 - false_alarm / blocks, blocks - 1))


class Refusal(NamedTuple):
    """A union the rigidity tests refused (:func:`rigid_parts`).

    Attributes:
        part, other: the two branches' marker indices.
        value: the test's statistic: the median frame's misfit ratio F (``test == "misfit"``,
            :func:`union_misfit_ratio`) or the spread excess in robust standard deviations
            (``test == "spread"``, :func:`spread_excess`).
        limit: the quantile it exceeded.
        test: ``"misfit"``, ``"spread"`` or ``"burst"`` (:func:`burst_excess`: the worst stretch
            of frames' misfit, in robust standard deviations of the blocks' medians).
        ratio: the spread test's ratio of the between pairs' median distance spread to the within
            pairs' (:func:`spread_excess`); NaN for the misfit test.
        false_alarm: the rate at which one rigid body exceeds ``limit``.
    """

    part: list[int]
    other: list[int]
    value: float
    limit: float
    test: str = "misfit"
    ratio: float = math.nan
    false_alarm: float = RIGID_FALSE_ALARM


@dataclass(frozen=True)
class SpreadNoise:
    """How the distance spreads of one rigid cluster's pairs scatter in a recording
    (:func:`spread_noise`).

    Attributes:
        level: the recording's marker noise (:func:`exact_groups`: the median over its markers of
            each one's steadiest pair's spread), in the markers' unit: pairs steadier than that are
            judged against it.
        tau: robust standard deviation of a within pair's log spread about its cluster's level
            (unit-free).
        pairs: the pairs it was taken from.
    """

    level: float
    tau: float
    pairs: int


def _log_spreads(spread: np.ndarray, rows: np.ndarray, cols: np.ndarray | None = None) -> np.ndarray:
    """Log spreads of the pairs within ``rows`` (``cols`` None) or between ``rows`` and ``cols``,
    finite and positive only."""
    if cols is None:
        sub = spread[np.ix_(rows, rows)][np.triu_indices(len(rows), 1)]
    else:
        sub = spread[np.ix_(rows, cols)].ravel()
    sub = sub[np.isfinite(sub) & (sub > 0)]
    return np.log(sub)


def _scatter(spread: np.ndarray, sets: list[np.ndarray], level: float) -> SpreadNoise | None:
    """:class:`SpreadNoise` of the pairs within each of ``sets`` (:func:`spread_noise`)."""
    differences, weights, pairs = [], [], 0
    for g in sets:
        logs = _log_spreads(spread, np.asarray(g))
        if len(logs) < 2:
            continue
        i, j = np.triu_indices(len(logs), 1)
        differences.append(np.abs(logs[i] - logs[j]))
        weights.append(np.full(len(i), 1.0 / len(i)))
        pairs += len(logs)
    if not differences:
        return None
    # the weighted median absolute difference, each set weighing the same
    d, w = np.concatenate(differences), np.concatenate(weights)
    order = np.argsort(d)
    cumulative = np.cumsum(w[order])
    median = float(d[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
    tau = MAD_TO_SIGMA * median / math.sqrt(2.0)
    if not tau > 0:
        return None
    return SpreadNoise(level=level, tau=tau, pairs=pairs)


def spread_noise(spread: np.ndarray, clusters: list[np.ndarray], marker_noise: float) -> SpreadNoise | None:
    """The scatter of the spreads of one body's pairs, from a recording's clusters (3+ markers).

    Within one cluster, the log spreads of its pairs differ by the markers' own noise (skin,
    camera) and by chance; a cluster on skin and one on a rigid plate differ in level, not in how
    their pairs scatter. So ``tau`` is taken from the absolute differences between the log spreads
    of two pairs of one cluster, over all its pairs of pairs: their median, each cluster weighing
    the same (a large cluster has many more pairs of pairs), times
    :data:`calibration.quantiles.MAD_TO_SIGMA` over ``sqrt(2)``: the standard deviation of one
    pair's log spread if they are normal. Each difference is that of two within pairs, so the
    estimate holds however few pairs a cluster has (deviations from a cluster's median would
    include a zero for every cluster of three). ``level`` is ``marker_noise``, the recording's
    marker noise (:func:`exact_groups`).

    The clusters are those the misfit test leaves, and some may still be two bodies -- this is
    what the spread test is to find out -- whose pairs between the bodies would widen the scatter
    they are judged by, and hide themselves (when every cluster is such a union, as when the
    segment cut joined the segments in pairs). So a cluster of four markers or more whose top union
    (:func:`_top_union`) lies beyond the :data:`SPREAD_DOUBT` quantile lends only the pairs within
    its spread tree's two main branches (those of three or more markers); the scatter is taken
    from above: first with every cluster whole (too wide if some are unions), then again with
    those whose top union that scatter puts beyond the quantile in their branches, until the same
    clusters are. Not from below (every cluster in its branches first): a cluster's branches hold
    its steadiest pairs, and a scatter that narrow keeps one body's clusters split, the noisiest
    marker of a clean recording's cluster refused (chains of 3-4 skin markers: 133 of 140 grouped
    right from below, 137 from above). ``None`` when no cluster of three or more markers has two
    positive spreads, or the differences have no scale.
    """
    whole = [np.asarray(g) for g in clusters if len(g) >= 3]
    tops = [_top_union(spread, g) if len(g) > 3 else None for g in whole]
    split = [False] * len(whole)  # from above: every cluster whole, then those beyond in two
    for _ in range(len(whole) + 1):
        sets = [
            p
            for g, top, s in zip(whole, tops, split, strict=True)
            for p in (top if s else [g])
            if len(p) >= 3
        ]
        noise = _scatter(spread, sets, marker_noise)
        if noise is None:
            return None
        again = [top is not None and _beyond(spread, *top, noise) for top in tops]
        if again == split:
            break
        split = again
    return noise


def _beyond(spread: np.ndarray, a: np.ndarray, b: np.ndarray, noise: SpreadNoise) -> bool:
    """Whether the union of ``a`` and ``b`` lies beyond the :data:`SPREAD_DOUBT` quantile."""
    excess = spread_excess(spread, a, b, noise)
    return excess is not None and excess[1] > spread_limit(len(a), len(b), SPREAD_DOUBT)


def spread_limit(n_a: int, n_b: int, false_alarm: float = SPREAD_FALSE_ALARM) -> float:
    """The spread test's limit for branches of ``n_a`` and ``n_b`` markers (:data:`SPREAD_NULL`).

    Sizes beyond the table take the smallest limit of the sizes it holds that are no larger in
    either branch: the limit falls as the branches grow, so that one is never below the true one.

    Raises:
        CalibrationInputError: a false-alarm rate other than 0.01 or 0.001 (the table's), or two
            single markers (no within pair to compare with).
    """
    column = {1e-2: 0, 1e-3: 1}.get(false_alarm)
    if column is None:
        raise CalibrationInputError(f"Expected a false-alarm rate of 0.01 or 0.001, got {false_alarm!r}")
    small, large = sorted((int(n_a), int(n_b)))
    if large < 2:
        raise CalibrationInputError("two single markers have no within pair to compare their spread with")
    return min(q[column] for (a, b), q in SPREAD_NULL.items() if a <= small and b <= large)


def spread_excess(
    spread: np.ndarray, a: np.ndarray, b: np.ndarray, noise: SpreadNoise
) -> tuple[float, float] | None:
    """How far the distances between two branches vary beyond those within them: ``(ratio, z)``.

    ``ratio`` is the median distance spread of the pairs between ``a`` and ``b`` over the larger
    of the median spread of the pairs within them and the recording's marker noise
    (``noise.level``): markers far steadier than a typical marker of the recording (a rigid plate
    with camera noise only, among skin markers) are judged against that noise, not against how
    much steadier one of them happens to be than another. ``z = log(ratio) / noise.tau``: how many
    of the recording's robust standard deviations of a within pair's log spread the between pairs
    lie above. Unit-free.

    Returns:
        ``None`` when it cannot be judged: two single markers (no within pair), or no finite,
        positive spread between them or within them.
    """
    a, b = np.asarray(a), np.asarray(b)
    if len(a) < 2 and len(b) < 2:
        return None
    within = np.concatenate([_log_spreads(spread, a), _log_spreads(spread, b)])
    between = _log_spreads(spread, a, b)
    if not len(within) or not len(between):
        return None
    floor = math.log(noise.level) if noise.level > 0 else -math.inf  # NaN: no floor
    reference = max(float(np.median(within)), floor)
    excess = float(np.median(between)) - reference
    return math.exp(excess), excess / noise.tau


def rigid_parts(
    markers: np.ndarray,
    spread: np.ndarray,
    members: np.ndarray,
    *,
    false_alarm: float = RIGID_FALSE_ALARM,
    noise: SpreadNoise | None = None,
    min_size: int = 3,
) -> tuple[list[np.ndarray], list[Refusal]]:
    """A group split into the largest parts that each move as one rigid body.

    The group's complete-linkage tree on the distance spread is walked from its leaves up: two
    branches are joined only when each is one body, :func:`union_misfit_ratio` finds their
    union no worse a rigid body than the two apart (median frame's F below its ``false_alarm``
    quantile), and -- given the recording's ``noise`` -- the distances between them vary no
    more than one body's (:func:`spread_excess` within :func:`spread_limit` at
    :data:`SPREAD_FALSE_ALARM`; at :data:`SPREAD_SMALL` for a branch of fewer than ``min_size``
    markers joining one of ``min_size`` or more), and -- two poses, both branches ``min_size`` or
    more -- no stretch of the recording misfits far beyond the others (:func:`burst_excess`: a
    joint that turns part of the time). A union a test cannot judge is joined, as the distances
    alone joined it. The branches refused are the parts: a segment that lost markers is
    not merged into the next one because the distances between them are as steady as its own, and
    a pair of markers on one segment is not joined to the next segment's cluster because the
    misfit test has too few degrees of freedom to refuse it.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        spread: ``(M, M)`` distance spread (:func:`distance_spread`).
        members: marker indices of the group, sorted.
        false_alarm: the misfit test's false-alarm rate per frame.
        noise: the recording's within-cluster spread scatter (:func:`spread_noise`); ``None``:
            the misfit test alone.
        min_size: the smallest cluster.

    Returns:
        The parts (sorted index arrays, in the tree's order) and each union refused
        (:class:`Refusal`).
    """
    if len(members) < 2:
        return [members], []
    Z = _spread_tree(spread, members)
    m = len(members)
    nodes = _tree_nodes(Z, members)
    whole: list[bool] = [True] * m  # each node one rigid body
    splits: list[Refusal] = []
    for left, right, _, _ in Z:
        i, j = int(left), int(right)
        a, b = nodes[i], nodes[j]
        ok = whole[i] and whole[j]
        if ok:
            frames = union_misfit_frames(markers, a, b)
            if frames is not None:
                added, own, d1, d2 = frames
                f = (added / d1) / (own / d2)
                test = (float(np.nanmedian(f)), float(f_ppf(1.0 - false_alarm, d1, d2)))
                if not test[0] <= test[1]:
                    ok = False
                    splits.append(Refusal([int(k) for k in a], [int(k) for k in b], *test))
                elif min(len(a), len(b)) >= min_size:  # two poses: a joint turning part of the time
                    burst = burst_excess(added, own, false_alarm=false_alarm)
                    if burst is not None and not burst[0] <= burst[1]:
                        ok = False
                        pa, pb = [int(k) for k in a], [int(k) for k in b]
                        splits.append(Refusal(pa, pb, burst[0], burst[1], "burst", math.nan, false_alarm))
        if ok and noise is not None:
            excess = spread_excess(spread, a, b, noise)
            if excess is not None:
                rate = (
                    SPREAD_SMALL
                    if min(len(a), len(b)) < min_size <= max(len(a), len(b))
                    else SPREAD_FALSE_ALARM
                )
                limit = spread_limit(len(a), len(b), rate)
                if not excess[1] <= limit:
                    ok = False
                    pa, pb = [int(k) for k in a], [int(k) for k in b]
                    splits.append(Refusal(pa, pb, excess[1], limit, "spread", excess[0], rate))
        whole.append(ok)
    # the parts: the rigid nodes whose parent is not (or the root, if rigid)
    parent = np.full(len(nodes), -1)
    for row, (left, right, _, _) in enumerate(Z):
        parent[int(left)] = parent[int(right)] = m + row
    parts = [nodes[n] for n in range(len(nodes)) if whole[n] and (parent[n] < 0 or not whole[parent[n]])]
    return parts, splits


class Partner(NamedTuple):
    """A cluster that may hold a marker of a pair of markers left out (:func:`pair_partners`).

    Attributes:
        marker: the cluster's marker that is the pair's steadiest partner.
        rest: the cluster's other markers.
        pair: the two markers left out.
        to_pair: median distance spread of ``marker`` to the pair, in the markers' unit.
        to_rest: median distance spread of ``marker`` to ``rest``, same unit.
    """

    marker: int
    rest: list[int]
    pair: list[int]
    to_pair: float
    to_rest: float


def pair_partners(
    spread: np.ndarray,
    clusters: list[list[int]],
    pairs: list[list[int]],
    noise: SpreadNoise,
    min_size: int = 3,
) -> list[Partner]:
    """Clusters that may hold a marker of a pair left out: the pair with it would be a cluster.

    Two markers left out (too few for a pose) beside a cluster that joined last, as a branch of
    its own, the pair's steadiest partner (the marker whose median distance spread to the pair is
    the smallest of all clustered markers'), while the cluster keeps ``min_size`` markers without
    it: that marker may be the pair's segment's, its distances as unsteady to its own segment as
    to the cluster (a marker near the joint, on soft tissue), and no steadier with the cluster than
    the spread test lets a marker join one (:func:`spread_excess` of the two median spreads within
    :func:`spread_limit` at :data:`SPREAD_SMALL`). The data do not say which; the
    grouping is kept and the cluster named. The distances alone cannot tell them apart: a thigh
    marker 15 cm from the anterior iliac spine, near the hip, varies 5.5 mm in distance to the
    pelvis's markers and 6.4 mm to the thigh's two others (OpenSim's Rajagopal running trial).

    Args:
        spread: ``(M, M)`` distance spread (:func:`distance_spread`).
        clusters: the clusters (marker index lists).
        pairs: the pairs of markers left out that move (split off a group).
        noise: the recording's spread scatter (:func:`spread_noise`).
        min_size: the smallest cluster.
    """
    out = []
    clustered = [(k, c) for c in clusters for k in c]
    for pair in pairs:
        if len(pair) != 2 or not clustered:
            continue
        p = np.asarray(pair)
        to_pair = [float(np.median(spread[k, p])) for k, _ in clustered]
        best = int(np.argmin(to_pair))
        k, c = clustered[best]
        if len(c) <= min_size:
            continue
        a, b = _top_union(spread, np.asarray(c))
        if k not in (a.tolist() if len(a) == 1 else b.tolist() if len(b) == 1 else []):
            continue
        rest = sorted(int(j) for j in c if j != k)
        to_rest = float(np.median(spread[k, rest]))
        if not math.log(to_pair[best] / to_rest) / noise.tau <= spread_limit(1, len(rest), SPREAD_SMALL):
            continue  # much steadier with its cluster than with the pair
        out.append(Partner(int(k), rest, sorted(int(j) for j in pair), to_pair[best], to_rest))
    return out


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


def _rounding(markers: np.ndarray) -> float:
    """A spread at the rounding of the markers' values (1e3 of their largest value's relative
    precision): a recording whose marker noise is no larger has no noise to judge by."""
    x = np.asarray(markers, dtype=float)
    return 1e3 * np.finfo(float).eps * float(np.nanmax(np.abs(x))) if np.isfinite(x).any() else math.inf


def exact_groups(
    markers: np.ndarray, spread: np.ndarray, members: np.ndarray
) -> tuple[list[list[int]], float]:
    """Markers exactly rigid with each other: landmarks computed from a cluster, not measured.

    A probing-based export writes anatomical landmarks (acromion, epicondyles, styloids) as
    markers, each a fixed point in one cluster's frame placed by that cluster's fitted pose every
    frame: the landmarks of one cluster keep their distances to the last bit of the file's
    values. The recording's marker noise is the median over ``members`` of each one's steadiest
    pair (the spread of its distance to its steadiest partner); a pair steadier than
    :data:`ZERO_SPREAD` times that noise is exactly rigid, and the markers such pairs link are one
    group. A recording whose noise is itself at the rounding of its values (markers simulated
    without noise) has none: no pair stands out.

    Args:
        markers: ``(F, M, 3)`` marker positions, any length unit (NaN where not seen).
        spread: ``(M, M)`` distance spread (:func:`distance_spread`).
        members: the markers judged (seen enough, :func:`unjudged_markers`).

    Returns:
        The groups (sorted index lists of two or more markers, sorted) and the marker noise (NaN
        with fewer than two members), in the markers' unit.
    """
    members = np.asarray(members)
    if len(members) < 2:
        return [], math.nan
    sub = spread[np.ix_(members, members)].copy()
    np.fill_diagonal(sub, np.inf)
    nearest = sub.min(axis=1)
    nearest = nearest[np.isfinite(nearest)]
    if not len(nearest):
        return [], math.nan
    noise = float(np.median(nearest))
    if not noise > _rounding(markers):
        return [], noise
    exact = sub < ZERO_SPREAD * noise
    n, labels = connected_components(exact, directed=False)
    groups = [sorted(int(k) for k in members[labels == c]) for c in range(n)]
    return sorted(g for g in groups if len(g) >= 2), noise


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


def _virtual_hosts(
    spread: np.ndarray, virtual: list[list[int]], groups: list[list[int]], noise: SpreadNoise | None
) -> list[int | None]:
    """For each virtual group, the index of the group in ``groups`` it moves with, or ``None``.

    The candidate is the group whose pairs with the virtual markers have the smallest median
    spread; it is their host when those pairs vary no more than the group's own markers do
    (:func:`spread_excess` within :func:`spread_limit`, the virtual markers' own pairs, exactly
    steady, having no level to add).
    """
    hosts: list[int | None] = []
    for v in virtual:
        v = np.asarray(v)
        best, host = math.inf, None
        for k, g in enumerate(groups):
            between = _log_spreads(spread, v, np.asarray(g))
            if len(between) and float(np.median(between)) < best:
                best, host = float(np.median(between)), k
        if host is not None and noise is not None:
            g = np.asarray(groups[host])
            excess = spread_excess(spread, v[:1], g, noise)
            if excess is not None and excess[1] > spread_limit(1, len(g)):
                host = None
        hosts.append(host)
    return hosts


def find_clusters(markers: np.ndarray, *, still_deg: float = 10.0, min_size: int = 3) -> MarkerGroups:
    """Rigid marker clusters found from the steadiness of their distances, relative to motion.

    Two cuts, each at the largest ratio gap of a complete-linkage tree on the pairs' distance
    spread (standard deviation over frames), so no tolerance in metres is needed and the result
    is the same in any unit. The first cut, over all markers, separates groups that move against
    each other; a group of ``min_size`` or more whose rigid fit rotates less than ``still_deg``
    (95th percentile from its mean orientation) is *still*: its distances are steady because it
    barely moves, so its rigidity is not proven (a body at rest, lab markers); it is reported
    apart -- once the tests below have split off any marker that moves against it (a still group
    is one rigid body too: an arm marker beside a pelvis that turns 5 degrees while running); a
    still group that splits into two or more parts of ``min_size`` is kept whole, no motion telling
    its bodies apart (a person standing). The second cut, over the markers of the moving groups
    only, separates the segments
    (skin spread within a cluster, joint motion between clusters); each group it gives is then
    split into the parts that are each one rigid body (:func:`rigid_parts`): first by the misfit
    test alone, then by the misfit and spread tests, the spread test's noise taken from the parts
    the first pass left (:func:`spread_noise`). So a segment whose distances to the next are as
    steady as its own (one that lost a marker) is not merged into it, and two markers -- too few
    for a pose -- are not joined to the next segment's cluster: a part too small to be a cluster is
    left out, named. A cluster that may still be two bodies is named in ``doubtful``
    (:func:`doubtful_unions`) or ``doubtful_spread`` (its top union's spread excess beyond the
    :data:`SPREAD_DOUBT` quantile), or ``doubtful_partner`` (a pair left out whose steadiest
    partner joined a cluster last, :func:`pair_partners`). ``still_deg`` defaults to 10 degrees:
    below that a joint centre is not determined (DESIGN.md, facts from real recordings).
    Markers seen too little to judge (:func:`unjudged_markers`) and markers exactly rigid with
    each other (:func:`exact_groups`: landmarks computed from a cluster) are set aside before
    either cut, with the reason, so that a marker never seen, or a spread of zero, does not decide
    where the tree is cut; each group of the latter is said to move with the cluster whose pairs
    with it are steadiest, if the spread test finds them one body (``virtual_with``).

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
    judged = np.setdiff1d(np.arange(x.shape[1]), list(left_out))
    virtual, marker_noise = exact_groups(x, spread, judged)
    for g in virtual:
        for k in g:
            left_out[k] = (
                f"virtual: exactly rigid with {len(g) - 1} other marker(s) (distance spread below "
                f"{ZERO_SPREAD:g} of the recording's marker noise): computed from a cluster, not measured"
            )
    everyone = np.setdiff1d(judged, [k for g in virtual for k in g])
    measured_noise = exact_groups(x, spread, everyone)[1] if virtual else marker_noise  # without them
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
    noise = None
    for _ in range(2):  # the misfit test alone, then both with the noise of the parts it left
        rigid, splits, split_off = [], [], set()
        for g in second:
            parts, refused = (
                rigid_parts(x, spread, g, noise=noise, min_size=min_size) if len(g) >= min_size else ([g], [])
            )
            rigid += parts
            splits += refused
            if len(parts) > 1:
                split_off.update(tuple(p) for p in parts)
        if noise is not None or not marker_noise > _rounding(x):  # exact positions: no noise to judge by
            break
        noise = spread_noise(spread, [p for p in rigid if len(p) >= min_size], measured_noise)
        if noise is None:
            break
    # a still group is one rigid body too: a marker that moves against it (an arm's, steady in
    # distance to a pelvis that turns 5 degrees while running) is split off by the same tests
    kept_still = []
    for g in still:
        parts, refused = rigid_parts(x, spread, g, noise=noise, min_size=min_size)
        if sum(len(p) >= min_size for p in parts) != 1:  # no motion to tell its bodies apart: whole
            kept_still.append(g)
            continue
        splits += refused
        for part in parts:
            if len(part) >= min_size and tuple(part) not in stats:
                try:
                    stats[tuple(part)] = _rotation_deg(x[:, part])
                except CalibrationError:
                    pass
            if len(part) >= min_size and tuple(part) in stats and stats[tuple(part)][1] < still_deg:
                kept_still.append(part)
            else:
                rigid.append(part)
                split_off.add(tuple(part))
    still = kept_still
    split_off = {int(k) for p in split_off for k in p}
    clusters = []
    for g in rigid:
        if len(g) < min_size:
            for k in g:
                left_out[int(k)] = (
                    f"moves; its group is not one rigid body, and the rigid part it is in has only "
                    f"{len(g) - 1} other marker(s): too few for a pose, and not joined to a neighbour"
                    if int(k) in split_off
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
    doubtful_spread = []
    for g in clusters if noise is not None else []:
        a, b = _top_union(spread, np.array(g))
        excess = spread_excess(spread, a, b, noise)
        if excess is not None and excess[1] > spread_limit(len(a), len(b), SPREAD_DOUBT):
            pa, pb = sorted(int(k) for k in a), sorted(int(k) for k in b)
            limit = spread_limit(len(a), len(b), SPREAD_DOUBT)
            doubtful_spread.append(Refusal(pa, pb, excess[1], limit, "spread", excess[0], SPREAD_DOUBT))
    pairs = [sorted(int(k) for k in g) for g in rigid if len(g) == 2 and int(g[0]) in split_off]
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
        doubtful_spread=doubtful_spread,
        doubtful_partner=pair_partners(spread, clusters, pairs, noise, min_size) if noise is not None else [],
        virtual=virtual,
        virtual_with=_virtual_hosts(spread, virtual, groups, noise),
        virtual_spread=[float(spread[np.ix_(g, g)].max()) for g in virtual],
        marker_noise=marker_noise,
        noise=noise,
    )


def group_markers(markers: np.ndarray, *, still_deg: float = 10.0, min_size: int = 3) -> list[list[int]]:
    """The moving rigid clusters of :func:`find_clusters`: marker index lists, largest first."""
    return find_clusters(markers, still_deg=still_deg, min_size=min_size).clusters
