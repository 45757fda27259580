"""Sensor pose recordings and the pose CSV format of docs/conventions.md.

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
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.poses import check_poses
from calibration.rotations import matrix_to_quat
from simbench.errors import InputError
from simbench.io.atomic import atomic_open
from simbench.io.csv_blocks import CSV_COLUMNS, read_table
from simbench.units import LENGTH_UNITS, metres_per_unit

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


def first_bad_time(time_s: np.ndarray) -> tuple[int, str] | None:
    """The first sample whose time is not finite or does not increase, and what is wrong with it
    (for the caller to place: a file's line, a dataset's path); ``None`` when all are right.

    Args:
        time_s: ``(frames,)`` sample times, seconds.
    """
    bad = np.flatnonzero(~np.isfinite(time_s))
    if bad.size:
        return int(bad[0]), f"expected a finite time in seconds, got {float(time_s[bad[0]])!r}"
    back = np.flatnonzero(np.diff(time_s) <= 0)
    if back.size:
        k = int(back[0]) + 1
        return k, f"times must increase, got {float(time_s[k])!r} s after {float(time_s[k - 1])!r} s"
    return None


@dataclass(frozen=True)
class PoseRecording:
    """6-DoF sensor poses over time: the container every joints estimator receives.

    Batched like scipy's ``Rotation``: ``len(poses)`` frames, ``poses[frames]`` a selection of
    frames, ``poses.sensors(names)`` of sensors, ``poses.in_unit("mm")``; made from bare arrays by
    :meth:`from_arrays`. It checks itself once, when made (shapes by
    :func:`calibration.poses.check_poses`, increasing times, a known unit).

    Attributes:
        names: ``(sensors,)`` sensor names.
        time_s: ``(frames,)`` strictly increasing times, seconds.
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world (NaN where missing).
        p_w_s: ``(frames, sensors, 3)`` sensor positions in world, in ``unit`` (NaN where missing).
        valid: ``(frames, sensors)`` bool, False where a pose is missing or not finite.
        source: where the data came from (a path, or a description).
        notes: what the reader repaired or noticed, in plain language.
        unit: the positions' length unit (a key of :data:`simbench.units.LENGTH_UNITS`): ``"m"``
            from every reader, which converts; a tracker's own metres for a simulated session
            (its ``position_unit_scale`` is the truth's, not the recording's).
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    R_w_s: np.ndarray
    p_w_s: np.ndarray
    valid: np.ndarray
    source: str = ""
    notes: tuple[str, ...] = ()
    unit: str = "m"

    def __post_init__(self) -> None:
        if self.unit not in LENGTH_UNITS:
            raise InputError(f"Expected unit to be one of {sorted(LENGTH_UNITS)}, got {self.unit!r}")
        time_s = self.time_s
        if not isinstance(time_s, np.ndarray) or time_s.ndim != 1:
            raise InputError(f"Expected time_s to have shape (frames,), got {np.shape(time_s)}")
        try:  # the one check of pose arrays, the calibration's (calibration.poses.check_poses)
            f, n = check_poses(self.R_w_s, self.p_w_s, self.valid)
        except CalibrationInputError as exc:
            raise InputError(str(exc)) from None
        if (f, n) != (time_s.shape[0], len(self.names)):
            raise InputError(
                f"Expected R_w_s to have shape ({time_s.shape[0]}, {len(self.names)}, 3, 3) for "
                f"{time_s.shape[0]} times and {len(self.names)} names, got {tuple(self.R_w_s.shape)}"
            )
        if self.valid is None:
            raise InputError("Expected valid, an array of shape (frames, sensors), got None")
        if f > 1 and not np.all(np.diff(time_s) > 0):
            raise InputError("times must be strictly increasing")
        _, note = sample_rate(time_s)
        if note is not None and note not in self.notes:  # every reader's recording says so
            object.__setattr__(self, "notes", (*self.notes, note))

    @classmethod
    def from_arrays(
        cls,
        names: Sequence[str],
        time_s: Any,
        R_w_s: Any,
        p_w_s: Any,
        *,
        valid: Any = None,
        unit: str = "m",
        source: str = "arrays",
    ) -> PoseRecording:
        """A recording from bare arrays: ``time_s`` ``(F,)`` s, ``R_w_s`` ``(F, N, 3, 3)``,
        ``p_w_s`` ``(F, N, 3)`` in ``unit``; ``valid`` ``(F, N)`` (default: where the pose is finite).

        Raises:
            InputError: shapes that do not agree (what was expected and what arrived), times that do
                not increase, an unknown unit.
        """
        R = np.asarray(R_w_s, dtype=float)
        p = np.asarray(p_w_s, dtype=float)
        if valid is None and R.shape[:2] == p.shape[:2]:
            valid = np.isfinite(R).all(axis=(-2, -1)) & np.isfinite(p).all(axis=-1)
        return cls(
            tuple(names),
            np.asarray(time_s, dtype=float),
            R,
            p,
            np.asarray(valid, dtype=bool),
            source,
            (),
            unit,
        )

    def __len__(self) -> int:
        return self.n_frames

    def __getitem__(self, frames: Any) -> PoseRecording:
        """The recording over some frames (a slice, a bool mask or indices), every sensor kept:
        ``poses[:600]``, ``poses[poses.time_s > 10]``."""
        t = self.time_s[frames]
        if np.ndim(t) != 1:
            raise InputError(f"Expected a selection of frames (slice, mask, indices), got {frames!r}")
        return replace(
            self, time_s=t, R_w_s=self.R_w_s[frames], p_w_s=self.p_w_s[frames], valid=self.valid[frames]
        )

    def sensors(self, names: Sequence[str]) -> PoseRecording:
        """The recording of some sensors, in the order given.

        Raises:
            InputError: a name the recording lacks.
        """
        missing = [n for n in names if n not in self.names]
        if missing:
            raise InputError(f"sensor(s) {missing} are not in the recording ({', '.join(self.names)})")
        k = [self.names.index(n) for n in names]
        return replace(
            self, names=tuple(names), R_w_s=self.R_w_s[:, k], p_w_s=self.p_w_s[:, k], valid=self.valid[:, k]
        )

    def in_unit(self, unit: str) -> PoseRecording:
        """The same poses with positions in another length unit (``m``, ``cm``, ``mm``, ``in``)."""
        factor = metres_per_unit(self.unit) / metres_per_unit(unit)
        return replace(self, p_w_s=self.p_w_s * factor, unit=unit)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.time_s.shape[0])

    def pair(self, parent: str, child: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(R_w_p, p_w_p, R_w_c, p_w_c)`` of two sensors, as the joint functions take them."""
        p, c = self.names.index(parent), self.names.index(child)
        return self.R_w_s[:, p], self.p_w_s[:, p], self.R_w_s[:, c], self.p_w_s[:, c]

    def pair_views(
        self, parent: str, child: str, drop: np.ndarray | None = None
    ) -> tuple[SensorFrames, SensorFrames, SensorFrames, SensorFrames]:
        """:meth:`pair` read a slice of frames at a time (:class:`SensorFrames`), with the frames
        ``drop`` (``(frames,)`` bool) NaN: for a recording larger than memory."""
        p, c = self.names.index(parent), self.names.index(child)
        return tuple(SensorFrames(x, k, drop) for k in (p, c) for x in (self.R_w_s, self.p_w_s))  # type: ignore[return-value]

    @property
    def rate_hz(self) -> float:
        """Sample rate, Hz: from the median step, or from the sample count over the span when
        the time stamps come in bursts (:func:`sample_rate`); NaN with fewer than 2 frames."""
        return sample_rate(self.time_s)[0]


@dataclass(frozen=True)
class SensorFrames:
    """One sensor's series of a ``(frames, sensors, ...)`` array (or h5py dataset), read a slice of
    frames at a time: ``view[a:b]`` is ``(b - a, ...)`` float, NaN where ``drop`` is true."""

    data: Any
    sensor: int
    drop: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.data.shape[0])

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self), *self.data.shape[2:])

    def __getitem__(self, frames: slice) -> np.ndarray:
        x = self.data[frames, self.sensor]
        if isinstance(self.data, np.ndarray) or x.dtype != np.float64:  # a view of the caller's array
            x = np.array(x, dtype=float)
        if self.drop is not None:
            x[self.drop[frames]] = np.nan
        return x


def read_pose_csv(
    path: str | os.PathLike[str], *, units: str = "m", in_memory: bool | None = None
) -> PoseRecording:
    """Read a pose CSV (see the module docstring), streaming: memory holds one block of rows
    and the ``(frames, sensors)`` flags, not the file (:mod:`simbench.io.csv_blocks`).

    Args:
        path: the file.
        units: length unit of the file's positions; converted to metres.
        in_memory: poses in arrays (True), or in an unlinked temporary HDF5 file read a chunk
            at a time (False; then ``R_w_s`` and ``p_w_s`` are h5py datasets); ``None`` chooses
            by size (:data:`~simbench.io.csv_blocks.IN_MEMORY_BYTES`).

    Raises:
        InputError: naming the file, line and problem.
    """
    scale = metres_per_unit(units)
    path = Path(path)
    table = read_table(path, scale, in_memory=in_memory)
    notes = (
        table.notes if units == "m" else (*table.notes, f"positions read in {units} and converted to metres")
    )
    return PoseRecording(
        names=table.names,
        time_s=table.time_s,
        R_w_s=table.R_w_s,
        p_w_s=table.p_w_s,
        valid=table.valid,
        source=str(path),
        notes=notes,
    )


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
    scale = metres_per_unit(units) / metres_per_unit(rec.unit)
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
