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
from simbench.experiments.sweep import check_scheduler, dask_executor, dask_security, finished, run_study
from simbench.report.study import plot_study, write_summary


def add_arguments(swp: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench sweep``."""
    swp.add_argument("study", help="the study TOML (see studies/ and simbench/experiments/study.py)")
    swp.add_argument(
        "--workers", type=positive_int, default=os.cpu_count() or 1, help="local worker processes"
    )
    swp.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="a Dask scheduler, e.g. tcp://127.0.0.1:8786 or tls://host:8786 (off this machine: TLS or "
        "--insecure; docs/dask.md)",
    )
    swp.add_argument("--tls-ca-file", metavar="PEM", help="Dask TLS: the certificate authority to trust")
    swp.add_argument("--tls-cert", metavar="PEM", help="Dask TLS: this client's certificate")
    swp.add_argument("--tls-key", metavar="PEM", help="Dask TLS: this client's private key")
    swp.add_argument(
        "--insecure",
        action="store_true",
        help="connect to a scheduler off this machine by plain TCP (the network must be yours alone: Dask "
        "unpickles what the cluster sends back)",
    )
    swp.add_argument("--out", metavar="DIR", help="output folder (default: the study file's name)")
    swp.add_argument(
        "--force", action="store_true", help="start over in a folder that holds another study's trials"
    )
    swp.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
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

    security = dask_security(args.tls_ca_file, args.tls_cert, args.tls_key)
    if security is not None and not args.scheduler:
        raise InputError("--tls-ca-file, --tls-cert and --tls-key are for --scheduler: give its address too")
    if args.scheduler:
        check_scheduler(args.scheduler, security, args.insecure)  # before any work
    cluster = (
        dask_executor(args.scheduler, security=security, insecure=args.insecure)
        if args.scheduler
        else nullcontext(None)
    )
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
