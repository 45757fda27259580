"""Live calibration at the command line: ``simbench replay`` and ``simbench calibrate --follow``.

Both feed frames to :class:`calibration.streaming.StreamingCalibrator` and print a table that
refreshes every ``--refresh`` seconds of capture time (joints, residuals, guidance, slip alerts);
slip alerts are printed the moment they are raised. On a terminal each table replaces the last;
otherwise (a log, a pipe) tables follow each other.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.errors import CalibrationError
from calibration.hierarchy import HIERARCHY_METHODS
from calibration.joint import SINGLE_AXIS_RATIO
from calibration.rotations import quat_to_matrix
from calibration.slip import FALSE_ALARMS_PER_HOUR
from calibration.streaming import LiveState, SlipAlert, StreamingCalibrator
from simbench.cli.table import text_table
from simbench.cli.types import positive_float
from simbench.errors import InputError
from simbench.io.poses import CSV_COLUMNS
from simbench.io.read import read_poses
from simbench.sim.live import live_blocks
from simbench.units import metres_per_unit

#: Seconds of capture between two tables.
REFRESH_S = 1.0

#: Seconds to wait before looking at a followed file again when it has not grown.
POLL_S = 0.05

#: Frames a followed file must hold before its rate is estimated (count over span, DESIGN.md).
RATE_FRAMES = 64


def add_replay_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand to ``simbench``'s subparsers."""
    rep = sub.add_parser(
        "replay",
        help="feed a recorded or simulated session through the live (streaming) calibration",
        description="Replay a pose file (dataset .h5 or pose CSV) frame by frame through the "
        "incremental calibration, printing a refreshing table and slip alerts as they are raised.",
    )
    rep.add_argument("input", help="a simbench dataset .h5 or a pose CSV")
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


def add_follow_arguments(cal: argparse.ArgumentParser) -> None:
    """``--follow`` and its options on ``simbench calibrate``."""
    cal.add_argument(
        "--follow",
        action="store_true",
        help="INPUT is a pose CSV a logger is still writing: calibrate live as rows arrive "
        "(Ctrl-C or --timeout stops)",
    )
    cal.add_argument(
        "--timeout",
        type=positive_float,
        default=None,
        metavar="SECONDS",
        help="with --follow: stop after this many seconds of wall time (default: until Ctrl-C)",
    )
    cal.add_argument(
        "--rate-hz",
        type=positive_float,
        default=None,
        metavar="HZ",
        help=f"with --follow: the capture rate (default: from the first {RATE_FRAMES} frames' time stamps)",
    )
    cal.add_argument(
        "--refresh",
        type=positive_float,
        default=REFRESH_S,
        metavar="SECONDS",
        help=f"with --follow: seconds of capture between tables (default {REFRESH_S:g})",
    )


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--refresh",
        type=positive_float,
        default=REFRESH_S,
        metavar="SECONDS",
        help=f"seconds of capture between tables (default {REFRESH_S:g})",
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
    """Prints alerts as they come and a table every ``refresh_s`` of capture time."""

    source: str
    refresh_s: float
    out: Callable[[str], None] = print
    clear: bool = False
    next_at: float = 0.0
    shown: list[SlipAlert] = field(default_factory=list)

    def frames(self, cal: StreamingCalibrator, time_s: float) -> None:
        """After frames up to ``time_s`` (capture time) were pushed."""
        for alert in cal.new_alerts():
            self.shown.append(alert)
            raised = cal.start_time_s + alert.raised_frame / cal.rate_hz
            self.out(f"ALERT at {raised:.2f} s: {alert.message} (joint {alert.joint})")
        if time_s >= self.next_at:
            self.next_at = time_s + self.refresh_s
            self.table(cal)

    def table(self, cal: StreamingCalibrator, final: bool = False) -> None:
        """The table now; the ``final`` one raises ``CalibrationError`` when there is none."""
        try:
            state = cal.state()
        except CalibrationError as exc:
            if final:  # the recording is over: what was waited for never came
                raise CalibrationError(
                    f"{self.source}: no calibration from its {cal.n_frames} frames: {exc}"
                ) from None
            self.out(f"simbench live: {self.source}: {cal.n_frames} frames, waiting ({exc})")
            return
        text = live_table(self.source, state, final=final)
        self.out(("\x1b[H\x1b[2J" if self.clear and not final else "") + text)


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
                "single" if fit.single_axis else ("none" if fit.rank < 5 else "-"),
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


@dataclass(frozen=True)
class LiveOptions:
    """The calibrator's options the live commands pass on (:class:`StreamingCalibrator`)."""

    slip: bool = True
    parent_of: dict[str, str] | None = None
    root: str | None = None
    hierarchy_method: str = HIERARCHY_METHODS[0]
    single_axis_ratio: float = SINGLE_AXIS_RATIO
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR


