"""``simbench report``: the report of one dataset (scored against its truth when it has one)."""

from __future__ import annotations

import argparse
from pathlib import Path

from simbench.api import pose_inputs_text
from simbench.cli.calibrate import DROP_NOISY_FRAMES_HELP
from simbench.errors import InputError
from simbench.report.dataset import SOURCES as REPORT_SOURCES
from simbench.report.dataset import dataset_report
from simbench.units import LENGTH_UNITS


def add_arguments(rep: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench report``."""
    rep.add_argument("dataset", help=f"the recording: {pose_inputs_text()}")
    rep.add_argument(
        "--units",
        choices=sorted(LENGTH_UNITS),
        default=None,
        help="length unit of the positions (default: m for a CSV; a C3D file's own POINT:UNITS, which a "
        "unit given here overrides, with a note)",
    )
    rep.add_argument("--clusters", metavar="SPEC.toml", help="C3D input: marker clusters (default: found)")
    rep.add_argument(
        "--wide", metavar="SPEC.toml", help="INPUT is a wide tracker export laid out as SPEC says"
    )
    rep.add_argument(
        "--calibration", metavar="FILE.json", help="report this calibration JSON instead of calibrating"
    )
    rep.add_argument("--drop-noisy-frames", action="store_true", help=DROP_NOISY_FRAMES_HELP)
    rep.add_argument(
        "--source",
        choices=REPORT_SOURCES,
        default="auto",
        help="of a simbench dataset, what is calibrated: its optical markers' clusters or its sensors' "
        "poses (default auto: the markers when it has them)",
    )
    rep.add_argument("--out", default="report", metavar="DIR", help="report folder (default ./report)")
    rep.set_defaults(func=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    """``simbench report``: the report of one dataset."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    paths = dataset_report(
        Path(args.dataset),
        out,
        Path(args.calibration) if args.calibration else None,
        units=args.units,
        clusters=args.clusters,
        wide=args.wide,
        drop_noisy_frames=args.drop_noisy_frames,
        source=args.source,
    )
    for p in paths.values():
        print(f"wrote {p}")
    return 0
