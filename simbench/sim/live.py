"""A live capture: a session's frames emitted at the capture rate, with a slip at a given time.

MuJoCo's rollout simulates a whole session at once (:mod:`simbench.sim.session`); a live capture
replays the measured poses of such a session (or of any recording) block by block, paced by the
wall clock at the capture rate times ``speed`` (``None``: as fast as the consumer takes them), so
that the streaming calibration (:mod:`calibration.streaming`) and the live commands are tested
end to end. :func:`with_slip` injects a slip (a sensor shifting on its segment, a
:class:`simbench.sim.skin.SkinSlip`) into a sensor configuration.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from simbench.errors import InputError
from simbench.io.poses import PoseRecording
from simbench.sim.plan import SessionConfig, load_session_model
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.sim.session import run_session
from simbench.sim.skin import SkinSlip


@dataclass(frozen=True)
class LiveBlock:
    """Consecutive frames of a live capture.

    Attributes:
        start: index of the block's first frame in the capture.
        time_s: ``(F,)`` capture times, s.
        R_w_s: ``(F, S, 3, 3)`` rotations, sensor to world (NaN where missing).
        p_w_s: ``(F, S, 3)`` positions in world, m (NaN where missing).
        valid: ``(F, S)`` bool.
    """

    start: int
    time_s: np.ndarray
    R_w_s: np.ndarray
    p_w_s: np.ndarray
    valid: np.ndarray


def with_slip(
    sensors: str | SensorConfig, sensor: str, time_s: float, offset_m: Sequence[float]
) -> SensorConfig:
    """A sensor configuration (preset name, TOML path or :class:`SensorConfig`) with one slip more:
    ``sensor`` shifts by ``offset_m`` (``(3,)``, m, in its segment's frame) from ``time_s`` on."""
    config = load_sensor_config(sensors) if isinstance(sensors, str) else sensors
    slip = SkinSlip(sensor=sensor, time_s=float(time_s), offset_m=tuple(float(x) for x in offset_m))
    skin = dataclasses.replace(config.skin, slip=(*config.skin.slip, slip))
    return dataclasses.replace(config, skin=skin)


def recording_with_slip(
    recording: PoseRecording, sensor: str, time_s: float, offset: Sequence[float]
) -> PoseRecording:
    """A recording with one slip injected into its poses: from the first frame at or after ``time_s``
    (seconds, the recording's clock), ``sensor`` sits ``offset`` (``(3,)``, the recording's length
    unit, in the sensor's own frame) away from where it was on its segment (``p += R @ offset``).

    Raises:
        InputError: an unknown sensor, or a time past the recording's end.
    """
    if sensor not in recording.names:
        raise InputError(f"no sensor {sensor!r} in the recording; sensors are {list(recording.names)}")
    frame = int(np.searchsorted(recording.time_s, time_s))
    if frame >= recording.time_s.size:
        raise InputError(
            f"slip time {time_s:g} s is past the recording's last frame ({recording.time_s[-1]:g} s)"
        )
    delta = np.asarray(offset, dtype=float)
    if delta.shape != (3,):
        raise InputError(f"Expected offset to have shape (3,), got {delta.shape}")
    k = recording.names.index(sensor)
    p = recording.p_w_s.copy()
    p[frame:, k] += np.einsum("fab,b->fa", recording.R_w_s[frame:, k], delta)
    return dataclasses.replace(recording, p_w_s=p)


def live_blocks(
    recording: PoseRecording,
    *,
    block_frames: int = 1,
    speed: float | None = 1.0,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Iterator[LiveBlock]:
    """Emit a recording's frames in blocks, each when the capture would have delivered its last frame.

    Args:
        recording: the poses to emit.
        block_frames: frames per block (1: frame by frame).
        speed: multiple of real time (1.0: the capture rate; 10.0: ten times faster); ``None``
            emits as fast as the consumer takes the blocks.
        clock, sleep: the wall clock, seconds, and how to wait (tests pass fakes).

    Raises:
        InputError: ``block_frames`` below 1 or ``speed`` not positive.
    """
    if block_frames < 1:
        raise InputError(f"block_frames must be at least 1, got {block_frames}")
    if speed is not None and not (np.isfinite(speed) and speed > 0):
        raise InputError(f"speed must be a positive number or None, got {speed}")
    t = recording.time_s
    start_clock = clock()
    for lo in range(0, t.shape[0], block_frames):
        hi = min(lo + block_frames, t.shape[0])
        if speed is not None:
            due = start_clock + (t[hi - 1] - t[0]) / speed
            wait = due - clock()
            if wait > 0:
                sleep(wait)
        yield LiveBlock(
            start=lo,
            time_s=t[lo:hi].copy(),
            R_w_s=recording.R_w_s[lo:hi].copy(),
            p_w_s=recording.p_w_s[lo:hi].copy(),
            valid=recording.valid[lo:hi].copy(),
        )


def live_session(
    config: SessionConfig, *, block_frames: int = 1, speed: float | None = 1.0
) -> tuple[PoseRecording, Iterator[LiveBlock]]:
    """Simulate a session (ahead of time: the rollout is one batch), then emit its measured poses
    live (:func:`live_blocks`). Returns the recording (names, rate) and the block iterator."""
    ds = run_session(config, load_session_model(config))
    rec = ds.poses()
    return rec, live_blocks(rec, block_frames=block_frames, speed=speed)
