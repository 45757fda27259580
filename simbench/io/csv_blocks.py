"""Pose CSV rows read in blocks and arranged into frames x sensors without holding the file.

**Two readers, one result.** Both yield the same blocks of rows (time, sensor name, the seven
numbers ``x..qz``, and each row's line in the file):

- pyarrow's streaming CSV reader (C++, :data:`BLOCK_BYTES` of text at a time), used when the
  header is the file's first line. It stops at anything it does not read exactly as the csv
  module would: a row with another number of fields (a blank line is one), a number it cannot
  parse, text that is not UTF-8, a NUL byte in a name.
- the csv module, row by row, which reads what pyarrow refuses and names the line of any error.

The first stop of the fast reader restarts the read with the exact one, so a file is read as the
csv-module reader reads it, or refused with that reader's error (file, line, what was expected).

**Two passes.** The first collects the frame times (the sorted distinct times) and the sensor
names (in order of first appearance); the second writes each row's pose into its (frame, sensor)
cell. Memory is one block of rows plus ``(frames, sensors)`` flags: the poses go to arrays when
they fit in :data:`IN_MEMORY_BYTES`, otherwise to an HDF5 file in the temporary directory
(``TMPDIR``), chunked by frames and sensor, that is unlinked as soon as it is created: nothing is
left on disk whatever ends the process, and the space is returned when the recording is dropped.
"""

from __future__ import annotations

import csv
import os
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from calibration.rotations import UNIT_TOLERANCE, quat_to_matrix
from simbench.errors import InputError

CSV_COLUMNS = ("time", "sensor", "x", "y", "z", "qw", "qx", "qy", "qz")

#: Text parsed per batch by pyarrow, bytes: as fast as larger batches, and pyarrow holds a
#: multiple of it (65 MiB over its baseline at 1 MiB, 17 MiB at 64 KiB).
BLOCK_BYTES = 1 << 16

#: Rows per block (pyarrow's batches are gathered into blocks this long).
BLOCK_ROWS = 1 << 14

#: Poses (``R`` and ``p``, float64) up to this size are held in memory; larger recordings are
#: written to an unlinked temporary HDF5 file and read back a chunk at a time.
IN_MEMORY_BYTES = 64 << 20

#: Frames per HDF5 chunk (one sensor per chunk, so that one sensor's series is read alone).
CHUNK_FRAMES = 1024

