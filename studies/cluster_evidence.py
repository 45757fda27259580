"""How much evidence the humanoid's sessions give against each union across a joint (issue 42, item 1).

    .venv/bin/python studies/cluster_evidence.py [--seeds 6] [--skin-mm 2 1] [--real PATH ...] [--out FILE]

Not a test: the figures of ``docs/cluster-finding.md`` ("What limits the humanoid"). For each seed
and skin level, ``sb.simulate("humanoid", duration_s=20, seed=s,
markers=MarkerConfig(skin_sd_m=skin))`` is grouped by ``find_clusters`` (right: every segment's
markers one cluster, nothing left out), and for every joint the union of its two segments' markers
is judged by each of ``rigid_parts``' tests as if the tree had proposed it: the median frame's
misfit ratio F (``union_misfit_ratio``), the worst stretch (``burst_excess``) and the spread excess
(``spread_excess``, with the noise ``find_clusters`` took from the recording), each as its
statistic over its limit (above 1: refused). So is each marker of the child segment beside the
parent's markers (one marker joining a cluster: the misfit and spread tests, the spread at 1 in
100; the burst test is not run on it by ``rigid_parts`` but is recorded). The joint's rotation is
the 95th percentile from its mean relative orientation (truth).

The *relative noise* of a cluster is the median over its pairs of the distance spread over the
distance (unit-free: what decides how far a joint must turn for its segments to be told apart).
It is recorded for the simulated segments and for the clusters ``find_clusters`` finds on the real
files given with ``--real`` (C3D and TRC). Results go to ``studies/results/cluster_evidence.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import simbench as sb
from calibration.clusters import (
    SPREAD_FALSE_ALARM,
    SPREAD_SMALL,
    burst_excess,
    distance_spread,
    find_clusters,
    spread_excess,
    spread_limit,
    union_misfit_frames,
)
from calibration.quantiles import f_ppf
from simbench.io.atomic import atomic_write_text
from simbench.io.c3d import read_c3d
from simbench.io.trc import read_trc
from simbench.sim.marker_clusters import MarkerConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cluster_sessions import compact_json, joint_rotation_deg

OUT = Path(__file__).resolve().parent / "results" / "cluster_evidence.json"


def relative_noise(markers: np.ndarray, groups: list[list[int]]) -> list[float]:
    """Each group's median over its pairs of distance spread / median distance (unit-free)."""
    out = []
    for g in groups:
        x = markers[:, g]
        spread = distance_spread(x)
        with np.errstate(invalid="ignore"):
            d = np.nanmedian(np.linalg.norm(x[:, :, None] - x[:, None, :], axis=3), axis=0)
        i, j = np.triu_indices(len(g), 1)
        out.append(round(float(np.median(spread[i, j] / d[i, j])), 4))
    return out


def tests(x: np.ndarray, spread: np.ndarray, a: np.ndarray, b: np.ndarray, noise: Any) -> dict[str, float]:
    """Each test's statistic over its limit for the union of ``a`` and ``b`` (above 1: refused)."""
    added, own, d1, d2 = union_misfit_frames(x, a, b)
    f = (added / d1) / (own / d2)
    out = {"misfit": float(np.nanmedian(f)) / float(f_ppf(1.0 - 1e-3, d1, d2))}
    burst = burst_excess(added, own)
    out["burst"] = burst[0] / burst[1] if burst else float("nan")
    excess = spread_excess(spread, a, b, noise)
    rate = SPREAD_SMALL if min(len(a), len(b)) < 3 <= max(len(a), len(b)) else SPREAD_FALSE_ALARM
    out["spread"] = excess[1] / spread_limit(len(a), len(b), rate) if excess else float("nan")
    return {k: round(v, 2) for k, v in out.items()}


def session(seed: int, skin_m: float) -> dict[str, Any]:
    """One seed at one skin level: right or not, each joint's union judged."""
    ds = sb.simulate("humanoid", duration_s=20.0, seed=seed, markers=MarkerConfig(skin_sd_m=skin_m))
    rotation = joint_rotation_deg(ds)
    x = ds.markers.xyz
    segment = np.array(ds.markers.segment)
    truth = [np.flatnonzero(segment == s).tolist() for s in ds.sensors]
    found = find_clusters(x)
    spread = distance_spread(x)
    joints = []
    for parent, child in zip(ds.truth.parent, ds.truth.child, strict=True):
        a, b = np.flatnonzero(segment == parent), np.flatnonzero(segment == child)
        joints.append(
            {
                "joint": f"{parent}+{child}",
                "p95_deg": round(rotation[frozenset((parent, child))], 1),
                "union": tests(x, spread, a, b, found.noise),
                "single": [tests(x, spread, a, np.array([k]), found.noise) for k in b],
            }
        )
    return {
        "seed": seed,
        "skin_mm": skin_m * 1e3,
        "right": sorted(found.clusters) == sorted(truth),
        "unions": [
            "+".join(sorted(set(segment[c].tolist())))
            for c in found.clusters
            if len(set(segment[c].tolist())) > 1
        ],
        "relative_noise": relative_noise(x, truth),
        "joints": joints,
    }


def real(paths: list[Path]) -> list[dict[str, Any]]:
    """The relative noise of each cluster found on each real file."""
    files = sorted({f for p in paths for f in ([p] if p.is_file() else [*p.glob("*.c3d"), *p.glob("*.trc")])})
    rows = []
    for f in files:
        try:
            x = read_c3d(f).xyz_m if f.suffix == ".c3d" else read_trc(f).xyz
        except Exception as error:  # a study: a file not read is recorded
            rows.append({"file": f.name, "not read": str(error)[:120]})
            continue
        found = find_clusters(x)
        rows.append({"file": f.name, "relative_noise": sorted(relative_noise(x, found.clusters))})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=6)
    parser.add_argument("--skin-mm", type=float, nargs="*", default=[2.0, 1.0])
    parser.add_argument("--real", type=Path, nargs="*", default=[])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    start = time.perf_counter()
    trials = [session(seed, mm / 1e3) for mm in args.skin_mm for seed in range(args.seeds)]
    summary = {}
    for mm in args.skin_mm:
        rows = [t for t in trials if t["skin_mm"] == mm]
        names = [j["joint"] for j in rows[0]["joints"]]
        summary[f"{mm:g} mm"] = {
            "right": sum(t["right"] for t in rows),
            "of": len(rows),
            "relative_noise_median": float(np.median([v for t in rows for v in t["relative_noise"]])),
            "unions": sorted({u for t in rows for u in t["unions"]}),
            # per joint: the largest of the three tests' statistic/limit, median over seeds
            "joint_evidence": {
                n: float(np.median([max(t["joints"][i]["union"].values()) for t in rows]))
                for i, n in enumerate(names)
            },
        }
    result = {
        "summary": summary,
        "real": real(args.real),
        "trials": trials,
        "seconds": round(time.perf_counter() - start, 1),
    }
    atomic_write_text(args.out, compact_json(result, ("real", "trials")))
    print(json.dumps(summary, indent=1))
    print(f"wrote {args.out} in {result['seconds']} s")


if __name__ == "__main__":
    main()
