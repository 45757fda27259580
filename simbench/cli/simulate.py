"""``simbench simulate``: a physics-simulated capture session with exact ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from simbench.api import (
    BUILTIN_MODELS,
    BUILTIN_PROGRAMS,
    BVH_CUTOFF_HZ,
    MarkerConfig,
    preset_names,
    simulate,
    truth_document,
    write_calibration,
    write_dataset,
    write_pose_csv,
)
from simbench.cli.types import non_negative_float, positive_float, seed
from simbench.errors import InputError
from simbench.units import BVH_LENGTH_UNITS


def add_arguments(sim: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench simulate``."""
    sim.description = (
        "Move a MuJoCo model through a capture session by physics and record ideal sensor "
        "data with exact ground truth."
    )
    sim.add_argument(
        "--model",
        default=None,
        help=f"{', '.join(BUILTIN_MODELS)}, dm_control:NAME or an MJCF .xml path (default linkage; a "
        "recorded motion: the model it brings (a .bvh clip's skeleton, a pose trajectory's bodies) or "
        "names (a .npz), humanoid for OpenSim angles)",
    )
    sim.add_argument(
        "--motion",
        default="exercise",
        metavar="PROGRAM|FILE",
        help=f"{', '.join(BUILTIN_PROGRAMS)} (gait: humanoids only), a program .toml, or a recorded motion "
        "played back kinematically: a .bvh clip, a qpos series (.npz, .csv), OpenSim angles (.mot, .sto), "
        "pose trajectories (a pose .csv, a .c3d of marker clusters, a BROAD-layout .hdf5) (default exercise)",
    )
    sim.add_argument(
        "--motion-units",
        default=None,
        choices=tuple(BVH_LENGTH_UNITS),
        help="a recorded motion's length unit (default the file's convention: .bvh cm, pose .csv m, .c3d "
        "its POINT:UNITS; cmu: the CMU mocap database's BVH unit, 1/0.45 in)",
    )
    sim.add_argument(
        "--motion-clusters",
        default=None,
        metavar="SPEC.toml",
        help="a .c3d motion's marker clusters ([clusters] spec; default found automatically)",
    )
    sim.add_argument(
        "--motion-cutoff",
        type=positive_float,
        default=BVH_CUTOFF_HZ,
        metavar="HZ",
        help="a recorded motion's smoothing cutoff for velocities and accelerations (Savitzky-Golay; default "
        f"{BVH_CUTOFF_HZ:g})",
    )
    sim.add_argument(
        "--motion-position-cutoff",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="a recorded motion's positions' own smoothing cutoff (accelerations are positions "
        "differentiated twice; default --motion-cutoff)",
    )
    sim.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        metavar="SECONDS",
        help="session length (default 20; a recorded motion: the whole recording)",
    )
    sim.add_argument(
        "--rate",
        type=positive_float,
        default=None,
        metavar="HZ",
        help="capture rate (default 120; a recorded motion: its own; another rate resamples its smoothed "
        "motion)",
    )
    sim.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    sim.add_argument(
        "--sensors",
        default="ideal",
        metavar="PRESET|FILE.toml",
        help=f"sensor preset ({', '.join(preset_names())}) or a configuration TOML (default ideal)",
    )
    sim.add_argument(
        "--sensors-on", metavar="BODY,BODY,...", help="bodies that carry a sensor (default: the model's)"
    )
    sim.add_argument(
        "--markers",
        action="store_true",
        help="also simulate optical marker clusters on every sensor's segment (stored in the dataset; "
        "`simbench export --trc/--c3d` writes them)",
    )
    sim.add_argument(
        "--markers-per-segment", type=int, choices=(3, 4), default=4, help="markers per cluster (default 4)"
    )
    sim.add_argument(
        "--marker-skin",
        type=non_negative_float,
        default=0.0,
        metavar="MM",
        help="markers' skin motion, standard deviation per coordinate in mm (default 0)",
    )
    sim.add_argument(
        "--marker-noise",
        type=non_negative_float,
        default=0.0,
        metavar="MM",
        help="markers' camera noise, standard deviation per coordinate in mm (default 0)",
    )
    sim.add_argument(
        "-o",
        "--output",
        metavar="OUT.h5",
        help="the dataset (HDF5; default MODEL-MOTION-SENSORS-seedSEED.h5 here, e.g. "
        "linkage-exercise-ideal-seed0.h5)",
    )
    sim.add_argument("--csv", metavar="OUT.csv", help="also export the measured poses as a pose CSV")
    sim.add_argument("--truth-json", metavar="OUT.json", help="also export the truth as calibration JSON")
    sim.set_defaults(func=cmd_simulate)


