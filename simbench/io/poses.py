"""Sensor pose recordings and the pose CSV format of DESIGN.md.

**Pose CSV**: header ``time,sensor,x,y,z,qw,qx,qy,qz`` (extra columns are ignored), one row per
sensor per frame; ``time`` in seconds, rows of one frame share the same time; positions in the
file's units (``m``, ``cm``, ``mm`` or ``in``, metres unless told); ``qw..qz`` the scalar-first
quaternion of ``R_w_s`` (sensor to world).

Reading is strict about what cannot be guessed and explicit about what it repairs:

- errors (with file and line): empty file, missing columns, a row with the wrong number of
  fields, a value that is not a number, a non-finite time, an empty sensor name, the same
  sensor twice in one frame, a zero quaternion, unknown units;
- repaired and reported in ``notes``: a sensor missing from some frames, and rows with NaN or
  inf values (both become missing poses, which each pair of sensors drops), quaternions off
  unit norm by more than 1e-3 (normalised).

**Sample rate.** Some tracker loggers stamp samples in bursts: many consecutive samples a few
microseconds apart, then a long step. The smallest or median step then gives a rate orders of
magnitude too high (12.7 kHz printed for a 240 Hz tracker). :func:`sample_rate` calls time
stamps bursty when at least :data:`BURST_FRACTION` of the steps are shorter than
:data:`BURST_STEP` of the mean step (span over steps; unit-free), and then takes the rate from the
sample count over the span; otherwise from the median step (robust to gaps in the recording).
A :class:`PoseRecording` with bursty times says so in its ``notes``, whichever reader made it.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from calibration.rotations import UNIT_TOLERANCE, matrix_to_quat, quat_to_matrix
from simbench.errors import InputError
from simbench.io.atomic import atomic_open
from simbench.units import metres_per_unit

CSV_COLUMNS = ("time", "sensor", "x", "y", "z", "qw", "qx", "qy", "qz")

#: A step shorter than this fraction of the mean step is part of a burst.
BURST_STEP = 0.1

#: Time stamps are bursty when at least this fraction of the steps are part of bursts.
BURST_FRACTION = 0.1


def sample_rate(time_s: np.ndarray) -> tuple[float, str | None]:
    """The sample rate of strictly increasing times, and a note when the stamps come in bursts.

    Args:
        time_s: ``(frames,)`` times, seconds.

    Returns:
        ``(rate_hz, note)``: the rate from the median step, or from the sample count over the
        span when the stamps are bursty (module docstring; the note then says so and why); NaN
        and ``None`` with fewer than 2 frames.
    """
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        return float("nan"), None
    step = np.diff(t)
    mean_step = (t[-1] - t[0]) / step.size
    short = step < BURST_STEP * mean_step
    if np.mean(short) < BURST_FRACTION:
        return float(1.0 / np.median(step)), None
    rate = 1.0 / mean_step
    note = (
        f"time stamps come in bursts: {int(short.sum())} of {step.size} steps are shorter than "
        f"{BURST_STEP:g} of the mean step (median step {np.median(step):.3g} s, which would give "
        f"{1.0 / np.median(step):.4g} Hz); rate taken from the sample count over the span: {rate:.4g} Hz"
    )
    return float(rate), note


class _Text:
    """A text file's lines for ``csv.reader``; bytes that are not UTF-8 are an InputError naming
    the file and line (a binary file, or Latin-1 text, named ``.csv``)."""

    def __init__(self, path: Path, fh: TextIO) -> None:
        self._path, self._fh, self._line = path, fh, 0

    def __enter__(self) -> _Text:
        return self

    def __exit__(self, *exc: object) -> None:
        self._fh.close()

    def __iter__(self) -> _Text:
        return self

    def __next__(self) -> str:
        try:
            line = next(self._fh)
        except UnicodeDecodeError as exc:
            raise InputError(  # no line number: the file is decoded a block at a time
                f"{self._path}: expected UTF-8 text, got byte 0x{exc.object[exc.start]:02x} after line "
                f"{self._line} (a binary file, or another encoding: save it as UTF-8)"
            ) from None
        self._line += 1
        if "\0" in line:
            raise InputError(
                f"{self._path}, line {self._line}: expected text, got a NUL byte (a binary file?)"
            )
        return line


def open_csv(path: Path) -> _Text:
    """Open a text table for ``csv.reader`` (UTF-8, a byte-order mark allowed); a missing or
    unreadable file, or one that is not UTF-8 text, is an InputError."""
    try:
        return _Text(path, path.open(newline="", encoding="utf-8-sig"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None


@dataclass(frozen=True)
class PoseRecording:
    """6-DoF sensor poses over time.

    Attributes:
        names: ``(sensors,)`` sensor names.
        time_s: ``(frames,)`` strictly increasing times, seconds.
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (NaN where missing).
        p_w_s: ``(frames, sensors, 3)`` sensor positions in world, metres (NaN where missing).
        valid: ``(frames, sensors)`` bool, False where a pose is missing or not finite.
        source: where the data came from (a path, or a description).
        notes: what the reader repaired or noticed, in plain language.
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    R_w_s: np.ndarray
    p_w_s: np.ndarray
    valid: np.ndarray
    source: str = ""
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        f, n = self.time_s.shape[0], len(self.names)
        expected = {"time_s": (f,), "R_w_s": (f, n, 3, 3), "p_w_s": (f, n, 3), "valid": (f, n)}
        for name, shape in expected.items():
            got = getattr(self, name).shape
            if got != shape:
                raise InputError(f"Expected {name} to have shape {shape}, got {got}")
        if f > 1 and not np.all(np.diff(self.time_s) > 0):
            raise InputError("times must be strictly increasing")
        _, note = sample_rate(self.time_s)
        if note is not None and note not in self.notes:  # every reader's recording says so
            object.__setattr__(self, "notes", (*self.notes, note))

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.time_s.shape[0])

    def pair(self, parent: str, child: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(R_w_p, p_w_p, R_w_c, p_w_c)`` of two sensors, as the joint functions take them."""
        p, c = self.names.index(parent), self.names.index(child)
        return self.R_w_s[:, p], self.p_w_s[:, p], self.R_w_s[:, c], self.p_w_s[:, c]

    @property
    def rate_hz(self) -> float:
        """Sample rate, Hz: from the median step, or from the sample count over the span when
        the time stamps come in bursts (:func:`sample_rate`); NaN with fewer than 2 frames."""
        return sample_rate(self.time_s)[0]


def _fail(path: str | os.PathLike[str], line: int | None, message: str) -> InputError:
    where = f"{path}" if line is None else f"{path}, line {line}"
    return InputError(f"{where}: {message}")


def read_pose_csv(path: str | os.PathLike[str], *, units: str = "m") -> PoseRecording:
    """Read a pose CSV (see the module docstring).

    Args:
        path: the file.
        units: length unit of the file's positions; converted to metres.

    Raises:
        InputError: naming the file, line and problem.
    """
    scale = metres_per_unit(units)
    path = Path(path)
    with open_csv(path) as fh:
        reader = csv.reader(fh)
        header = None
        for row in reader:
            if any(cell.strip() for cell in row):
                header = [cell.strip() for cell in row]
                break
        if header is None:
            raise _fail(path, None, f"the file is empty; expected a header {','.join(CSV_COLUMNS)}")
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise _fail(
                path,
                reader.line_num,
                f"missing columns {missing}; expected {','.join(CSV_COLUMNS)}, got {','.join(header)}",
            )
        repeated = sorted({c for c in header if header.count(c) > 1 and c in CSV_COLUMNS})
        if repeated:
            raise _fail(path, reader.line_num, f"columns repeated in the header: {repeated}")
        col = [header.index(c) for c in CSV_COLUMNS]
        times: list[float] = []
        sensors: list[str] = []
        values: list[list[float]] = []
        lines: list[int] = []
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            line = reader.line_num
            if len(row) != len(header):
                raise _fail(path, line, f"expected {len(header)} fields, got {len(row)}")
            name = row[col[1]].strip()
            if not name:
                raise _fail(path, line, "empty sensor name")
            nums = []
            for c, k in zip(CSV_COLUMNS, col, strict=True):
                if c == "sensor":
                    continue
                try:
                    nums.append(float(row[k]))
                except ValueError:
                    raise _fail(path, line, f"column {c!r} is not a number: {row[k]!r}") from None
            if not np.isfinite(nums[0]):
                raise _fail(path, line, f"time is not finite: {row[col[0]]!r}")
            times.append(nums[0])
            sensors.append(name)
            values.append(nums[1:])
            lines.append(line)
    if not times:
        raise _fail(path, None, "no data rows after the header")
    return _assemble(path, np.array(times), sensors, np.array(values), np.array(lines), scale, units)


def _assemble(
    path: Path,
    times: np.ndarray,
    sensors: list[str],
    values: np.ndarray,
    lines: np.ndarray,
    scale: float,
    units: str,
) -> PoseRecording:
    """Arrange parsed rows ``(rows, 7)`` = ``x, y, z, qw, qx, qy, qz`` into frames x sensors."""
    names = tuple(dict.fromkeys(sensors))
    s_idx = _index(names, sensors)
    frame_times, t_idx = np.unique(times, return_inverse=True)
    n_frames, n = len(frame_times), len(names)
    key = t_idx * n + s_idx
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(np.diff(key[order]) == 0)
    if dup.size:
        a, b = lines[order[dup[0]]], lines[order[dup[0] + 1]]
        raise _fail(
            path,
            int(b),
            f"sensor {sensors[order[dup[0]]]!r} appears twice at time "
            f"{float(times[order[dup[0]]])!r} (also on line {a}); {dup.size} duplicate row(s) in all",
        )
    notes: list[str] = []
    q = values[:, 3:]
    finite = np.isfinite(values).all(axis=1)
    qnorm = np.linalg.norm(q, axis=1)
    zero = finite & (qnorm == 0.0)
    if zero.any():
        raise _fail(
            path, int(lines[np.flatnonzero(zero)[0]]), f"zero quaternion ({int(zero.sum())} in the file)"
        )
    off = finite & (np.abs(qnorm - 1.0) > UNIT_TOLERANCE)
    if off.any():
        worst = int(np.argmax(np.where(off, np.abs(qnorm - 1.0), -1.0)))
        notes.append(
            f"{int(off.sum())} quaternion(s) off unit norm by more than {UNIT_TOLERANCE:g} were "
            f"normalised (worst |q| = {qnorm[worst]:.6g} on line {int(lines[worst])})"
        )
    R = np.full((n_frames, n, 3, 3), np.nan)
    p = np.full((n_frames, n, 3), np.nan)
    valid = np.zeros((n_frames, n), dtype=bool)
    R[t_idx[finite], s_idx[finite]] = quat_to_matrix(q[finite])
    p[t_idx[finite], s_idx[finite]] = values[finite, :3] * scale
    valid[t_idx[finite], s_idx[finite]] = True
    present = np.zeros((n_frames, n), dtype=bool)
    present[t_idx, s_idx] = True
    for k, name in enumerate(names):
        absent = int(n_frames - present[:, k].sum())
        bad = int(present[:, k].sum() - valid[:, k].sum())
        if absent:
            notes.append(f"sensor {name}: no row in {absent} of {n_frames} frames (treated as missing)")
        if bad:
            notes.append(f"sensor {name}: {bad} row(s) with NaN or inf values (treated as missing)")
    if units != "m":
        notes.append(f"positions read in {units} and converted to metres")
    return PoseRecording(
        names=names, time_s=frame_times, R_w_s=R, p_w_s=p, valid=valid, source=str(path), notes=tuple(notes)
    )


def _index(names: tuple[str, ...], sensors: list[str]) -> np.ndarray:
    lookup = {name: k for k, name in enumerate(names)}
    return np.array([lookup[s] for s in sensors])


def write_pose_csv(
    path: str | os.PathLike[str], rec: PoseRecording, *, units: str = "m", digits: int | None = None
) -> None:
    """Write a pose CSV atomically; missing poses are left out (no row).

    Args:
        path: destination.
        rec: the poses.
        units: length unit for the positions in the file.
        digits: significant digits per value; ``None`` writes every value exactly (``repr``),
            so that reading gives back the same numbers.
    """
    scale = metres_per_unit(units)
    fmt = repr if digits is None else (lambda v: f"{v:.{digits}g}")
    q = matrix_to_quat(np.where(rec.valid[..., None, None], rec.R_w_s, np.eye(3)))
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        for f in range(rec.n_frames):
            t = repr(float(rec.time_s[f]))
            for k, name in enumerate(rec.names):
                if not rec.valid[f, k]:
                    continue
                pos = rec.p_w_s[f, k] / scale
                writer.writerow([t, name, *map(fmt, pos.tolist()), *map(fmt, q[f, k].tolist())])
