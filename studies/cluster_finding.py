"""Automatic marker cluster finding on simulated skin-mounted marker sets (issue 12, item 2).

    .venv/bin/python studies/cluster_finding.py

Marker sets from ``simbench.sim.markers.simulate_marker_chain``: a moving chain of 4-6
segments carries 3-4 markers per segment sliding on the skin (distances within a cluster vary by
2-7 mm), plus a few static markers (lab or a body at rest) with 0.2 mm camera noise only.
``find_clusters`` must return every segment's markers as one cluster and the static markers as
a still group, in every seed.
Also the real trial ``../shared/data/biobuddy_right_hip.c3d`` (automatic clusters). Results go
to ``studies/results/cluster_finding.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from calibration.clusters import find_clusters
from simbench.io.c3d import read_c3d_markers
from simbench.sim.markers import simulate_marker_chain

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
SEEDS = 20


def trial(seed: int) -> dict:
    """One seed: the grouping and whether it is right (every cluster exact, static markers still)."""
    x, truth, static = simulate_marker_chain(np.random.default_rng(seed))
    found = find_clusters(x)
    right = sorted(found.clusters) == truth and [static] == found.still and not found.left_out
    return {
        "seed": seed,
        "segments": len(truth),
        "right": bool(right),
        "clusters_found": len(found.clusters),
        "still_found": [len(g) for g in found.still],
        "left_out": len(found.left_out),
        "cut_mm": [round(c * 1e3, 3) for c in found.cut_m],
        "residual_mm": [round(r * 1e3, 3) for r in found.residual_m],
    }


def real_trial() -> dict | None:
    if not C3D.is_file():
        return None
    labels, xyz, _ = read_c3d_markers(C3D)
    found = find_clusters(xyz)
    return {
        "file": C3D.name,
        "clusters": [[labels[k] for k in g] for g in found.clusters],
        "still_sizes": [len(g) for g in found.still],
        "left_out": {labels[k]: why for k, why in found.left_out.items()},
        "rotation_deg": [round(a, 1) for a in found.rotation_deg],
        "residual_mm": [round(r * 1e3, 2) for r in found.residual_m],
        "cut_mm": [round(c * 1e3, 2) for c in found.cut_m],
    }


def main() -> None:
    start = time.perf_counter()
    trials = [trial(seed) for seed in range(SEEDS)]
    right = sum(t["right"] for t in trials)
    result = {
        "target": "grouped right in 20 of 20 seeds",
        "right": right,
        "seeds": SEEDS,
        "trials": trials,
        "real": real_trial(),
        "seconds": round(time.perf_counter() - start, 1),
    }
    out = HERE / "results" / "cluster_finding.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"grouped right in {right} of {SEEDS} seeds; wrote {out}")
    for t in trials:
        if not t["right"]:
            print("  wrong:", t)


if __name__ == "__main__":
    main()
