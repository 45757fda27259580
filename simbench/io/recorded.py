"""A recorded motion as the simulator plays it: one time series of generalised coordinates per joint.

Every motion source (a BVH clip, a ``qpos`` series, OpenSim joint angles, rigid-body pose
trajectories) becomes a :class:`RecordedMotion`: frames at a constant period, and for each
MuJoCo joint it moves a :class:`Track` of that joint's ``qpos`` (a free joint: position, m, in
world then quaternion wxyz; a ball joint: quaternion wxyz of its rotation in the parent; a hinge:
angle, rad; a slide: displacement, m). Joints it does not name keep the model's ``qpos0``.
:mod:`simbench.sim.playback` smooths the tracks for velocities and accelerations and sets MuJoCo's
state from them, exactly at the recorded frames.

Frames where the recording has no pose (an occluded optical marker: ``valid`` false) are filled
for the smoothing (positions linearly, rotations by spherical interpolation between the recorded
frames on either side; held at the ends) and named in the session's metadata.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from simbench.errors import InputError
from simbench.io.poses import sample_rate

#: ``qpos`` width of each joint kind.
WIDTH = {"free": 7, "ball": 4, "hinge": 1, "slide": 1}

#: A time stamp more than this fraction of a period off its frame's time is off the grid (a
#: stamp's jitter is a small fraction of a period; half a period would be another frame).
GRID_TOLERANCE = 0.25

#: A recording whose stamps span more than this many frames per stamp is mostly gaps: refused.
MAX_FRAMES_PER_STAMP = 2


@dataclass(frozen=True)
class Track:
    """One joint's recorded coordinates.

    Attributes:
        joint: the MuJoCo joint it moves.
        kind: ``free``, ``ball``, ``hinge`` or ``slide``.
        values: ``(F, w)``: ``w`` = 7, 4, 1, 1 (:data:`WIDTH`); SI units, quaternions wxyz.
    """

    joint: str
    kind: str
    values: np.ndarray

    def __post_init__(self) -> None:
        if self.kind not in WIDTH:
            raise InputError(f"joint {self.joint!r}: kind {self.kind!r} is not one of {', '.join(WIDTH)}")
        width = WIDTH[self.kind]
        if self.values.ndim != 2 or self.values.shape[1] != width:
            raise InputError(
                f"joint {self.joint!r} ({self.kind}): expected (frames, {width}) coordinates, got "
                f"{self.values.shape}"
            )

    @property
    def quaternion_columns(self) -> slice | None:
        """The columns holding a quaternion, or ``None``."""
        return {"free": slice(3, 7), "ball": slice(0, 4)}.get(self.kind)


@dataclass(frozen=True)
class RecordedMotion:
    """A recording's joint coordinates at a constant frame period.

    Attributes:
        source: the file (for messages and the Dataset's metadata).
        frame_time_s: time between frames, s.
        tracks: one per joint it moves, every one ``F`` frames long, no NaN.
        valid: ``(F,)`` frames the recording holds (false: filled, module docstring).
        start_s: the time of the first frame in the recording's own clock, s.
        format: what the file was read as (``bvh``, ``qpos``, ``opensim``, ``poses``).
    """

    source: str
    frame_time_s: float
    tracks: tuple[Track, ...]
    valid: np.ndarray
    start_s: float = 0.0
    format: str = ""
    notes: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not self.tracks:
            raise InputError(f"{self.source}: the recording moves no joint")
        n = self.n_frames
        for t in self.tracks:
            if t.values.shape[0] != n:
                raise InputError(
                    f"{self.source}: joint {t.joint!r} has {t.values.shape[0]} frames, "
                    f"{self.tracks[0].joint!r} {n}"
                )
            if not np.all(np.isfinite(t.values)):
                raise InputError(f"{self.source}: joint {t.joint!r} has coordinates that are not finite")
        if self.valid.shape != (n,):
            raise InputError(f"{self.source}: expected ({n},) valid flags, got {self.valid.shape}")
        if not (math.isfinite(self.frame_time_s) and self.frame_time_s > 0):
            raise InputError(f"{self.source}: frame time must be > 0 s, got {self.frame_time_s}")
        names = [t.joint for t in self.tracks]
        if len(set(names)) != len(names):
            raise InputError(f"{self.source}: joints moved twice: {names}")

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.tracks[0].values.shape[0])

    @property
    def rate_hz(self) -> float:
        """Frame rate, Hz."""
        return 1.0 / self.frame_time_s

    @property
    def joints(self) -> tuple[str, ...]:
        """The joints it moves, in track order."""
        return tuple(t.joint for t in self.tracks)


def frame_grid(
    time_s: np.ndarray, source: str, first_line: int = 2, lines: np.ndarray | None = None
) -> tuple[float, np.ndarray]:
    """The constant frame period of recorded time stamps ``(F,)`` s and each stamp's frame on it.

    The period is the median step, refined by a least-squares line through the stamps against their
    frames; time stamps written in bursts (:func:`simbench.io.poses.sample_rate`) are taken as
    samples at the count-over-span rate. A step of about ``k`` periods is ``k - 1`` dropped frames
    (the caller fills them, :func:`fill_gaps`).

    Returns:
        ``(period_s, frame)``: ``frame`` ``(F,)`` int, 0 for the first stamp, increasing.

    Raises:
        InputError: fewer than 2 stamps, a stamp that is not a number, stamps that do not increase,
            or a stamp more than :data:`GRID_TOLERANCE` of a period off the grid (naming its line:
            ``lines[k]`` for stamp ``k`` when given, else ``first_line + k``; a negative
            ``first_line`` names frames, counted from 0, for a file without lines).
    """
    t = np.asarray(time_s, dtype=float)

    def at(k: int) -> str:
        if lines is not None:
            return f"{source}, line {int(lines[k])}"
        return f"{source}, frame {k}" if first_line < 0 else f"{source}, line {first_line + k}"

    if t.ndim != 1 or t.size < 2:
        raise InputError(f"{source}: expected at least 2 frames, got {t.size}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputError(f"{at(int(bad[0]))}: time {t[bad[0]]} is not a number")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:  # before the rate: repeated stamps have no rate
        k = int(back[0]) + 1
        raise InputError(f"{at(k)}: time {t[k]:.9g} s does not follow {t[k - 1]:.9g} s")
    _, bursty = sample_rate(t)
    if bursty is not None:
        return float((t[-1] - t[0]) / (t.size - 1)), np.arange(t.size)
    period = float(np.median(np.diff(t)))
    frame = np.rint((t - t[0]) / period).astype(np.int64)
    if frame[-1] > 1 and np.all(np.diff(frame) > 0):  # refine: the line through (frame, t)
        period = float(np.polyfit(frame, t, 1)[0])
        frame = np.rint((t - t[0]) / period).astype(np.int64)
    off = np.abs(t - t[0] - frame * period) > GRID_TOLERANCE * period
    off[1:] |= np.diff(frame) <= 0
    if off.any():
        k = int(np.flatnonzero(off)[0])
        raise InputError(
            f"{at(k)}: time {t[k]:.9g} s is off the recording's frame grid (period "
            f"{period:.6g} s from {t[0]:.9g} s; {int(off.sum())} such stamp(s)): a constant rate is needed, "
            "resample the recording"
        )
    if frame[-1] + 1 > MAX_FRAMES_PER_STAMP * t.size:
        raise InputError(
            f"{source}: {t.size} time stamps span {frame[-1] + 1} frames of {period:.6g} s: mostly gaps"
        )
    return period, frame


def _slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Spherical interpolation between unit quaternions ``(4,)`` at fractions ``s`` ``(k,)``."""
    if np.dot(q0, q1) < 0:
        q1 = -q1
    dot = float(np.clip(np.dot(q0, q1), -1.0, 1.0))
    theta = math.acos(dot)
    if theta < 1e-9:
        out = q0[None] + s[:, None] * (q1 - q0)[None]
    else:
        out = (np.sin((1 - s) * theta)[:, None] * q0 + np.sin(s * theta)[:, None] * q1) / math.sin(theta)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def fill_gaps(values: np.ndarray, valid: np.ndarray, quaternion: slice | None) -> np.ndarray:
    """``values`` ``(F, w)`` with the frames not ``valid`` filled (module docstring).

    Raises:
        InputError: no valid frame at all (the caller names the file).
    """
    valid = np.asarray(valid, dtype=bool)
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        raise InputError("no frame holds a pose")
    out = np.array(values, dtype=float)
    frames = np.arange(out.shape[0])
    in_q = np.zeros(out.shape[1], dtype=bool)
    if quaternion is not None:
        in_q[quaternion] = True
    rest = np.flatnonzero(~in_q)
    for c in rest:
        out[:, c] = np.interp(frames, idx, out[idx, c])
    if quaternion is not None:
        q = out[:, quaternion]
        q[: idx[0]] = q[idx[0]]
        q[idx[-1] + 1 :] = q[idx[-1]]
        gaps = np.flatnonzero(np.diff(idx) > 1)
        for g in gaps:
            a, b = idx[g], idx[g + 1]
            q[a + 1 : b] = _slerp(q[a], q[b], (np.arange(a + 1, b) - a) / (b - a))
        out[:, quaternion] = q
    return out


def on_frame_grid(
    source: str,
    time_s: np.ndarray,
    tracks: list[Track],
    format: str,
    lines: np.ndarray | None = None,
    notes: tuple[str, ...] = (),
) -> RecordedMotion:
    """A recording's tracks, one row per time stamp ``(F,)`` s, placed on its frame grid
    (:func:`frame_grid`: ``lines`` each row's line in the file, or ``None`` to name frames) with
    dropped frames filled (:func:`fill_gaps`).

    Raises:
        InputError: what :func:`frame_grid` refuses.
    """
    period, frame = frame_grid(time_s, source, first_line=-1, lines=lines)
    n = int(frame[-1]) + 1
    valid = np.zeros(n, dtype=bool)
    valid[frame] = True
    full = []
    for t in tracks:
        v = np.zeros((n, t.values.shape[1]))
        v[frame] = t.values
        full.append(Track(t.joint, t.kind, fill_gaps(v, valid, t.quaternion_columns)))
    return RecordedMotion(
        source=source,
        frame_time_s=period,
        tracks=tuple(full),
        valid=valid,
        start_s=float(time_s[0]),
        format=format,
        notes=notes,
    )
