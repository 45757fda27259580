"""Kinematic playback of a recorded motion: the session's "physics" stage when a BVH clip moves it.

The recorded motion is the truth, exactly: at every capture sample ``qpos`` is set from the clip
(the root's free joint from its position and rotation, each ball joint from the quaternion of its
``R_parent_joint``) and MuJoCo's inverse dynamics (``mj_inverse``, with ``qvel`` and ``qacc``
given) computes the bodies and the same sensors a physics session reads; the rows returned are
those :func:`simbench.sim.physics.run_physics` returns, so readings, skin, sensor models and the
Dataset are made as in any session.

**Velocities and accelerations** (what the gyroscopes and accelerometers feel) are not finite
differences of the recorded poses, which amplify their rounding and noise: every recorded signal
(the root's position, each joint's quaternion made sign-continuous) is smoothed by a
Savitzky-Golay filter of degree :data:`POLYORDER` whose derivatives give the velocities and
accelerations (``scipy.signal.savgol_filter``). Its window is the shortest whose gain at the
cutoff (:data:`DEFAULT_CUTOFF_HZ` unless given) is at most ``1/sqrt(2)`` (-3 dB): the motion's
content below the cutoff passes, above it is removed. A joint's angular velocity in its own frame
is ``omega = 2 Im(conj(q) dq/dt) / |q|^2`` and its derivative ``2 Im(conj(q) d2q/dt2) / |q|^2 -
omega 2 (q . dq/dt) / |q|^2``, of the smoothed quaternion ``q``. The filter reproduces a
polynomial of degree 4 exactly; a rotation at a constant rate ``w`` (its quaternion's frequency
``w / 4 pi``) well below the cutoff comes out with a small gyroscope error, largest at the clip's
ends where the window is one-sided: rates of 1.6 rad/s at 100 Hz with the default cutoff, 2.9e-6
rad/s at the ends and 5.2e-7 rad/s a window away from them (``tests/test_bvh_session.py``; 1.7e-7
with a 12 Hz cutoff, 4.8e-5 with 3 Hz).

**Rates.** At the clip's own rate (or within :data:`SAME_RATE` of it) the samples are the clip's
frames and the poses the recorded ones, exactly. At another rate the *smoothed* motion is
resampled: between two frames each signal is the quintic that matches its smoothed value, first
and second derivatives at both (continuous accelerations); the quaternions are normalised for the
poses. The smoothed motion holds content up to the cutoff, so a rate must be above twice it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat
from simbench.errors import InputError
from simbench.io.bvh import BvhMotion
from simbench.sim.models import CaptureModel

#: The smoothing's default cutoff, Hz: 6 Hz, the usual low-pass of human movement kinematics
#: (Winter, Biomechanics and Motor Control of Human Movement, 4th ed. 2009, sec. 2.2.4.4).
DEFAULT_CUTOFF_HZ = 6.0

#: Degree of the Savitzky-Golay polynomials (accelerations are their second derivatives).
POLYORDER = 4

#: A capture rate within this fraction of the clip's is the clip's (a frame time written to four
#: significant digits, 0.008333 s, is 120 Hz).
SAME_RATE = 1e-3


@dataclass(frozen=True)
class Playback:
    """What a playback session plays, fixed when it is planned.

    Attributes:
        motion: the clip.
        cutoff_hz: the smoothing's cutoff, Hz.
        window: the Savitzky-Golay window, frames (odd).
        time_s: ``(n,)`` the samples' times, s.
        frames: ``(n,)`` the clip's frame of each sample, or ``None`` when resampled.
    """

    motion: BvhMotion
    cutoff_hz: float
    window: int
    time_s: np.ndarray
    frames: np.ndarray | None

    def as_dict(self) -> dict:
        """JSON-ready summary (the Dataset's metadata)."""
        return {
            "source": self.motion.source,
            "frames": self.motion.n_frames,
            "frame_time_s": self.motion.frame_time_s,
            "smoothing": "savitzky-golay",
            "cutoff_hz": self.cutoff_hz,
            "window_frames": self.window,
            "polyorder": POLYORDER,
            "resampled": self.frames is None,
        }


def clip_rate_hz(motion: BvhMotion) -> float:
    """The clip's frame rate, Hz."""
    return 1.0 / motion.frame_time_s


def same_rate(motion: BvhMotion, rate_hz: float) -> bool:
    """``rate_hz`` is the clip's own (within :data:`SAME_RATE`)."""
    return abs(rate_hz * motion.frame_time_s - 1.0) <= SAME_RATE


def default_duration_s(motion: BvhMotion, rate_hz: float) -> float:
    """The whole clip at ``rate_hz``: its last sample at or before the clip's last frame, s."""
    return (motion.n_frames - 1) * motion.frame_time_s + 1.0 / rate_hz


def savgol_window(rate_hz: float, cutoff_hz: float, n_frames: int, source: str = "") -> int:
    """The shortest odd window whose Savitzky-Golay smoothing (degree :data:`POLYORDER`) has a gain
    of at most ``1/sqrt(2)`` at ``cutoff_hz`` (its -3 dB point at or below the cutoff).

    Raises:
        InputError: a cutoff at or above the clip's Nyquist frequency, or a clip shorter than the window.
    """
    from scipy.signal import savgol_coeffs  # scipy.signal: 0.6 s of every start of the command line

    nyquist = rate_hz / 2
    if not (math.isfinite(cutoff_hz) and 0 < cutoff_hz < nyquist):
        raise InputError(
            f"{source}: a smoothing cutoff of {cutoff_hz:g} Hz: expected one above 0 and below the clip's "
            f"Nyquist frequency {nyquist:g} Hz"
        )

    def gain(window: int) -> float:
        c = savgol_coeffs(window, POLYORDER)
        k = np.arange(window) - window // 2
        return float(abs(np.sum(c * np.exp(-2j * np.pi * cutoff_hz / rate_hz * k))))

    lo, hi = POLYORDER // 2 + 1, max(POLYORDER // 2 + 1, (n_frames - 1) // 2)  # half-windows
    if gain(2 * hi + 1) > 1 / math.sqrt(2):
        raise InputError(
            f"{source}: {n_frames} frames are too few to smooth below {cutoff_hz:g} Hz at {rate_hz:g} Hz "
            "(a longer clip or a higher cutoff)"
        )
    while lo < hi:  # the gain at a fixed frequency falls as the window grows
        mid = (lo + hi) // 2
        if gain(2 * mid + 1) <= 1 / math.sqrt(2):
            hi = mid
        else:
            lo = mid + 1
    return 2 * lo + 1


def plan_playback(
    motion: BvhMotion, rate_hz: float, duration_s: float, cutoff_hz: float = DEFAULT_CUTOFF_HZ
) -> Playback:
    """The samples of a playback session, checked against the clip.

    Raises:
        InputError: a session longer than the clip, a rate not the clip's at or below twice the
            cutoff (it cannot be resampled), a cutoff the clip cannot be smoothed to.
    """
    source = motion.source
    fs = clip_rate_hz(motion)
    window = savgol_window(fs, cutoff_hz, motion.n_frames, source)
    own = same_rate(motion, rate_hz)
    n = math.floor(duration_s * rate_hz + 1e-9)
    period = motion.frame_time_s if own else 1.0 / rate_hz
    last = (motion.n_frames - 1) * motion.frame_time_s
    if (n - 1) * period > last * (1 + 1e-9) + 1e-12:
        raise InputError(
            f"{source}: the clip lasts {motion.n_frames} frames at {fs:g} Hz (its last at {last:g} s); a "
            f"session of {duration_s:g} s at {rate_hz:g} Hz needs samples up to {(n - 1) * period:g} s "
            f"(at most {default_duration_s(motion, rate_hz):g} s)"
        )
    if not own and rate_hz <= 2 * cutoff_hz:
        raise InputError(
            f"{source}: frame time {motion.frame_time_s:g} s ({fs:g} Hz) is not the rate {rate_hz:g} Hz, and "
            f"the motion smoothed below {cutoff_hz:g} Hz cannot be resampled at or below twice that: give "
            f"a rate above {2 * cutoff_hz:g} Hz, the clip's {fs:g} Hz, or a lower cutoff"
        )
    return Playback(motion, float(cutoff_hz), window, np.arange(n) * period, np.arange(n) if own else None)


def _continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(F, ..., 4)`` with signs flipped so that neighbours are on one hemisphere."""
    q = q.copy()
    flip = np.sum(q[1:] * q[:-1], axis=-1) < 0
    sign = np.where(np.cumsum(flip, axis=0) % 2 == 1, -1.0, 1.0)
    q[1:] *= sign[..., None]
    return q


def _im_conj_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``Im(conj(a) b)`` of quaternions ``(..., 4)`` wxyz: ``a_w b_v - b_w a_v - a_v x b_v``."""
    return a[..., :1] * b[..., 1:] - b[..., :1] * a[..., 1:] - np.cross(a[..., 1:], b[..., 1:])


def angular_rates(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(omega, domega/dt)`` in the rotating frame, from a (not necessarily unit) quaternion and its
    first and second time derivatives, ``(..., 4)`` each (module docstring)."""
    n2 = np.sum(q * q, axis=-1, keepdims=True)
    omega = 2 * _im_conj_mul(q, dq) / n2
    domega = 2 * _im_conj_mul(q, ddq) / n2 - omega * 2 * np.sum(q * dq, axis=-1, keepdims=True) / n2
    return omega, domega


def _hermite5(y: np.ndarray, dy: np.ndarray, ddy: np.ndarray, h: float, t: np.ndarray) -> list[np.ndarray]:
    """Value, first and second derivative at ``t`` ``(n,)`` s of the quintic through frames ``h``
    apart matching ``y``, ``dy``, ``ddy`` ``(F, C)`` at both ends of each interval."""
    i = np.clip(np.floor(t / h).astype(int), 0, y.shape[0] - 2)
    s = np.clip(t / h - i, 0.0, 1.0)
    # rows: the bases of y0, h y0', h^2 y0'', h^2 y1'', h y1', y1; columns: powers s^0..s^5
    B = np.array(
        [
            [1, 0, 0, -10, 15, -6],
            [0, 1, 0, -6, 8, -3],
            [0, 0, 0.5, -1.5, 1.5, -0.5],
            [0, 0, 0, 0.5, -1, 0.5],
            [0, 0, 0, -4, 7, -3],
            [0, 0, 0, 10, -15, 6],
        ]
    )
    powers = np.arange(6)
    P = [s[:, None] ** powers, np.zeros((s.size, 6)), np.zeros((s.size, 6))]
    P[1][:, 1:] = powers[1:] * s[:, None] ** powers[:-1]
    P[2][:, 2:] = powers[2:] * powers[1:-1] * s[:, None] ** powers[:-2]
    ends = [y[i], h * dy[i], h * h * ddy[i], h * h * ddy[i + 1], h * dy[i + 1], y[i + 1]]
    return [sum((p @ B.T)[:, b, None] * ends[b] for b in range(6)) / h**d for d, p in enumerate(P)]


@dataclass(frozen=True)
class PlaybackState:
    """The clip's generalised coordinates at the samples.

    Attributes:
        root_pos, root_vel, root_acc: ``(n, 3)`` the root's position (m), velocity (m/s) and
            acceleration (m/s^2) in world.
        quat: ``(n, J, 4)`` each joint's quaternion, wxyz (the root's: world; the others': in the parent).
        omega, domega: ``(n, J, 3)`` each joint's angular velocity (rad/s) and acceleration
            (rad/s^2) in its own frame.
    """

    root_pos: np.ndarray
    root_vel: np.ndarray
    root_acc: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    domega: np.ndarray


def playback_state(playback: Playback) -> PlaybackState:
    """The poses, velocities and accelerations of the samples (module docstring)."""
    from scipy.signal import savgol_filter  # scipy.signal: 0.6 s of every start of the command line

    motion = playback.motion
    f, j = motion.n_frames, len(motion.names)
    root = motion.offset_m[0] + motion.translation_m[:, 0]
    quat = _continuous(matrix_to_quat(motion.R_parent_joint))
    raw = np.concatenate([root, quat.reshape(f, -1)], axis=1)
    smooth = [
        savgol_filter(
            raw, playback.window, POLYORDER, deriv=d, delta=motion.frame_time_s, axis=0, mode="interp"
        )
        for d in range(3)
    ]
    if playback.frames is not None:
        at = [x[playback.frames] for x in smooth]
        pose = raw[playback.frames]
    else:
        at = _hermite5(*smooth, motion.frame_time_s, playback.time_s)
        pose = at[0]
    n = playback.time_s.size
    q = [x[:, 3:].reshape(n, j, 4) for x in at]
    omega, domega = angular_rates(*q)
    quat = pose[:, 3:].reshape(n, j, 4)
    return PlaybackState(
        root_pos=pose[:, :3],
        root_vel=at[1][:, :3],
        root_acc=at[2][:, :3],
        quat=quat / np.linalg.norm(quat, axis=-1, keepdims=True),
        omega=omega,
        domega=domega,
    )


def run_playback(cm: CaptureModel, playback: Playback) -> tuple[np.ndarray, dict[str, int]]:
    """The session's sensor data played back from the clip (the rows of
    :func:`simbench.sim.physics.run_physics`).

    Returns:
        ``(sensordata, warnings)``: ``(n, nsensordata)`` MuJoCo's sensors at the samples, and
        ``{warning name: count}`` of MuJoCo's warnings.
    """
    m = cm.model
    state = playback_state(playback)
    n = playback.time_s.size
    qpos = np.tile(m.qpos0, (n, 1))
    qvel = np.zeros((n, m.nv))
    qacc = np.zeros((n, m.nv))
    for k, name in enumerate(playback.motion.names):
        jnt = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        q, v = int(m.jnt_qposadr[jnt]), int(m.jnt_dofadr[jnt])
        if k == 0:  # the free root: position and linear rates in world, angular in its own frame
            qpos[:, q : q + 3], qvel[:, v : v + 3], qacc[:, v : v + 3] = (
                state.root_pos,
                state.root_vel,
                state.root_acc,
            )
            q, v = q + 3, v + 3
        qpos[:, q : q + 4] = state.quat[:, k]
        qvel[:, v : v + 3] = state.omega[:, k]
        qacc[:, v : v + 3] = state.domega[:, k]
    d = mujoco.MjData(m)
    sensordata = np.empty((n, m.nsensordata))
    for i in range(n):
        d.time = playback.time_s[i]
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[i], qvel[i], qacc[i]
        mujoco.mj_inverse(m, d)
        sensordata[i] = d.sensordata
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(d.warning) if w.number > 0}
    return sensordata, warnings