def _calibrator(
    names: tuple[str, ...], rate_hz: float, start_s: float, options: LiveOptions
) -> StreamingCalibrator:
    try:
        return StreamingCalibrator(
            names,
            rate_hz=rate_hz,
            start_time_s=start_s,
            slip=options.slip,
            parent_of=options.parent_of,
            root=options.root,
            hierarchy_method=options.hierarchy_method,
            single_axis_ratio=options.single_axis_ratio,
            false_alarms_per_hour=options.false_alarms_per_hour,
        )
    except CalibrationError as exc:
        raise InputError(str(exc)) from None


def cmd_replay(args: argparse.Namespace) -> int:
    """``simbench replay``: a pose file through the live calibration."""
    speed = parse_speed(args.rate)
    rec = read_poses(args.input, args.units)
    if rec.n_frames < 2 or not np.isfinite(rec.rate_hz):
        raise InputError(f"{args.input}: too few frames to replay ({rec.n_frames})")
    cal = _calibrator(rec.names, rec.rate_hz, float(rec.time_s[0]), LiveOptions(slip=not args.no_slip))
    printer = LivePrinter(str(args.input), args.refresh, clear=sys.stdout.isatty())
    printer.next_at = float(rec.time_s[0]) + args.refresh
    block = max(1, round(rec.rate_hz / 20))  # 50 ms of frames at a time
    for b in live_blocks(rec, block_frames=block, speed=speed):
        cal.push(b.R_w_s, b.p_w_s, b.valid)
        printer.frames(cal, float(b.time_s[-1]))
    printer.table(cal, final=True)
    return 0


# ---------------------------------------------------------------- following a growing pose CSV


