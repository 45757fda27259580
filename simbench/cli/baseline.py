"""``simbench baseline``: the accuracy regression check against ``reports/baseline.json``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simbench.cli.types import non_negative_float
from simbench.errors import InputError
from simbench.experiments.baseline import (
    BASELINE_FILE,
    CHECKOUT_BASELINE,
    compare,
    compute,
    diff_lines,
    load_baseline,
    load_scenarios,
    write_baseline,
)


def add_arguments(bas: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench baseline``."""
    bas.description = (
        "Recompute fixed seeded scenarios' accuracy figures and compare them with the accepted "
        "ones (exit 1 if any got worse than the tolerance), or --update them. simbench's own scenarios by "
        "default; --scenarios FILE runs yours, with your estimators (joint:SPEC, orientation:SPEC)."
    )
    bas.add_argument(
        "--scenarios",
        metavar="FILE.toml",
        help="your own scenarios ([[scenario]] name, estimator, model, motion, sensors, duration_s, rate_hz, "
        "seed); their accepted figures are in FILE.baseline.json beside it unless --file says",
    )
    bas.add_argument(
        "--update", action="store_true", help="recompute and rewrite the baseline, showing the diff"
    )
    bas.add_argument(
        "--tolerance", type=non_negative_float, default=0.10, help="relative tolerance (default 0.10)"
    )
    bas.add_argument(
        "--file",
        metavar="PATH",
        help="baseline file (default: a checkout's reports/baseline.json, else the package's; or beside "
        "--scenarios)",
    )
    bas.set_defaults(func=cmd_baseline)


def cmd_baseline(args: argparse.Namespace) -> int:
    """``simbench baseline``: check accuracy against the accepted figures, or update them.

    Returns 0 when no figure got worse than the tolerance (or after ``--update``), 1 otherwise.
    """
    scenarios = load_scenarios(args.scenarios) if args.scenarios else None
    default = Path(args.scenarios).with_suffix(".baseline.json") if args.scenarios else BASELINE_FILE
    path = Path(args.file) if args.file else default
    if args.update and not args.file and not args.scenarios and path != CHECKOUT_BASELINE:
        raise InputError(
            f"--update: {path} is the installed package's baseline, not yours to rewrite; give --file PATH "
            "(simbench examples DIR writes a copy to start from)"
        )
    if args.update:
        if not path.resolve().parent.is_dir():
            raise InputError(f"cannot write {path}: folder {path.parent} does not exist")
        if path.is_dir():
            raise InputError(f"cannot write {path}: it is a folder")
        current = compute(scenarios)
        try:
            old = load_baseline(path)
        except InputError:
            old = {}
        kept = {name: old[name] for name in current.unavailable if name in old}
        changes = diff_lines(old, {**kept, **current})
        write_baseline({**kept, **current}, path)
        print(f"simbench baseline --update: wrote {path}")
        print("\n".join(f"  {line}" for line in changes) if changes else "  no change")
        return 0
    accepted = load_baseline(path)  # a missing or broken file is found before the long computation
    current = compute(scenarios)
    problems = compare(current, accepted, rel_tol=args.tolerance)
    for name, figures in current.items():
        print(f"  {name}: " + ", ".join(f"{k} {v:.4g}" for k, v in figures.items()))
    for name in current.unavailable:
        print(f"  {name}: not computed here (its data is missing), not checked")
    if problems:
        print("simbench baseline: accuracy got worse:", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 1
    print("simbench baseline: no regression")
    return 0
