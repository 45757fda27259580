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
