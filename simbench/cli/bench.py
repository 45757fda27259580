"""``simbench bench``: the benchmark suite's scenarios, every built-in and the user's estimators,
scored in ``DIR/scorecard.json``, ``DIR/index.md`` and ``DIR/index.html``."""

from __future__ import annotations

import argparse
import os
import sys
from contextlib import nullcontext
from pathlib import Path

from tqdm import tqdm

from simbench.api import TIME_LIMIT_S
from simbench.cli.types import positive_float, positive_int
from simbench.experiments.bench import KIND_CHOICES, check_out, run_bench, write_bench
from simbench.experiments.sweep import dask_executor


def add_arguments(b: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench bench``."""
    b.add_argument(
        "--estimator",
        action="append",
        default=[],
        metavar="SPEC",
        help="an estimator of yours (module:function, path/file.py:function, cmd:COMMAND {poses} "
        "{hierarchy} {out}); repeat for several; each runs on the scenarios of its kind",
    )
    b.add_argument("--kind", choices=KIND_CHOICES, default="all", help="the scenarios run (default: all)")
    b.add_argument("--quick", action="store_true", help="the quick scenarios over the first seeds only")
    b.add_argument("--out", metavar="DIR", default="bench", help="output folder (default: bench)")
    where = b.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=positive_int, default=os.cpu_count() or 1, help="local worker processes"
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://127.0.0.1:8786")
    b.add_argument(
        "--time-limit",
        type=positive_float,
        default=TIME_LIMIT_S,
        metavar="SECONDS",
        help=f"a command estimator's time limit per dataset (default: {TIME_LIMIT_S:g} s)",
    )
    b.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    b.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    """``simbench bench``: exits 0 whatever the estimators do (their failures are in the
    scorecard); 2 on bad input (an unknown spec, an --out that is a file), before any work."""
    out = check_out(Path(args.out))
    bar = tqdm(desc="simbench bench", unit="dataset", file=sys.stderr, disable=args.no_progress)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    cluster = dask_executor(args.scheduler) if args.scheduler else nullcontext(None)
    try:
        with cluster as executor:
            card = run_bench(
                args.estimator,
                kind=args.kind,
                quick=args.quick,
                executor=executor,
                workers=args.workers,
                time_limit_s=args.time_limit,
                progress=progress,
            )
    finally:
        bar.close()
    paths = write_bench(card, out)
    failures = sum(r["failures"] for r in card["rows"])
    significant = sum(c["significant"] for c in card["comparisons"])
    print(
        f"simbench bench: {len(card['scenarios'])} scenario(s) x {len(card['seeds'])} seed(s), "
        f"{len(card['estimators'])} estimator(s) in {card['run_time_s']:.1f} s; "
        f"{significant} significant difference(s), {failures} failure(s) (metric x seed)"
    )
    print(f"  wrote {', '.join(str(p) for p in paths)}")
    return 0
