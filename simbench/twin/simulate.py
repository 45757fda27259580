"""Ideal IMU readings from an optical pose: the twin's one seam to the simulator.

:func:`twin_readings` plays a recorded pose trajectory (a point's position and a body's
orientation, world ENU: x east, y north, z up, as BROAD's ``opt_pos``/``opt_quat``) back through
the simulator, as ``sb.simulate(motion="trial.hdf5")`` does (:mod:`simbench.sim.pose_model`: a
free body whose sensor frame is the recorded one; :mod:`simbench.sim.playback`: Savitzky-Golay
smoothing, MuJoCo's inverse dynamics), and returns what an ideal accelerometer, gyroscope and
magnetometer on that body read, in the body frame:

- gyroscope: the body's angular velocity in its own frame (rad/s);
- accelerometer: the specific force (m/s^2, ``+g`` up at rest) at the lever arm ``r`` from the
  tracked point (the sensor's placement on the body): ``R^T (a + g e_z) + alpha x r + omega x
  (omega x r)``;
- magnetometer ``R^T b`` (uT), ``b`` the world field given (uniform, or at every sample), ``R``
  the body's recorded orientation.

Every reading is linear in the field and the lever arm: the identification
(:mod:`simbench.twin.identify`) takes what a unit field or a unit lever arm adds from here too.
Positions get a smoothing cutoff of their own (``position_cutoff_hz``): an acceleration is the
position differentiated twice, which multiplies the markers' jitter by ``(2 pi f)^2``, while the
orientation is differentiated once.

**Gaps.** Optical systems lose markers: BROAD's trials have 1-9 % of rows NaN, in runs.
:func:`fill_gaps` fills every gap as the simulator does (positions linearly, rotations by
spherical interpolation, held at the ends: :func:`simbench.io.recorded.fill_gaps`) so that the
smoothing runs through, and
:func:`near_gaps` marks the gap samples and every sample within the smoothing's half-window of
one: those readings rest on filled poses and are left out of every comparison.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.recorded import RecordedMotion, Track
from simbench.io.recorded import fill_gaps as fill_recorded_gaps
from simbench.sim.motion_source import MotionSource
from simbench.sim.playback import _continuous, savgol_window
from simbench.sim.pose_model import BROAD_SENSOR, POSES_MODEL, poses_spec
from simbench.sim.session import SessionConfig, run_session

#: Standard gravity, m/s^2 (the simulator's; BROAD was recorded in Berlin, 9.813).
GRAVITY = 9.81

#: A time step within this fraction of the median is uniform.
UNIFORM = 1e-6


def _check(time_s: np.ndarray, p_w: np.ndarray, q_w: np.ndarray, field_w: np.ndarray) -> float:
    """The sample rate of ``time_s`` (Hz), after checking the shapes and values."""
    if time_s.ndim != 1 or time_s.size < 2:
        raise InputError(f"twin_readings: expected time_s of shape (F,) with F >= 2, got {time_s.shape}")
    f = time_s.size
    for name, x, tail in (("p_w", p_w, 3), ("q_w", q_w, 4)):
        if x.shape != (f, tail):
            raise InputError(f"twin_readings: expected {name} of shape ({f}, {tail}), got {x.shape}")
        if not np.isfinite(x).all():
            raise InputError(f"twin_readings: {name} has non-finite values: fill the gaps first (fill_gaps)")
    if field_w.shape not in ((3,), (f, 3)) or not np.isfinite(field_w).all():
        raise InputError(
            f"twin_readings: expected field_w of shape (3,) or ({f}, 3), finite (uT), got {field_w.shape}"
        )
    dt = np.diff(time_s)
    step = float(np.median(dt))
    if not (step > 0 and np.all(np.abs(dt - step) <= UNIFORM * step)):
        raise InputError("twin_readings: expected uniformly sampled, increasing time_s")
    return 1.0 / step


def smoothing_window(rate_hz: float, cutoff_hz: float, n_frames: int, source: str = "") -> int:
    """The Savitzky-Golay window (frames, odd) of ``cutoff_hz`` at ``rate_hz``: the playback's
    (:func:`simbench.sim.playback.savgol_window`, which remembers its search).

    Raises:
        InputError: as ``savgol_window``, naming ``source``.
    """
    return savgol_window(rate_hz, cutoff_hz, n_frames, source)


@dataclass(frozen=True)
class IdealReadings:
    """Ideal readings of a body moving as recorded, at several lever arms (:func:`ideal_readings`).

    Attributes:
        acc: ``(F, K, 3)`` specific force at each of the ``K`` lever arms, sensor frame, m/s^2.
        gyro: ``(F, 3)`` angular velocity, sensor frame, rad/s.
        R_w_s: ``(F, 3, 3)`` the sensor's orientation (sensor frame to world, ENU), as played back.
    """

    acc: np.ndarray
    gyro: np.ndarray
    R_w_s: np.ndarray

    def mag(self, field_w: np.ndarray) -> np.ndarray:
        """``(F, 3)`` an ideal magnetometer's ``R^T b`` of the world field ``b`` (``(3,)`` or
        ``(F, 3)``, uT), uT."""
        return np.einsum("fji,fj->fi", self.R_w_s, np.broadcast_to(field_w, (self.R_w_s.shape[0], 3)))


def ideal_readings(
    time_s: np.ndarray,
    p_w: np.ndarray,
    q_w: np.ndarray,
    cutoff_hz: float,
    *,
    position_cutoff_hz: float | None = None,
    lever_arms_m: np.ndarray | None = None,
) -> IdealReadings:
    """Ideal accelerometers at ``K`` lever arms, the gyroscope and the orientation of a body moving
    as recorded: one playback through the simulator (module docstring), a sensor body per lever arm
    following the one recorded pose (the bodies are not joined: each reads as if alone).

    Args:
        time_s, p_w, q_w, cutoff_hz, position_cutoff_hz: as :func:`twin_readings`.
        lever_arms_m: ``(K, 3)`` the accelerometers' positions relative to the tracked point, in the
            sensor frame, m (default: one, at the tracked point).

    Raises:
        InputError: shapes or values not as :func:`twin_readings` takes them.
    """
    time_s, p_w, q_w = (np.asarray(x, dtype=float) for x in (time_s, p_w, q_w))
    rate = _check(time_s, p_w, q_w, np.zeros(3))
    n = time_s.size
    arms = np.zeros((1, 3)) if lever_arms_m is None else np.asarray(lever_arms_m, dtype=float)
    if arms.ndim != 2 or arms.shape[0] < 1 or arms.shape[1] != 3 or not np.isfinite(arms).all():
        raise InputError(
            f"twin_readings: expected lever arms as (K, 3) finite numbers (m), got {np.shape(lever_arms_m)}"
        )
    names = tuple(BROAD_SENSOR if k == 0 else f"{BROAD_SENSOR}_{k}" for k in range(arms.shape[0]))
    placement = tuple(
        (name, (float(r[0]), float(r[1]), float(r[2])))
        for name, r in zip(names, arms, strict=True)
        if r.any()
    )
    for name, cutoff in (("orientation", cutoff_hz), ("position", position_cutoff_hz or cutoff_hz)):
        smoothing_window(rate, cutoff, n, f"twin_readings ({name})")  # the twin's own error message
    q = q_w / np.linalg.norm(q_w, axis=1, keepdims=True)
    pose = np.concatenate([p_w, q], axis=1)
    motion = RecordedMotion(
        source="twin_readings",
        frame_time_s=1.0 / rate,
        tracks=tuple(Track(name, "free", pose) for name in names),
        valid=np.ones(n, dtype=bool),
        format="poses",
    )
    config = SessionConfig(
        model=POSES_MODEL,
        motion="twin_readings: an optical pose",
        duration_s=n / rate,
        rate_hz=rate,
        sensors="ideal",
        placement=placement,
        motion_cutoff_hz=float(cutoff_hz),
        motion_position_cutoff_hz=None if position_cutoff_hz is None else float(position_cutoff_hz),
        recording=MotionSource(motion, POSES_MODEL, functools.partial(poses_spec, names, "twin")),
    )
    truth = run_session(config).truth.rigid
    return IdealReadings(
        acc=np.array(truth.acc), gyro=np.array(truth.gyro[:, 0]), R_w_s=quat_to_matrix(truth.q_w_s[:, 0])
    )


def twin_readings(
    time_s: np.ndarray,
    p_w: np.ndarray,
    q_w: np.ndarray,
    field_w: np.ndarray,
    cutoff_hz: float,
    *,
    position_cutoff_hz: float | None = None,
    lever_arm_m: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ideal accelerometer, gyroscope and magnetometer readings of a body moving as recorded.

    Args:
        time_s: ``(F,)`` uniformly spaced sample times, s.
        p_w: ``(F, 3)`` the tracked point's position in world (ENU), m; finite (:func:`fill_gaps`).
        q_w: ``(F, 4)`` the sensor's orientation ``R_w_s`` as scalar-first quaternions (the
            sensor frame to ENU); finite, not necessarily unit or sign-continuous.
        field_w: ``(3,)`` the magnetic field in world, uT; or ``(F, 3)``, at each sample.
        cutoff_hz: the smoothing's cutoff for the orientation, Hz (module docstring).
        position_cutoff_hz: the positions' cutoff, Hz (default ``cutoff_hz``).
        lever_arm_m: ``(3,)`` the accelerometer's position relative to the tracked point, in the
            sensor frame, m (default zero). Several at once: :func:`ideal_readings`.

    Returns:
        ``(acc, gyro, mag)``, each ``(F, 3)`` in the sensor frame: specific force m/s^2,
        angular velocity rad/s, field uT.

    Raises:
        InputError: shapes or values not as above, a cutoff the samples cannot be smoothed to.
    """
    time_s, p_w, q_w, field_w = (np.asarray(x, dtype=float) for x in (time_s, p_w, q_w, field_w))
    _check(time_s, p_w, q_w, field_w)
    arms = None
    if lever_arm_m is not None:
        r = np.asarray(lever_arm_m, dtype=float)
        if r.shape != (3,) or not np.isfinite(r).all():
            raise InputError(f"twin_readings: expected lever_arm_m as 3 finite numbers (m), got {r!r}")
        arms = r[None]
    got = ideal_readings(
        time_s, p_w, q_w, cutoff_hz, position_cutoff_hz=position_cutoff_hz, lever_arms_m=arms
    )
    return got.acc[:, 0], got.gyro, got.mag(field_w)


