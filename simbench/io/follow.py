"""A pose CSV read while a logger is still appending to it (``simbench calibrate --follow``).

:class:`CsvFollower` returns, at each call, the frames completed since the last: the rows a logger
has appended, cut where a row is still being written, read by the batch reader's rules
(:mod:`simbench.io.csv_blocks`): UTF-8 with or without a byte-order mark, the csv module's quoting,
the header on the first line that is not blank, extra columns ignored, blank lines skipped, a row
of NaN or inf values a missing pose; refused, naming the line: a missing or repeated column, a row
of another number of fields, a number that is not one, a non-finite time, an empty sensor name, a
sensor twice in one frame, a zero quaternion. Two rules are the live reading's own: times must not
decrease (a frame is complete when a later time arrives), and the sensors are those of the frames
read before the calibration starts (:meth:`CsvFollower.set_names`), a sensor first seen later
being an error (the live calibration cannot grow a sensor).

The file is read at most :data:`READ_BYTES` at a time, so memory holds that much text, not a
backlog. It is tracked by its identity (device, inode), its size and the bytes last read: a file
replaced (rotated), truncated or rewritten under the follower stops the follow with
:class:`FollowStopped`, naming what happened; the frames read before stay calibrated, and the new
file is followed by a new command.
"""

from __future__ import annotations

import codecs
import csv
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.csv_blocks import CSV_COLUMNS, check_header, fail

#: Bytes read from the file per call, at most.
READ_BYTES = 1 << 20

#: Bytes before the read position compared with the file at each read (a file rewritten in place).
TAIL_BYTES = 64

#: One frame as read: ``(time_s, [(sensor, [x, y, z, qw, qx, qy, qz], line), ...])``.
RawFrame = tuple[float, list[tuple[str, list[float], int]]]


class FollowStopped(InputError):
    """The followed file was truncated, replaced or removed while it was followed."""


