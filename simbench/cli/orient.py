"""``simbench orient``: sensor orientations from accelerometer and magnetometer (Fontaine et al.)."""

from __future__ import annotations

import argparse

from simbench.cli.types import positive_float
from simbench.io.orientation_csv import write_orientation_csv
from simbench.io.read import read_imu
from simbench.orient import GYRO_AIDED, METHODS, calibrate_magnetometers, describe_fit, estimate, in_frame
from simbench.score import score_orientation


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``orient`` subcommand to ``simbench``'s subparsers."""
    ori = sub.add_parser(
        "orient",
        help="sensor orientations from accelerometer and magnetometer (sourceless, Fontaine et al.)",
        description="Estimate sensor orientations from accelerometer and magnetometer readings; with a "
        "reference in the input, print BROAD's error figures.",
    )
    ori.add_argument("input", help="a simbench dataset (.h5) or a BROAD trial (.hdf5)")
    ori.add_argument("--method", choices=METHODS, default="fontaine")
    ori.add_argument(
        "--frame", choices=("enu", "ned"), default="enu", help="world frame of the output (default enu)"
    )
    ori.add_argument("--csv", metavar="OUT", help="write time,sensor,qw,qx,qy,qz (NaN where not estimated)")
    ori.add_argument("--no-weighting", action="store_true", help="fixed weights (no disturbance weighting)")
    ori.add_argument(
        "--calibrate-mag",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="fit each magnetometer's hard and soft iron to the recording's own samples and apply it "
        "where the samples determine it and it steadies the field strength (default: on)",
    )
    ori.add_argument(
        "--smooth-hz",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="zero-phase low-pass of the inputs (no lag)",
    )
    ori.set_defaults(func=cmd_orient)


def cmd_orient(args: argparse.Namespace) -> int:
    """``simbench orient``: sensor orientations from accelerometer and magnetometer."""
    rec = read_imu(args.input)
    fits = {}
    if args.calibrate_mag:
        rec, fits = calibrate_magnetometers(rec)
    run = estimate(rec, args.method, weighting=not args.no_weighting, smooth_hz=args.smooth_hz)
    n_total = run.ok.size
    print(f"simbench orient: {rec.source}")
    print(
        f"  sensors: {len(rec.names)}   samples: {rec.time_s.size} at {rec.rate_hz:.6g} Hz   "
        f"method: {args.method}"
        f"{'' if args.no_weighting or args.method in ('triad', *GYRO_AIDED) else ' (disturbance weighting)'}"
    )
    print(
        f"  reference field from the data: {run.field_strength_ut:.1f} uT, inclination "
        f"{run.inclination_deg:.1f} deg; world frame of the output: {args.frame.upper()}"
    )
    masked = int((~rec.valid).sum())
    print(f"  estimated {int(run.ok.sum())} of {n_total} sensor samples ({masked} masked by the reader)")
    for note in rec.notes:
        print(f"  note: {note}")
    for name, fit in fits.items():
        print(f"  magnetometer {name}: {describe_fit(fit)}")
    if rec.q_true is not None:
        print("\n  error against the reference (BROAD definitions, both in ENU), RMSE in degrees")
        print(f"  {'sensor':<16}{'total':>9}{'heading':>9}{'inclin.':>9}{'samples':>9}")
        scored = score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate)
        for name, s in scored.per_sensor.items():
            print(
                f"  {name:<16}{s['total_deg']:>9.2f}{s['heading_deg']:>9.2f}{s['inclination_deg']:>9.2f}"
                f"{s['samples']:>9}"
            )
    if args.csv:
        write_orientation_csv(args.csv, rec, in_frame(run.q_enu, args.frame))
        print(f"\n  wrote {args.csv}")
    return 0
