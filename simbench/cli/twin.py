"""``simbench twin``: a real IMU recording's digital twin, simulated from the optical pose."""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

from simbench.api import (
    TWIN_EFFECTS,
    TWIN_METHODS,
    TwinResult,
    parse_twin_window,
    twin,
    write_twin,
)
from simbench.cli.types import seed
from simbench.errors import InputError

EPILOG = """\
example:
  simbench twin broad_02_undisturbed_slow_rotation_B.hdf5 --json twin.json --out twin_report --window 20:30

The JSON holds readings.{acc,gyro,mag}.{r2,rms,spectrum}, identified (units in the key names),
orientation.<method>.{real_deg,twin_deg,ratio}, the seed, the file and the software versions.
docs/twin.md explains what is identified, how, and how to read the report.
"""


def _window(text: str) -> tuple[float, float]:
    try:
        return parse_twin_window(text)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--window: ")) from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench twin``."""
    p.description = textwrap.fill(
        "For a BROAD-layout trial (IMU readings beside the optical pose of the housing, opt_pos "
        "and opt_quat), simulate the IMU's readings from the pose, identify what the real sensor adds "
        "(accelerometer and gyroscope bias and noise from the still phases, magnetometer hard and soft "
        "iron, the local field and its gradient, each sensor's time offset against the optical clock, "
        "the axis misalignment, the accelerometer's lever arm), compare real and twin sample by sample "
        "over the motion phase (R^2, rms, the difference's spectrum), and score the orientation methods "
        f"({', '.join(TWIN_METHODS)}) on the real recording and on the twin.",
        width=96,
    )
    p.add_argument("recording", help="a BROAD trial (.hdf5) with opt_pos and opt_quat")
    p.add_argument("--json", metavar="OUT", help="write the figures as JSON")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write a report there: index.md, index.html, results.json, traces.png (real and twin "
        "overlaid over the window), spectra.png",
    )
    p.add_argument(
        "--window",
        type=_window,
        default=None,
        metavar="START:END",
        help="the report's traces, s (default: 10 s about the middle of the motion phase)",
    )
    p.add_argument("--seed", type=seed, default=0, help="seed of the twin's noise (default 0)")
    p.add_argument(
        "--without",
        action="append",
        choices=TWIN_EFFECTS,
        default=[],
        metavar="EFFECT",
        help=f"leave an effect out, to measure what it explains (repeatable): {', '.join(TWIN_EFFECTS)}",
    )
    p.set_defaults(func=cmd_twin)


def print_summary(result: TwinResult) -> None:
    """The figures on standard output."""
    d = result.as_dict()
    ident, cov = d["identified"], d["coverage"]
    off = ident["time_offset_ms"]
    lever = ", ".join(f"{x:.1f}" for x in ident["lever_arm_mm"])
    hard = ", ".join(f"{x:.2f}" for x in ident["hard_iron_ut"])
    lines = [
        f"simbench twin: {result.source}",
        f"  {d['samples']} samples at {result.rate_hz:.6g} Hz; compared "
        f"{100 * cov['compared_fraction']:.0f} % (motion; {100 * cov['motion_excluded_fraction']:.1f} % of "
        f"it left out near the {100 * cov['optical_gap_fraction']:.1f} % of optical gaps)",
        f"  identified: time offset gyro {off['gyro']:.2f} ms, acc {off['acc']:.2f} ms, mag "
        f"{off['mag']:.2f} ms; misalignment {ident['misalignment_deg']:.2f} deg; lever arm ({lever}) mm",
        f"  field {ident['field_strength_ut']:.1f} uT, dip {ident['field_inclination_deg']:.1f} deg; hard "
        f"iron ({hard}) uT; {100 * ident['mag_disturbed_fraction']:.1f} % of the magnetometer samples left "
        "out as disturbed",
    ]
    if not ident["mag_field_determined"]:
        lines.append(
            "  (hard iron and field not told apart: the orientations span too little; the readings are "
            "predicted all the same)"
        )
    for kind, r in d["readings"].items():
        s = r["spectrum"]
        lines.append(
            f"  {kind:4s} R^2 {r['r2']:.4f} (noise ceiling {r['r2_noise_ceiling']:.4f})  rms "
            f"{r['rms']:.3g} {r['unit']}  difference: median {s['median_frequency_hz']:.1f} Hz, peak "
            f"{s['peak_frequency_hz']:.1f} Hz"
        )
    for method, o in d["orientation"].items():
        lines.append(
            f"  {method:9s} real {o['real_deg']:.2f} deg  twin {o['twin_deg']:.2f} deg  twin/real "
            f"{o['ratio']:.2f}"
        )
    print("\n".join(lines))


def cmd_twin(args: argparse.Namespace) -> int:
    """``simbench twin``: the digital twin of a real IMU recording."""
    if args.out is not None:
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise InputError(f"--out {out} exists and is not a folder")
        if not out.parent.is_dir():
            raise InputError(f"--out {out}: folder {out.parent} does not exist")
    result = twin(args.recording, seed=args.seed, window=args.window, without=args.without)
    print_summary(result)
    for path in write_twin(result, json_path=args.json, out=args.out).values():
        print(f"wrote {path}")
    return 0
