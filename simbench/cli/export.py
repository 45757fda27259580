"""``simbench export``: a dataset into the files OpenSim, MuJoCo and other tools read."""

from __future__ import annotations

import argparse

from simbench.api import EXPORT_SOURCES, export
from simbench.errors import InputError
from simbench.units import LENGTH_UNITS


def add_arguments(exp: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench export``."""
    exp.description = (
        "Write a simbench dataset (.h5), or a real recording of poses, into the files other "
        "tools read: markers (TRC, "
        "C3D), sensor orientations in OpenSense's .sto layout, raw accelerometer, gyroscope and "
        "magnetometer readings (CSV), the skeleton of a calibration or of the truth (MJCF, OpenSim .osim). "
        "Every "
        "output is checked before the first file is written; each is written atomically."
    )
    exp.add_argument(
        "dataset",
        metavar="RECORDING",
        help="a simbench dataset (simbench simulate -o), or a real recording of poses: a pose CSV, a wide "
        "export (--wide) or a C3D file of marker clusters (--clusters), whose orientations (--sto) and "
        "calibrated skeleton (--mjcf, --osim with --calibration) can be exported; a C3D file's markers "
        "themselves go to --trc and --c3d as read (metres from POINT:UNITS, gaps kept), no clusters needed",
    )
    exp.add_argument(
        "--units",
        choices=sorted(LENGTH_UNITS),
        default=None,
        help="length unit of the positions (default: m for a CSV; a C3D file's own POINT:UNITS, which a "
        "unit given here overrides, with a note)",
    )
    exp.add_argument("--clusters", metavar="SPEC.toml", help="a C3D file's marker clusters (default: found)")
    exp.add_argument("--wide", metavar="SPEC.toml", help="read the recording as a wide tracker export")
    exp.add_argument(
        "--trc",
        metavar="OUT.trc",
        help="markers as TRC text (a C3D file, or a dataset of simulate --markers)",
    )
    exp.add_argument(
        "--c3d",
        metavar="OUT.c3d",
        help="markers as C3D, in mm (a C3D file, or a dataset of simulate --markers)",
    )
    exp.add_argument("--sto", metavar="OUT.sto", help="sensor orientations in OpenSense's .sto layout")
    exp.add_argument("--imu-csv", metavar="OUT.csv", help="raw accelerometer, gyroscope, magnetometer")
    exp.add_argument("--mjcf", metavar="OUT.xml", help="the skeleton as an MJCF model MuJoCo loads")
    exp.add_argument("--osim", metavar="OUT.osim", help="the same skeleton as an OpenSim model")
    exp.add_argument(
        "--calibration",
        metavar="CAL.json",
        help="the skeleton (--mjcf, --osim) of this calibration JSON (simbench calibrate --json; default: "
        "the truth)",
    )
    exp.add_argument(
        "--markers",
        choices=EXPORT_SOURCES,
        default="measured",
        help="marker positions: measured (skin motion, camera noise) or the exact truth (default measured)",
    )
    exp.add_argument(
        "--orientations",
        choices=EXPORT_SOURCES,
        default="measured",
        help="sensor orientations: measured, or the truth of the sensors as worn (default measured)",
    )
    exp.add_argument(
        "--trc-units", choices=sorted(LENGTH_UNITS), default="mm", help="the TRC file's units (default mm)"
    )
    exp.add_argument(
        "--trc-up",
        choices=("z", "y"),
        default="z",
        help="the TRC file's vertical axis: z, the dataset's world (default), or y, as OpenSim's models and "
        "marker IK expect ((x, y, z) -> (x, z, -y))",
    )
    exp.set_defaults(func=cmd_export)


def cmd_export(args: argparse.Namespace) -> int:
    """``simbench export``: write the requested files."""
    if not any((args.trc, args.c3d, args.sto, args.imu_csv, args.mjcf, args.osim)):
        raise InputError(
            "nothing to export: give one or more of --trc, --c3d, --sto, --imu-csv, --mjcf, --osim"
        )
    if args.calibration is not None and args.mjcf is None and args.osim is None:
        raise InputError("--calibration gives the skeleton of --mjcf or --osim: give one of them too")
    written = export(
        args.dataset,
        trc=args.trc,
        c3d=args.c3d,
        sto=args.sto,
        imu_csv=args.imu_csv,
        mjcf=args.mjcf,
        osim=args.osim,
        calibration=args.calibration,
        markers=args.markers,
        orientations=args.orientations,
        trc_units=args.trc_units,
        trc_up=args.trc_up,
        units=args.units,
        clusters=args.clusters,
        wide=args.wide,
    )
    for kind, path in written.items():
        print(f"wrote {path} ({kind})")
    return 0