def gap_mask(p_w: np.ndarray, q_w: np.ndarray) -> np.ndarray:
    """``(F,)`` True where the pose is missing: a position or quaternion not finite, or a
    quaternion of zero."""
    p_w, q_w = np.asarray(p_w, dtype=float), np.asarray(q_w, dtype=float)
    ok = np.isfinite(p_w).all(axis=1) & np.isfinite(q_w).all(axis=1)
    ok[ok] &= np.linalg.norm(q_w[ok], axis=1) > 0
    return ~ok


def fill_gaps(p_w: np.ndarray, q_w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses with their gaps filled as the simulator fills a recording's
    (:func:`simbench.io.recorded.fill_gaps`: positions linearly, rotations by spherical
    interpolation, held at the ends).

    Args:
        p_w: ``(F, 3)`` m, NaN where missing. q_w: ``(F, 4)`` wxyz, NaN (or zero) where missing.

    Returns:
        ``(p_w, q_w, gap)``: filled copies (quaternions unit and sign-continuous) and the
        ``(F,)`` mask of the samples that were filled.

    Raises:
        InputError: fewer than 2 poses present.
    """
    gap = gap_mask(p_w, q_w)
    have = np.flatnonzero(~gap)
    if have.size < 2:
        raise InputError(f"expected at least 2 samples with an optical pose, got {have.size}")
    values = np.zeros((gap.size, 7))
    values[have, :3] = np.asarray(p_w, dtype=float)[have]
    q = np.asarray(q_w, dtype=float)[have]
    values[have, 3:] = q / np.linalg.norm(q, axis=1, keepdims=True)
    filled = fill_recorded_gaps(values, ~gap, slice(3, 7))
    return filled[:, :3], _continuous(filled[:, 3:]), gap


def near_gaps(gap: np.ndarray, half_window: int) -> np.ndarray:
    """``(F,)`` the gap samples and those within ``half_window`` frames of one."""
    gap = np.asarray(gap, dtype=bool)
    if half_window <= 0 or not gap.any():
        return gap.copy()
    kernel = np.ones(2 * half_window + 1)
    return np.convolve(gap.astype(float), kernel, mode="same") > 0.5