@dataclass
class CsvFollower:
    """Reads the complete rows a logger has appended to a pose CSV since the last call (module
    docstring for the rules).

    Frames are the rows sharing a time; a frame is complete when a row of a later time arrives
    (the last frame read is complete at :meth:`flush`).
    """

    path: Path
    scale: float
    names: tuple[str, ...] | None = None
    _fd: int | None = None
    _identity: tuple[int, int] = (0, 0)
    _offset: int = 0  # bytes consumed
    _tail: bytes = b""  # the last TAIL_BYTES consumed
    _decoder: codecs.IncrementalDecoder = field(
        default_factory=lambda: codecs.getincrementaldecoder("utf-8-sig")()
    )
    _partial: str = ""
    _rows: list[tuple[float, str, list[float], int]] = field(default_factory=list)
    _line: int = 0  # lines read
    _header: list[str] | None = None
    _columns: list[int] = field(default_factory=list)  # of CSV_COLUMNS in the header
    _last_time: float = -math.inf

    @property
    def appeared(self) -> bool:
        """Whether the file has been opened (it may not exist yet when the follow starts)."""
        return self._identity != (0, 0)

    def frames(self) -> Iterator[RawFrame]:
        """Every frame completed by one read (at most :data:`READ_BYTES`) and those before it."""
        self._read()
        yield from self._complete(final=False)

    def flush(self) -> Iterator[RawFrame]:
        """The frames read but not yet returned, the last one too (the follow ends); reads
        nothing more."""
        yield from self._complete(final=True)

    def set_names(self, names: tuple[str, ...]) -> None:
        """Fix the sensors of :meth:`arrays` (the live calibration's)."""
        self.names = tuple(names)

    def _stopped(self, what: str) -> FollowStopped:
        return FollowStopped(
            f"{self.path}: {what} while it was followed (after line {self._line}, byte {self._offset}); the "
            "frames read before are calibrated; follow the new file with a new command"
        )

    def _read(self) -> None:
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            if self._fd is not None:
                raise self._stopped("removed") from None
            return
        except OSError as exc:
            raise InputError(f"{self.path}: cannot read: {exc.strerror}") from None
        if self._fd is None:
            if not os.path.isfile(self.path):
                raise InputError(f"{self.path}: expected a file that a logger appends to")
            try:
                self._fd = os.open(self.path, os.O_RDONLY)
            except OSError as exc:
                raise InputError(f"{self.path}: cannot read: {exc.strerror}") from None
            opened = os.fstat(self._fd)
            self._identity = (opened.st_dev, opened.st_ino)
        elif (st.st_dev, st.st_ino) != self._identity:
            raise self._stopped("replaced by another file (rotated?)")
        if st.st_size < self._offset:
            raise self._stopped(f"truncated to {st.st_size} bytes")
        if self._tail and os.pread(self._fd, len(self._tail), self._offset - len(self._tail)) != self._tail:
            raise self._stopped("rewritten")
        chunk = os.pread(self._fd, READ_BYTES, self._offset)
        if not chunk:
            return
        try:
            text = self._partial + self._decoder.decode(chunk)
        except UnicodeDecodeError as exc:
            raise InputError(
                f"{self.path}: not a pose CSV: byte {self._offset + exc.start} is not UTF-8 text"
            ) from None
        self._offset += len(chunk)
        self._tail = (self._tail + chunk)[-TAIL_BYTES:]
        lines = text.split("\n")
        self._partial = lines.pop()  # a row still being written
        self._parse([line + "\n" for line in lines])

    def _parse(self, lines: list[str]) -> None:
        reader = csv.reader(lines)
        first = self._line
        while True:
            try:
                row = next(reader)
            except StopIteration:
                break
            except csv.Error as exc:
                raise fail(self.path, first + reader.line_num, f"not a readable CSV row ({exc})") from None
            self._line = first + reader.line_num
            if not any(cell.strip() for cell in row):
                continue
            if self._header is None:
                header = [cell.strip() for cell in row]
                check_header(self.path, header, self._line)
                self._header, self._columns = header, [header.index(c) for c in CSV_COLUMNS]
                continue
            self._rows.append(self._row(row))

    def _row(self, row: list[str]) -> tuple[float, str, list[float], int]:
        """``(time_s, sensor, [x, y, z, qw, qx, qy, qz], line)`` of one data row, or an error."""
        assert self._header is not None
        line = self._line
        if len(row) != len(self._header):
            raise fail(self.path, line, f"expected {len(self._header)} fields, got {len(row)}")
        nums = []
        for c, k in zip(CSV_COLUMNS, self._columns, strict=True):
            if c == "sensor":
                continue
            try:
                nums.append(float(row[k]))
            except ValueError:
                raise fail(self.path, line, f"column {c!r} is not a number: {row[k]!r}") from None
        t, values = nums[0], nums[1:]
        name = row[self._columns[1]].strip()
        if not math.isfinite(t):
            raise fail(self.path, line, f"time is not finite: {t!r}")
        if t < self._last_time:
            raise fail(
                self.path,
                line,
                f"time {t!r} s is earlier than the row before ({self._last_time!r} s): a followed file "
                "must be written in time order",
            )
        if not name:
            raise fail(self.path, line, "empty sensor name")
        if all(math.isfinite(v) for v in values) and all(v == 0.0 for v in values[3:]):
            raise fail(self.path, line, "zero quaternion")
        self._last_time = t
        return t, name, values, line

    def _complete(self, final: bool) -> Iterator[RawFrame]:
        while self._rows:
            rows = self._rows
            t = rows[0][0]
            stop = 1
            while stop < len(rows) and rows[stop][0] == t:
                stop += 1
            if stop == len(rows) and not final:
                return
            frame = [(s, v, line) for _, s, v, line in rows[:stop]]
            del rows[:stop]  # before the yield: a frame is returned once, whatever the caller does
            seen: dict[str, int] = {}
            for s, _, line in frame:
                if s in seen:
                    raise fail(
                        self.path, line, f"sensor {s!r} appears twice at time {t!r} (also on line {seen[s]})"
                    )
                seen[s] = line
            yield t, frame

    def arrays(self, frame: RawFrame) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """``(time_s, R (S, 3, 3), p (S, 3) in metres, valid (S,))`` of a frame, the sensors those
        of :meth:`set_names` (a sensor of the frame not among them is an error)."""
        assert self.names is not None, "set_names first"
        time_s, rows = frame
        index = {s: k for k, s in enumerate(self.names)}
        n = len(self.names)
        p = np.full((n, 3), np.nan)
        q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
        valid = np.zeros(n, dtype=bool)
        for s, v, line in rows:
            if s not in index:
                raise fail(
                    self.path,
                    line,
                    f"sensor {s!r} first appears at {time_s!r} s, after the live calibration started with "
                    f"{list(self.names)}; it cannot add a sensor (calibrate the file without --follow)",
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
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def first_seen(frames: list[RawFrame]) -> tuple[str, ...]:
    """The sensors of ``frames`` in the order of their first row (the batch reader's order)."""
    return tuple(dict.fromkeys(s for _, rows in frames for s, _, _ in rows))


__all__ = ["READ_BYTES", "CsvFollower", "FollowStopped", "RawFrame", "first_seen"]
