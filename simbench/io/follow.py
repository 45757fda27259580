"""A pose CSV read while a logger is still appending to it (``simbench calibrate --follow``).

:class:`CsvFollower` returns, at each call, the frames completed since the last: the rows a logger
has appended, cut where a row is still being written, checked by the batch reader's rules
(:mod:`simbench.io.poses`). :func:`simbench.experiments.live.follow` pushes them into the live
calibration.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.poses import CSV_COLUMNS


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


__all__ = ["CsvFollower"]
