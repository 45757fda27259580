"""Wide tracker exports: one row per frame, each sensor's position and orientation in columns.

Polhemus and Ascension software (and most tools around them) write a row per frame with every
sensor's position and orientation, as a quaternion or as Euler angles, in columns whose names
vary. A small TOML specification maps them::

    [wide]
    time = "Time"                 # a time column in seconds; or rate_hz = 120 for none
    units = "cm"                  # m, cm, mm, in
    orientation = "euler"         # or "quaternion" (scalar first: w, x, y, z)
    euler = "ZYX"                 # scipy convention: uppercase intrinsic, lowercase extrinsic
    angle_units = "deg"           # or "rad"
    repeated = "drop"             # a sensor's sample equal to its previous one is missing
                                  # (trackers polled faster than they measure repeat samples);
                                  # "keep" to keep them
    [wide.sensors.pelvis]
    position = ["P1_X", "P1_Y", "P1_Z"]
    euler = ["P1_AZ", "P1_EL", "P1_RO"]      # or quaternion = ["P1_W", "P1_X", ...]

Errors name the file, line and column; what was repaired is said in the recording's notes.
"""

from __future__ import annotations

import csv
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.rotations import euler_to_matrix, matrix_to_euler, matrix_to_quat, quat_to_matrix
from simbench.errors import InputError, load_toml
from simbench.io.atomic import atomic_open
from simbench.io.csv_blocks import open_csv
from simbench.io.poses import PoseRecording, first_bad_time
from simbench.units import LENGTH_UNITS, metres_per_unit


@dataclass(frozen=True)
class WideSpec:
    """A parsed wide-CSV specification (module docstring)."""

    time: str | None
    rate_hz: float | None
    units: str
    orientation: str
    euler: str
    degrees: bool
    drop_repeated: bool
    sensors: dict[str, dict[str, list[str]]]


#: Euler sequences scipy takes: three axes, no axis twice in a row; uppercase intrinsic,
#: lowercase extrinsic.
EULER_SEQUENCE = re.compile(r"[XYZ]{3}|[xyz]{3}")


def _check_euler(path: Path, seq: object) -> str:
    if not (isinstance(seq, str) and EULER_SEQUENCE.fullmatch(seq) and seq[0] != seq[1] and seq[1] != seq[2]):
        raise InputError(
            f"{path}, key wide.euler: expected three axes, no axis twice in a row, all uppercase "
            f"(intrinsic) or all lowercase (extrinsic), e.g. 'ZYX'; got {seq!r}"
        )
    return seq


