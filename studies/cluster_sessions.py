"""Cluster finding on simbench's own marker sessions and on real C3D files (issue 42, items 1-2).

    .venv/bin/python studies/cluster_sessions.py [--seeds 50] [--workers 1] [--real DIR ...]

Not a test: the figures of the closing note. Each simulated session is ``sb.simulate(model,
duration_s=20, seed=seed, markers=MarkerConfig(skin_sd_m=0.002))`` (4 markers a segment, 2 mm
smooth skin motion), on the humanoid and the linkage, and its markers are grouped by
``calibration.clusters.find_clusters``:

- **markers**: the dataset's markers as they are; **c3d**: written to C3D (single-precision
  millimetres, ``write_c3d_markers``) and read back, as ``simbench export --c3d`` and
  ``simbench calibrate`` do. Right: every segment's markers one cluster, nothing left out.
- **2-4 markers**: each segment keeps 2, 3 or 4 of its markers (drawn; at least one segment
  keeps 2). Right: the segments with 3 or 4 markers exactly, the markers of those with 2 in no
  cluster (left out, named).
- **virtual**: two clusters each get two or three virtual markers, fixed points 5-15 cm from the
  cluster placed by the least-squares pose of its markers every frame (as probing exports
  write landmarks). Right: those set aside as virtual groups, each said to move with its cluster,
  and the clusters those of the same markers without them.
- **messy**: ``simbench.sim.marker_clusters.messy_markers`` (2-4 markers a segment, skin motion
  that follows the joint angles, two clusters with virtual markers), 10 s: right as in the two
  above.

A union of two segments is *named* when a note says it may be two bodies
(``doubtful``/``doubtful_spread``). For every union the largest rotation (95th percentile from the
mean) of the joints between its segments is recorded: below 10 degrees a joint centre is not
determined (``find_clusters``' still limit) and the segments are one body to the data.

Real C3D files given with ``--real`` (directories or files) are grouped and their clusters and
notes recorded. Results go to ``studies/results/cluster_sessions.json``: the summary indented,
each session and each real file on one line.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

import simbench as sb
from calibration.clusters import find_clusters, reference_shape, rigid_fit
from calibration.rotations import quat_to_matrix
from simbench.io.atomic import atomic_write_text
from simbench.io.c3d import auto_clusters, read_c3d, write_c3d_markers
from simbench.sim.marker_clusters import MarkerConfig, messy_markers

OUT = Path(__file__).resolve().parent / "results" / "cluster_sessions.json"
MODELS = ("linkage", "humanoid")
DURATION_S = 20.0
MESSY_DURATION_S = 10.0
STILL_DEG = 10.0


def joint_rotation_deg(ds: sb.Dataset) -> dict[frozenset[str], float]:
    """95th-percentile rotation of each joint from its mean relative orientation, degrees."""
    names = list(ds.sensors)
    R = quat_to_matrix(ds.truth.q_w_b)
    out = {}
    for p, c in zip(ds.truth.parent, ds.truth.child, strict=True):
        rel = np.einsum("fji,fjk->fik", R[:, names.index(p)], R[:, names.index(c)])
        U, _, Vt = np.linalg.svd(rel.mean(axis=0))
        cos = (np.einsum("ij,fij->f", U @ Vt, rel) - 1.0) / 2.0
        out[frozenset((p, c))] = float(np.percentile(np.degrees(np.arccos(np.clip(cos, -1, 1))), 95))
    return out


def judge(
    found: Any, segment: np.ndarray, truth: list[list[int]], pairs: list[int], rotation: dict
) -> dict[str, Any]:
    """Right or not, and every cluster that spans two segments (with its joints' rotation)."""
    named = [sorted(d.part + d.other) for d in found.doubtful_spread] + [
        sorted(a + b) for a, b, *_ in found.doubtful
    ]
    unions = []
    for c in found.clusters:
        segs = sorted(set(segment[c].tolist()))
        if len(segs) > 1:
            joints = [
                rotation[frozenset((a, b))]
                for a in segs
                for b in segs
                if a < b and frozenset((a, b)) in rotation
            ]
            unions.append(
                {
                    "segments": segs,
                    "markers": [int((segment[c] == s).sum()) for s in segs],
                    "joint_p95_deg": [round(j, 1) for j in joints],
                    "named": c in named,
                }
            )
    in_clusters = {k for c in found.clusters for k in c}
    return {
        "right": sorted(found.clusters) == sorted(truth) and not (set(pairs) & in_clusters),
        "unions": unions,
        "pairs_left_out": all(k in found.left_out for k in pairs),
        "missing": [str(segment[t[0]]) for t in truth if t not in found.clusters],
        "doubtful": len(found.doubtful_spread) + len(found.doubtful),
    }


def add_virtual(x: np.ndarray, truth: list[list[int]], rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """Two or three virtual markers on each of two clusters (module docstring)."""
    groups, extra = [], []
    for h in sorted(rng.choice(len(truth), 2, replace=False).tolist()):
        fit = rigid_fit(reference_shape(x[:, truth[h]]), x[:, truth[h]])
        k = int(rng.integers(2, 4))
        d = rng.standard_normal((k, 3))
        points = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.05, 0.15, (k, 1))
        extra.append(np.einsum("fij,kj->fki", fit.R_w_c, points) + fit.p_w_c[:, None])
        start = x.shape[1] + sum(e.shape[1] for e in extra[:-1])
        groups.append((h, list(range(start, start + k))))
    return np.concatenate([x, *extra], axis=1), groups


def session(model: str, seed: int) -> dict[str, Any]:
    """One seed of one model: the four variants (module docstring)."""
    ds = sb.simulate(model, duration_s=DURATION_S, seed=seed, markers=MarkerConfig(skin_sd_m=0.002))
    rotation = joint_rotation_deg(ds)
    m = ds.markers
    segment = np.array(m.segment)
    truth = [np.flatnonzero(segment == s).tolist() for s in ds.sensors]
    out: dict[str, Any] = {"model": model, "seed": seed}
    start = time.perf_counter()
    out["markers"] = judge(find_clusters(m.xyz), segment, truth, [], rotation)
    out["seconds_per_grouping"] = round(time.perf_counter() - start, 2)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.c3d"
        write_c3d_markers(path, list(m.labels), m.xyz, 1.0 / float(ds.time_s[1] - ds.time_s[0]))
        out["c3d"] = judge(find_clusters(read_c3d(path).xyz_m), segment, truth, [], rotation)
    rng = np.random.default_rng([42, seed])
    keep = rng.integers(2, 5, len(truth))
    keep[rng.integers(len(truth))] = 2
    kept = np.sort(np.concatenate([t[:k] for t, k in zip(truth, keep, strict=True)]))
    sub = segment[kept]
    sub_truth = [np.flatnonzero(sub == s).tolist() for s in ds.sensors if (sub == s).sum() >= 3]
    sub_pairs = [int(k) for s in ds.sensors if (sub == s).sum() < 3 for k in np.flatnonzero(sub == s)]
    out["two_to_four"] = judge(find_clusters(m.xyz[:, kept]), sub, sub_truth, sub_pairs, rotation)
    x, groups = add_virtual(m.xyz, truth, rng)
    found = find_clusters(x)
    vseg = np.concatenate([segment, np.array(["virtual"] * (x.shape[1] - len(segment)))])
    row = judge(found, vseg, truth, [], rotation)
    hosts_all = found.clusters + found.still
    row["virtual_set_aside"] = found.virtual == sorted(g for _, g in groups)
    row["virtual_hosts_right"] = all(
        g in found.virtual
        and found.virtual_with[found.virtual.index(g)] is not None
        and hosts_all[found.virtual_with[found.virtual.index(g)]] == truth[h]
        for h, g in groups
    )
    row["rest_as_without"] = found.clusters == find_clusters(m.xyz).clusters
    out["virtual"] = row
    mm = messy_markers(
        sb.simulate(model, duration_s=MESSY_DURATION_S, seed=seed),
        np.random.default_rng([43, seed]),
        virtual=2,
    )
    found = find_clusters(mm.xyz)
    mseg = np.array(mm.segment)
    for g in mm.virtual:
        mseg[g] = "virtual"
    row = judge(found, mseg, mm.clusters, [k for p in mm.pairs for k in p], rotation)
    row["virtual_set_aside"] = found.virtual == sorted(mm.virtual)
    out["messy"] = row
    return out


def real(paths: list[Path]) -> list[dict[str, Any]]:
    """Each real file's automatic clusters and notes."""
    files = sorted({f for p in paths for f in ([p] if p.is_file() else p.glob("*.c3d"))})
    rows = []
    for f in files:
        c3d = read_c3d(f)
        start = time.perf_counter()
        clusters, notes = auto_clusters(c3d.labels, c3d.xyz_m)
        rows.append(
            {
                "file": f.name,
                "markers": len(c3d.labels),
                "frames": int(c3d.xyz_m.shape[0]),
                "clusters": clusters,
                "notes": [n[:240] for n in notes if n.startswith(("cluster ", "virtual", "still"))],
                "seconds": round(time.perf_counter() - start, 2),
            }
        )
    return rows


def _tally(trials: list[dict[str, Any]], key: str) -> dict[str, Any]:
    rows = [t[key] for t in trials]
    unions = [u for r in rows for u in r["unions"]]
    moving = [u for u in unions if max(u["joint_p95_deg"], default=0.0) >= STILL_DEG]
    return {
        "right": sum(r["right"] for r in rows),
        "of": len(rows),
        "sessions_with_a_union": sum(bool(r["unions"]) for r in rows),
        "unions": len(unions),
        "unions_named": sum(u["named"] for u in unions),
        "unions_across_a_joint_turning_10_deg_or_more": len(moving),
        "those_named": sum(u["named"] for u in moving),
        "sessions_with_a_doubt_note": sum(r["doubtful"] > 0 for r in rows),
        **{
            name: sum(bool(r.get(name)) for r in rows)
            for name in ("pairs_left_out", "virtual_set_aside", "virtual_hosts_right", "rest_as_without")
            if name in rows[0]
        },
    }


def brief(trial: dict[str, Any]) -> dict[str, Any]:
    """A session's record for the results file: each union as one string
    (``"forearm_l+hand_l 4+4 14.2deg named"``: segments, markers of each, the joints' rotation)."""
    out = dict(trial)
    for key, row in trial.items():
        if isinstance(row, dict) and "unions" in row:
            out[key] = {k: v for k, v in row.items() if k not in ("unions", "missing")}
            out[key]["unions"] = [
                f"{'+'.join(u['segments'])} {'+'.join(map(str, u['markers']))} "
                f"{'/'.join(f'{d:g}' for d in u['joint_p95_deg'])}deg{' named' if u['named'] else ''}"
                for u in row["unions"]
            ]
    return out


def compact_json(result: dict[str, Any], listed: tuple[str, ...]) -> str:
    """``result`` as indented JSON, but each item of the lists under ``listed`` on one line."""
    head = {k: v for k, v in result.items() if k not in listed}
    text = json.dumps(head, indent=1)[:-2]
    for key in listed:
        rows = ",\n".join("  " + json.dumps(r, separators=(",", ":")) for r in result[key])
        text += f',\n "{key}": [\n{rows}\n ]'
    return text + "\n}\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--real", type=Path, nargs="*", default=[])
    args = parser.parse_args()
    start = time.perf_counter()
    jobs = [(model, seed) for model in MODELS for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        trials = list(pool.map(session, *zip(*jobs, strict=True)))
    summary = {
        model: {
            key: _tally([t for t in trials if t["model"] == model], key)
            for key in ("markers", "c3d", "two_to_four", "virtual", "messy")
        }
        for model in MODELS
    }
    result = {
        "seeds": args.seeds,
        "duration_s": DURATION_S,
        "summary": summary,
        "real": real(args.real),
        "trials": [brief(t) for t in trials],
        "seconds": round(time.perf_counter() - start, 1),
    }
    atomic_write_text(OUT, compact_json(result, ("real", "trials")))
    print(json.dumps(summary, indent=1))
    print(f"wrote {OUT} in {result['seconds']} s")


if __name__ == "__main__":
    main()
