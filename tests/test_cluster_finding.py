"""Automatic cluster finding on skin-mounted markers (issue 12, item 2): simulated chains, units."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.clusters import (
    distance_spread,
    doubtful_unions,
    find_clusters,
    rigid_parts,
    union_misfit_ratio,
)
from calibration.rotations import rotvec_to_matrix
from simbench.sim.markers import simulate_marker_chain, smooth_noise


@pytest.mark.parametrize("seed", [100, 101, 102])
def test_skin_clusters_and_static_markers_grouped_right(seed):
    x, truth, static = simulate_marker_chain(np.random.default_rng(seed))
    found = find_clusters(x)
    assert sorted(found.clusters) == truth
    assert found.still == [static] and not found.left_out
    assert found.rotation_deg[-1] < 1.0 < min(found.rotation_deg[:-1])  # the still group barely turns


def test_same_grouping_in_any_unit():
    x, truth, _ = simulate_marker_chain(np.random.default_rng(103))
    groups = [find_clusters(x * scale) for scale in (1.0, 100.0, 1000.0, 1 / 0.0254)]
    assert all(g.clusters == groups[0].clusters and g.still == groups[0].still for g in groups)
    assert sorted(groups[0].clusters) == truth


def test_loose_marker_left_out_with_a_reason():
    rng = np.random.default_rng(104)
    x, truth, static = simulate_marker_chain(rng)
    loose = x[:, truth[0][0]] + 0.05 * smooth_noise(rng, x.shape[0], (3,), 2.0)
    found = find_clusters(np.concatenate([x, loose[:, None]], axis=1))
    assert sorted(found.clusters) == truth and found.still == [static]
    assert list(found.left_out) == [x.shape[1]] and "steady with only 0 other" in found.left_out[x.shape[1]]


@pytest.mark.parametrize("frames_seen", [0, 2])
def test_marker_seen_too_little_is_set_aside_not_cut_on(frames_seen):
    """A marker never seen (or in fewer frames than a spread needs) must not decide the cut.

    It used to stand in as the farthest pair of all, became the largest gap of the tree, and
    the whole set was cut into {that marker} and everything else.
    """
    x, truth, static = simulate_marker_chain(np.random.default_rng(100))
    dead = np.full((x.shape[0], 1, 3), np.nan)
    dead[:frames_seen, 0] = x[:frames_seen, 0]
    m = x.shape[1]
    found = find_clusters(np.concatenate([x, dead], axis=1))
    assert sorted(found.clusters) == truth and found.still == [static]
    assert list(found.left_out) == [m] and found.unseen == [m]
    why = found.left_out[m]
    assert ("not seen in any frame" if frames_seen == 0 else f"seen in {frames_seen} frame(s)") in why
    assert "moves" not in why


def test_markers_of_one_cluster_never_seen_together_leave_the_others_grouped():
    """Two markers of one cluster, one seen only in the first half, the other only in the second.

    Their pair has no spread; it must not become the tree's largest gap (it once cut the whole
    set in two): every other cluster and the still group are still found.
    """
    x, truth, static = simulate_marker_chain(np.random.default_rng(105))
    big = next(c for c in truth if len(c) == 4)
    a, b = big[:2]
    half = x.shape[0] // 2
    x[half:, a] = np.nan
    x[:half, b] = np.nan
    found = find_clusters(x)
    assert all(c in found.clusters for c in truth if c != big) and found.still == [static]
    assert not found.unseen


def test_markers_that_never_move_are_one_still_group():
    """One frame repeated: every distance is exactly steady, so every spread is exactly 0.

    The spreads were the rounding of their means (1e-17 m), whose differences the tree was cut
    at: 17 groups of a file that never moves, one of them called moving.
    """
    x, _, _ = simulate_marker_chain(np.random.default_rng(100))
    found = find_clusters(np.repeat(x[:1], 300, axis=0))
    assert found.clusters == [] and found.still == [list(range(x.shape[1]))] and not found.left_out
    assert found.rotation_deg == [0.0]


def _hinged_bodies(bend_rad: float, scale: float = 1.0) -> np.ndarray:
    """``(1000, 8, 3)`` markers: six on a swinging body, two on a second hinged to it, 1 mm noise.

    The second body (two markers, as a three-marker cluster that lost one) bends ``bend_rad`` at
    most about a hinge 25 cm from the first's centre; ``bend_rad = 0`` makes them one body.
    """
    rng = np.random.default_rng(7)
    t = np.arange(1000) / 100.0
    swing = np.stack(
        [0.6 * np.sin(2 * np.pi * 0.3 * t), 0.4 * np.cos(2 * np.pi * 0.2 * t), 0.2 * np.sin(t)], 1
    )
    R = rotvec_to_matrix(swing)
    bend = rotvec_to_matrix(np.stack([bend_rad * np.sin(2 * np.pi * 0.7 * t), 0 * t, 0 * t], 1))
    a = rng.normal(0, 0.15, (6, 3))
    hinge = np.array([0.0, 0.0, -0.25])
    b = np.array([[0.03, 0.0, -0.45], [0.0, 0.04, -0.50]]) - hinge
    xa = np.einsum("fij,kj->fki", R, a)
    xb = np.einsum("fij,fjk,lk->fli", R, bend, b) + np.einsum("fij,j->fi", R, hinge)[:, None]
    return scale * (np.concatenate([xa, xb], axis=1) + rng.normal(0, 0.001, (1000, 8, 3)))


def test_two_hinged_bodies_are_split_into_their_rigid_parts_in_any_unit():
    """A two-marker body bending against a six-marker one is not one rigid body; unbent, it is.

    The test's ratio is of squared lengths, so metres and millimetres give the same verdict.
    """
    for scale in (1.0, 1000.0):
        x = _hinged_bodies(0.2, scale)
        f, limit = union_misfit_ratio(x, np.arange(6), np.array([6, 7]))
        assert f > 5 * limit
        parts, splits = rigid_parts(x, distance_spread(x), np.arange(8))
        assert sorted(p.tolist() for p in parts) == [[0, 1, 2, 3, 4, 5], [6, 7]]
        assert len(splits) == 1 and splits[0][2] > splits[0][3]
        x = _hinged_bodies(0.0, scale)
        f, limit = union_misfit_ratio(x, np.arange(6), np.array([6, 7]))
        assert f < limit / 2
        parts, splits = rigid_parts(x, distance_spread(x), np.arange(8))
        assert [p.tolist() for p in parts] == [list(range(8))] and not splits


def test_rigidity_test_cannot_judge_two_single_markers_and_keeps_exact_bodies_whole():
    """Two single markers leave no degree of freedom to scale the test by: not judged (joined).

    Exact positions misfit only by rounding, which is no noise to judge a union against.
    """
    x = _hinged_bodies(0.2)
    assert union_misfit_ratio(x, np.array([0]), np.array([6])) is None
    exact = np.repeat(x[:1], 50, axis=0)  # one frame repeated: every part fits exactly
    assert rigid_parts(exact, distance_spread(exact), np.arange(8))[0][0].tolist() == list(range(8))


def _planted(seed: int) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """A chain with 5-8 skin markers per segment: its true clusters, and the same with segment 0
    cut to 3 markers and joined by 2 of segment 1's (a union of two segments)."""
    rng = np.random.default_rng(seed)
    x, truth, _ = simulate_marker_chain(rng, markers=(5, 9))
    a = list(rng.choice(truth[0], 3, replace=False))
    b = list(rng.choice(truth[1], 2, replace=False))
    union = np.array(sorted(a + b))
    rest = [np.array([k for k in t if k not in b]) for t in truth[1:]]
    return x, [np.array(t) for t in truth], [union, *rest]


