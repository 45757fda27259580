"""``simbench calibrate``'s run (its options: :mod:`simbench.cli.calibrate`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from simbench.api import (
    DEFAULT_JOINTS,
    Estimator,
    JointsResult,
    calibrate,
    calibration_document,
    read_hierarchy,
    read_poses,
    refuse_unlocated,
    resolve_estimator,
    slip_reports,
    write_calibration,
)
from simbench.cli.calibrate import add_arguments
from simbench.cli.live import follow_csv
from simbench.cli.table import format_table
from simbench.errors import CalibrationError, InputError
from simbench.units import implausible_lengths


def _file_units(path: str) -> str:
    """Where a file's length unit came from when ``--units`` is not given."""
    suffix = Path(path).suffix.lower()
    return {".c3d": "POINT:UNITS", ".trc": "Units"}.get(suffix, "m")


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``simbench calibrate``: joints, hierarchy and skeleton from a pose file."""
    if args.follow:
        if args.method != DEFAULT_JOINTS:
            raise InputError(f"--follow calibrates live with {DEFAULT_JOINTS}, not {args.method}")
        return _follow(args)
    est = resolve_estimator(args.method, "joints")  # a spec that names nothing is refused before reading
    if est.data != "poses":
        raise InputError(f"{est.name!r} estimates joints from IMU data, not poses: it is not for calibrate")
    if args.method != DEFAULT_JOINTS:
        return _other_method(args, est)
    rec = read_poses(args.input, args.units, args.clusters, args.wide)
    parent_of = read_hierarchy(args.hierarchy) if args.hierarchy else None
    sensors = f"its sensors: {', '.join(rec.names)}"
    if args.root is not None and args.root not in rec.names:
        raise InputError(f"--root: no sensor {args.root!r} in {args.input} ({sensors})")
    unknown = sorted({s for edge in (parent_of or {}).items() for s in edge} - set(rec.names))
    if unknown:
        raise InputError(f"{args.hierarchy}: sensor(s) {unknown} are not in {args.input} ({sensors})")
    try:
        cal = calibrate(
            rec,
            hierarchy=parent_of,
            root=args.root,
            hierarchy_method=args.hierarchy_method,
            single_axis_ratio=args.single_axis_ratio,
            robust=args.robust,
            intervals=args.intervals,
            correct_rotation_noise=args.correct_rotation_noise,
            drop_noisy_frames=args.drop_noisy_frames,
        )
    except CalibrationError as exc:  # the data (or the hierarchy given) cannot be calibrated
        raise InputError(
            f"{args.input}{f' with {args.hierarchy}' if args.hierarchy else ''}: {exc}"
        ) from None
    refuse_unlocated(rec, cal, args.input)
    slips = (
        []
        if args.no_slip
        else slip_reports(
            rec,
            cal,
            window_s=args.slip_window,
            false_alarms_per_hour=args.slip_false_alarms_per_hour,
            series=False,  # the events are printed and written; the statistic's series is not
        )
    )
    print(format_table(rec, cal, slips))
    odd = implausible_lengths(cal.lengths, args.units, args.input, wide=bool(args.wide))
    if odd:
        print(f"\n  warning: {odd}")
    if args.json:
        # with each joint's range of motion in these poses, for the skeleton orientation estimator
        doc = calibration_document(
            cal,
            rec,
            slips=slips,
            input_info={
                "source": rec.source,
                "sensors": list(rec.names),
                "frames": rec.n_frames,
                "rate_hz": rec.rate_hz,
                "units": args.units or _file_units(args.input),
            },
            notes=(*rec.notes, odd) if odd else rec.notes,
            options={
                "hierarchy_file": args.hierarchy,
                "root": args.root,
                "hierarchy_method": None if args.hierarchy else args.hierarchy_method,
                "single_axis_ratio": args.single_axis_ratio,
                "robust": args.robust,
                "intervals": args.intervals,
                "correct_rotation_noise": args.correct_rotation_noise,
                "drop_noisy_frames": args.drop_noisy_frames,
                "slip_window_s": None if args.no_slip else args.slip_window,
                "slip_false_alarms_per_hour": None if args.no_slip else args.slip_false_alarms_per_hour,
            },
        )
        write_calibration(args.json, doc)
        print(f"\n  wrote {args.json}")
    return 0


#: Options of ``calibrate`` that are estimator parameters: ``(flag, argparse dest, parameter)``;
#: another --method gets those it declares, and refuses the others when given.
PARAMETER_OPTIONS = (
    ("--root", "root", "root"),
    ("--hierarchy-method", "hierarchy_method", "hierarchy_method"),
    ("--single-axis-ratio", "single_axis_ratio", "single_axis_ratio"),
    ("--intervals", "intervals", "intervals"),
    ("--drop-noisy-frames", "drop_noisy_frames", "drop_noisy_frames"),
    ("--robust", "robust", "robust"),
)


def _other_method(args: argparse.Namespace, est: Estimator) -> int:
    """``simbench calibrate --method SPEC``: any joints estimator on the recording's poses; the
    whole table and JSON for O'Brien's variants, the joints (and their JSON) for the others."""
    defaults = parser_defaults()
    params = {}
    for flag, dest, param in PARAMETER_OPTIONS:
        value = getattr(args, dest)
        if value == defaults[dest]:
            continue
        if param not in est.defaults:
            raise InputError(
                f"{flag}: not a parameter of {est.name!r} ({[p.name for p in est.params] or 'none'})"
            )
        params[param] = value
    if args.correct_rotation_noise:
        raise InputError(
            f"--correct-rotation-noise is O'Brien's; with --method give obrien-eiv, not {est.name!r}"
        )
    if args.slip_window != defaults["slip_window"]:
        raise InputError("--slip-window: slip detection runs with O'Brien's calibration (the default method)")
    rec = read_poses(args.input, args.units, args.clusters, args.wide)
    parent_of = read_hierarchy(args.hierarchy) if args.hierarchy else None
    limit = None if est.origin == "builtin" else args.time_limit
    got = calibrate(rec, method=est, hierarchy=parent_of, params=params, time_limit_s=limit)
    assert isinstance(got, JointsResult)
    if got.calibration is not None:
        refuse_unlocated(rec, got.calibration, args.input)
        print(format_table(rec, got.calibration, []))
        doc = calibration_document(got, rec, ranges=False)
    else:
        print(f"simbench calibrate: {rec.source}")
        print(f"  sensors: {len(rec.names)}   frames: {rec.n_frames}   method: {est.name}")
        print(f"\n  {'joint':<28}{'centre in parent (mm)':>30}{'centre in child (mm)':>30}")
        j = got.joints
        for k in range(len(j.child)):
            jp = " ".join(f"{1000 * v:8.1f}" for v in j.joint_in_parent[k])
            jc = " ".join(f"{1000 * v:8.1f}" for v in j.joint_in_child[k])
            print(f"  {j.parent[k] + '-' + j.child[k]:<28}{jp:>30}{jc:>30}")
        if got.residuals is not None:  # how the joints fit these poses, beside the least-squares fit
            r = got.residuals
            print(f"\n  {'joint':<28}{'rms mm':>9}{'max mm':>9}{'least-squares rms mm':>22}{'frames':>8}")
            for k in range(len(j.child)):
                print(
                    f"  {j.parent[k] + '-' + j.child[k]:<28}{1e3 * r.rms[k]:9.3f}{1e3 * r.max[k]:9.3f}"
                    f"{1e3 * r.best[k]:22.3f}{r.frames[k]:8d}"
                )
        for note in (*rec.notes, *got.notes):
            print(f"  note: {note}")
        for warning in got.warnings:
            print(f"  warning: {warning}")
        doc = calibration_document(got)  # the joints alone, with the estimator's notes
    doc["method"] = est.name
    if args.json:
        write_calibration(args.json, doc)
        print(f"\n  wrote {args.json}")
    return 0


def parser_defaults() -> dict:
    """The defaults of ``calibrate``'s options, by argparse dest."""
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return vars(parser.parse_args(["input"]))