#: A (frame, sensor) cell's state while reading; as a bool, VALID is True and the others False.
ABSENT, VALID, NOT_FINITE = 0, 1, 2


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
        if path.is_dir():
            raise InputError(f"{path}: expected a file, got a directory")
        return _Text(path, path.open(newline="", encoding="utf-8-sig"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None


def csv_rows(path: Path, reader: Any) -> Iterator[list[str]]:
    """The rows of a ``csv.reader``; a row the csv module cannot read (a field beyond its size
    limit, as an unclosed quote makes) is an InputError naming the file and line."""
    rows = iter(reader)
    while True:
        try:
            row = next(rows)
        except StopIteration:
            return
        except csv.Error as exc:
            raise fail(path, reader.line_num, f"not a readable CSV row ({exc}; an unclosed quote?)") from None
        yield row


def fail(path: str | os.PathLike[str], line: int | None, message: str) -> InputError:
    """An InputError naming the file and, when known, the line."""
    where = f"{path}" if line is None else f"{path}, line {line}"
    return InputError(f"{where}: {message}")


@dataclass(frozen=True)
class PoseTable:
    """A pose CSV arranged into frames: the fields of a ``PoseRecording`` (metres), and notes.

    ``R_w_s`` and ``p_w_s`` are ndarrays, or h5py datasets of an unlinked temporary file for a
    recording larger than :data:`IN_MEMORY_BYTES` (sliceable along frames; ``np.asarray`` loads).
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    R_w_s: Any
    p_w_s: Any
    valid: np.ndarray
    notes: tuple[str, ...]


@dataclass(frozen=True)
class _Block:
    """Rows of the file: ``(m,)`` times, ``(m,)`` codes into ``names`` (this block's distinct
    names, stripped), ``(m, 7)`` values ``x..qz`` (``None`` when not asked for), ``(m,)`` lines."""

    time: np.ndarray
    codes: np.ndarray
    names: list[str]
    values: np.ndarray | None
    lines: np.ndarray


class _Fallback(Exception):
    """The fast reader met something it does not read as the csv module does."""


Blocks = Callable[[bool], Iterator[_Block]]


def read_header(path: Path) -> tuple[list[str], int]:
    """The header's stripped cells and its line; errors for an empty file, missing or repeated
    columns."""
    with open_csv(path) as fh:
        reader = csv.reader(fh)
        for row in csv_rows(path, reader):
            if any(cell.strip() for cell in row):
                header = [cell.strip() for cell in row]
                break
        else:
            raise fail(path, None, f"the file is empty; expected a header {','.join(CSV_COLUMNS)}")
        line = reader.line_num
    check_header(path, header, line)
    return header, line


def check_header(path: str | os.PathLike[str], header: list[str], line: int) -> None:
    """Refuse a header (stripped cells) without every column of :data:`CSV_COLUMNS`, or with one
    of them twice, naming the file and line."""
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise fail(
            path, line, f"missing columns {missing}; expected {','.join(CSV_COLUMNS)}, got {','.join(header)}"
        )
    repeated = sorted({c for c in header if header.count(c) > 1 and c in CSV_COLUMNS})
    if repeated:
        raise fail(path, line, f"columns repeated in the header: {repeated}")


def exact_blocks(path: Path, header: list[str], header_line: int) -> Blocks:
    """The csv-module reader: blocks of :data:`BLOCK_ROWS` rows, errors naming the line."""
    col = [header.index(c) for c in CSV_COLUMNS]

    def blocks(values: bool) -> Iterator[_Block]:
        with open_csv(path) as fh:
            reader = csv.reader(fh)
            lines = csv_rows(path, reader)
            while reader.line_num < header_line:
                next(lines)
            rows: list[tuple[float, str, list[float], int]] = []
            for row in lines:
                if not any(cell.strip() for cell in row):
                    continue
                line = reader.line_num
                if len(row) != len(header):
                    raise fail(path, line, f"expected {len(header)} fields, got {len(row)}")
                nums = []
                for c, k in zip(CSV_COLUMNS, col, strict=True):
                    if c == "sensor" or (not values and c != "time"):
                        continue
                    try:
                        nums.append(float(row[k]))
                    except ValueError:
                        raise fail(path, line, f"column {c!r} is not a number: {row[k]!r}") from None
                rows.append((nums[0], row[col[1]].strip(), nums[1:], line))
                if len(rows) == BLOCK_ROWS:
                    yield _rows_block(rows, values)
                    rows = []
            if rows:
                yield _rows_block(rows, values)

    return blocks


def _rows_block(rows: list[tuple[float, str, list[float], int]], values: bool) -> _Block:
    names = list(dict.fromkeys(r[1] for r in rows))
    lookup = {name: k for k, name in enumerate(names)}
    return _Block(
        time=np.array([r[0] for r in rows]),
        codes=np.array([lookup[r[1]] for r in rows], dtype=np.int64),
        names=names,
        values=np.array([r[2] for r in rows], dtype=float).reshape(len(rows), 7) if values else None,
        lines=np.array([r[3] for r in rows], dtype=np.int64),
    )


def fast_blocks(path: Path, header: list[str]) -> Blocks:
    """pyarrow's streaming reader (header on line 1): batches of :data:`BLOCK_BYTES` of text
    gathered into blocks of at least :data:`BLOCK_ROWS` rows; raises :class:`_Fallback` where it
    would not read the file as :func:`exact_blocks` does."""
    names = [f"c{i}" for i in range(len(header))]
    col = {c: names[header.index(c)] for c in CSV_COLUMNS}

    def blocks(values: bool) -> Iterator[_Block]:
        wanted = CSV_COLUMNS if values else CSV_COLUMNS[:2]
        types = {col[c]: pa.float64() for c in wanted}
        types[col["sensor"]] = pa.string()
        try:
            reader = pacsv.open_csv(
                path,
                read_options=pacsv.ReadOptions(skip_rows=1, column_names=names, block_size=BLOCK_BYTES),
                parse_options=pacsv.ParseOptions(ignore_empty_lines=False),
                convert_options=pacsv.ConvertOptions(
                    include_columns=[col[c] for c in wanted],
                    column_types=types,
                    null_values=[],
                    strings_can_be_null=False,
                    quoted_strings_can_be_null=False,
                ),
            )
            line, batches, rows = 2, [], 0
            for batch in reader:
                batches.append(batch)
                rows += batch.num_rows
                if rows >= BLOCK_ROWS:
                    yield _batches_block(batches, col, wanted, values, line)
                    line, batches, rows = line + rows, [], 0
            if batches:
                yield _batches_block(batches, col, wanted, values, line)
        except (pa.ArrowException, UnicodeDecodeError):
            raise _Fallback from None

    return blocks


def _batches_block(
    batches: list[pa.RecordBatch], col: dict[str, str], wanted: tuple[str, ...], values: bool, line: int
) -> _Block:
    """One block from pyarrow's batches, the first row on ``line``."""
    encoded = (
        pa.chunked_array([b.column(col["sensor"]) for b in batches]).combine_chunks().dictionary_encode()
    )
    raw = encoded.dictionary.to_pylist()
    if any("\0" in name for name in raw):
        raise _Fallback

    def column(c: str) -> np.ndarray:
        return np.concatenate([b.column(col[c]).to_numpy(zero_copy_only=False) for b in batches])

    time = column("time")
    return _Block(
        time=time,
        codes=encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64),
        names=[name.strip() for name in raw],
        values=np.column_stack([column(c) for c in wanted[2:]]) if values else None,
        lines=np.arange(line, line + time.size, dtype=np.int64),
    )


def read_table(path: Path, scale: float, *, in_memory: bool | None = None) -> PoseTable:
    """Read a pose CSV into frames (module docstring); positions times ``scale`` (to metres).

    Args:
        path: the file.
        scale: metres per unit of the file's positions.
        in_memory: hold the poses in arrays (True), in a temporary HDF5 file (False), or
            choose by size (``None``: :data:`IN_MEMORY_BYTES`).

    Raises:
        InputError: naming the file, line and problem.
    """
    header, header_line = read_header(path)
    if header_line == 1:
        try:
            return _arrange(path, fast_blocks(path, header), scale, in_memory)
        except _Fallback:
            pass
    return _arrange(path, exact_blocks(path, header, header_line), scale, in_memory)


def _arrange(path: Path, blocks: Blocks, scale: float, in_memory: bool | None) -> PoseTable:
    names, frame_times = _frames_and_names(path, blocks)
    n_frames, n = frame_times.size, len(names)
    if in_memory is None:
        in_memory = n_frames * n * 12 * 8 <= IN_MEMORY_BYTES
    store: _Store = _ArrayStore(n_frames, n) if in_memory else TemporaryPoses(n_frames, n)
    lookup = {name: k for k, name in enumerate(names)}
    state = np.zeros((n_frames, n), dtype=np.int8)  # ABSENT, VALID or NOT_FINITE: one byte a cell
    n_off, worst = 0, (0.0, 1.0, 0)  # quaternions off unit norm: count, (|1 - |q||, |q|, line)
    for b in blocks(True):
        assert b.values is not None
        f = np.searchsorted(frame_times, b.time)
        s = np.array([lookup[name] for name in b.names], dtype=np.int64)[b.codes]
        _check_repeats(path, blocks, b, f, s, state, n, names, frame_times)
        finite = np.isfinite(b.values).all(axis=1)
        q = b.values[:, 3:]
        big = np.max(np.abs(q), axis=1, keepdims=True)
        with np.errstate(invalid="ignore", over="ignore"):  # a norm beyond float64 is inf: reported
            q = q / np.where(big > 0, big, 1.0)  # scaled first: |(1e200, 0, 0, 0)| would overflow
            qnorm = np.linalg.norm(q, axis=1) * big[:, 0]
        zero = finite & (qnorm == 0.0)
        if zero.any():
            raise fail(path, int(b.lines[np.flatnonzero(zero)[0]]), "zero quaternion")
        off = finite & (np.abs(qnorm - 1.0) > UNIT_TOLERANCE)
        if off.any():
            n_off += int(off.sum())
            k = int(np.argmax(np.where(off, np.abs(qnorm - 1.0), -1.0)))
            if abs(qnorm[k] - 1.0) > worst[0]:
                worst = (abs(qnorm[k] - 1.0), float(qnorm[k]), int(b.lines[k]))
        state[f, s] = np.where(finite, VALID, NOT_FINITE)
        store.write(f[finite], s[finite], quat_to_matrix(q[finite]), b.values[finite, :3] * scale)
    notes = []
    if n_off:
        notes.append(
            f"{n_off} quaternion(s) off unit norm by more than {UNIT_TOLERANCE:g} were "
            f"normalised (worst |q| = {worst[1]:.6g} on line {worst[2]})"
        )
    for k, name in enumerate(names):
        absent, bad = (int(np.count_nonzero(state[:, k] == x)) for x in (ABSENT, NOT_FINITE))
        if absent:
            notes.append(f"sensor {name}: no row in {absent} of {n_frames} frames (treated as missing)")
        if bad:
            notes.append(f"sensor {name}: {bad} row(s) with NaN or inf values (treated as missing)")
    R, p = store.arrays()
    pa.default_memory_pool().release_unused()  # pyarrow's freed blocks, back to the system
    for start in range(0, n_frames, 1 << 16):  # to the valid flags in place, a slice at a time
        rows = state[start : start + (1 << 16)]
        rows[rows == NOT_FINITE] = ABSENT
    valid = state.view(bool)
    cut = cut_short_note(path)
    if cut:
        notes.append(cut)
    return PoseTable(names=names, time_s=frame_times, R_w_s=R, p_w_s=p, valid=valid, notes=tuple(notes))


def cut_short_note(path: Path) -> str | None:
    """A note when the file's last line has no line end: a writer stopped in the middle of it (a
    number cut short reads as a shorter number, which no check can tell), or one that never ends
    its lines; ``None`` for a file that ends with one (or is empty)."""
    try:
        with path.open("rb") as fh:
            if fh.seek(0, os.SEEK_END) == 0:
                return None
            fh.seek(-1, os.SEEK_END)
            last = fh.read(1)
    except OSError:
        return None
    if last in (b"\n", b"\r"):
        return None
    return (
        "the file does not end with a line end: its last line may be cut short (a writer stopped "
        "in the middle of it) and was read as it stands; check its numbers, or leave it out"
    )


def _frames_and_names(path: Path, blocks: Blocks) -> tuple[tuple[str, ...], np.ndarray]:
    """First pass: the sensor names in order of first appearance and the sorted distinct times;
    errors for a non-finite time or an empty name."""
    names: dict[str, None] = {}
    done = np.empty(0)  # distinct times so far; `pending` merged in when it outgrows them
    pending: list[np.ndarray] = []
    n_pending = n_rows = 0
    for b in blocks(False):
        bad = ~np.isfinite(b.time)
        if bad.any():
            raise fail(
                path, int(b.lines[np.flatnonzero(bad)[0]]), f"time is not finite: {float(b.time[bad][0])!r}"
            )
        codes, first = np.unique(b.codes, return_index=True)
        for code in codes[np.argsort(first)]:  # this block's names in order of their first row
            if not b.names[code]:
                raise fail(path, int(b.lines[np.flatnonzero(b.codes == code)[0]]), "empty sensor name")
            names.setdefault(b.names[code], None)
        pending.append(np.unique(b.time))
        n_pending += pending[-1].size
        n_rows += b.time.size
        if n_pending > max(done.size, 1 << 20):
            done, pending, n_pending = np.unique(np.concatenate([done, *pending])), [], 0
    if not n_rows:
        raise fail(path, None, "no data rows after the header")
    return tuple(names), np.unique(np.concatenate([done, *pending]))


def _check_repeats(
    path: Path,
    blocks: Blocks,
    b: _Block,
    f: np.ndarray,
    s: np.ndarray,
    state: np.ndarray,
    n: int,
    names: tuple[str, ...],
    frame_times: np.ndarray,
) -> None:
    """Refuse a sensor that appears twice at one time: within the block, or already read."""
    key = f * n + s
    order = np.argsort(key, kind="stable")
    same = np.flatnonzero(np.diff(key[order]) == 0)
    seen = np.flatnonzero(state[f, s] != ABSENT)
    later = [int(b.lines[order[i + 1]]) for i in same] + [int(b.lines[i]) for i in seen]
    if not later:
        return
    line = min(later)
    row = int(np.flatnonzero(b.lines == line)[0])
    name, t = names[s[row]], float(frame_times[f[row]])
    first = next(
        int(c.lines[k])
        for c in blocks(False)
        for k in np.flatnonzero((c.time == t) & (np.array([x == name for x in c.names])[c.codes]))
    )
    raise fail(path, line, f"sensor {name!r} appears twice at time {t!r} (also on line {first})")


class _Store:
    def write(self, f: np.ndarray, s: np.ndarray, R: np.ndarray, p: np.ndarray) -> None:
        raise NotImplementedError

    def arrays(self) -> tuple[Any, Any]:
        raise NotImplementedError


class _ArrayStore(_Store):
    """Poses in memory, NaN where missing."""

    def __init__(self, n_frames: int, n: int) -> None:
        self.R = np.full((n_frames, n, 3, 3), np.nan)
        self.p = np.full((n_frames, n, 3), np.nan)

    def write(self, f: np.ndarray, s: np.ndarray, R: np.ndarray, p: np.ndarray) -> None:
        self.R[f, s] = R
        self.p[f, s] = p

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return self.R, self.p


class TemporaryPoses(_Store):
    """Poses in an unlinked temporary HDF5 file (NaN where missing): ``R`` ``(frames, sensors, 3,
    3)`` and ``p`` ``(frames, sensors, 3)`` h5py datasets, chunked by :data:`CHUNK_FRAMES` frames;
    :meth:`write` fills them a slab of frames at a time (read, filled, written back: rows of one
    frame may span two blocks), or they are assigned slices directly. The file's space is freed
    when the last of its datasets is gone."""

    def __init__(self, n_frames: int, n: int) -> None:
        fd, name = tempfile.mkstemp(prefix="simbench-poses-", suffix=".h5")
        os.close(fd)
        try:
            chunk = min(CHUNK_FRAMES, max(n_frames, 1))
            cache = n * chunk * 9 * 8  # one chunk of every sensor: a frame slab spans a block boundary
            self.file = h5py.File(name, "w", rdcc_nbytes=cache, rdcc_nslots=10007)
        finally:
            os.unlink(name)  # the open file lives on; its space is freed when it is closed
        self.R = self.file.create_dataset(
            "R_w_s", (n_frames, n, 3, 3), dtype="f8", chunks=(chunk, 1, 3, 3), fillvalue=np.nan
        )
        self.p = self.file.create_dataset(
            "p_w_s", (n_frames, n, 3), dtype="f8", chunks=(chunk, 1, 3), fillvalue=np.nan
        )
        self.chunk = chunk

    def write(self, f: np.ndarray, s: np.ndarray, R: np.ndarray, p: np.ndarray) -> None:
        if not f.size:
            return
        order = np.argsort(f, kind="stable")
        f, s, R, p = f[order], s[order], R[order], p[order]
        start = 0
        while start < f.size:  # slabs of at most `chunk` frames
            lo = int(f[start])
            stop = int(np.searchsorted(f, lo + self.chunk))
            hi = int(f[stop - 1]) + 1
            slab_R, slab_p = self.R[lo:hi], self.p[lo:hi]
            slab_R[f[start:stop] - lo, s[start:stop]] = R[start:stop]
            slab_p[f[start:stop] - lo, s[start:stop]] = p[start:stop]
            self.R[lo:hi], self.p[lo:hi] = slab_R, slab_p
            start = stop

    def arrays(self) -> tuple[h5py.Dataset, h5py.Dataset]:
        self.file.flush()
        return self.R, self.p
