"""Every estimator on every BROAD trial in a folder, against TRIAD and issue 15's targets.

    .venv/bin/python studies/broad_trials.py [--data DIR] [--json studies/results/broad_trials.json]

BROAD (Laidig et al. 2021, CC BY 4.0) has 39 trials; ``../shared/data`` holds two. The others are
in the authors' repository (github.com/dlaidig/broad, ``data_hdf5/``); point ``--data`` at a
folder of them (file names as there, e.g. ``07_undisturbed_fast_rotation_B.hdf5``). Each trial
goes through what ``simbench orient`` does: the magnetometer calibrated from the recording
(whole and span by span), then each method; errors with BROAD's definitions. The default
gyro-free method's targets: never worse than TRIAD, at most 0.8 x TRIAD on undisturbed trials and
0.6 x on trials with a magnet.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from simbench.estimators import DEFAULT_ORIENTATION as DEFAULT_METHOD
from simbench.io.imu import read_broad
from simbench.orient import calibrate_magnetometers, estimate
from simbench.score import score_orientation

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
METHODS = (DEFAULT_METHOD, "triad", "fontaine", "vqf")


def target(stem: str) -> float:
    """The default's target as a fraction of TRIAD's error, by the trial's kind."""
    return 0.6 if "magnet" in stem else 0.8 if "undisturbed" in stem else 1.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str(DATA), help="folder of BROAD .hdf5 trials")
    parser.add_argument("--json", metavar="OUT")
    args = parser.parse_args()
    trials = sorted(
        p for p in Path(args.data).glob("*.hdf5") if "undisturbed" in p.stem or "disturbed" in p.stem
    )
    results = {}
    print(f"{'trial':<44}" + "".join(f"{m:>10}" for m in METHODS) + f"{'x TRIAD':>9}{'target':>8}")
    for path in trials:
        rec, _ = calibrate_magnetometers(read_broad(path))
        row = {}
        for method in METHODS:
            run = estimate(rec, method)
            row[method] = score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate).per_sensor["imu"]
        ratio = row[DEFAULT_METHOD]["total_deg"] / row["triad"]["total_deg"]
        results[path.stem] = {
            "methods": row,
            "ratio_to_triad": ratio,
            "target_ratio": target(path.stem),
            "target_met": bool(ratio <= target(path.stem)),
        }
        print(
            f"{path.stem[:43]:<44}"
            + "".join(f"{row[m]['total_deg']:>10.2f}" for m in METHODS)
            + f"{ratio:>9.2f}{'met' if ratio <= target(path.stem) else 'NOT':>8}",
            flush=True,
        )
    ratios = np.array([r["ratio_to_triad"] for r in results.values()])
    if ratios.size:
        print(
            f"\n{ratios.size} trials: {DEFAULT_METHOD} beats TRIAD on {int(np.sum(ratios < 1))}, "
            f"meets its target on {sum(r['target_met'] for r in results.values())}"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