def _follow(args: argparse.Namespace) -> int:
    """``simbench calibrate --follow``: the live calibration of a growing pose CSV."""
    unsupported = [
        flag
        for flag, value in (
            ("--json", args.json),
            ("--robust", args.robust),
            ("--intervals", args.intervals),
            ("--correct-rotation-noise", args.correct_rotation_noise),
            ("--drop-noisy-frames", args.drop_noisy_frames),
            ("--clusters", args.clusters),
            ("--wide", args.wide),
        )
        if value
    ]
    if unsupported:
        raise InputError(f"--follow calibrates a pose CSV live; it does not take {', '.join(unsupported)}")
    suffix = Path(args.input).suffix.lower()
    if suffix not in (".csv", ".txt", ""):
        raise InputError(
            f"{args.input}: --follow calibrates a pose CSV (.csv) that another process appends to, not a "
            f"{suffix} file; calibrate it without --follow"
        )
    follow_csv(
        args.input,
        units=args.units or "m",
        rate_hz=args.rate_hz,
        timeout_s=args.timeout,
        refresh_s=args.refresh,
        slip=not args.no_slip,
        hierarchy=read_hierarchy(args.hierarchy) if args.hierarchy else None,
        root=args.root,
        hierarchy_method=args.hierarchy_method,
        single_axis_ratio=args.single_axis_ratio,
        false_alarms_per_hour=args.slip_false_alarms_per_hour,
    )
    return 0