def default_output(args: argparse.Namespace) -> str:
    """The dataset's file name when ``-o`` is not given: what made it, ``MODEL-MOTION-SENSORS-seedSEED.h5``
    (a file's stem for a model, motion or sensor file), in the current folder."""

    def part(value: str | None, default: str) -> str:
        text = Path(value).stem if value and value.lower().endswith(FILE_SUFFIXES) else (value or default)
        return "".join(c if c.isalnum() or c in "-_." else "_" for c in text)

    model = part(args.model, "linkage")
    return f"{model}-{part(args.motion, 'exercise')}-{part(args.sensors, 'ideal')}-seed{args.seed}.h5"


#: File suffixes of a model, motion or sensor file (:func:`default_output` names them by their stem).
FILE_SUFFIXES = (".xml", ".toml", ".bvh", ".npz", ".csv", ".mot", ".sto", ".c3d", ".hdf5", ".h5")


def cmd_simulate(args: argparse.Namespace) -> int:
    """``simbench simulate``: a physics-simulated capture session with exact ground truth."""
    for out in (args.output, args.csv, args.truth_json):
        if out is not None and not Path(out).resolve().parent.is_dir():
            raise InputError(f"cannot write {out}: folder {Path(out).parent} does not exist")
        if out is not None and Path(out).is_dir():
            raise InputError(f"cannot write {out}: it is a folder")
    for option, value in (("--model", args.model), ("--motion", args.motion), ("--sensors", args.sensors)):
        if value is not None and not value.strip():
            raise InputError(f"{option}: expected a name or a file, got {value!r}")
    bodies = None
    if args.sensors_on is not None:
        bodies = tuple(b.strip() for b in args.sensors_on.split(",") if b.strip())
        twice = sorted({b for b in bodies if bodies.count(b) > 1})
        if twice:
            raise InputError(f"--sensors-on: bodies named twice: {twice}")
        if len(bodies) < 2:
            raise InputError(
                "--sensors-on: a capture needs at least 2 bodies, separated by commas, got "
                f"{args.sensors_on!r}"
            )
    asked = (args.markers_per_segment != 4, args.marker_skin > 0, args.marker_noise > 0)
    if any(asked) and not args.markers:
        raise InputError("--markers-per-segment, --marker-skin and --marker-noise need --markers")
    markers = args.markers and MarkerConfig(
        per_segment=args.markers_per_segment,
        skin_sd_m=args.marker_skin * 1e-3,
        camera_noise_m=args.marker_noise * 1e-3,
    )
    ds = simulate(
        args.model,
        args.motion,
        sensors=args.sensors,
        duration_s=args.duration,
        rate_hz=args.rate,
        seed=args.seed,
        sensors_on=bodies,
        markers=markers,
        motion_units=args.motion_units,
        motion_cutoff_hz=args.motion_cutoff,
        motion_clusters=args.motion_clusters,
        motion_position_cutoff_hz=args.motion_position_cutoff,
    )
    meta = ds.meta
    print(
        f"simbench simulate: model {meta['model']}, motion {meta['program']}, sensors "
        f"{meta['sensor_model']}, seed {args.seed}"
    )
    played = meta.get("playback")
    if played:
        filled = played["frames_filled"]
        stage = (
            f"played back (kinematic; rates smoothed below {played['cutoff_hz']:g} Hz, Savitzky-Golay window "
            f"{played['window_frames']} frames{', resampled' if played['resampled'] else ''}"
            f"{f'; {filled} frames without a pose filled' if filled else ''})"
        )
    else:
        rate = 1 / meta["physics_timestep_s"]
        stage = f"physics: {rate:.6g} Hz ({meta['steps_per_sample']} steps per sample)"
    print(f"  sensors: {len(ds.sensors)}   samples: {meta['n_samples']} at {meta['rate_hz']:g} Hz   {stage}")
    print(f"  sensors on: {', '.join(ds.sensors)}")
    if ds.markers is not None:
        print(
            f"  markers: {len(ds.markers.labels)} ({args.markers_per_segment} per segment; skin motion "
            f"{args.marker_skin:g} mm, camera noise {args.marker_noise:g} mm)"
        )
    for note in [*(played or {}).get("notes", ()), *meta.get("sensor_notes", ())]:
        print(f"  note: {note}")
    if meta["mujoco_warnings"]:
        print(f"  MuJoCo warnings: {meta['mujoco_warnings']}")
    write_dataset(args.output, ds)
    print(f"  wrote {args.output}")
    if args.csv:
        write_pose_csv(args.csv, ds.poses())
        print(f"  wrote {args.csv}")
    if args.truth_json:
        write_calibration(args.truth_json, truth_document(ds))
        print(f"  wrote {args.truth_json}")
    return 0
