"""``simbench sweep``: a study of seeded trials, run locally or on a Dask cluster."""

from __future__ import annotations

import argparse
import os
import sys
from contextlib import nullcontext
from pathlib import Path

from tqdm import tqdm

from simbench.cli.types import positive_int
from simbench.errors import InputError
from simbench.experiments.study import load_study, trials
from simbench.experiments.sweep import dask_executor, finished, run_study
from simbench.report.study import plot_study, write_summary


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand to ``simbench``'s subparsers."""
    swp = sub.add_parser(
        "sweep", help="a study of seeded trials (noise, slip, placement...), local or on Dask"
    )
    swp.add_argument("study", help="the study TOML (see studies/ and simbench/experiments/study.py)")
    swp.add_argument(
        "--workers", type=positive_int, default=os.cpu_count() or 1, help="local worker processes"
    )
    swp.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://127.0.0.1:8786")
    swp.add_argument("--out", metavar="DIR", help="output folder (default: the study file's name)")
    swp.add_argument(
        "--force", action="store_true", help="start over in a folder that holds another study's trials"
    )
    swp.add_argument("--no-progress", action="store_true")
    swp.set_defaults(func=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    """``simbench sweep``: a study of seeded trials, locally or on a Dask cluster."""
    study = load_study(args.study)  # every problem of the file before any work
    out = Path(args.out) if args.out else Path(args.study).with_suffix("")
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: expected a folder for the study's results, got a file")
    total = len(trials(study))
    bar = tqdm(total=total, desc=study.name, unit="trial", file=sys.stderr, disable=args.no_progress)
    bar.update(len(finished(out)))

    def progress(done: int, _total: int) -> None:
        bar.update(done - bar.n)

    cluster = dask_executor(args.scheduler) if args.scheduler else nullcontext(None)
    try:
        with cluster as executor:
            table = run_study(
                study, out, executor=executor, workers=args.workers, progress=progress, force=args.force
            )
    finally:
        bar.close()
    plots = plot_study(study, table, out)
    write_summary(study, table, plots, out)
    failed = sum(1 for e in table.to_pydict().get("error", []) if e)
    without = f" ({failed} without metrics: see summary.md)" if failed else ""
    print(f"simbench sweep {study.name}: {table.num_rows} of {total} trials in {out}{without}")
    print(f"  wrote {out / 'results.parquet'}, {out / 'summary.md'} and {len(plots)} plot(s)")
    return 0