def read_wide_spec(path: str | os.PathLike[str]) -> WideSpec:
    """Read and check a wide-CSV specification TOML.

    Raises:
        InputError: naming the file and key: no ``[wide]`` table, unknown keys, neither a time
            column nor a positive finite ``rate_hz`` (or both), unknown units, orientation,
            angle units or Euler sequence, sensors without their column names, a column used
            twice.
    """
    path = Path(path)
    doc = load_toml(path)
    w = doc.get("wide")
    if not isinstance(w, dict):
        raise InputError(f"{path}: expected a [wide] table, got {'none' if w is None else repr(w)}")
    known = {"time", "rate_hz", "units", "orientation", "euler", "angle_units", "repeated", "sensors"}
    unknown = sorted(set(w) - known)
    if unknown:
        raise InputError(f"{path}: wide: unknown keys {unknown}; expected {sorted(known)}")
    orientation = w.get("orientation", "quaternion")
    if orientation not in ("quaternion", "euler"):
        raise InputError(
            f"{path}, key wide.orientation: expected 'quaternion' or 'euler', got {orientation!r}"
        )
    time = w.get("time")
    rate = w.get("rate_hz")
    if time is not None and not (isinstance(time, str) and time.strip()):
        raise InputError(f"{path}, key wide.time: expected the name of the time column, got {time!r}")
    if rate is not None and not (
        isinstance(rate, int | float) and not isinstance(rate, bool) and math.isfinite(rate) and rate > 0
    ):
        raise InputError(f"{path}, key wide.rate_hz: expected a finite number of Hz > 0, got {rate!r}")
    if (time is None) == (rate is None):
        raise InputError(
            f"{path}: wide: give a time column (time = ...) or a sample rate (rate_hz = ...), got "
            f"{'both' if time is not None else 'neither'}"
        )
    angle_units = w.get("angle_units", "deg")
    if angle_units not in ("deg", "rad"):
        raise InputError(f"{path}, key wide.angle_units: expected 'deg' or 'rad', got {angle_units!r}")
    repeated = w.get("repeated", "drop")
    if repeated not in ("drop", "keep"):
        raise InputError(f"{path}, key wide.repeated: expected 'drop' or 'keep', got {repeated!r}")
    units = w.get("units", "m")
    if not isinstance(units, str) or units not in LENGTH_UNITS:
        raise InputError(
            f"{path}, key wide.units: unknown units {units!r}: expected one of {', '.join(LENGTH_UNITS)}"
        )
    euler = _check_euler(path, w.get("euler", "ZYX"))
    sensors = w.get("sensors")
    if not isinstance(sensors, dict) or len(sensors) < 1:
        raise InputError(f"{path}: expected [wide.sensors.<name>] tables, got {sensors!r}")
    used: dict[str, str] = {time: "wide.time"} if time is not None else {}
    for name, cols in sensors.items():
        if not isinstance(cols, dict):
            raise InputError(
                f"{path}, key wide.sensors.{name}: expected a table of column names, got {cols!r}"
            )
        need = {"position": 3, orientation: 4 if orientation == "quaternion" else 3}
        for key, count in need.items():
            v = cols.get(key)
            if not isinstance(v, list) or len(v) != count or not all(isinstance(c, str) for c in v):
                raise InputError(
                    f"{path}, key wide.sensors.{name}.{key}: expected {count} column names, got {v!r}"
                )
            for c in v:
                if c in used:
                    raise InputError(f"{path}, key wide.sensors.{name}.{key}: column {c!r} is also {used[c]}")
                used[c] = f"wide.sensors.{name}.{key}"
        extra = sorted(set(cols) - set(need))
        if extra:
            raise InputError(f"{path}: wide.sensors.{name}: unexpected keys {extra} for {orientation} input")
    return WideSpec(
        time=time,
        rate_hz=None if rate is None else float(rate),
        units=units,
        orientation=orientation,
        euler=euler,
        degrees=angle_units == "deg",
        drop_repeated=repeated == "drop",
        sensors=sensors,
    )


