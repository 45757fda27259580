"""Live calibration of a pose CSV being written, or of a recording replayed at capture rate.

:func:`follow` reads a pose CSV that a logger is still appending to
(:class:`simbench.io.follow.CsvFollower`); :func:`replay` emits a recording's frames block by
block at the capture rate (:func:`simbench.sim.live.live_blocks`). Both push the frames into
:class:`calibration.streaming.StreamingCalibrator` and yield :class:`LiveUpdate`s as they come:
each slip alert the moment it is raised, the calibration every ``refresh_s`` seconds of capture
time (or why there is none yet), and the final calibration of every frame. ``simbench calibrate
--follow`` and ``simbench replay`` print them (:mod:`simbench.cli.live`); ``sb.follow`` and
``sb.replay`` hand them to Python.
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np

from calibration.errors import CalibrationError
from calibration.slip import FALSE_ALARMS_PER_HOUR
from calibration.streaming import LiveState, SlipAlert, StreamingCalibrator
from simbench.errors import InputError
from simbench.estimators import DEFAULT_JOINTS, resolve
from simbench.experiments.live_defaults import RATE_FRAMES, REFRESH_S
from simbench.io.follow import CsvFollower, FollowStopped, RawFrame, first_seen
from simbench.io.poses import PoseRecording
from simbench.sim.live import live_blocks
from simbench.units import metres_per_unit

#: Seconds to wait before looking at a followed file again when it has not grown.
POLL_S = 0.05

_OBRIEN = resolve(DEFAULT_JOINTS)


@dataclass(frozen=True)
class LiveOptions:
    """The options of the live calibration (:class:`calibration.streaming.StreamingCalibrator`);
    O'Brien's at the registry's defaults (:mod:`simbench.estimators.builtin`).

    Attributes:
        slip: raise slip alerts.
        parent_of: a known hierarchy ``{child: parent}``; inferred when ``None``.
        root: root sensor (default: the centre of the inferred tree).
        hierarchy_method: how an inferred tree weighs the pairs (``misfit`` or ``mst``).
        single_axis_ratio: see :mod:`calibration.joint`.
        false_alarms_per_hour: per joint, the rate the alert threshold is set for.
    """

    slip: bool = True
    parent_of: Mapping[str, str] | None = None
    root: str | None = None
    hierarchy_method: str = _OBRIEN.param("hierarchy_method").default
    single_axis_ratio: float = _OBRIEN.param("single_axis_ratio").default
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR


@dataclass(frozen=True)
class LiveUpdate:
    """One thing the live calibration has to say.

    Attributes:
        kind: ``"alert"``: a slip alert was just raised (``alert``, ``raised_s``); ``"state"``:
            the calibration of the frames so far (``state``), every ``refresh_s`` of capture;
            ``"waiting"``: no calibration yet (``reason``: why, e.g. too few frames);
            ``"stopped"``: Ctrl-C, or the file truncated or replaced, ended a follow (``reason``;
            the final update comes next); ``"final"``: the
            calibration of every frame (``state``), the last update.
        calibrator: the streaming calibrator, every frame so far pushed (``None`` only when a
            follow was stopped before the capture rate was known).
        state: for ``state`` and ``final``: joints, residuals, guidance and alerts so far.
        alert: for ``alert``: the sensor that may have slipped, when and by how much.
        raised_s: for ``alert``: the capture time it was raised at, s.
        reason: for ``waiting``: why there is no calibration yet (a file that does not exist yet:
            ``calibrator`` is ``None``); for ``stopped``: what stopped the follow.
    """

    kind: Literal["alert", "state", "waiting", "stopped", "final"]
    calibrator: StreamingCalibrator | None
    state: LiveState | None = None
    alert: SlipAlert | None = None
    raised_s: float | None = None
    reason: str = ""


def calibrator(
    names: tuple[str, ...], rate_hz: float, start_s: float, options: LiveOptions
) -> StreamingCalibrator:
    """A streaming calibrator of these sensors with ``options``.

    Raises:
        InputError: an option the calibrator refuses (a root that is not a sensor, a hierarchy
            that is not a tree of them, a rate too low for the slip window).
    """
    try:
        return StreamingCalibrator(
            names,
            rate_hz=rate_hz,
            start_time_s=start_s,
            slip=options.slip,
            parent_of=options.parent_of,
            root=options.root,
            hierarchy_method=options.hierarchy_method,
            single_axis_ratio=options.single_axis_ratio,
            false_alarms_per_hour=options.false_alarms_per_hour,
        )
    except CalibrationError as exc:
        raise InputError(str(exc)) from None


@dataclass
class _Updates:
    """The updates of a calibrator as frames are pushed: alerts as they come, the calibration
    every ``refresh_s`` of capture time. Every time they report is a frame's own time stamp
    (``stamps``: one per frame pushed), not a count of frames over the rate: a gap in the
    recording does not shift the times after it."""

    refresh_s: float
    cal: StreamingCalibrator | None = None
    next_at: float = 0.0
    stamps: array = field(default_factory=lambda: array("d"))

    def push(self, time_s: np.ndarray, R: np.ndarray, p: np.ndarray, ok: np.ndarray) -> None:
        """Push frames ``(F,)`` times, ``(F, S, 3, 3)``, ``(F, S, 3)``, ``(F, S)`` (or one frame
        without the leading axis) into the calibrator, keeping their time stamps."""
        assert self.cal is not None
        self.cal.push(R, p, ok)
        self.stamps.extend(np.atleast_1d(np.asarray(time_s, dtype=float)).tolist())

    def at(self, frame: int) -> float:
        """The time stamp of a frame pushed, s."""
        return self.stamps[min(max(frame, 0), len(self.stamps) - 1)]

    def after(self, time_s: float) -> Iterator[LiveUpdate]:
        """After frames up to ``time_s`` (capture time) were pushed."""
        cal = self.cal
        assert cal is not None
        for alert in cal.new_alerts():
            alert = replace(alert, time_s=self.at(alert.frame))
            yield LiveUpdate("alert", cal, alert=alert, raised_s=self.at(alert.raised_frame))
        if time_s >= self.next_at:
            self.next_at = time_s + self.refresh_s
            try:
                yield LiveUpdate("state", cal, state=self.state())
            except CalibrationError as exc:
                yield LiveUpdate("waiting", cal, reason=str(exc))

    def state(self) -> LiveState:
        """The calibrator's state, its times the frames' time stamps."""
        assert self.cal is not None
        state = self.cal.state()
        alerts = tuple(replace(a, time_s=self.at(a.frame)) for a in state.alerts)
        return replace(state, time_s=self.at(len(self.stamps) - 1), alerts=alerts)

    def final(self, source: str) -> Iterator[LiveUpdate]:
        """The calibration of every frame.

        Raises:
            CalibrationError: there is none (what was waited for never came), naming ``source``.
        """
        cal = self.cal
        assert cal is not None
        try:
            state = self.state()
        except CalibrationError as exc:
            raise CalibrationError(
                f"{source}: no calibration from its {cal.n_frames} frames: {exc}"
            ) from None
        yield LiveUpdate("final", cal, state=state)


def replay(
    rec: PoseRecording,
    *,
    source: str,
    speed: float | None = 1.0,
    refresh_s: float = REFRESH_S,
    options: LiveOptions = LiveOptions(),
) -> Iterator[LiveUpdate]:
    """A recording's frames through the live calibration, 50 ms of frames at a time, paced at
    ``speed`` times the capture rate (``None``: as fast as the updates are taken).

    Args:
        rec: the poses.
        source: what is replayed, for messages (a path).
        speed: multiple of real time, or ``None``.
        refresh_s: seconds of capture between two ``state`` updates.
        options: the calibrator's options.

    Raises:
        InputError: fewer than 2 frames, or an option the calibrator refuses (at once).
        CalibrationError: at the end, when the frames never gave a calibration.
    """
    if rec.n_frames < 2 or not np.isfinite(rec.rate_hz):
        raise InputError(f"{source}: too few frames to replay ({rec.n_frames})")
    cal = calibrator(rec.names, rec.rate_hz, float(rec.time_s[0]), options)
    return _replay(
        rec, cal, source, speed, _Updates(refresh_s, cal, next_at=float(rec.time_s[0]) + refresh_s)
    )


def _replay(
    rec: PoseRecording, cal: StreamingCalibrator, source: str, speed: float | None, updates: _Updates
) -> Iterator[LiveUpdate]:
    block = max(1, round(rec.rate_hz / 20))  # 50 ms of frames at a time
    for b in live_blocks(rec, block_frames=block, speed=speed):
        updates.push(b.time_s, b.R_w_s, b.p_w_s, b.valid)
        yield from updates.after(float(b.time_s[-1]))
    yield from updates.final(source)


def follow(
    path: str | Path,
    *,
    units: str = "m",
    rate_hz: float | None = None,
    timeout_s: float | None = None,
    refresh_s: float = REFRESH_S,
    options: LiveOptions = LiveOptions(),
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[LiveUpdate]:
    """Calibrate live from a pose CSV that another process is appending to.

    Reads the new complete rows every :data:`POLL_S` seconds (at most
    :data:`simbench.io.follow.READ_BYTES` at a time) and pushes each completed frame. The
    calibration starts once :data:`RATE_FRAMES` frames are read (or at the end, with fewer): the
    capture rate, unless given, from their time stamps; the sensors, those of their rows
    (:func:`simbench.io.follow.first_seen`). Every time reported is a frame's time stamp. Stops
    after ``timeout_s`` seconds of wall time (checked between frames, so a backlog cannot hold it)
    or at Ctrl-C (a ``stopped`` update), then gives the ``final`` update. A file that does not
    exist yet is waited for (a ``waiting`` update says so); one that never held a complete frame
    ends without a ``final`` update.

    Args:
        path: the pose CSV (``time,sensor,x,y,z,qw,qx,qy,qz``).
        units: length unit of its positions.
        rate_hz: the capture rate, Hz (default: from the time stamps).
        timeout_s: wall-time bound, s (``None``: until Ctrl-C).
        refresh_s: seconds of capture between two ``state`` updates.
        options: the calibrator's options.
        clock: the wall clock, seconds (tests pass a fake).

    Raises:
        InputError: a row the batch reader would refuse (line named), an option the calibrator
            refuses, or a file that never appeared.
        FollowStopped: the file was truncated, replaced or removed while followed: after the
            ``stopped`` and ``final`` updates of the frames read before.
        CalibrationError: at the end, when the frames never gave a calibration.
    """
    follower = CsvFollower(Path(path), metres_per_unit(units))
    start = clock()
    waiting: list[RawFrame] = []  # frames before the calibration starts
    updates = _Updates(refresh_s)

    def timed_out() -> bool:
        return timeout_s is not None and clock() - start >= timeout_s

    def begin() -> Iterator[LiveUpdate]:
        times = np.array([f[0] for f in waiting])
        rate = rate_hz if rate_hz is not None else (len(times) - 1) / (times[-1] - times[0])
        follower.set_names(first_seen(waiting))
        assert follower.names is not None
        updates.cal = calibrator(follower.names, rate, float(times[0]), options)
        updates.next_at = float(times[0]) + refresh_s
        for frame in waiting:
            updates.push(*follower.arrays(frame))
        waiting.clear()
        yield from updates.after(float(times[-1]))

    def push(frame: RawFrame) -> Iterator[LiveUpdate]:
        if updates.cal is None:
            waiting.append(frame)
            if len(waiting) >= RATE_FRAMES and waiting[-1][0] > waiting[0][0]:
                yield from begin()
            return
        arrays = follower.arrays(frame)
        updates.push(*arrays)
        yield from updates.after(arrays[0])

    stopped: FollowStopped | None = None
    said_missing = False
    try:
        read_once = False
        while not (read_once and timed_out()):  # at least one read, however short the bound
            read_once = True
            got = False
            for frame in follower.frames():
                yield from push(frame)
                got = True
                if timed_out():
                    break
            if not got:
                if not follower.appeared and not said_missing:
                    said_missing = True
                    yield LiveUpdate("waiting", None, reason=f"{path} does not exist yet")
                time.sleep(POLL_S)
    except KeyboardInterrupt:
        yield LiveUpdate("stopped", updates.cal, reason="Ctrl-C")
    except FollowStopped as exc:
        stopped = exc
        yield LiveUpdate("stopped", updates.cal, reason=str(exc))
    finally:
        follower.close()
    for frame in follower.flush():  # the rows read and not yet pushed, the last frame too
        yield from push(frame)
    if updates.cal is None and len(waiting) >= 2 and waiting[-1][0] > waiting[0][0]:
        yield from begin()  # a short file: the rate and sensors from what there is
    if updates.cal is not None:
        yield from updates.after(float("-inf"))
        yield from updates.final(str(path))
    if stopped is not None:
        raise stopped
    if not follower.appeared:
        waited = "" if timeout_s is None else f" (waited {timeout_s:g} s for it to appear)"
        raise InputError(f"{path}: no such file{waited}")


__all__ = [
    "POLL_S",
    "RATE_FRAMES",
    "REFRESH_S",
    "LiveOptions",
    "LiveUpdate",
    "calibrator",
    "follow",
    "replay",
]
