"""Live calibration at the command line: ``simbench replay`` and ``simbench calibrate --follow``.

Both print the updates of the live calibration (:mod:`simbench.experiments.live`; ``sb.follow``
and ``sb.replay`` in Python): a table that refreshes every ``--refresh`` seconds of capture time
(joints, residuals, guidance, slip alerts); slip alerts are printed the moment they are raised.
On a terminal each table replaces the last; otherwise (a log, a pipe) tables follow each other.
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simbench.api import (
    LIVE_REFRESH_S,
    LOCATED_RANK,
    LiveState,
    LiveUpdate,
    StreamingCalibrator,
    follow,
    pose_inputs_text,
    replay,
)
from simbench.cli.table import text_table
from simbench.cli.types import positive_float
from simbench.errors import InputError

#: Print a line and flush it: an alert reaches a pipe or a log the moment it is raised.
PRINT: Callable[..., None] = functools.partial(print, flush=True)


def add_replay_arguments(rep: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench replay``."""
    rep.description = (
        "Replay a pose file (dataset .h5 or pose CSV) frame by frame through the "
        "incremental calibration, printing a refreshing table and slip alerts as they are raised."
    )
    rep.add_argument("input", help=f"the poses: {pose_inputs_text(without=('wide',))}")
    rep.add_argument(
        "--rate",
        default="1x",
        metavar="1x|10x|max",
        help="speed: a multiple of the capture rate (1x: real time), or max (default 1x)",
    )
    rep.add_argument(
        "--units",
        default=None,
        help="length unit of the positions (default: m for a CSV; a C3D file's own POINT:UNITS, which a "
        "unit given here overrides)",
    )
    _common(rep)
    rep.set_defaults(func=cmd_replay)


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--refresh",
        type=positive_float,
        default=LIVE_REFRESH_S,
        metavar="SECONDS",
        help=f"seconds of capture between tables (default {LIVE_REFRESH_S:g})",
    )
    parser.add_argument("--no-slip", action="store_true", help="no slip alerts")


def parse_speed(text: str) -> float | None:
    """``"1x"`` -> 1.0, ``"10x"`` -> 10.0, ``"max"`` -> ``None`` (as fast as possible)."""
    t = text.strip().lower()
    if t == "max":
        return None
    try:
        speed = float(t[:-1] if t.endswith("x") else t)
    except ValueError:
        speed = float("nan")
    if not (np.isfinite(speed) and speed > 0):
        raise InputError(f"--rate must be like 1x, 10x or max, got {text!r}")
    return speed


@dataclass
class LivePrinter:
    """Prints the live calibration's updates (:class:`simbench.experiments.live.LiveUpdate`): slip
    alerts as they are raised, the tables, and the final table."""

    source: str
    out: Callable[[str], None] = field(default=PRINT)
    clear: bool = False

    def show(self, update: LiveUpdate) -> None:
        """Print one update."""
        if update.kind == "alert":
            assert update.alert is not None
            self.out(f"ALERT at {update.raised_s:.2f} s: {update.alert.message} (joint {update.alert.joint})")
        elif update.kind == "waiting":
            n = 0 if update.calibrator is None else update.calibrator.n_frames
            self.out(f"simbench live: {self.source}: {n} frames, waiting ({update.reason})")
        elif update.kind in ("state", "final"):
            assert update.state is not None
            final = update.kind == "final"
            text = live_table(self.source, update.state, final=final)
            self.out(("\x1b[H\x1b[2J" if self.clear and not final else "") + text)
        else:
            self.out(f"simbench: stopped ({update.reason or 'Ctrl-C'})")

    def show_all(self, updates: Generator[LiveUpdate, None, None]) -> StreamingCalibrator | None:
        """Print every update; returns the calibrator of the final one (``None`` without one).

        Ctrl-C while a line is being printed is handed to the live loop, which takes it as if it
        had come while it read: a follow stops and still gives its final table.
        """
        final = None
        pending: BaseException | None = None
        while True:
            try:
                update = next(updates) if pending is None else updates.throw(pending)
            except StopIteration:
                return final
            pending = None
            if update.kind == "final":
                final = update.calibrator
            try:
                self.show(update)
            except KeyboardInterrupt as exc:
                pending = exc


def live_table(source: str, state: LiveState, *, final: bool = False) -> str:
    """The live table: joints (mm), residuals, single-axis verdicts, guidance, slip alerts.

    Args:
        source: what is being calibrated (a path).
        state: from :meth:`calibration.streaming.StreamingCalibrator.state`.
        final: the last table (headed so).
    """
    cal = state.calibration
    head = "final" if final else "live"
    lines = [
        f"simbench {head}: {source}",
        f"  frames: {state.n_frames}   time: {state.time_s:.2f} s   sensors: {len(cal.names)}   "
        f"hierarchy: {'given' if cal.hierarchy_given else 'inferred'}, root {cal.root}",
        "",
    ]
    rows = []
    for joint, cov in zip(cal.joints, state.coverage, strict=True):
        fit = joint.fit
        rows.append(
            [
                joint.name,
                " ".join(f"{v * 1e3:7.1f}" for v in fit.joint_in_parent),
                " ".join(f"{v * 1e3:7.1f}" for v in fit.joint_in_child),
                f"{fit.rms_residual * 1e3:.2f}",
                "single" if fit.single_axis else ("none" if fit.rank < LOCATED_RANK else "-"),
                " ".join(f"{v:.0f}" for v in cov.rotation_rms_deg),
                cov.advice,
            ]
        )
    headers = ["joint", "in parent (mm)", "in child (mm)", "rms mm", "axis", "turned deg", "guidance"]
    lines += text_table(headers, rows, "lllrlll")
    lines.append("")
    lines.append(
        f"  slip alerts: {len(state.alerts)}   (threshold set for {state.false_alarms_per_hour:.3g} false "
        f"alarms per hour over {len(cal.joints)} joints)"
    )
    lines += [f"    - {a.message} (joint {a.joint})" for a in state.alerts]
    return "\n".join(lines)


def cmd_replay(args: argparse.Namespace) -> int:
    """``simbench replay``: a pose file through the live calibration."""
    speed = parse_speed(args.rate)
    updates = replay(args.input, units=args.units, speed=speed, refresh_s=args.refresh, slip=not args.no_slip)
    LivePrinter(str(args.input), clear=sys.stdout.isatty()).show_all(updates)
    return 0


def follow_csv(
    path: str | os.PathLike[str],
    *,
    units: str = "m",
    rate_hz: float | None = None,
    timeout_s: float | None = None,
    refresh_s: float = LIVE_REFRESH_S,
    out: Callable[[str], None] = PRINT,
    clock: Callable[[], float] = time.monotonic,
    **options: Any,
) -> StreamingCalibrator | None:
    """Calibrate live from a pose CSV that another process is appending to, printing alerts and
    tables (:func:`simbench.api.follow`, which takes ``options``: the hierarchy, O'Brien's
    options, slip alerts) until ``timeout_s`` seconds of wall time or Ctrl-C, then the final
    table. Returns the calibrator (``None`` when no frame arrived)."""
    printer = LivePrinter(str(path), out=out, clear=sys.stdout.isatty())
    updates = follow(
        path,
        units=units,
        rate_hz=rate_hz,
        timeout_s=timeout_s,
        refresh_s=refresh_s,
        clock=clock,
        **options,
    )
    cal = printer.show_all(updates)
    if cal is None:
        out(f"simbench: {path}: no complete frames")
    return cal
