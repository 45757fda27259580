"""IMU orientations as an OpenSim storage file (``.sto``) in OpenSense's layout.

OpenSense (OpenSim's IMU workflow: ``IMUPlacer``, ``IMUInverseKinematicsTool``) reads sensor
orientations as a ``TimeSeriesTable_<Quaternion>`` from a tab-separated ``.sto`` file::

    DataRate=120.000000
    DataType=Quaternion
    version=3
    OpenSimVersion=4.5
    endheader
    time    pelvis_imu       thigh_l_imu      ...
    0       w,x,y,z          w,x,y,z          ...

One column per sensor named ``<sensor>_imu`` (simbench's sensors are named after the segment they
sit on), each cell one scalar-first quaternion ``w,x,y,z`` (comma-separated, no spaces). The
quaternion is the sensor's orientation ``R_w_s``: it maps vectors in the sensor (IMU) frame into
the world frame of the recording -- here simbench's world, z up (ENU-like: gravity along -z, the
Earth field's horizontal part along +y), exactly as an IMU's own fusion gives sensor-to-earth
orientations. ``OpenSimVersion`` names the version whose layout this follows; the file is not
written by OpenSim.

OpenSim, not this writer, turns the recording's world into OpenSim's ground (y up): OpenSense
premultiplies every orientation by the rotation of its ``sensor_to_opensim_rotations`` setting
(space-fixed X, Y, Z angles in radians; ``OpenSenseUtilities::rotateOrientationTable``). For
simbench's z-up world use ``-1.5707963267948966 0 0`` (-90 degrees about x: z up becomes y up),
the value of OpenSense's own examples. Samples without an orientation are written as
``nan,nan,nan,nan``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_write_text

#: The OpenSim version whose ``.sto`` layout the writer follows (written as ``OpenSimVersion``).
OPENSIM_LAYOUT_VERSION = "4.5"
#: ``sensor_to_opensim_rotations`` (rad, space-fixed X, Y, Z) that takes simbench's z-up world to
#: OpenSim's y-up ground.
SENSOR_TO_OPENSIM_ROTATIONS = (-math.pi / 2, 0.0, 0.0)
SUFFIX = "_imu"


@dataclass(frozen=True)
class Orientations:
    """Orientations read from an OpenSense ``.sto`` file.

    Attributes:
        names: ``(N,)`` column names without the ``_imu`` suffix (the sensors).
        time_s: ``(F,)`` s.
        q_w_s: ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` as written (NaN where missing).
        rate_hz: the header's ``DataRate``, Hz.
        header: every ``key=value`` of the header.
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    q_w_s: np.ndarray
    rate_hz: float
    header: dict[str, str]


def sto_text(
    names: tuple[str, ...] | list[str],
    time_s: np.ndarray,
    q_w_s: np.ndarray,
    *,
    rate_hz: float | None = None,
) -> str:
    """The ``.sto`` text of sensor orientations (module docstring).

    Args:
        names: ``(N,)`` sensor names; the columns are ``<name>_imu``.
        time_s: ``(F,)`` sample times, s.
        q_w_s: ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` (sensor to world, z up); NaN
            where missing. Written with 17 significant digits (reads back exactly).
        rate_hz: the header's ``DataRate`` (default: count over span of the times).
    """
    names = tuple(names)
    time_s = np.asarray(time_s, dtype=float)
    q = np.asarray(q_w_s, dtype=float)
    if q.ndim != 3 or q.shape[1:] != (len(names), 4):
        raise InputError(f"Expected q_w_s of shape (frames, {len(names)}, 4), got {q.shape}")
    if time_s.shape != (q.shape[0],):
        raise InputError(f"Expected {q.shape[0]} sample times, got shape {time_s.shape}")
    bad = [x for x in names if not x or any(c in x for c in "\t\r\n,")]
    if bad:
        raise InputError(f"Expected sensor names without tabs, commas or line breaks, got {bad}")
    if rate_hz is None:
        span = float(time_s[-1] - time_s[0]) if time_s.size > 1 else 0.0
        rate_hz = (time_s.size - 1) / span if span > 0 else math.nan
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"Expected a positive rate in Hz (or 2 or more increasing times), got {rate_hz!r}")
    lines = [
        f"DataRate={rate_hz:.6f}",
        "DataType=Quaternion",
        "version=3",
        f"OpenSimVersion={OPENSIM_LAYOUT_VERSION}",
        "endheader",
        "\t".join(["time", *(n + SUFFIX for n in names)]),
    ]
    for i in range(q.shape[0]):
        cells = (",".join(repr(float(v)) for v in q[i, k]) for k in range(len(names)))
        lines.append("\t".join([repr(float(time_s[i])), *cells]))
    return "\n".join(lines) + "\n"


def write_opensense_sto(
    path: str | os.PathLike[str],
    names: tuple[str, ...] | list[str],
    time_s: np.ndarray,
    q_w_s: np.ndarray,
    *,
    rate_hz: float | None = None,
) -> None:
    """Write sensor orientations to an OpenSense ``.sto`` file atomically (see :func:`sto_text`)."""
    atomic_write_text(path, sto_text(names, time_s, q_w_s, rate_hz=rate_hz))


def read_opensense_sto(path: str | os.PathLike[str]) -> Orientations:
    """Read an OpenSense quaternion ``.sto`` file (module docstring).

    Raises:
        InputError: naming the file and line: no ``endheader``, ``DataType`` not ``Quaternion``,
            a first column not ``time``, a cell that is not 4 comma-separated numbers.
    """
    path = Path(path)
    lines = read_text(path).splitlines()
    try:
        end = next(k for k, line in enumerate(lines) if line.strip() == "endheader")
    except StopIteration:
        raise InputError(f"{path}: not an OpenSim .sto file: no 'endheader' line") from None
    header = dict(line.split("=", 1) for line in lines[:end] if "=" in line)
    if header.get("DataType") != "Quaternion":
        raise InputError(f"{path}: expected DataType=Quaternion, got {header.get('DataType')!r}")
    if end + 1 >= len(lines):
        raise InputError(f"{path}: no column names after endheader")
    columns = lines[end + 1].split("\t")
    if columns[0] != "time":
        raise InputError(f"{path}, line {end + 2}: expected the first column 'time', got {columns[0]!r}")
    names = tuple(c.removesuffix(SUFFIX) for c in columns[1:])
    rows = [(k + 1, line) for k, line in enumerate(lines[end + 2 :], start=end + 2) if line.strip()]
    time_s = np.empty(len(rows))
    q = np.empty((len(rows), len(names), 4))
    for i, (number, line) in enumerate(rows):
        cells = line.split("\t")
        if len(cells) != len(columns):
            raise InputError(f"{path}, line {number}: {len(cells)} fields, expected {len(columns)}")
        try:
            time_s[i] = float(cells[0])
            parts = [[float(v) for v in c.split(",")] for c in cells[1:]]
        except ValueError:
            raise InputError(f"{path}, line {number}: expected numbers, got {line[:80]!r}") from None
        if any(len(p) != 4 for p in parts):
            raise InputError(f"{path}, line {number}: expected each cell to be w,x,y,z (4 numbers)")
        q[i] = parts
    try:
        rate = float(header.get("DataRate", "nan"))
    except ValueError:
        raise InputError(f"{path}: DataRate is {header['DataRate']!r}; expected a number") from None
    return Orientations(names=names, time_s=time_s, q_w_s=q, rate_hz=rate, header=header)


__all__ = [
    "OPENSIM_LAYOUT_VERSION",
    "SENSOR_TO_OPENSIM_ROTATIONS",
    "Orientations",
    "read_opensense_sto",
    "sto_text",
    "write_opensense_sto",
]