def read_wide_csv(path: str | os.PathLike[str], spec: WideSpec) -> PoseRecording:
    """Read a wide tracker export with its specification."""
    path = Path(path)
    with open_csv(path) as fh:
        reader = csv.reader(fh)
        header = next((r for r in reader if any(c.strip() for c in r)), None)
        if header is None:
            raise InputError(f"{path}: the file is empty")
        header = [h.strip() for h in header]
        wanted = [spec.time] if spec.time else []
        for cols in spec.sensors.values():
            for group in cols.values():
                wanted += group
        missing = [c for c in wanted if c not in header]
        if missing:
            raise InputError(f"{path}, line {reader.line_num}: missing columns {missing}; header: {header}")
        col = {c: header.index(c) for c in wanted}
        rows = []
        line_of = []
        done = reader.line_num  # the last line of the last complete row
        try:
            for row in reader:
                done = reader.line_num
                if not any(c.strip() for c in row):
                    continue
                if len(row) != len(header):
                    raise InputError(
                        f"{path}, line {reader.line_num}: expected {len(header)} fields, got {len(row)}"
                    )
                values = []
                for c in wanted:
                    try:
                        values.append(float(row[col[c]]))
                    except ValueError:
                        raise InputError(
                            f"{path}, line {reader.line_num}: column {c!r} is not a number: "
                            f"{_shown(row[col[c]])}"
                        ) from None
                rows.append(values)
                line_of.append(reader.line_num)
        except csv.Error as exc:  # a field beyond the csv module's limit (an unclosed quote)
            raise InputError(
                f"{path}, line {done + 1}: not a readable CSV row ({exc}; an unclosed quote?)"
            ) from None
    if len(rows) < 1:
        raise InputError(f"{path}: no data rows after the header")
    data = np.array(rows)
    offset = 0
    if spec.time:
        time_s = data[:, 0]
        offset = 1
        wrong = first_bad_time(time_s)
        if wrong is not None:
            raise InputError(f"{path}, line {line_of[wrong[0]]}, column {spec.time!r}: {wrong[1]}")
    else:
        time_s = np.arange(len(data)) / spec.rate_hz
    scale = metres_per_unit(spec.units)
    names = tuple(spec.sensors)
    f, n = len(data), len(names)
    R = np.full((f, n, 3, 3), np.nan)
    p = np.full((f, n, 3), np.nan)
    valid = np.zeros((f, n), dtype=bool)
    notes = [f"read {f} frames of {n} sensors ({spec.orientation} orientation, positions in {spec.units})"]
    k = offset
    for s, name in enumerate(names):
        width = 7 if spec.orientation == "quaternion" else 6
        block = data[:, k : k + width]
        k += width
        ok = np.isfinite(block).all(axis=1)
        if spec.drop_repeated:
            same = np.zeros(f, dtype=bool)
            same[1:] = np.all(block[1:] == block[:-1], axis=1)
            ok &= ~same
            if same.any():
                notes.append(f"sensor {name}: {int(same.sum())} repeated samples treated as missing")
        if spec.orientation == "quaternion":
            q = block[ok, 3:]
            zero = np.flatnonzero(np.linalg.norm(q, axis=1) == 0)
            if zero.size:
                raise InputError(
                    f"{path}, line {line_of[np.flatnonzero(ok)[zero[0]]]}: sensor {name}: zero quaternion "
                    f"({zero.size} in the file)"
                )
            R[ok, s] = quat_to_matrix(q)
        else:
            R[ok, s] = euler_to_matrix(spec.euler, block[ok, 3:], degrees=spec.degrees)
        p[ok, s] = block[ok, :3] * scale
        valid[:, s] = ok
    return PoseRecording(
        names=names, time_s=time_s, R_w_s=R, p_w_s=p, valid=valid, source=str(path), notes=tuple(notes)
    )


def _shown(text: str, limit: int = 40) -> str:
    """A field for a message: quoted, and cut when long."""
    return repr(text) if len(text) <= limit else f"{text[:limit]!r}... ({len(text)} characters)"


def write_wide_csv(path: str | os.PathLike[str], rec: PoseRecording, spec: WideSpec) -> None:
    """Write poses in the layout a specification describes (for tests and conversions)."""
    scale = metres_per_unit(spec.units)
    header = [spec.time] if spec.time else []
    cols = []
    for name in rec.names:
        c = spec.sensors[name]
        header += c["position"] + c[spec.orientation]
        cols.append(name)
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(header)
        q = matrix_to_quat(np.where(rec.valid[..., None, None], rec.R_w_s, np.eye(3)))
        for f in range(rec.n_frames):
            row = [repr(float(rec.time_s[f]))] if spec.time else []
            for s in range(len(rec.names)):
                if not rec.valid[f, s]:
                    row += ["nan"] * (7 if spec.orientation == "quaternion" else 6)
                    continue
                row += [repr(float(v)) for v in rec.p_w_s[f, s] / scale]
                if spec.orientation == "quaternion":
                    row += [repr(float(v)) for v in q[f, s]]
                else:
                    angles = matrix_to_euler(spec.euler, rec.R_w_s[f, s], degrees=spec.degrees)
                    row += [repr(float(v)) for v in angles]
            writer.writerow(row)
