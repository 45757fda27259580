"""Automatic cluster finding on skin-mounted markers (issue 12, item 2): simulated chains, units."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.clusters import find_clusters
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
