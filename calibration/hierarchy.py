"""The body hierarchy: a minimum spanning tree over the pairs' joint fits (O'Brien section 3.3).

Each sensor is a node, each pair of sensors an edge. Two weightings (:data:`HIERARCHY_METHODS`):

- ``"mst"``, **the paper's method**: the pair's rms joint-fit residual; the hierarchy that
  minimises the sum of the joints' residuals is the minimum spanning tree.
- ``"misfit"`` (the default): the pair's mean square residual minus the part the measurement
  noise explains, ``r^2 - nu`` (:func:`misfit_weights`, ``nu`` from
  :func:`calibration.pair_noise.pair_noise_variance`): the tree that minimises the joints'
  summed misfit. A residual is a joint's misfit plus both sensors' noise; when the noise differs
  between sensors (a magnetic tracker's grows as about ``r^4`` with the distance to its
  transmitter), the quiet sensors' pairs fit "well" whether or not they are joints, and the
  paper's tree follows the noise. Measured (``studies/walk_hierarchy.py``: 20 seeded 45 s
  humanoid walks per case, preset ``skin-paper-human`` with its transmitter moved to a stand in
  front of the capture area, so that the walk's far end sees several centimetres of noise): the
  MST was right in 6 of 20 walks (a hand made the child of the upper arm, the head of the upper
  arm, one thigh of the other) and in 0 of 20 walks whose hips turn nearly about one lateral axis
  (one thigh the child of the other in all 20, as in O'Brien's walks); the misfit tree in 20 of
  20 and 19 of 20 (the one: with the pelvis sensor's pushed pack, whose misfit there is within
  2 mm of the thigh-thigh pair's). With the preset's own transmitter, at the walk's centre, both
  trees were right in all 80 walks. Both are right on the linkage, the humanoid's exercise
  trials, noise-free sessions and the biobuddy hip trial. Residuals and noise variances share one
  length unit, so the tree does not depend on the unit; nothing is tuned. Noise that is not white
  is only partly removed, and the misfit tree then moves towards the paper's
  (:mod:`calibration.pair_noise`); on noise-free data the two are the same tree.

**Tiny weights.** scipy's ``minimum_spanning_tree`` treats entries near zero as missing edges,
and noise-free residuals are exactly that small. The tree only depends on the order of the edge
weights (Kruskal), so the graph is built from the *ranks* of the residuals (1, 2, ...), which
keeps every edge and gives the same tree.

**Root rule** (when no root is given): the centre of the tree -- the sensor whose largest
number of joints to any other sensor is smallest; ties go to the one with the smaller sum of
joint counts to all others, then to the earlier sensor in input order. For a human torso
chain this picks a trunk segment, for O'Brien's linkage the chest bar.

**Loop joints** (section 5): a pair left out of the tree whose residual is no larger than
``loop_factor`` times the largest residual among the tree's joints (or below
:data:`LOOP_FLOOR`, 1 micrometre, where all are numerically zero) would have made as good a
joint as one the tree accepted; such pairs are reported as possible loop joints (or as pairs
the motion did not tell apart, such as two sensors on one rigid piece).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import (
    breadth_first_order,
    connected_components,
    minimum_spanning_tree,
    shortest_path,
)

from calibration.defaults import HIERARCHY_METHODS as HIERARCHY_METHODS  # the edge weightings
from calibration.errors import CalibrationError, CalibrationInputError

#: Default factor of :func:`loop_candidates`.
LOOP_FACTOR = 1.0

#: Residuals below this (metres) are numerically zero: the normal equations' rounding floor on
#: exact data is about 1e-8 m (see :mod:`calibration.pairs`).
LOOP_FLOOR = 1e-6


@dataclass(frozen=True)
class Hierarchy:
    """A tree over sensors.

    Attributes:
        parent: ``(N,)`` parent index of each sensor, ``-1`` for the root.
        root: index of the root sensor.
        order: ``(N,)`` sensor indices, every parent before its children (root first).
    """

    parent: np.ndarray
    root: int
    order: np.ndarray

    @property
    def joints(self) -> list[tuple[int, int]]:
        """``(parent, child)`` index pairs, in ``order``."""
        return [(int(self.parent[c]), int(c)) for c in self.order if self.parent[c] >= 0]


def _adjacency(n: int, edges: np.ndarray) -> np.ndarray:
    """Dense 0/1 adjacency matrix ``(n, n)`` of an undirected edge list ``(E, 2)``."""
    adj = np.zeros((n, n))
    if len(edges):
        adj[edges[:, 0], edges[:, 1]] = 1.0
        adj[edges[:, 1], edges[:, 0]] = 1.0
    return adj


def _tree_from_edges(n: int, edges: np.ndarray, root: int) -> Hierarchy:
    """Orient an undirected spanning tree ``(n-1, 2)`` from ``root``."""
    order, pred = breadth_first_order(_adjacency(n, edges), root, directed=False, return_predecessors=True)
    if len(order) != n:
        raise CalibrationError("the edges given do not connect every sensor")
    parent = np.where(pred < 0, -1, pred).astype(np.int64)
    parent[root] = -1
    return Hierarchy(parent=parent, root=int(root), order=np.asarray(order, dtype=np.int64))


def centre_of_tree(n: int, edges: np.ndarray) -> int:
    """The root chosen by the rule in the module docstring, for a tree given by its edges."""
    hops = shortest_path(_adjacency(n, edges), directed=False, unweighted=True)
    ecc = hops.max(axis=1)
    total = hops.sum(axis=1)
    candidates = np.lexsort((np.arange(n), total, ecc))  # last key sorts first
    return int(candidates[0])


def _groups(n: int, edges: np.ndarray, labels: Sequence[str]) -> list[list[str]]:
    """Names of the sensors in each connected group of an edge list."""
    n_comp, comp = connected_components(_adjacency(n, edges), directed=False)
    return [[labels[k] for k in np.flatnonzero(comp == c)] for c in range(n_comp)]


def misfit_weights(residual: np.ndarray, noise_variance: np.ndarray) -> np.ndarray:
    """The misfit tree's edge weights: each pair's mean square residual less its noise variance.

    Args:
        residual: ``(N, N)`` symmetric rms residuals (any length unit); ``inf`` where a pair
            cannot be fitted.
        noise_variance: ``(N, N)`` symmetric noise variance of each pair's residual, in that unit
            squared (:func:`calibration.pair_noise.pair_noise_variance`).

    Returns:
        ``(N, N)`` ``residual^2 - noise_variance`` (length squared; may be negative where the
        noise estimate exceeds the residual by chance), ``inf`` where the residual is.
    """
    residual = np.asarray(residual, dtype=float)
    noise_variance = np.asarray(noise_variance, dtype=float)
    if noise_variance.shape != residual.shape:
        raise CalibrationInputError(
            f"Expected noise_variance of shape {residual.shape} like residual, got {noise_variance.shape}"
        )
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(residual), residual**2 - noise_variance, np.inf)


def spanning_tree(
    residual: np.ndarray, *, root: int | None = None, names: Sequence[str] | None = None
) -> Hierarchy:
    """Minimum spanning tree of the pair weights, oriented from a root.

    Args:
        residual: ``(N, N)`` symmetric edge weights, smaller for a better joint: the rms residuals
            (metres) for the paper's tree, :func:`misfit_weights` for the misfit tree; ``inf``
            where a pair cannot be fitted (the diagonal is ignored). Only their order matters.
        root: index of the root, or ``None`` for the rule in the module docstring.
        names: sensor names, for error messages.

    Raises:
        CalibrationError: when some sensors cannot be joined to the others (no pair with enough
            common frames), naming them.
    """
    residual = np.asarray(residual, dtype=float)
    n = residual.shape[0]
    if residual.shape != (n, n):
        raise CalibrationInputError(f"Expected a square residual matrix, got {residual.shape}")
    if n < 2:
        raise CalibrationInputError(f"A hierarchy needs at least 2 sensors, got {n}")
    labels = list(names) if names is not None else [str(k) for k in range(n)]
    i, j = np.triu_indices(n, k=1)
    w = residual[i, j]
    usable = np.isfinite(w)
    i, j, w = i[usable], j[usable], w[usable]
    ranks = np.zeros((n, n))  # 0 = no edge; edges weigh 1, 2, ... in residual order
    by_residual = np.argsort(w, kind="stable")
    ranks[i[by_residual], j[by_residual]] = np.arange(1, len(w) + 1)
    mst = minimum_spanning_tree(ranks).tocoo()
    edges = np.stack([mst.row, mst.col], axis=1).astype(np.int64)
    if len(edges) != n - 1:
        raise CalibrationError(
            "the sensors fall into groups with no fittable pair between them (fewer than 3 common "
            f"valid frames, or too few for the fit asked for): {_groups(n, np.stack([i, j], axis=1), labels)}"
        )
    if root is None:
        root = centre_of_tree(n, edges)
    elif not 0 <= root < n:
        raise CalibrationInputError(f"root index must be in [0, {n}), got {root}")
    return _tree_from_edges(n, edges, root)


def hierarchy_from_parents(
    parent_of: Mapping[str, str], names: Sequence[str], *, root: str | None = None
) -> Hierarchy:
    """A known hierarchy given as ``{child: parent}`` by sensor name.

    Every sensor but one (the root) must appear as a child exactly once; names must be known
    and the map must be a tree. If ``root`` is also given it must be that sensor.

    Raises:
        CalibrationInputError: naming the unknown, missing or cyclic sensors.
    """
    index = {name: k for k, name in enumerate(names)}
    unknown = sorted({*parent_of.keys(), *parent_of.values()} - index.keys())
    if unknown:
        raise CalibrationInputError(
            f"the hierarchy names sensors the data lacks: {unknown} (sensors are {list(names)})"
        )
    self_parent = sorted(c for c, p in parent_of.items() if c == p)
    if self_parent:
        raise CalibrationInputError(f"the hierarchy makes sensors their own parent: {self_parent}")
    roots = [name for name in names if name not in parent_of]
    if len(roots) != 1:
        raise CalibrationInputError(
            "the hierarchy must give a parent to every sensor but one (the root); "
            f"sensors without a parent: {roots}"
        )
    if root is not None and root != roots[0]:
        raise CalibrationInputError(f"--root is {root!r} but the hierarchy's root is {roots[0]!r}")
    n = len(names)
    edges = np.array([[index[c], index[p]] for c, p in parent_of.items()], dtype=np.int64).reshape(-1, 2)
    groups = _groups(n, edges, names)
    if len(groups) > 1:
        cut = sorted(name for g in groups if roots[0] not in g for name in g)
        raise CalibrationInputError(f"the hierarchy has a cycle: sensors not reachable from the root: {cut}")
    tree = _tree_from_edges(n, edges, index[roots[0]])
    for child, par in parent_of.items():
        if tree.parent[index[child]] != index[par]:  # pragma: no cover - a tree orients uniquely
            raise CalibrationInputError(f"the hierarchy is not a tree at {child!r}")
    return tree


def loop_candidates(
    residual: np.ndarray, tree: Hierarchy, *, loop_factor: float = LOOP_FACTOR
) -> list[tuple[int, int, float]]:
    """Pairs left out of the tree that fit about as well as its joints (possible loop joints).

    Args:
        residual: ``(N, N)`` pair residuals, metres.
        tree: the hierarchy.
        loop_factor: a non-tree pair is reported when its residual is at most this times the
            largest residual among the tree's joints, or below :data:`LOOP_FLOOR`.

    Returns:
        ``(i, j, residual)`` with ``i < j``, smallest residual first.
    """
    n = residual.shape[0]
    in_tree = np.zeros((n, n), dtype=bool)
    for p, c in tree.joints:
        in_tree[p, c] = in_tree[c, p] = True
    worst = max((residual[p, c] for p, c in tree.joints), default=0.0)
    i, j = np.triu_indices(n, k=1)
    pick = ~in_tree[i, j] & (residual[i, j] <= max(loop_factor * worst, LOOP_FLOOR))
    out = [(int(a), int(b), float(residual[a, b])) for a, b in zip(i[pick], j[pick], strict=True)]
    return sorted(out, key=lambda t: t[2])
