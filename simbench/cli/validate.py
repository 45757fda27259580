"""``simbench validate``: the paper's experiments reproduced in simulation, scored; writes the report."""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path

from tqdm import tqdm

from simbench.errors import InputError
from simbench.experiments.validate import expected_cost, run_validation
from simbench.report.validation import write_report


def add_arguments(val: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench validate``."""
    val.description = (
        "Reproduce O'Brien et al.'s linkage and human experiments and Fontaine et al.'s "
        "sourceless orientation in simulation, score them against the truth and write the report."
    )
    val.add_argument("--quick", action="store_true", help="fewer, shorter sessions (under a minute)")
    val.add_argument("--out", default="reports", metavar="DIR", help="report folder (default reports)")
    val.add_argument("--no-progress", action="store_true", help="no progress bar")
    val.add_argument(
        "--physics-cache",
        metavar="DIR",
        help="keep the sessions' physics in DIR and read back what an earlier run left there: the "
        "same figures, a second full run in under a minute instead of two (a full run keeps about "
        "830 MiB; default: a temporary folder, removed at the end)",
    )
    val.set_defaults(func=cmd_validate)


def cmd_validate(args: argparse.Namespace) -> int:
    """``simbench validate``: the paper's experiments reproduced and scored; writes the report."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    physics = None if args.physics_cache is None else Path(args.physics_cache)
    if physics is not None:
        if physics.exists() and not physics.is_dir():
            raise InputError(f"--physics-cache {physics} exists and is not a folder")
        try:
            physics.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"--physics-cache {physics}: cannot make the folder ({exc.strerror})") from exc
    # the bar's units are the work: each step's expected CPU seconds, credited as its jobs end, so
    # that its rate and the time it says is left mean something (issue 44)
    cost = expected_cost(args.quick)
    bar = tqdm(
        total=round(sum(cost.values())),
        desc="validate",
        unit="cpu-s",
        file=sys.stderr,
        disable=args.no_progress,
        bar_format="{l_bar}{bar}| {percentage:3.0f}% [{elapsed}<{remaining}]",
    )

    lock = threading.Lock()  # the pool's threads report the jobs they see end

    def progress(done: float) -> None:
        with lock:
            bar.update(max(0, round(done) - bar.n))

    results, keep = run_validation(quick=args.quick, progress=progress, physics_folder=physics)
    progress(sum(cost.values()) - cost["report"])
    paths = write_report(results, keep, out)
    progress(sum(cost.values()))
    bar.close()
    s = results["summary"]
    print(f"simbench validate{' --quick' if args.quick else ''}: {results['run_time_s']:.0f} s")
    print(
        f"  linkage: max error {s['linkage_max_error_cm']:.2f} cm (paper 1.1), hierarchy correct in "
        f"{s['linkage_hierarchy_correct']} of {s['linkage_sets']} sets"
    )
    print(
        f"  humanoid: max limb error {s['humanoid_max_error_cm']:.2f} cm (paper 4.1); hierarchy correct in "
        f"{s['exercise_hierarchy_correct']} of {s['exercise_trials']} exercise and "
        f"{s['walk_hierarchy_correct']} of {s['walk_trials']} walk trials"
    )
    print(f"  slip found: {s['slip_found']}")
    for name, p in paths.items():
        print(f"  wrote {p}" if name != "json" else f"  wrote {p} (every figure)")
    return 0
