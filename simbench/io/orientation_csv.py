"""The orientation CSV that ``simbench orient --csv`` writes and an external orientation estimator
writes back (``cmd:``, :mod:`simbench.estimators.command`)."""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_open
from simbench.io.imu import ImuRecording

#: The columns of the file.
HEADER = ("time", "sensor", "qw", "qx", "qy", "qz")


def write_orientation_csv(path: str | os.PathLike[str], rec: ImuRecording, q_w_s: np.ndarray) -> None:
    """``time,sensor,qw,qx,qy,qz``: one row per input sample and sensor (``q_w_s`` ``(F, N, 4)``,
    scalar-first ``R_w_s``), NaN where not estimated; written atomically."""
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(HEADER)
        for f in range(rec.time_s.size):
            t = repr(float(rec.time_s[f]))
            for k, name in enumerate(rec.names):
                writer.writerow([t, name, *(repr(float(v)) for v in q_w_s[f, k])])


def read_orientation_csv(
    path: str | os.PathLike[str], names: Sequence[str], time_s: np.ndarray
) -> np.ndarray:
    """Read ``time,sensor,qw,qx,qy,qz`` (as :func:`write_orientation_csv` writes it) onto a
    recording's samples and sensors.

    Args:
        path: the file.
        names: ``(N,)`` the recording's sensor names.
        time_s: ``(F,)`` the recording's sample times, s; a row's time must be one of them (to
            1e-9 s, or 1e-9 of the time).

    Returns:
        ``(F, N, 4)`` scalar-first quaternions, NaN where the file has no row (or NaN values).

    Raises:
        InputError: naming the file and line: no header or another header, a row of the wrong
            length, a value that is not a number, a sensor or time the recording lacks, a sample
            given twice, a quaternion that is not of unit norm (to 1e-3), no row at all.
    """
    path = Path(path)
    text = read_text(path)
    rows = [(k + 1, r) for k, r in enumerate(csv.reader(io.StringIO(text))) if r]
    if not rows or [c.strip().lower() for c in rows[0][1]] != list(HEADER):
        got = rows[0][1] if rows else "nothing"
        raise InputError(f"{path}, line 1: expected the header {','.join(HEADER)}, got {got}")
    index = {n: k for k, n in enumerate(names)}
    t = np.asarray(time_s, dtype=float)
    q = np.full((t.size, len(names), 4), np.nan)
    seen = np.zeros((t.size, len(names)), dtype=bool)
    for line, row in rows[1:]:
        if len(row) != len(HEADER):
            raise InputError(f"{path}, line {line}: {len(row)} fields, expected {len(HEADER)}")
        sensor = row[1].strip()
        if sensor not in index:
            raise InputError(
                f"{path}, line {line}: sensor {sensor!r} is not in the recording ({list(names)})"
            )
        try:
            time, *values = (float(v) for v in (row[0], *row[2:]))
        except ValueError:
            raise InputError(f"{path}, line {line}: expected numbers, got {','.join(row)[:80]!r}") from None
        f = int(np.searchsorted(t, time))
        near = [k for k in (f - 1, f) if 0 <= k < t.size and abs(t[k] - time) <= 1e-9 * max(1.0, abs(time))]
        if not near:
            raise InputError(f"{path}, line {line}: time {time!r} s is not a sample time of the recording")
        f, k = near[0], index[sensor]
        if seen[f, k]:
            raise InputError(f"{path}, line {line}: sensor {sensor!r} at {time!r} s given twice")
        seen[f, k] = True
        v = np.array(values)
        if np.isfinite(v).all() and abs(np.linalg.norm(v) - 1) > 1e-3:
            raise InputError(
                f"{path}, line {line}: expected a unit quaternion (qw,qx,qy,qz), "
                f"got norm {np.linalg.norm(v):.6g}"
            )
        q[f, k] = v
    if not seen.any():
        raise InputError(f"{path}: no rows after the header")
    return q
