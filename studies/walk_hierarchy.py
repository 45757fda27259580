"""Walk hierarchies (issue 13, part 3): O'Brien et al.'s "one thigh the child of the other", its
suspected cause (the pelvis sensor on a pushed battery pack), and the misfit tree.

    .venv/bin/python studies/walk_hierarchy.py [--seeds 20] [--duration 45] [--quiet-seeds 0] [--workers 2]

Seeded humanoid walks (seeds 101..., the validation's walk seeds) with the paper-like preset
``skin-paper-human``, each with the pelvis sensor on the pushed pack (the preset's ``[skin.pack]``)
and without it, same seed, calibrated with O'Brien's minimum spanning tree (``mst``) and the
misfit tree (``misfit``, :mod:`calibration.hierarchy`), root the pelvis
(:func:`simbench.experiments.walk_hierarchy.walk_trial`). Conditions: hips ``walk`` (the
built-in walk) or ``sagittal`` (abduction and rotation at a quarter: both hips turning nearly
about one lateral axis), times tracker ``preset`` (transmitter at the walk's centre) or ``stand``
(transmitter on ascension-flock's stand, the walk's far end 2 m away), times pack on / off;
``--quiet-seeds`` more with the sagittal hips and a quiet tracker.

For each condition and method: trees right, trees with one thigh the child of the other, the
wrong edges and how often each occurs, and the median residual / noise / misfit of the pairs
between pelvis and thighs. Results: ``studies/results/walk_hierarchy.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from simbench.experiments.walk_hierarchy import FIRST_SEED, HIP_PAIRS, METHODS, walk_trial
from simbench.io.atomic import atomic_write_text

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "walk_hierarchy.json"


def run_trial(job: tuple[int, float, bool, str, str]) -> dict[str, Any]:
    """One walk trial (a picklable job for the process pool)."""
    seed, duration_s, pack, hips, tracker = job
    return walk_trial(seed, duration_s, pack=pack, hips=hips, tracker=tracker)


def condition_name(trial: dict[str, Any]) -> str:
    """``"<hips>, <tracker> tracker, pack|no pack"``."""
    return f"{trial['hips']}, {trial['tracker']} tracker, {'pack' if trial['pack'] else 'no pack'}"


def summarise(trials: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts per condition and method, and the hip pairs' median figures per condition."""
    out: dict[str, Any] = {}
    for name in dict.fromkeys(condition_name(t) for t in trials):
        runs = [t for t in trials if condition_name(t) == name]
        entry: dict[str, Any] = {"trials": len(runs), "seeds": [t["seed"] for t in runs]}
        for method in METHODS:
            trees = [t["methods"][method] for t in runs]
            edges = Counter(e for tree in trees for e in tree["wrong_edges"])
            entry[method] = {
                "correct": sum(tree["correct"] for tree in trees),
                "thigh_child_of_thigh": sum(tree["thigh_child_of_thigh"] for tree in trees),
                "wrong_edges": dict(edges.most_common()),
            }
        entry["hip_pairs_median"] = {
            f"{a}-{b}": {
                key: float(np.median([t["hip_pairs"][f"{a}-{b}"][key] for t in runs]))
                for key in ("rms_residual_cm", "noise_cm", "misfit_cm", "weak_ratio")
            }
            for a, b in HIP_PAIRS
        }
        out[name] = entry
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="walks per condition (default 20)")
    parser.add_argument("--duration", type=float, default=45.0, help="walk length, s (default 45)")
    parser.add_argument(
        "--quiet-seeds", type=int, default=0, help="walks per quiet-tracker condition (default 0)"
    )
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    seeds = range(FIRST_SEED, FIRST_SEED + args.seeds)
    jobs = [
        (s, args.duration, pack, hips, tracker)
        for tracker in ("preset", "stand")
        for hips in ("walk", "sagittal")
        for pack in (True, False)
        for s in seeds
    ]
    quiet = range(FIRST_SEED, FIRST_SEED + args.quiet_seeds)
    jobs += [(s, args.duration, pack, "sagittal", "quiet") for pack in (True, False) for s in quiet]
    with ProcessPoolExecutor(args.workers) as pool:
        trials = list(pool.map(run_trial, jobs))
    summary = summarise(trials)
    doc = {
        "settings": {
            "preset": "skin-paper-human",
            "seeds": args.seeds,
            "first_seed": FIRST_SEED,
            "duration_s": args.duration,
            "quiet_seeds": args.quiet_seeds,
            "root": "pelvis",
            "seconds": time.perf_counter() - start,
        },
        "summary": summary,
        "trials": trials,
    }
    atomic_write_text(OUT, json.dumps(doc, indent=1))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
