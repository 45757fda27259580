"""Calibrate the simulator against O'Brien et al. (2000): the Flock of Birds and the linkage.

    .venv/bin/python studies/paper_tracker.py [--json OUT]

The same experiments as the validation run (:mod:`simbench.experiments.obrien`), printed on their own:
two sensors rigidly 56.5 cm apart moved through the volume with the paper-like preset
``ascension-flock-paper`` (the paper's scale factor 0.94 and scaled spread 0.7 cm), then six 45 s
linkage exercise sets, the sixth with the sensors moved (max error 1.1 cm, 23 of 30 differences
negative, hierarchy right in all six). The preset's systematic effects are fitted on Table 1
(its comments say which values).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from simbench.experiments.obrien import PAPER, linkage_experiment, rigid_pair_scale
from simbench.experiments.validate import Plan
from simbench.io.atomic import atomic_write_text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="OUT")
    args = parser.parse_args()
    scale = rigid_pair_scale()
    plan = Plan.of(quick=False)
    linkage = linkage_experiment(plan.linkage_sets, plan.linkage_s, scale["scale"])
    print("Two sensors rigidly 56.5 cm apart, ascension-flock-paper preset")
    print(f"  {'':24}{'paper':>10}{'simbench':>10}")
    print(f"  {'scale factor':24}{PAPER['unit_scale']:>10.3f}{scale['scale']:>10.3f}")
    spread = scale["scaled_std_cm"]
    print(f"  {'scaled std (cm)':24}{PAPER['scaled_std_cm']:>10.2f}{spread:>10.2f}")
    print(f"\nLinkage, {len(linkage['sets'])} exercise sets, lengths x {scale['scale']:.3f}")
    for s in linkage["sets"]:
        errs = " ".join(f"{r['difference_cm']:+.2f}" for r in s["rows"].values())
        verdict = "right" if s["hierarchy_correct"] else "WRONG"
        print(f"  set {s['set']}: hierarchy {verdict}, errors (cm) {errs}")
    worst = max(s["max_abs_error_cm"] for s in linkage["sets"])
    right = sum(s["hierarchy_correct"] for s in linkage["sets"])
    verdict = f"{right} of {len(linkage['sets'])}"
    print(f"  {'max error (cm)':24}{PAPER['linkage_max_error_cm']:>10.2f}{worst:>10.2f}")
    print(f"  {'hierarchy right':24}{'6 of 6':>10}{verdict:>10}")
    if args.json:
        atomic_write_text(
            Path(args.json),
            json.dumps({"unit_scale": scale, "linkage": linkage, "paper": PAPER}, indent=2) + "\n",
        )


if __name__ == "__main__":
    main()
