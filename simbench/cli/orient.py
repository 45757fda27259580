"""``simbench orient``: sensor orientations from accelerometer and magnetometer (sourceless)."""

from __future__ import annotations

import argparse

from simbench.api import (
    DEFAULT_ORIENTATION,
    TIME_LIMIT_S,
    Priors,
    Skeleton,
    describe_fit,
    estimator_names,
    orient,
    read_imu,
    resolve_estimator,
    skeleton_from_calibration,
    write_orientation_csv,
)
from simbench.cli.types import positive_float
from simbench.errors import CalibrationInputError, InputError


def add_arguments(ori: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench orient``."""
    lone_speed = resolve_estimator("skeleton").param("lone_speed_m_per_s").default
    ori.description = (
        "Estimate sensor orientations from accelerometer and magnetometer readings; with a "
        "reference in the input, print BROAD's error figures. The default method estimates every sensor "
        "over the whole recording at once, on the skeleton of --skeleton when given."
    )
    ori.add_argument("input", help="a simbench dataset (.h5) or a BROAD trial (.hdf5)")
    ori.add_argument(
        "--method",
        default=DEFAULT_ORIENTATION,
        metavar="SPEC",
        help=f"the estimator: {', '.join(estimator_names('orientation'))} (default {DEFAULT_ORIENTATION}); "
        "or your own: package.module:function, path/to/file.py:function, an installed plugin's name, or "
        "'cmd:COMMAND ... {imu} ... {out}' (docs/estimators.md)",
    )
    ori.add_argument(
        "--time-limit",
        type=positive_float,
        default=TIME_LIMIT_S,
        metavar="SECONDS",
        help=f"your estimator's time limit: a command's, or a Python function's (default {TIME_LIMIT_S:g} s)",
    )
    ori.add_argument(
        "--skeleton",
        metavar="CALIBRATION.json",
        help="the skeleton method's joints and tree: a calibration of the same sensors (simbench calibrate "
        "--json, e.g. on the session's tracker poses); without it each sensor is estimated on its own",
    )
    ori.add_argument(
        "--frame", choices=("enu", "ned"), default="enu", help="world frame of the output (default enu)"
    )
    ori.add_argument("--csv", metavar="OUT", help="write time,sensor,qw,qx,qy,qz (NaN where not estimated)")
    ori.add_argument("--no-weighting", action="store_true", help="fixed weights (no disturbance weighting)")
    ori.add_argument(
        "--calibrate-mag",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="fit each magnetometer's hard and soft iron to the recording's own samples and apply it "
        "where the samples determine it and it steadies the field strength (default: on for the "
        "built-in methods; off for your own, which get the readings as recorded)",
    )
    ori.add_argument(
        "--lone-speed",
        type=positive_float,
        default=None,
        metavar="M/S",
        help="the skeleton method: the speed prior of a sensor on its own (no skeleton, or a root with "
        f"no children), m/s (default {lone_speed:g})",
    )
    ori.add_argument(
        "--smooth-hz",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="zero-phase low-pass of the inputs (no lag); for the per-sample and gyro-aided methods "
        "(the skeleton method low-passes level by level itself)",
    )
    ori.set_defaults(func=cmd_orient)


def cmd_orient(args: argparse.Namespace) -> int:
    """``simbench orient``: sensor orientations from accelerometer and magnetometer."""
    est = resolve_estimator(args.method, "orientation")  # a spec that names nothing is refused before reading
    if est.origin != "builtin":
        given = [
            f
            for f, v in (("--lone-speed", args.lone_speed), ("--smooth-hz", args.smooth_hz))
            if v is not None
        ]
        given += ["--no-weighting"] if args.no_weighting else []
        if given:
            raise InputError(f"{', '.join(given)}: options of the built-in methods, not of {est.name!r}")
    rec = read_imu(args.input)
    skeleton = None
    if args.skeleton is not None:
        if not est.takes_skeleton:
            raise InputError(f"--skeleton is for --method skeleton, not {args.method}")
        skeleton = skeleton_from_calibration(args.skeleton, rec.names)
    priors = None
    if args.lone_speed is not None:
        if args.method != "skeleton":
            raise InputError(f"--lone-speed is for --method skeleton, not {args.method}")
        priors = Priors(lone_speed=args.lone_speed)
    if args.smooth_hz is not None and args.method == "skeleton":
        raise InputError(
            "--smooth-hz is for the per-sample and gyro-aided methods, not skeleton (it low-passes "
            "level by level itself)"
        )
    notes = rec.notes
    try:
        ori = orient(
            rec,
            est,
            time_limit_s=args.time_limit,
            skeleton=skeleton,
            weighting=not args.no_weighting,
            smooth_hz=args.smooth_hz,
            calibrate_mag=args.calibrate_mag,
            priors=priors,
        )
    except CalibrationInputError as exc:
        if not notes:
            raise
        # what the reader noticed is often why (e.g. every sample masked)
        raise CalibrationInputError(f"{exc} (the reader's notes: {'; '.join(notes)})") from None
    n_total = ori.ok.size
    print(f"simbench orient: {rec.source}")
    print(
        f"  sensors: {len(rec.names)}   samples: {rec.time_s.size} at {rec.rate_hz:.6g} Hz   "
        f"method: {args.method}"
        f"{' (disturbance weighting)' if 'weighting' in est.defaults and not args.no_weighting else ''}"
        f"{skeleton_line(skeleton, priors or Priors()) if args.method == 'skeleton' else ''}"
    )
    if est.origin == "builtin":
        print(
            f"  reference field from the data: {ori.field_strength_ut:.1f} uT, inclination "
            f"{ori.inclination_deg:.1f} deg; world frame of the output: {args.frame.upper()}"
        )
    else:
        print(f"  world frame of the output: {args.frame.upper()} (the estimator's ENU converted)")
    masked = int((~rec.valid).sum())
    print(f"  estimated {int(ori.ok.sum())} of {n_total} sensor samples ({masked} masked by the reader)")
    for note in ori.notes:  # the reader's, and what the magnetometer calibration did
        print(f"  note: {note}")
    for warning in ori.warnings:  # inputs that cannot be trusted
        print(f"  warning: {warning}")
    for name, fit in (ori.magnetometers or {}).items():
        print(f"  magnetometer {name}: {describe_fit(fit)}")
    disturbed = {n: f for n, f in (ori.disturbed or {}).items() if f > 0}
    if disturbed:
        listed = ", ".join(f"{n} {100 * f:.1f} %" for n, f in disturbed.items())
        print(f"  magnetic disturbance left after calibration (share of each sensor's samples): {listed}")
    if ori.score is not None:  # the recording has a reference
        print("\n  error against the reference (BROAD definitions, both in ENU), RMSE in degrees")
        print(f"  {'sensor':<16}{'total':>9}{'heading':>9}{'inclin.':>9}{'samples':>9}")
        for name, s in ori.score.per_sensor.items():
            print(
                f"  {name:<16}{s['total_deg']:>9.2f}{s['heading_deg']:>9.2f}{s['inclination_deg']:>9.2f}"
                f"{s['samples']:>9}"
            )
    if args.csv:
        write_orientation_csv(args.csv, rec, ori.in_frame(args.frame))
        print(f"\n  wrote {args.csv}")
    return 0


def skeleton_line(skeleton: Skeleton | None, priors: Priors) -> str:
    """What the skeleton method stands on, for the header."""
    speed = f", speed prior {priors.lone_speed:g} m/s" if priors.lone_speed is not None else ""
    if skeleton is None:
        return f" (no skeleton: each sensor on its own{speed})"
    lone = skeleton.lone.size
    alone = f"; {lone} sensor(s) on their own{speed}" if lone else ""
    ranged = f"; ranges of motion on {skeleton.ranged.size}" if skeleton.ranged.size else ""
    return f" ({skeleton.children.size} joints, {skeleton.roots.size} root(s){ranged}{alone})"