@dataclass
class CsvFollower:
    """Reads the complete rows a logger has appended to a pose CSV since the last call.

    Frames are the rows sharing a time; a frame is complete when a row of a later time arrives
    (the last frame of the file is complete only at :meth:`flush`). The sensors are those of the
    first frame; a later row naming another sensor is an error. Like the batch reader
    (:mod:`simbench.io.poses`), it ignores extra columns, takes a row of NaN or inf values as a
    missing pose, and refuses (naming the line) a non-finite or decreasing time, an empty sensor
    name, a sensor twice in one frame and a zero quaternion.
    """

    path: Path
    scale: float
    names: tuple[str, ...] | None = None
    _fh: object = None
    _partial: str = ""
    _rows: list[tuple[float, str, list[float], int]] = field(default_factory=list)
    _line: int = 0  # lines read
    _columns: list[int] = field(default_factory=list)  # of CSV_COLUMNS in the header
    _width: int = 0  # fields per row
    _last_time: float = -np.inf

    def frames(self) -> Iterator[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
        """``(time_s, R (S, 3, 3), p (S, 3), valid (S,))`` of every newly completed frame."""
        for time_s, rows in self._complete(final=False):
            yield self._frame(time_s, rows)

    def flush(self) -> Iterator[tuple[float, np.ndarray, np.ndarray, np.ndarray]]:
        """The last frame too (the logger has stopped)."""
        for time_s, rows in self._complete(final=True):
            yield self._frame(time_s, rows)

    def _read(self) -> None:
        if self._fh is None:
            if not self.path.exists():
                return
            self._fh = open(self.path, encoding="utf-8", newline="")
        try:
            chunk = self._fh.read()  # type: ignore[attr-defined]
        except UnicodeDecodeError as exc:
            raise InputError(
                f"{self.path}: not a pose CSV: byte {exc.start} of what was read is not UTF-8 text"
            ) from None
        if not chunk:
            return
        text = self._partial + chunk
        lines = text.split("\n")
        self._partial = lines.pop()  # a row still being written
        for raw in lines:
            line = raw.strip()
            self._line += 1
            if self._line == 1:
                header = [c.strip() for c in line.split(",")]
                if any(header.count(c) != 1 for c in CSV_COLUMNS):
                    raise InputError(
                        f"{self.path}: header must be {','.join(CSV_COLUMNS)} (extra columns are "
                        f"ignored), got {line!r}"
                    )
                self._columns, self._width = [header.index(c) for c in CSV_COLUMNS], len(header)
                continue
            if not line:
                continue
            self._rows.append(self._row(line))

    def _row(self, line: str) -> tuple[float, str, list[float], int]:
        """``(time_s, sensor, [x, y, z, qw, qx, qy, qz], line)`` of one data line, or an error."""
        where = f"{self.path}: line {self._line}"
        cells = line.split(",")
        if len(cells) != self._width:
            raise InputError(f"{where}: expected {self._width} values, got {len(cells)}")
        time_cell, name, *value_cells = (cells[k].strip() for k in self._columns)
        try:
            t = float(time_cell)
            values = [float(c) for c in value_cells]
        except ValueError:
            raise InputError(f"{where}: not a number in {line!r}") from None
        if not np.isfinite(t):
            raise InputError(f"{where}: time is not finite: {time_cell!r}")
        if t < self._last_time:
            raise InputError(f"{where}: time {t!r} s is earlier than the row before ({self._last_time!r} s)")
        if not name:
            raise InputError(f"{where}: empty sensor name")
        if all(v == 0.0 for v in values[3:]):
            raise InputError(f"{where}: zero quaternion")
        self._last_time = t
        return t, name, values, self._line

    def _complete(self, final: bool) -> Iterator[tuple[float, list[tuple[str, list[float], int]]]]:
        self._read()
        rows = self._rows
        start = 0
        while start < len(rows):
            t = rows[start][0]
            stop = start
            while stop < len(rows) and rows[stop][0] == t:
                stop += 1
            if stop == len(rows) and not final:
                break
            yield t, [(s, v, line) for _, s, v, line in rows[start:stop]]
            start = stop
        self._rows = rows[start:]

    def _frame(
        self, time_s: float, rows: list[tuple[str, list[float], int]]
    ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        seen: dict[str, int] = {}
        for s, _, line in rows:
            if s in seen:
                raise InputError(
                    f"{self.path}: line {line}: sensor {s!r} appears twice at time {time_s!r} "
                    f"(also on line {seen[s]})"
                )
            seen[s] = line
        if self.names is None:
            self.names = tuple(seen)
        index = {s: k for k, s in enumerate(self.names)}
        n = len(self.names)
        p = np.full((n, 3), np.nan)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        valid = np.zeros(n, dtype=bool)
        for s, v, _ in rows:
            if s not in index:
                raise InputError(
                    f"{self.path}: sensor {s!r} at {time_s} s was not in the first frame ({list(self.names)})"
                )
            k = index[s]
            p[k] = np.array(v[:3]) * self.scale
            q[k] = v[3:]
            valid[k] = True
        valid &= np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1)  # NaN or inf: a missing pose
        R = np.full((n, 3, 3), np.nan)
        R[valid] = quat_to_matrix(q[valid] / np.linalg.norm(q[valid], axis=1, keepdims=True))
        return time_s, R, p, valid

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()  # type: ignore[attr-defined]


def follow_csv(
    path: str | os.PathLike[str],
    *,
    units: str = "m",
    rate_hz: float | None = None,
    timeout_s: float | None = None,
    refresh_s: float = REFRESH_S,
    options: LiveOptions = LiveOptions(),
    out: Callable[[str], None] = print,
    clock: Callable[[], float] = time.monotonic,
) -> StreamingCalibrator | None:
    """Calibrate live from a pose CSV that another process is appending to.

    Reads new complete rows every :data:`POLL_S` seconds, pushes each completed frame and prints
    alerts and tables (:class:`LivePrinter`); stops after ``timeout_s`` seconds of wall time or at
    Ctrl-C (KeyboardInterrupt), then prints the final table. Returns the calibrator (``None`` when
    no frame arrived).
    """
    follower = CsvFollower(Path(path), metres_per_unit(units))
    start = clock()
    waiting: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []  # frames before the rate is known
    cal: StreamingCalibrator | None = None
    printer = LivePrinter(str(path), refresh_s, out=out, clear=sys.stdout.isatty())

    def push(frame: tuple[float, np.ndarray, np.ndarray, np.ndarray]) -> None:
        nonlocal cal
        if cal is None:
            waiting.append(frame)
            times = np.array([f[0] for f in waiting])
            if rate_hz is None and (len(waiting) < RATE_FRAMES or times[-1] <= times[0]):
                return
            rate = rate_hz if rate_hz is not None else (len(times) - 1) / (times[-1] - times[0])
            assert follower.names is not None
            cal = _calibrator(follower.names, rate, float(times[0]), options)
            printer.next_at = float(times[0]) + refresh_s
            for _, R, p, ok in waiting:
                cal.push(R, p, ok)
            printer.frames(cal, float(times[-1]))
            waiting.clear()
            return
        t, R, p, ok = frame
        cal.push(R, p, ok)
        printer.frames(cal, t)

    try:
        while timeout_s is None or clock() - start < timeout_s:
            got = False
            for frame in follower.frames():
                push(frame)
                got = True
            if not got:
                time.sleep(POLL_S)
        for frame in follower.flush():
            push(frame)
    except KeyboardInterrupt:
        out("simbench: stopped (Ctrl-C)")
    finally:
        follower.close()
    if cal is None and len(waiting) >= 2:  # a short file: the rate from what there is
        times = np.array([f[0] for f in waiting])
        if times[-1] > times[0]:
            rate_hz = rate_hz or (len(times) - 1) / (times[-1] - times[0])
            assert follower.names is not None
            cal = _calibrator(follower.names, rate_hz, float(times[0]), options)
            for _, R, p, ok in waiting:
                cal.push(R, p, ok)
    if cal is None:
        out(f"simbench: {path}: no complete frames")
        return None
    printer.frames(cal, float("-inf"))
    printer.table(cal, final=True)
    return cal
