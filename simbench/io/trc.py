"""Marker trajectories as TRC text files (Motion Analysis' layout, read by OpenSim and others).

Layout (tab-separated; OpenSim's ``TRCFileAdapter`` reads it)::

    PathFileType  4  (X/Y/Z)  NAME.trc
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    120  120  240  24  mm  120  1  240
    Frame#  Time  M1  <tab>  <tab>  M2 ...
            X1  Y1  Z1  X2  Y2  Z2 ...
    <blank line>
    1  0.000000  x  y  z  x  y  z ...

Frames are numbered from 1; ``Time`` is in seconds; coordinates are in ``Units`` (``mm`` by
default, or ``m``, ``cm``, ``in``); a marker not seen in a frame has its three fields empty.
Coordinates are in the dataset's world frame, z up (``up="z"``, the default), or turned to y up
(``up="y"``: ``(x, y, z) -> (x, z, -y)``, a -90 degree turn about x), as OpenSim's models and
marker IK expect. The reader converts to metres and turns a y-up file back to z up when told
(``read_trc(path, up="y")``; the file itself does not say).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_write_text
from simbench.units import LENGTH_UNITS

HEADER_KEYS = (
    "DataRate",
    "CameraRate",
    "NumFrames",
    "NumMarkers",
    "Units",
    "OrigDataRate",
    "OrigDataStartFrame",
    "OrigNumFrames",
)


@dataclass(frozen=True)
class TrcMarkers:
    """Markers read from a TRC file.

    Attributes:
        labels: ``(M,)`` marker names.
        time_s: ``(F,)`` sample times, s.
        xyz: ``(F, M, 3)`` positions, m (converted from the file's units); NaN where empty.
        rate_hz: the file's ``DataRate``, Hz.
        units: the file's ``Units``.
    """

    labels: tuple[str, ...]
    time_s: np.ndarray
    xyz: np.ndarray
    rate_hz: float
    units: str


#: The vertical axes a TRC file can be written with (the world's z, or OpenSim's y).
UP_AXES = ("z", "y")


def turned(xyz: np.ndarray, up: str, *, back: bool = False) -> np.ndarray:
    """``(..., 3)`` positions of the z-up world with ``up`` as the vertical axis: unchanged for
    ``z``; for ``y`` turned -90 degrees about x, ``(x, y, z) -> (x, z, -y)`` (``back``: the
    inverse, ``(x, y, z) -> (x, -z, y)``).

    Raises:
        InputError: ``up`` not one of :data:`UP_AXES`.
    """
    if up not in UP_AXES:
        raise InputError(f"Expected the up axis to be one of {list(UP_AXES)}, got {up!r}")
    if up == "z":
        return xyz
    x, y, z = np.moveaxis(np.asarray(xyz, dtype=float), -1, 0)
    return np.stack([x, -z, y] if back else [x, z, -y], axis=-1)


def _rate(time_s: np.ndarray) -> float:
    """Samples per second from the count over the span (docs/conventions.md: loggers stamp in bursts)."""
    span = float(time_s[-1] - time_s[0]) if time_s.size > 1 else 0.0
    if not span > 0:
        raise InputError("Expected at least 2 sample times spanning a positive time to give a rate")
    return (time_s.size - 1) / span


def trc_text(
    labels: tuple[str, ...] | list[str],
    time_s: np.ndarray,
    xyz_m: np.ndarray,
    *,
    units: str = "mm",
    decimals: int = 6,
    rate_hz: float | None = None,
    name: str = "markers.trc",
    up: str = "z",
) -> str:
    """The TRC text of markers (module docstring).

    Args:
        labels: ``(M,)`` marker names (no tabs).
        time_s: ``(F,)`` sample times, s.
        xyz_m: ``(F, M, 3)`` positions in world, m; NaN where not seen (written as empty fields).
        units: the file's length unit (``mm``, ``m``, ``cm``, ``in``).
        decimals: digits after the point, in ``units``.
        rate_hz: ``DataRate`` and ``CameraRate``, Hz (default: from the times, count over span).
        name: the file name written on the first line.
        up: the file's vertical axis, ``z`` (the world's) or ``y`` (OpenSim's): :func:`turned`.
    """
    labels = tuple(labels)
    time_s = np.asarray(time_s, dtype=float)
    xyz = np.asarray(xyz_m, dtype=float)
    if units not in LENGTH_UNITS:
        raise InputError(f"Expected TRC units among {sorted(LENGTH_UNITS)}, got {units!r}")
    if xyz.ndim != 3 or xyz.shape[1:] != (len(labels), 3):
        raise InputError(f"Expected markers of shape (frames, {len(labels)}, 3), got {xyz.shape}")
    if time_s.shape != (xyz.shape[0],):
        raise InputError(f"Expected {xyz.shape[0]} sample times, got shape {time_s.shape}")
    bad = [x for x in labels if not x or any(c in x for c in "\t\r\n")]
    if bad:
        raise InputError(f"Expected marker labels without tabs or line breaks, got {bad}")
    if not isinstance(decimals, int) or not 0 <= decimals <= 15:
        raise InputError(f"Expected decimals to be an integer in [0, 15], got {decimals!r}")
    rate = _rate(time_s) if rate_hz is None else float(rate_hz)
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"Expected a positive rate in Hz, got {rate_hz!r}")
    f, m = xyz.shape[:2]
    scaled = turned(xyz, up) / LENGTH_UNITS[units]
    head = [
        f"PathFileType\t4\t(X/Y/Z)\t{name}",
        "\t".join(HEADER_KEYS),
        "\t".join([f"{rate:.10g}", f"{rate:.10g}", str(f), str(m), units, f"{rate:.10g}", "1", str(f)]),
        "\t".join(["Frame#", "Time", *(f"{x}\t\t" for x in labels)]).rstrip("\t"),
        "\t".join(["", "", *(f"X{k}\tY{k}\tZ{k}" for k in range(1, m + 1))]),
        "",
    ]
    fmt = f"%.{decimals}f"
    rows = []
    for i in range(f):
        cells = [fmt % v if math.isfinite(v) else "" for v in scaled[i].ravel()]
        rows.append("\t".join([str(i + 1), repr(float(time_s[i])), *cells]))
    return "\n".join(head + rows) + "\n"


def write_trc(
    path: str | os.PathLike[str],
    labels: tuple[str, ...] | list[str],
    time_s: np.ndarray,
    xyz_m: np.ndarray,
    *,
    units: str = "mm",
    decimals: int = 6,
    rate_hz: float | None = None,
    up: str = "z",
) -> None:
    """Write markers to a TRC file atomically (arguments as :func:`trc_text`)."""
    text = trc_text(
        labels, time_s, xyz_m, units=units, decimals=decimals, rate_hz=rate_hz, name=Path(path).name, up=up
    )
    atomic_write_text(path, text)


def _float(text: str, where: str) -> float:
    try:
        return float(text) if text.strip() else math.nan
    except ValueError:
        raise InputError(f"{where}: expected a number, got {text!r}") from None


def read_trc(path: str | os.PathLike[str], *, up: str = "z") -> TrcMarkers:
    """Read a TRC file (module docstring): labels, times, positions in metres (z up: a file
    written with ``up="y"`` is turned back), rate, units.

    Raises:
        InputError: naming the file and line: not a TRC file, unknown units, a header that
            disagrees with the data (marker or frame count), a field that is not a number.
    """
    path = Path(path)
    lines = read_text(path).splitlines()
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise InputError(f"{path}: not a TRC file: expected a first line starting with PathFileType")
    # some writers put two tabs between the values (OpenSim's Rajagopal walk) or tabs after them
    keys = [k.strip() for k in lines[1].split("\t") if k.strip()]
    values = [v.strip() for v in lines[2].split("\t") if v.strip()]
    header = dict(zip(keys, values, strict=False))
    missing = [k for k in ("DataRate", "NumFrames", "NumMarkers", "Units") if k not in header]
    if missing:
        raise InputError(f"{path}, line 2: not a TRC header: missing {missing}; got {keys}")
    units = header["Units"].strip()
    if units not in LENGTH_UNITS:
        raise InputError(f"{path}, line 3: Units is {units!r}; expected one of {sorted(LENGTH_UNITS)}")
    rate = _float(header["DataRate"], f"{path}, line 3, DataRate")
    try:
        n_frames, n_markers = int(header["NumFrames"]), int(header["NumMarkers"])
    except ValueError:
        raise InputError(f"{path}, line 3: NumFrames and NumMarkers must be integers") from None
    names = lines[3].split("\t")
    if names[:2] != ["Frame#", "Time"]:
        raise InputError(f"{path}, line 4: expected 'Frame#' and 'Time' first, got {names[:2]}")
    labels = tuple(x.strip() for x in names[2:] if x.strip())
    if len(labels) != n_markers:
        raise InputError(
            f"{path}, line 4: {len(labels)} marker names, the header says NumMarkers {n_markers}"
        )
    width = 2 + 3 * n_markers
    rows = [(k + 1, line) for k, line in enumerate(lines[5:], start=5) if line.strip()]
    if len(rows) != n_frames:
        raise InputError(f"{path}: {len(rows)} frames of data, the header says NumFrames {n_frames}")
    data = np.full((n_frames, width), np.nan)
    for i, (number, line) in enumerate(rows):
        cells = line.split("\t")
        if len(cells) < width:  # trailing empty fields of markers not seen may be cut
            cells += [""] * (width - len(cells))
        while len(cells) > width and not cells[-1].strip():  # or a line end with a tab (OpenSim's)
            cells.pop()
        if len(cells) != width:
            raise InputError(f"{path}, line {number}: {len(cells)} fields, expected {width}")
        data[i] = [_float(c, f"{path}, line {number}") for c in cells]
    time_s = data[:, 1]
    if not np.isfinite(time_s).all():
        raise InputError(f"{path}: every frame needs a time")
    xyz = turned(data[:, 2:].reshape(n_frames, n_markers, 3) * LENGTH_UNITS[units], up, back=True)
    return TrcMarkers(labels=labels, time_s=time_s, xyz=xyz, rate_hz=rate, units=units)


__all__ = ["TrcMarkers", "read_trc", "trc_text", "write_trc"]
