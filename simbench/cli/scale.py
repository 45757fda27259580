"""``simbench scale``: the unit scale factor of a capture system (O'Brien et al. 2000, section 4)."""

from __future__ import annotations

import argparse

from simbench.api import pose_inputs_text, read_poses, rigidity, unit_scale
from simbench.cli.types import positive_float
from simbench.errors import CalibrationError, InputError
from simbench.units import LENGTH_UNITS, metres_per_unit


def add_arguments(scale: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench scale``."""
    scale.description = (
        "Estimate the unit scale factor of a capture system from two sensors mounted "
        "rigidly a known distance apart (O'Brien et al. 2000, section 4)."
    )
    scale.add_argument("input", help=f"the poses: {pose_inputs_text(without=('wide',))}")
    scale.add_argument("--sensors", nargs=2, required=True, metavar=("A", "B"), help="the two sensors")
    scale.add_argument(
        "--distance", type=positive_float, required=True, help="their true distance, in --units"
    )
    scale.add_argument(
        "--units",
        choices=sorted(LENGTH_UNITS),
        default=None,
        help="length unit of the positions and of --distance (default m; a C3D file's positions are "
        "read in its POINT:UNITS unless this is given)",
    )
    scale.set_defaults(func=cmd_scale)


def cmd_scale(args: argparse.Namespace) -> int:
    """``simbench scale``: the unit scale factor from two rigidly mounted sensors (O'Brien 4)."""
    rec = read_poses(args.input, args.units)
    missing = [name for name in args.sensors if name not in rec.names]
    if missing:
        raise InputError(f"{args.input}: no sensor named {missing}; sensors are {list(rec.names)}")
    if args.sensors[0] == args.sensors[1]:
        raise InputError("--sensors needs two different sensors")
    known = args.distance * metres_per_unit(args.units or "m")
    try:
        est = unit_scale(rec, args.sensors, known)
    except CalibrationError as exc:  # too few frames with both sensors
        raise InputError(f"{args.input}: sensors {args.sensors[0]} and {args.sensors[1]}: {exc}") from None
    print(f"simbench scale: {rec.source}, sensors {args.sensors[0]} and {args.sensors[1]}")
    print(f"  frames used         {est.n_frames} of {rec.n_frames}")
    print(f"  known distance      {known * 100:.2f} cm")
    print(f"  mean reported       {est.mean_reported * 100:.2f} cm (as {args.units or 'm'} read)")
    print(f"  scale factor        {est.scale:#.4g}  (multiply reported lengths by this)")
    print(f"  scaled std          {est.scaled_std * 100:.3f} cm")
    steady, noise = rigidity(est.distances)
    if steady > 3 * noise:
        print(
            f"  note: the distance between the two sensors varies {steady / noise:.0f} times more than its "
            f"frame-to-frame noise ({100 * steady / est.mean_reported:.2g} % of it, robust spread): are they "
            "rigidly mounted, or is the field distorted where they moved?"
        )
    return 0
