"""The calibration JSON of DESIGN.md: what ``simbench calibrate --json`` writes.

The fields of DESIGN.md (``units``, ``root``, ``joints`` with ``parent``, ``child``,
``joint_in_parent``, ``joint_in_child``, ``rms_residual``, ``single_axis``, ``axis_in_parent``,
``axis_in_child``) are kept as they are; everything else is added beside them. Lengths are in
``units`` (always ``"m"`` here); a value JSON cannot hold (an infinite condition number) is
written as ``null``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from calibration.pipeline import Calibration
from calibration.slip import SlipReport
from simbench.io.atomic import atomic_write_text
from simbench.versions import software_versions

FORMAT = "simbench-calibration"
FORMAT_VERSION = 1


def _num(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _vec(v: np.ndarray | None) -> list[float] | None:
    return None if v is None else [float(a) for a in np.asarray(v)]


def calibration_to_dict(
    cal: Calibration,
    *,
    time_s: np.ndarray | None = None,
    slips: Sequence[tuple[str, SlipReport]] = (),
    input_info: dict[str, Any] | None = None,
    notes: Sequence[str] = (),
    options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The calibration as a JSON-ready dict (schema: module docstring and DESIGN.md).

    Args:
        cal: the calibration.
        time_s: ``(frames,)`` times, seconds, to give slip events and intervals in seconds.
        slips: ``(joint name, report)`` of slip detection per joint.
        input_info: what was read (source, sensors, frames, rate, units).
        notes: what the reader repaired or noticed.
        options: the options the calibration ran with.
    """
    joints = []
    for j in cal.joints:
        fit = j.fit
        s = fit.singular_values
        joints.append(
            {
                "parent": j.parent,
                "child": j.child,
                "joint_in_parent": _vec(fit.joint_in_parent),
                "joint_in_child": _vec(fit.joint_in_child),
                "rms_residual": float(fit.rms_residual),
                "single_axis": bool(fit.single_axis),
                "axis_in_parent": _vec(fit.axis_in_parent),
                "axis_in_child": _vec(fit.axis_in_child),
                "max_residual": (
                    _num(np.nanmax(fit.frame_residual))
                    if fit.frame_residual is not None and np.isfinite(fit.frame_residual).any()
                    else None
                ),
                "rank": fit.rank,
                "singular_values_per_sqrt_frame": [float(x) for x in s / math.sqrt(max(fit.n_frames, 1))],
                "condition": _num(fit.condition),
                "n_frames": fit.n_frames,
                "n_dropped": fit.n_dropped,
            }
        )

    def t(frame: int) -> float | None:
        if time_s is None:
            return None
        return float(time_s[min(frame, len(time_s) - 1)])

    def t_end(stop: int) -> float | None:
        if time_s is None:
            return None
        return float(time_s[stop - 1])

    slip_out = [
        {
            "joint": name,
            "window_frames": rep.window,
            "noise": float(rep.noise),
            "events": [
                {
                    "frame": ev.frame,
                    "time_s": t(ev.frame),
                    "jump": ev.jump,
                    "sensor": ev.sensor_frame,
                    "z": _num(ev.z),
                }
                for ev in rep.events
            ],
            "intervals": [
                {"start_frame": a, "stop_frame": b, "start_s": t(a), "end_s": t_end(b)}
                for a, b in rep.intervals
            ],
        }
        for name, rep in slips
    ]
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "units": "m",
        "root": cal.root,
        "hierarchy": "given" if cal.hierarchy_given else "inferred",
        "joints": joints,
        "limb_lengths": [
            {"segment": x.segment, "joint_a": x.joint_a, "joint_b": x.joint_b, "length": x.length}
            for x in cal.lengths
        ],
        "sensor_offsets": [
            {
                "sensor": pl.sensor,
                "joints": list(pl.joints),
                "offsets": [_vec(o) for o in pl.offsets],
                "distances": [float(d) for d in pl.distances],
            }
            for pl in cal.placements
        ],
        "loop_candidates": [{"a": a, "b": b, "rms_residual": r} for a, b, r in cal.loop_candidates],
        "slip": slip_out,
        "warnings": list(cal.warnings),
        "notes": list(notes),
        "input": dict(input_info or {}),
        "options": dict(options or {}),
        "timing_s": dict(cal.seconds),
        "software": software_versions(),
    }


def write_calibration_json(path: str | os.PathLike[str], doc: dict[str, Any]) -> None:
    """Write a calibration dict as JSON, atomically."""
    atomic_write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
