"""Automatic marker cluster finding on simulated skin-mounted marker sets (issue 12, item 2).

    .venv/bin/python studies/cluster_finding.py

A moving chain of 4-6 segments (random joint rotations, smooth in time) carries 3-4 markers per
segment; each marker slides on the skin with smooth random motion sized so that the distances
within a cluster vary by 2-7 mm (standard deviation, drawn per cluster); a few static markers
(lab or a body at rest) carry 0.2 mm camera noise only. ``find_clusters`` must return every
segment's markers as one cluster and the static markers as a still group, in every seed.
Also the real trial ``../shared/data/biobuddy_right_hip.c3d`` (automatic clusters). Results go
to ``studies/results/cluster_finding.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from calibration.clusters import find_clusters
from calibration.rotations import rotvec_to_matrix
from simbench.io.c3d import read_c3d_markers

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
SEEDS = 20


def smooth_noise(rng: np.random.Generator, frames: int, shape: tuple[int, ...], cycles: float) -> np.ndarray:
    """Smooth zero-mean unit-variance random signals ``(frames, *shape)``: sums of random sines."""
    t = np.linspace(0.0, 1.0, frames)[:, None]
    out = np.zeros((frames, *shape))
    for _ in range(4):
        f = rng.uniform(0.5, 1.5, shape).ravel() * cycles
        phase = rng.uniform(0, 2 * np.pi, f.shape)
        out += np.sin(2 * np.pi * f * t + phase).reshape(frames, *shape)
    return out / np.sqrt(2.0)  # four unit sines: variance 4 * 1/2


def simulate_marker_chain(
    rng: np.random.Generator, *, frames: int = 600, n_static: int = 3
) -> tuple[np.ndarray, list[list[int]], list[int]]:
    """Markers ``(frames, M, 3)`` in metres of a moving chain, the true clusters and the static markers.

    Returns:
        markers (shuffled order), true clusters (index lists, sorted), static marker indices.
    """
    n_seg = int(rng.integers(4, 7))
    length = rng.uniform(0.25, 0.45, n_seg)
    # root: translates and turns; each joint: rotations of about +-35 degrees about random axes
    R_root = rotvec_to_matrix(0.6 * smooth_noise(rng, frames, (3,), 2.0))
    p = 0.3 * smooth_noise(rng, frames, (3,), 1.5) + np.array([0.0, 0.0, 1.0])
    R = R_root
    parts, sizes = [], []
    for s in range(n_seg):
        if s > 0:
            R = R @ rotvec_to_matrix(0.6 * smooth_noise(rng, frames, (3,), 2.0))
        k = int(rng.integers(3, 5))
        local = np.column_stack(
            [rng.uniform(-0.05, 0.05, k), rng.uniform(-0.05, 0.05, k), -rng.uniform(0.3, 0.7, k) * length[s]]
        )
        local[:, :2] += 0.06 * rng.standard_normal((k, 2))  # cluster plate off the bone axis
        skin_sd = rng.uniform(0.002, 0.007)  # distance spread within this cluster, m
        slide = smooth_noise(rng, frames, (k, 3), 3.0) * skin_sd / np.sqrt(2.0)
        parts.append(np.einsum("fij,kj->fki", R, local) + p[:, None] + slide)
        sizes.append(k)
        p = p + np.einsum("fij,j->fi", R, np.array([0.0, 0.0, -length[s]]))
    static = rng.uniform(-1.0, 1.0, (n_static, 3)) + np.array([0.0, 0.0, 1.0])
    parts.append(np.broadcast_to(static, (frames, n_static, 3)).copy())
    x = np.concatenate(parts, axis=1)
    x += rng.normal(0.0, 0.0002, x.shape)  # camera noise
    order = rng.permutation(x.shape[1])
    where = np.argsort(order)  # original index -> shuffled index
    starts = np.cumsum([0, *sizes])
    clusters = sorted(sorted(where[starts[i] : starts[i + 1]].tolist()) for i in range(n_seg))
    static_idx = sorted(where[starts[-1] :].tolist())
    return x[:, order], clusters, static_idx


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
