"""The doubtful-cluster check on simulated skin markers: false alarms and power (not a test).

    .venv/bin/python studies/cluster_doubt.py [--seeds 30]

``calibration.clusters.doubtful_unions`` says a cluster may be two bodies when its top union
misfits far more than the same union in subsets of the recording's other clusters. Chains of
4-6 segments from ``simbench.sim.markers.simulate_marker_chain`` with 5-8 markers per segment
sliding on the skin (each segment its own skin level, 2-7 mm), as marker sets with anatomical
landmarks have; the chains of 3-4 markers of ``studies/cluster_finding.py`` leave every cluster
unjudged (no other cluster is as large).

1. **Whole sets:** ``find_clusters`` on each seed; clusters judged and doubtful (false alarms:
   every cluster is one segment).
2. **A segment that lost markers:** each segment in turn keeps 2 or 3 of its markers; the
   grouping, whether a group spans two segments, and the doubtful clusters.
3. **Planted unions (power):** each segment's 3 markers with 2 of the next segment's, the other
   segments as they are: is the union doubtful?

Results go to ``studies/results/cluster_doubt.json`` (about 3 minutes with 30 seeds).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from calibration.clusters import (
    DOUBT_FALSE_ALARM,
    DOUBT_MIN_SIZE,
    distance_spread,
    doubtful_unions,
    find_clusters,
)
from simbench.io.atomic import atomic_write_text
from simbench.sim.markers import simulate_marker_chain

OUT = Path(__file__).resolve().parent / "results" / "cluster_doubt.json"
MARKERS = (5, 9)  # markers per segment, [low, high)


def _spans_two(clusters: list[list[int]], truth: list[list[int]]) -> bool:
    return any(not any(set(c) <= set(t) for t in truth) for c in clusters)


def _can_be_judged(clusters: list[list[int]]) -> int:
    """Clusters that another is at least as large as (the others give the reference; those with
    fewer than ``DOUBT_MIN_NULL`` subsets of the same top-union sizes are still not judged)."""
    return sum(
        len(c) >= DOUBT_MIN_SIZE and any(len(o) >= len(c) for o in clusters if o is not c) for c in clusters
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    args = parser.parse_args()
    t0 = time.perf_counter()
    whole = {"sets": 0, "grouped_right": 0, "clusters": 0, "with_an_other_as_large": 0, "doubtful": 0}
    lost = {"cases": 0, "spanning_two_segments": 0, "spanning_and_doubtful": 0, "doubtful_otherwise": 0}
    planted = {"unions": 0, "with_an_other_as_large": 0, "doubtful": 0}
    for seed in range(args.seeds):
        x, truth, _ = simulate_marker_chain(np.random.default_rng(1000 + seed), markers=MARKERS)
        found = find_clusters(x)
        whole["sets"] += 1
        whole["grouped_right"] += sorted(found.clusters) == truth
        whole["clusters"] += len(found.clusters)
        whole["with_an_other_as_large"] += _can_be_judged(found.clusters)
        whole["doubtful"] += len(found.doubtful)
        rng = np.random.default_rng(seed)
        for seg in truth:
            keep = int(rng.integers(2, 4))
            y = x.copy()
            y[:, rng.choice(seg, len(seg) - keep, replace=False)] = np.nan
            got = find_clusters(y)
            spans = _spans_two(got.clusters, truth)
            lost["cases"] += 1
            lost["spanning_two_segments"] += spans
            lost["spanning_and_doubtful"] += spans and bool(got.doubtful)
            lost["doubtful_otherwise"] += (not spans) and bool(got.doubtful)
        # planted: segment s down to 3 markers, with 2 of segment s + 1
        x, truth, _ = simulate_marker_chain(np.random.default_rng(2000 + seed), markers=MARKERS)
        spread = distance_spread(x)
        for s in range(len(truth) - 1):
            a = sorted(int(k) for k in rng.choice(truth[s], 3, replace=False))
            b = sorted(int(k) for k in rng.choice(truth[s + 1], 2, replace=False))
            rest = [[k for k in t if k not in b] for i, t in enumerate(truth) if i != s]
            clusters = [np.array(sorted(a + b))] + [np.array(t) for t in rest if len(t) >= 3]
            planted["unions"] += 1
            planted["with_an_other_as_large"] += any(len(c) >= 5 for c in clusters[1:])
            planted["doubtful"] += any(
                sorted(p + q) == sorted(a + b) for p, q, *_ in doubtful_unions(x, spread, clusters)
            )
    doc = {
        "markers_per_segment": list(MARKERS),
        "seeds": args.seeds,
        "false_alarm": DOUBT_FALSE_ALARM,
        "whole_sets": whole,
        "segment_lost_markers": lost,
        "planted_unions": planted,
        "seconds": time.perf_counter() - t0,
    }
    atomic_write_text(OUT, json.dumps(doc, indent=1) + "\n")
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
