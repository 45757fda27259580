"""Raw inertial readings as a wide CSV: accelerometer, gyroscope and magnetometer of every sensor.

Layout: comment lines starting with ``#`` give the units, then one header row and one row per
sample::

    # simbench IMU readings; time_s: s; acc: m/s^2 (specific force); gyro: rad/s; mag: uT
    # vectors in each sensor's own frame; empty field: no reading
    time_s,pelvis_acc_x,pelvis_acc_y,pelvis_acc_z,pelvis_gyro_x,...,pelvis_mag_z,thigh_l_acc_x,...

Columns: ``time_s`` then, per sensor, ``<sensor>_acc_{x,y,z}`` (specific force, m/s^2),
``<sensor>_gyro_{x,y,z}`` (angular velocity, rad/s), ``<sensor>_mag_{x,y,z}`` (magnetic field,
microtesla, the dataset's unit), all in the sensor's frame. Numbers are written with 17
significant digits, so they read back exactly; a missing value (NaN) is an empty field.
``pandas.read_csv(path, comment="#")`` reads the file as it is.
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_write_text

#: ``(quantity, unit)`` in column order within each sensor.
QUANTITIES = (("acc", "m/s^2"), ("gyro", "rad/s"), ("mag", "uT"))
UNITS_LINE = "# simbench IMU readings; time_s: s; acc: m/s^2 (specific force); gyro: rad/s; mag: uT"
FRAME_LINE = "# vectors in each sensor's own frame; empty field: no reading"


@dataclass(frozen=True)
class ImuReadings:
    """Raw inertial readings of ``N`` sensors over ``F`` samples.

    Attributes:
        names: ``(N,)`` sensor names.
        time_s: ``(F,)`` s.
        acc: ``(F, N, 3)`` m/s^2. gyro: ``(F, N, 3)`` rad/s. mag: ``(F, N, 3)`` uT; sensor frames.
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray
    mag: np.ndarray


def imu_columns(names: tuple[str, ...] | list[str]) -> list[str]:
    """The header row for these sensors (module docstring)."""
    return ["time_s"] + [f"{n}_{q}_{a}" for n in names for q, _ in QUANTITIES for a in "xyz"]


def imu_csv_text(
    names: tuple[str, ...] | list[str], time_s: np.ndarray, acc: np.ndarray, gyro: np.ndarray, mag: np.ndarray
) -> str:
    """The CSV text of raw readings (arguments as the fields of :class:`ImuReadings`)."""
    names = tuple(names)
    time_s = np.asarray(time_s, dtype=float)
    if time_s.ndim != 1:
        raise InputError(f"Expected time_s of shape (frames,), got {time_s.shape}")
    f = time_s.shape[0]
    arrays = {"acc": acc, "gyro": gyro, "mag": mag}
    for key, a in arrays.items():
        if np.shape(a) != (f, len(names), 3):
            raise InputError(f"Expected {key} of shape ({f}, {len(names)}, 3), got {np.shape(a)}")
    bad = [x for x in names if not x or any(c in x for c in ',"\r\n')]
    if bad:
        raise InputError(f"Expected sensor names without commas, quotes or line breaks, got {bad}")
    table = np.concatenate(
        [
            time_s[:, None],
            np.stack([np.asarray(arrays[q], float) for q, _ in QUANTITIES], axis=2).reshape(f, -1),
        ],
        axis=1,
    )
    lines = [UNITS_LINE, FRAME_LINE, ",".join(imu_columns(names))]
    lines += [",".join(repr(float(v)) if math.isfinite(v) else "" for v in row) for row in table]
    return "\n".join(lines) + "\n"


def write_imu_csv(
    path: str | os.PathLike[str],
    names: tuple[str, ...] | list[str],
    time_s: np.ndarray,
    acc: np.ndarray,
    gyro: np.ndarray,
    mag: np.ndarray,
) -> None:
    """Write raw readings to a CSV file atomically (module docstring for the layout)."""
    atomic_write_text(path, imu_csv_text(names, time_s, acc, gyro, mag))


def read_imu_csv(path: str | os.PathLike[str]) -> ImuReadings:
    """Read a CSV written by :func:`write_imu_csv`.

    Raises:
        InputError: naming the file and line: no header, columns not in the layout (naming the
            first that differs), a row of the wrong length, a field that is not a number.
    """
    path = Path(path)
    text = read_text(path)
    numbered = [(k + 1, row) for k, row in enumerate(csv.reader(io.StringIO(text))) if row]
    numbered = [(k, row) for k, row in numbered if not row[0].startswith("#")]
    if not numbered:
        raise InputError(f"{path}: no header row (expected time_s,<sensor>_acc_x,...)")
    _, header = numbered[0]
    per_sensor = 3 * len(QUANTITIES)
    if header[0] != "time_s" or (len(header) - 1) % per_sensor:
        raise InputError(
            f"{path}: expected a header time_s then {per_sensor} columns per sensor, got {len(header)} "
            f"columns starting {header[:2]}"
        )
    names = tuple(
        header[1 + k * per_sensor].removesuffix("_acc_x") for k in range((len(header) - 1) // per_sensor)
    )
    expected = imu_columns(names)
    if header != expected:
        k = next(i for i, (a, b) in enumerate(zip(header, expected, strict=True)) if a != b)
        raise InputError(f"{path}: column {k + 1} is {header[k]!r}; expected {expected[k]!r}")
    rows = numbered[1:]
    table = np.empty((len(rows), len(header)))
    for i, (number, row) in enumerate(rows):
        if len(row) != len(header):
            raise InputError(f"{path}, line {number}: {len(row)} fields, expected {len(header)}")
        try:
            table[i] = [float(v) if v.strip() else math.nan for v in row]
        except ValueError:
            raise InputError(f"{path}, line {number}: expected numbers, got {','.join(row)[:80]!r}") from None
    values = table[:, 1:].reshape(len(rows), len(names), len(QUANTITIES), 3)
    return ImuReadings(
        names=names, time_s=table[:, 0], acc=values[:, :, 0], gyro=values[:, :, 1], mag=values[:, :, 2]
    )


__all__ = ["ImuReadings", "imu_columns", "imu_csv_text", "read_imu_csv", "write_imu_csv"]