@pytest.mark.parametrize("seed", [300, 302])
def test_a_union_of_two_segments_is_doubtful_and_true_clusters_are_not(seed):
    """The union's top union (3 markers of one segment, 2 of the next) misfits far more than the
    same union in subsets of the other clusters; the true clusters are judged and pass."""
    x, truth, planted = _planted(seed)
    spread = distance_spread(x)
    assert doubtful_unions(x, spread, truth) == []
    doubt = doubtful_unions(x, spread, planted)
    assert len(doubt) == 1
    part, other, f, z, n = doubt[0]
    assert sorted(part + other) == planted[0].tolist() and {len(part), len(other)} == {2, 3}
    assert z > 3.09 and n >= 20 and f > 0
    # unit-free, and the same seed the same answer
    again = doubtful_unions(x * 1000.0, distance_spread(x * 1000.0), planted)
    assert [d[:2] for d in again] == [d[:2] for d in doubt]
    assert again[0][2] == pytest.approx(f, rel=1e-9) and again[0][3] == pytest.approx(z, rel=1e-6)


def test_small_clusters_are_not_judged():
    """With no other cluster as large (chains of 3-4 markers per segment), there is no reference:
    nothing is said, whatever the clusters."""
    x, truth, _ = simulate_marker_chain(np.random.default_rng(105))
    union = np.array(sorted(truth[0] + truth[1][:2]))
    clusters = [union, *[np.array(t) for t in truth[2:]]]
    assert doubtful_unions(x, distance_spread(x), clusters) == []
