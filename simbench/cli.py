"""The ``simbench`` command line.

Every subcommand reports bad input as ``simbench: error: ...`` on stderr with exit status 2,
never as a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import simbench
from calibration import CalibrationError, calibrate, detect_slip, unit_scale
from calibration.joint import SINGLE_AXIS_RATIO
from calibration.pipeline import Calibration
from calibration.slip import SlipReport
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text
from simbench.io.calibration_json import calibration_to_dict, write_calibration_json
from simbench.io.dataset import truth_calibration_dict, write_dataset
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.io.read import read_poses
from simbench.units import LENGTH_UNITS, metres_per_unit


def _load_hierarchy(path: str) -> dict[str, str]:
    """Read ``{"child": "parent", ...}`` from a JSON file, rejecting repeated keys."""

    def no_repeats(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        keys = [k for k, _ in pairs]
        repeated = sorted({k for k in keys if keys.count(k) > 1})
        if repeated:
            raise InputError(f"{path}: sensors given a parent twice: {repeated}")
        return dict(pairs)

    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    try:
        doc = json.loads(text, object_pairs_hook=no_repeats)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}, line {exc.lineno}: not valid JSON: {exc.msg}") from None
    if not isinstance(doc, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in doc.items()
    ):
        raise InputError(f'{path}: expected a JSON object {{"child": "parent", ...}} of sensor names')
    return doc


def _slip_reports(rec: PoseRecording, cal: Calibration, window_s: float) -> list[tuple[str, SlipReport]]:
    window = round(window_s * rec.rate_hz) if np.isfinite(rec.rate_hz) else 0
    window = min(max(window, 2), rec.n_frames // 2)
    if window < 2:
        return []
    out = []
    for j in cal.joints:
        fit = j.fit
        report = detect_slip(
            *rec.pair(j.parent, j.child), fit.joint_in_parent, fit.joint_in_child, window=window
        )
        out.append((j.name, report))
    return out


def format_table(rec: PoseRecording, cal: Calibration, slips: Sequence[tuple[str, SlipReport]]) -> str:
    """A readable summary: joints (mm), limb lengths (cm), sensor offsets (cm), warnings."""
    lines = [
        f"simbench calibrate: {rec.source}",
        f"  sensors: {len(rec.names)}   frames: {rec.n_frames}   rate: {rec.rate_hz:.4g} Hz   "
        f"time: {cal.seconds.get('total', float('nan')):.3f} s",
        f"  hierarchy: {'given' if cal.hierarchy_given else 'inferred'}, root {cal.root}",
        "",
        f"  {'joint (parent -> child)':<34}{'rms mm':>9}{'max mm':>9}{'cond':>8}  {'axis':<12}{'frames':>8}",
    ]
    for j in cal.joints:
        fit = j.fit
        mx = np.nanmax(fit.frame_residual) if fit.frame_residual is not None else float("nan")
        cond = f"{fit.condition:.3g}" if np.isfinite(fit.condition) else "inf"
        axis = "single" if fit.single_axis else ("none" if fit.rank < 5 else "-")
        lines.append(
            f"  {j.parent + ' -> ' + j.child:<34}{fit.rms_residual * 1e3:>9.3f}{mx * 1e3:>9.3f}"
            f"{cond:>8}  {axis:<12}{fit.n_frames:>8}"
        )
    lines += ["", f"  {'limb lengths (cm)':<22}{'from joint':<30}{'to joint':<30}{'length':>8}"]
    for x in cal.lengths:
        lines.append(f"  {x.segment:<22}{x.joint_a:<30}{x.joint_b:<30}{x.length * 100:>8.2f}")
    lines += ["", f"  {'sensor offsets (cm)':<22}{'joint':<30}{'offset in sensor frame':<28}{'dist':>8}"]
    for pl in cal.placements:
        for name, off, d in zip(pl.joints, pl.offsets, pl.distances, strict=True):
            vec = " ".join(f"{v * 100:7.2f}" for v in off)
            lines.append(f"  {pl.sensor:<22}{name:<30}{vec:<28}{d * 100:>8.2f}")
    events = [(name, ev) for name, rep in slips for ev in rep.events]
    if slips:
        lines += ["", "  slip events (residual offset jumps)"]
        if not events:
            lines.append("    none found")
        for name, ev in events:
            lines.append(
                f"    {name}: at {rec.time_s[ev.frame]:.3f} s, jump {ev.jump * 1e3:.1f} mm "
                f"(steady in the {ev.sensor_frame} frame, z {ev.z:.3g})"
            )
    notes = [*rec.notes, *cal.warnings]
    if notes:
        lines += ["", "  warnings"]
        lines += [f"    - {w}" for w in notes]
    return "\n".join(lines)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """``simbench calibrate``: joints, hierarchy and skeleton from a pose file."""
    rec = read_poses(args.input, args.units, args.clusters, args.wide)
    parent_of = _load_hierarchy(args.hierarchy) if args.hierarchy else None
    cal = calibrate(
        rec.R_w_s,
        rec.p_w_s,
        rec.names,
        valid=rec.valid,
        parent_of=parent_of,
        root=args.root,
        single_axis_ratio=args.single_axis_ratio,
    )
    slips = [] if args.no_slip else _slip_reports(rec, cal, args.slip_window)
    print(format_table(rec, cal, slips))
    if args.json:
        doc = calibration_to_dict(
            cal,
            time_s=rec.time_s,
            slips=slips,
            input_info={
                "source": rec.source,
                "sensors": list(rec.names),
                "frames": rec.n_frames,
                "rate_hz": rec.rate_hz,
                "units": args.units,
            },
            notes=rec.notes,
            options={
                "hierarchy_file": args.hierarchy,
                "root": args.root,
                "single_axis_ratio": args.single_axis_ratio,
                "slip_window_s": None if args.no_slip else args.slip_window,
            },
        )
        write_calibration_json(args.json, doc)
        print(f"\n  wrote {args.json}")
    return 0


def cmd_scale(args: argparse.Namespace) -> int:
    """``simbench scale``: the unit scale factor from two rigidly mounted sensors (O'Brien 4)."""
    rec = read_poses(args.input, args.units)
    missing = [name for name in args.sensors if name not in rec.names]
    if missing:
        raise InputError(f"{args.input}: no sensor named {missing}; sensors are {list(rec.names)}")
    if args.sensors[0] == args.sensors[1]:
        raise InputError("--sensors needs two different sensors")
    a, b = (rec.names.index(name) for name in args.sensors)
    both = rec.valid[:, a] & rec.valid[:, b]
    pa = np.where(both[:, None], rec.p_w_s[:, a], np.nan)
    pb = np.where(both[:, None], rec.p_w_s[:, b], np.nan)
    known = args.distance * metres_per_unit(args.units)
    est = unit_scale(pa, pb, known)
    print(f"simbench scale: {rec.source}, sensors {args.sensors[0]} and {args.sensors[1]}")
    print(f"  frames used         {est.n_frames} of {rec.n_frames}")
    print(f"  known distance      {known * 100:.2f} cm")
    print(f"  mean reported       {est.mean_reported * 100:.2f} cm (as {args.units} read)")
    print(f"  scale factor        {est.scale:.4f}  (multiply reported lengths by this)")
    print(f"  scaled std          {est.scaled_std * 100:.3f} cm")
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    """``simbench simulate``: a physics-simulated capture session with exact ground truth."""
    from simbench.sim.session import SessionConfig, run_session

    for out in (args.output, args.csv, args.truth_json):
        if out is not None and not Path(out).resolve().parent.is_dir():
            raise InputError(f"cannot write {out}: folder {Path(out).parent} does not exist")
    bodies = tuple(b.strip() for b in args.sensors_on.split(",") if b.strip()) if args.sensors_on else None
    config = SessionConfig(
        model=args.model,
        motion=args.motion,
        duration_s=args.duration,
        rate_hz=args.rate,
        seed=args.seed,
        sensor_bodies=bodies,
        sensors=args.sensors,
    )
    ds = run_session(config)
    meta = ds.meta
    print(
        f"simbench simulate: model {args.model}, motion {meta['program']}, sensors {meta['sensor_model']}, "
        f"seed {args.seed}"
    )
    print(
        f"  sensors: {len(ds.sensors)}   samples: {meta['n_samples']} at {args.rate:g} Hz   physics: "
        f"{1 / meta['physics_timestep_s']:.6g} Hz ({meta['steps_per_sample']} steps per sample)"
    )
    print(f"  sensors on: {', '.join(ds.sensors)}")
    if meta["mujoco_warnings"]:
        print(f"  MuJoCo warnings: {meta['mujoco_warnings']}")
    write_dataset(args.output, ds)
    print(f"  wrote {args.output}")
    if args.csv:
        write_pose_csv(args.csv, ds.poses())
        print(f"  wrote {args.csv}")
    if args.truth_json:
        atomic_write_text(args.truth_json, json.dumps(truth_calibration_dict(ds), indent=2) + "\n")
        print(f"  wrote {args.truth_json}")
    return 0


def cmd_orient(args: argparse.Namespace) -> int:
    """``simbench orient``: sensor orientations from accelerometer and magnetometer."""
    from simbench.io.orientation_csv import write_orientation_csv
    from simbench.io.read import read_imu
    from simbench.orient import estimate, in_frame
    from simbench.score import score_orientation

    rec = read_imu(args.input)
    run = estimate(rec, args.method, weighting=not args.no_weighting, smooth_hz=args.smooth_hz)
    n_total = run.ok.size
    print(f"simbench orient: {rec.source}")
    print(
        f"  sensors: {len(rec.names)}   samples: {rec.time_s.size} at {rec.rate_hz:.6g} Hz   "
        f"method: {args.method}"
        f"{'' if args.no_weighting or args.method in ('triad', 'mahony') else ' (disturbance weighting)'}"
    )
    print(
        f"  reference field from the data: {run.field_strength_ut:.1f} uT, inclination "
        f"{run.inclination_deg:.1f} deg; world frame of the output: {args.frame.upper()}"
    )
    masked = int((~rec.valid).sum())
    print(f"  estimated {int(run.ok.sum())} of {n_total} sensor samples ({masked} masked by the reader)")
    for note in rec.notes:
        print(f"  note: {note}")
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


def cmd_validate(args: argparse.Namespace) -> int:
    """``simbench validate``: the paper's experiments reproduced and scored; writes the report."""
    from tqdm import tqdm

    from simbench.experiments.validate import run_validation
    from simbench.report.validation import write_report

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    steps = [
        "unit scale: two rigid sensors",
        "linkage sets",
        "humanoid trials",
        "slip detection",
        "sourceless orientation",
    ]
    bar = tqdm(total=len(steps) + 1, desc="validate", unit="step", file=sys.stderr, disable=args.no_progress)
    seen: list[str] = []

    def progress(step: str) -> None:
        if seen:
            bar.update(1)
        seen.append(step)
        bar.set_postfix_str(step)

    results, keep = run_validation(quick=args.quick, progress=progress)
    bar.update(1)
    bar.set_postfix_str("report")
    paths = write_report(results, keep, out)
    bar.update(1)
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


def cmd_report(args: argparse.Namespace) -> int:
    """``simbench report``: the report of one dataset."""
    from simbench.report.validation import dataset_report

    out = Path(args.out)
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    paths = dataset_report(
        Path(args.dataset),
        out,
        Path(args.calibration) if args.calibration else None,
        units=args.units,
        clusters=args.clusters,
        wide=args.wide,
    )
    for p in paths.values():
        print(f"wrote {p}")
    return 0


def cmd_baseline(args: argparse.Namespace) -> int:
    """``simbench baseline``: check accuracy against the accepted figures, or update them."""
    from simbench.experiments import baseline as bl

    path = Path(args.file) if args.file else bl.BASELINE_FILE
    current = bl.compute()
    if args.update:
        try:
            old = bl.load_baseline(path)
        except InputError:
            old = {}
        changes = bl.diff_lines(old, current)
        bl.write_baseline(current, path)
        print(f"simbench baseline --update: wrote {path}")
        print("\n".join(f"  {line}" for line in changes) if changes else "  no change")
        return 0
    problems = bl.compare(current, bl.load_baseline(path), rel_tol=args.tolerance)
    for name, figures in current.items():
        print(f"  {name}: " + ", ".join(f"{k} {v:.4g}" for k, v in figures.items()))
    if problems:
        print("simbench baseline: accuracy got worse:", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 1
    print("simbench baseline: no regression")
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """``simbench sweep``: a study of seeded trials, locally or on a Dask cluster."""
    from tqdm import tqdm

    from simbench.experiments import sweep as sw

    study = sw.load_study(args.study)  # every problem of the file before any work
    out = Path(args.out) if args.out else Path(args.study).with_suffix("")
    if not out.parent.is_dir():
        raise InputError(f"cannot write {out}: folder {out.parent} does not exist")
    total = len(sw.trials(study))
    bar = tqdm(total=total, desc=study.name, unit="trial", file=sys.stderr, disable=args.no_progress)
    bar.update(len(sw.finished(out)))
    executor = None
    client = None
    if args.scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise InputError("--scheduler needs dask distributed (pip install 'dask[distributed]')") from None
        client = Client(args.scheduler)
        executor = client.get_executor()
    try:
        table = sw.run_study(
            study, out, executor=executor, workers=args.workers, progress=lambda d, t: bar.update(d - bar.n)
        )
    finally:
        bar.close()
        if client is not None:
            client.close()
    plots = sw.plot_study(study, table, out)
    summary = sw.summary_markdown(study, table, plots)
    from simbench.io.atomic import atomic_write_text

    atomic_write_text(out / "summary.md", summary)
    print(f"simbench sweep {study.name}: {table.num_rows} of {total} trials in {out}")
    print(f"  wrote {out / 'results.parquet'}, {out / 'summary.md'} and {len(plots)} plot(s)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``simbench`` command."""
    parser = argparse.ArgumentParser(
        prog="simbench",
        description="Physics-simulation validation testbed for motion-capture skeleton calibration.",
    )
    parser.add_argument("--version", action="version", version=f"simbench {simbench.__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    cal = sub.add_parser(
        "calibrate",
        help="joint centres, hierarchy, limb lengths and sensor offsets from sensor poses",
        description="Estimate joint centres, body hierarchy, limb lengths and sensor placement from "
        "6-DoF sensor poses (O'Brien et al. 2000).",
    )
    cal.add_argument("input", help="pose file: a pose CSV (time,sensor,x,y,z,qw,qx,qy,qz) or a dataset .h5")
    cal.add_argument(
        "--units", choices=sorted(LENGTH_UNITS), default="m", help="length unit of the file (default m)"
    )
    cal.add_argument("--hierarchy", metavar="FILE.json", help='known hierarchy {"child": "parent", ...}')
    cal.add_argument("--root", metavar="NAME", help="root sensor (default: the centre of the inferred tree)")
    cal.add_argument("--json", metavar="OUT", help="write the calibration JSON here")
    cal.add_argument(
        "--clusters",
        metavar="SPEC.toml",
        help="C3D input: marker clusters [clusters] segment = [labels] (default: found)",
    )
    cal.add_argument(
        "--wide",
        metavar="SPEC.toml",
        help="INPUT is a wide tracker export (a row per frame) laid out as SPEC says",
    )
    cal.add_argument(
        "--single-axis-ratio",
        type=float,
        default=SINGLE_AXIS_RATIO,
        metavar="R",
        help=f"s_min/s_max below which a joint is single-axis (default {SINGLE_AXIS_RATIO})",
    )
    cal.add_argument(
        "--slip-window", type=float, default=1.0, metavar="SECONDS", help="slip detector window (default 1 s)"
    )
    cal.add_argument("--no-slip", action="store_true", help="skip slip detection")
    cal.set_defaults(func=cmd_calibrate)
    scale = sub.add_parser(
        "scale",
        help="unit scale factor of a capture system from two rigidly mounted sensors",
        description="Estimate the unit scale factor of a capture system from two sensors mounted "
        "rigidly a known distance apart (O'Brien et al. 2000, section 4).",
    )
    scale.add_argument("input", help="pose file: a pose CSV")
    scale.add_argument("--sensors", nargs=2, required=True, metavar=("A", "B"), help="the two sensors")
    scale.add_argument("--distance", type=float, required=True, help="their true distance, in --units")
    scale.add_argument("--units", choices=sorted(LENGTH_UNITS), default="m", help="length unit (default m)")
    scale.set_defaults(func=cmd_scale)
    sim = sub.add_parser(
        "simulate",
        help="a physics-simulated capture session with exact ground truth",
        description="Move a MuJoCo model through a capture session by physics and record ideal sensor "
        "data with exact ground truth.",
    )
    sim.add_argument(
        "--model",
        default="linkage",
        help="linkage, humanoid, dm_control:NAME or an MJCF .xml path (default linkage)",
    )
    sim.add_argument(
        "--motion",
        default="exercise",
        help="exercise, walk, single-axis, static, or a program .toml (default exercise)",
    )
    sim.add_argument(
        "--duration", type=float, default=20.0, metavar="SECONDS", help="session length (default 20)"
    )
    sim.add_argument("--rate", type=float, default=120.0, metavar="HZ", help="capture rate (default 120)")
    sim.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    sim.add_argument(
        "--sensors",
        default="ideal",
        metavar="PRESET|FILE.toml",
        help="sensor preset (ideal, ascension-flock, polhemus-liberty, mems-consumer, mems-industrial, "
        "skin-paper-human) or a configuration TOML (default ideal)",
    )
    sim.add_argument(
        "--sensors-on", metavar="BODY,BODY,...", help="bodies that carry a sensor (default: the model's)"
    )
    sim.add_argument("-o", "--output", required=True, metavar="OUT.h5", help="the dataset (HDF5)")
    sim.add_argument("--csv", metavar="OUT.csv", help="also export the measured poses as a pose CSV")
    sim.add_argument("--truth-json", metavar="OUT.json", help="also export the truth as calibration JSON")
    sim.set_defaults(func=cmd_simulate)
    ori = sub.add_parser(
        "orient",
        help="sensor orientations from accelerometer and magnetometer (sourceless, Fontaine et al.)",
        description="Estimate sensor orientations from accelerometer and magnetometer readings; with a "
        "reference in the input, print BROAD's error figures.",
    )
    ori.add_argument("input", help="a simbench dataset (.h5) or a BROAD trial (.hdf5)")
    ori.add_argument("--method", choices=("fontaine", "triad", "wahba", "mahony"), default="fontaine")
    ori.add_argument(
        "--frame", choices=("enu", "ned"), default="enu", help="world frame of the output (default enu)"
    )
    ori.add_argument("--csv", metavar="OUT", help="write time,sensor,qw,qx,qy,qz (NaN where not estimated)")
    ori.add_argument("--no-weighting", action="store_true", help="fixed weights (no disturbance weighting)")
    ori.add_argument(
        "--smooth-hz",
        type=float,
        default=None,
        metavar="HZ",
        help="zero-phase low-pass of the inputs (no lag)",
    )
    ori.set_defaults(func=cmd_orient)
    val = sub.add_parser(
        "validate",
        help="the main job: the paper's experiments reproduced in simulation, scored; writes the report",
        description="Reproduce O'Brien et al.'s linkage and human experiments and Fontaine et al.'s "
        "sourceless orientation in simulation, score them against the truth and write the report.",
    )
    val.add_argument("--quick", action="store_true", help="fewer, shorter sessions (under a minute)")
    val.add_argument("--out", default="reports", metavar="DIR", help="report folder (default reports)")
    val.add_argument("--no-progress", action="store_true", help="no progress bar")
    val.set_defaults(func=cmd_validate)
    rep = sub.add_parser(
        "report", help="the report of one dataset (scored against its truth when it has one)"
    )
    rep.add_argument(
        "dataset", help="a simbench dataset (.h5), pose CSV, wide tracker export (--wide) or C3D"
    )
    rep.add_argument(
        "--units", choices=sorted(LENGTH_UNITS), default="m", help="length unit of a CSV (default m)"
    )
    rep.add_argument("--clusters", metavar="SPEC.toml", help="C3D input: marker clusters (default: found)")
    rep.add_argument(
        "--wide", metavar="SPEC.toml", help="INPUT is a wide tracker export laid out as SPEC says"
    )
    rep.add_argument(
        "--calibration", metavar="FILE.json", help="report this calibration JSON instead of calibrating"
    )
    rep.add_argument("--out", default="report", metavar="DIR", help="report folder (default ./report)")
    rep.set_defaults(func=cmd_report)
    bas = sub.add_parser(
        "baseline", help="accuracy regression check against reports/baseline.json (or --update it)"
    )
    bas.add_argument(
        "--update", action="store_true", help="recompute and rewrite the baseline, showing the diff"
    )
    bas.add_argument("--tolerance", type=float, default=0.10, help="relative tolerance (default 0.10)")
    bas.add_argument("--file", metavar="PATH", help="baseline file (default reports/baseline.json)")
    bas.set_defaults(func=cmd_baseline)
    swp = sub.add_parser(
        "sweep", help="a study of seeded trials (noise, slip, placement...), local or on Dask"
    )
    swp.add_argument("study", help="the study TOML (see studies/ and simbench/sweep.py)")
    swp.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="local worker processes")
    swp.add_argument("--scheduler", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://127.0.0.1:8786")
    swp.add_argument("--out", metavar="DIR", help="output folder (default: the study file's name)")
    swp.add_argument("--no-progress", action="store_true")
    swp.set_defaults(func=cmd_sweep)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simbench`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except (InputError, CalibrationError) as exc:
        print(f"simbench: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"simbench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
