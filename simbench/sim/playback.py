"""Kinematic playback of a recorded motion: the session's "physics" stage when a recording moves it.

The recorded motion (:class:`~simbench.io.recorded.RecordedMotion`: a BVH clip, a ``qpos``
series, OpenSim joint angles, rigid-body pose trajectories) is the truth, exactly: at every
capture sample ``qpos`` is set from the recording (each track's joint: a free joint's position and
quaternion, a ball joint's quaternion, a hinge's angle, a slide's displacement) and MuJoCo's
inverse dynamics (``mj_inverse``, with ``qvel`` and ``qacc`` given) computes the bodies and the
same sensors a physics session reads; the rows returned are those
:func:`simbench.sim.physics.run_physics` returns, so readings, skin, sensor models and the
Dataset are made as in any session.

**Velocities and accelerations** (what the gyroscopes and accelerometers feel) are not finite
differences of the recorded poses, which amplify their rounding and noise: every recorded signal
(positions, angles, each quaternion made sign-continuous) is smoothed by a
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

import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from simbench.errors import InputError
from simbench.io.recorded import RecordedMotion, Track
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
        motion: the recording.
        cutoff_hz: the smoothing's cutoff, Hz (rotations, and every coordinate when
            ``position_cutoff_hz`` is the same).
        window: the Savitzky-Golay window, frames (odd).
        time_s: ``(n,)`` the samples' times, s.
        frames: ``(n,)`` the clip's frame of each sample, or ``None`` when resampled.
        position_cutoff_hz: the cutoff of positions (a free joint's, a slide's), Hz: an
            acceleration is a position differentiated twice, which multiplies a recording's jitter
            by ``(2 pi f)^2``, while a rotation is differentiated once for the gyroscope.
        position_window: its window, frames (odd).
    """

    motion: RecordedMotion
    cutoff_hz: float
    window: int
    time_s: np.ndarray
    frames: np.ndarray | None
    position_cutoff_hz: float = DEFAULT_CUTOFF_HZ
    position_window: int = 0

    def as_dict(self) -> dict:
        """JSON-ready summary (the Dataset's metadata)."""
        return {
            "source": self.motion.source,
            "format": self.motion.format,
            "frames": self.motion.n_frames,
            "frames_filled": int(np.count_nonzero(~self.motion.valid)),
            "start_s": self.motion.start_s,
            "frame_time_s": self.motion.frame_time_s,
            "smoothing": "savitzky-golay",
            "cutoff_hz": self.cutoff_hz,
            "window_frames": self.window,
            "position_cutoff_hz": self.position_cutoff_hz,
            "position_window_frames": self.position_window,
            "polyorder": POLYORDER,
            "resampled": self.frames is None,
            "notes": list(self.motion.notes),
        }


def clip_rate_hz(motion: RecordedMotion) -> float:
    """The clip's frame rate, Hz."""
    return 1.0 / motion.frame_time_s


def same_rate(motion: RecordedMotion, rate_hz: float) -> bool:
    """``rate_hz`` is the clip's own (within :data:`SAME_RATE`)."""
    return abs(rate_hz * motion.frame_time_s - 1.0) <= SAME_RATE


def default_duration_s(motion: RecordedMotion, rate_hz: float) -> float:
    """The whole clip at ``rate_hz``: its last sample at or before the clip's last frame, s."""
    return (motion.n_frames - 1) * motion.frame_time_s + 1.0 / rate_hz


def savgol_window(rate_hz: float, cutoff_hz: float, n_frames: int, source: str = "") -> int:
    """The shortest odd window whose Savitzky-Golay smoothing (degree :data:`POLYORDER`) has a gain
    of at most ``1/sqrt(2)`` at ``cutoff_hz`` (its -3 dB point at or below the cutoff).

    Raises:
        InputError: a cutoff at or above the clip's Nyquist frequency, or a clip shorter than the window.
    """
    nyquist = rate_hz / 2
    if not (math.isfinite(cutoff_hz) and 0 < cutoff_hz < nyquist):
        raise InputError(
            f"{source}: a smoothing cutoff of {cutoff_hz:g} Hz: expected one above 0 and below the clip's "
            f"Nyquist frequency {nyquist:g} Hz"
        )

    window = _shortest_window(float(rate_hz), float(cutoff_hz), int(n_frames))
    if window < 0:
        raise InputError(
            f"{source}: {n_frames} frames are too few to smooth below {cutoff_hz:g} Hz at {rate_hz:g} Hz "
            "(a longer clip or a higher cutoff)"
        )
    return window


@functools.lru_cache(maxsize=64)
def _shortest_window(rate_hz: float, cutoff_hz: float, n_frames: int) -> int:
    """:func:`savgol_window`'s search (a bisection over the window, 0.3 s on long recordings:
    remembered), or -1 when even the longest window passes more than -3 dB at the cutoff."""
    from scipy.signal import savgol_coeffs  # scipy.signal: 0.6 s of every start of the command line

    def gain(window: int) -> float:
        c = savgol_coeffs(window, POLYORDER)
        k = np.arange(window) - window // 2
        return float(abs(np.sum(c * np.exp(-2j * np.pi * cutoff_hz / rate_hz * k))))

    lo, hi = POLYORDER // 2 + 1, max(POLYORDER // 2 + 1, (n_frames - 1) // 2)  # half-windows
    if gain(2 * hi + 1) > 1 / math.sqrt(2):
        return -1
    while lo < hi:  # the gain at a fixed frequency falls as the window grows
        mid = (lo + hi) // 2
        if gain(2 * mid + 1) <= 1 / math.sqrt(2):
            hi = mid
        else:
            lo = mid + 1
    return 2 * lo + 1


def plan_playback(
    motion: RecordedMotion,
    rate_hz: float,
    duration_s: float,
    cutoff_hz: float = DEFAULT_CUTOFF_HZ,
    position_cutoff_hz: float | None = None,
) -> Playback:
    """The samples of a playback session, checked against the clip (``position_cutoff_hz``:
    positions' own cutoff, default ``cutoff_hz``).

    Raises:
        InputError: a session longer than the clip, a rate not the clip's at or below twice the
            cutoff (it cannot be resampled), a cutoff the clip cannot be smoothed to.
    """
    source = motion.source
    fs = clip_rate_hz(motion)
    window = savgol_window(fs, cutoff_hz, motion.n_frames, source)
    pos_cutoff = cutoff_hz if position_cutoff_hz is None else position_cutoff_hz
    pos_window = window if pos_cutoff == cutoff_hz else savgol_window(fs, pos_cutoff, motion.n_frames, source)
    highest = max(cutoff_hz, pos_cutoff)  # resampling keeps content up to the higher one
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
    if not own and rate_hz <= 2 * highest:
        raise InputError(
            f"{source}: frame time {motion.frame_time_s:g} s ({fs:g} Hz) is not the rate {rate_hz:g} Hz, and "
            f"the motion smoothed below {highest:g} Hz cannot be resampled at or below twice that: give "
            f"a rate above {2 * highest:g} Hz, the clip's {fs:g} Hz, or a lower cutoff"
        )
    return Playback(
        motion,
        float(cutoff_hz),
        window,
        np.arange(n) * period,
        np.arange(n) if own else None,
        float(pos_cutoff),
        pos_window,
    )


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
class TrackState:
    """One track's coordinates at the samples (:class:`~simbench.io.recorded.Track`).

    Attributes:
        qpos: ``(n, w)`` the joint's ``qpos`` (quaternions normalised).
        qvel: ``(n, d)`` its ``qvel``: a free joint's linear velocity in world (m/s) then angular
            velocity in its own frame (rad/s); a ball joint's angular velocity in its own frame; a
            hinge's or slide's rate.
        qacc: ``(n, d)`` the derivative of ``qvel``.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    qacc: np.ndarray


def playback_state(playback: Playback, at_s: np.ndarray | None = None) -> list[TrackState]:
    """The poses, velocities and accelerations of the samples, one per track (module docstring);
    or of the smoothed motion at times ``at_s`` ``(n,)`` s (a sprung mount's integration steps)."""
    from scipy.signal import savgol_filter  # scipy.signal: 0.6 s of every start of the command line

    motion = playback.motion
    raw = []
    for track in motion.tracks:
        values = np.array(track.values, dtype=float)
        cols = track.quaternion_columns
        if cols is not None:
            values[:, cols] = _continuous(values[:, cols])
        raw.append(values)
    widths = np.cumsum([0] + [r.shape[1] for r in raw])
    raw_all = np.concatenate(raw, axis=1)
    positions = np.zeros(raw_all.shape[1], dtype=bool)  # a free joint's xyz, a slide's displacement
    for k, track in enumerate(motion.tracks):
        if track.kind == "free":
            positions[widths[k] : widths[k] + 3] = True
        elif track.kind == "slide":
            positions[widths[k]] = True
    smooth = [np.empty_like(raw_all) for _ in range(3)]
    for cols, window in (
        (~positions, playback.window),
        (positions, playback.position_window or playback.window),
    ):
        if cols.any():
            for d in range(3):
                smooth[d][:, cols] = savgol_filter(
                    raw_all[:, cols],
                    window,
                    POLYORDER,
                    deriv=d,
                    delta=motion.frame_time_s,
                    axis=0,
                    mode="interp",
                )
    if at_s is None and playback.frames is not None:
        at = [x[playback.frames] for x in smooth]
        pose = raw_all[playback.frames]
    else:
        at = _hermite5(*smooth, motion.frame_time_s, playback.time_s if at_s is None else at_s)
        pose = at[0]
    states = []
    for k, track in enumerate(motion.tracks):
        cols = slice(widths[k], widths[k + 1])
        qpos, d1, d2 = pose[:, cols].copy(), at[1][:, cols], at[2][:, cols]
        q = track.quaternion_columns
        if q is None:
            states.append(TrackState(qpos, d1.copy(), d2.copy()))
            continue
        omega, domega = angular_rates(at[0][:, cols][:, q], d1[:, q], d2[:, q])
        qpos[:, q] /= np.linalg.norm(qpos[:, q], axis=-1, keepdims=True)
        lin = slice(0, q.start)  # a free joint's position
        qvel = np.concatenate([d1[:, lin], omega], axis=1)
        states.append(TrackState(qpos, qvel, np.concatenate([d2[:, lin], domega], axis=1)))
    return states


def _generalised(
    cm: CaptureModel, playback: Playback, states: list[TrackState]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(qpos, qvel, qacc)`` of the whole model, ``(n, nq)``, ``(n, nv)``, ``(n, nv)``: the tracks'
    joints from ``states``, every other joint at ``qpos0`` and at rest."""
    m = cm.model
    n = states[0].qpos.shape[0]
    qpos = np.tile(m.qpos0, (n, 1))
    qvel = np.zeros((n, m.nv))
    qacc = np.zeros((n, m.nv))
    for track, state in zip(playback.motion.tracks, states, strict=True):
        jnt = joint_of(m, track, playback.motion.source, cm.source)
        q, v = int(m.jnt_qposadr[jnt]), int(m.jnt_dofadr[jnt])
        qpos[:, q : q + state.qpos.shape[1]] = state.qpos
        qvel[:, v : v + state.qvel.shape[1]] = state.qvel
        qacc[:, v : v + state.qacc.shape[1]] = state.qacc
    return qpos, qvel, qacc


def mount_coordinates(m: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """The sprung mounts' joints (``<body>:mount_*``): ``(in_qpos, dofs)``, a ``(nq,)`` bool mask of
    their ``qpos`` and their degrees of freedom ``(k,)`` int."""
    in_qpos = np.zeros(m.nq, dtype=bool)
    dofs: list[int] = []
    for j in range(m.njnt):
        if ":mount_" in (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or ""):
            kind = joint_kind(m, j)
            q, v = int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
            in_qpos[q : q + {"free": 7, "ball": 4}.get(kind, 1)] = True
            dofs.extend(range(v, v + {"free": 6, "ball": 3}.get(kind, 1)))
    return in_qpos, np.array(dofs, dtype=int)


def _spring_damper(m: mujoco.MjModel, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(k, c)``: each degree of freedom's spring stiffness and damping, ``(len(dofs),)``."""
    stiffness = np.zeros(m.nv)
    for j in range(m.njnt):
        v = int(m.jnt_dofadr[j])
        stiffness[v : v + {"free": 6, "ball": 3}.get(joint_kind(m, j), 1)] = m.jnt_stiffness[j]
    return stiffness[dofs], np.asarray(m.dof_damping[dofs], dtype=float)


def mount_substeps(m: mujoco.MjModel, dofs: np.ndarray, period_s: float) -> int:
    """Integration steps per sample for the mounts: at most the model's timestep and at most
    :data:`MOUNT_STEP_FRACTION` of ``1/omega`` of each spring with its own inertia (the diagonal of
    the mass matrix at the reference pose)."""
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    k, _ = _spring_damper(m, dofs)
    omega = float(np.sqrt(k / np.diag(M)[dofs]).max(initial=0.0))
    step = min(float(m.opt.timestep), MOUNT_STEP_FRACTION / omega if omega > 0 else np.inf)
    return max(1, math.ceil(period_s / step - 1e-9))


#: A mount's integration step, as a fraction of ``1/omega`` of its stiffest spring (the springs and
#: dampers implicit, so that the fast modes of a mount turning about an offset pivot stay stable).
MOUNT_STEP_FRACTION = 0.1


def _integrate_mounts(
    cm: CaptureModel, playback: Playback, mount_q: np.ndarray, dofs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mounts' ``qpos``, ``qvel`` and ``qacc`` at the samples: their springs driven by the
    played-back segments (whose accelerations are prescribed).

    With the segments' accelerations ``a_s`` given, the mounts' follow from the equations of motion
    partitioned: ``M_mm a_m = f_m - M_ms a_s``, ``f`` the passive (spring, damper) minus the bias
    (gravity, Coriolis) forces; the mounts have no constraints. Each step of ``h`` is implicit in
    the springs ``K`` and dampers ``D`` (as MuJoCo's implicit integrator):
    ``(M_mm + h D + h^2 K) a_m = f_m - M_ms a_s - h K v_m``, then ``v += h a``, ``q += h v``.
    """
    m = cm.model
    n = playback.time_s.size
    period = float(playback.time_s[1] - playback.time_s[0]) if n > 1 else 1.0
    k = mount_substeps(m, dofs, period)
    h = period / k
    fine_t = playback.time_s[0] + np.arange((n - 1) * k + 1) * h
    qpos_s, qvel_s, qacc_s = _generalised(cm, playback, playback_state(playback, fine_t))
    others = np.setdiff1d(np.arange(m.nv), dofs)
    stiff, damp = _spring_damper(m, dofs)
    implicit = h * np.diag(damp) + h * h * np.diag(stiff)
    d = mujoco.MjData(m)
    q_now = m.qpos0.copy()
    v_now = np.zeros(m.nv)
    M = np.zeros((m.nv, m.nv))
    out = (np.empty((n, m.nq)), np.empty((n, m.nv)), np.empty((n, m.nv)))
    for i in range(fine_t.size):
        q_now[~mount_q] = qpos_s[i, ~mount_q]
        v_now[others] = qvel_s[i, others]
        d.qpos[:], d.qvel[:] = q_now, v_now
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fwdVelocity(m, d)
        mujoco.mj_fullM(m, d, M)
        f = d.qfrc_passive[dofs] - d.qfrc_bias[dofs] - M[np.ix_(dofs, others)] @ qacc_s[i, others]
        a_m = np.linalg.solve(M[np.ix_(dofs, dofs)] + implicit, f - h * stiff * v_now[dofs])
        if i % k == 0:
            out[0][i // k], out[1][i // k] = q_now, v_now
            out[2][i // k, dofs] = a_m
        v_now[dofs] += h * a_m
        step = np.zeros(m.nv)
        step[dofs] = v_now[dofs]
        mujoco.mj_integratePos(m, q_now, step, h)
    return out[0][:, mount_q], out[1][:, dofs], out[2][:, dofs]


def run_playback(cm: CaptureModel, playback: Playback) -> tuple[np.ndarray, dict[str, int]]:
    """The session's sensor data played back from the recording (the rows of
    :func:`simbench.sim.physics.run_physics`). Sprung mounts on the segments move by physics,
    driven by the played-back motion (:func:`_integrate_mounts`).

    Returns:
        ``(sensordata, warnings)``: ``(n, nsensordata)`` MuJoCo's sensors at the samples, and
        ``{warning name: count}`` of MuJoCo's warnings.

    Raises:
        InputError: a track naming a joint the model does not have, or of another kind.
    """
    m = cm.model
    n = playback.time_s.size
    qpos, qvel, qacc = _generalised(cm, playback, playback_state(playback))
    mount_q, dofs = mount_coordinates(m)
    if dofs.size:
        qpos[:, mount_q], qvel[:, dofs], qacc[:, dofs] = _integrate_mounts(cm, playback, mount_q, dofs)
    d = mujoco.MjData(m)
    sensordata = np.empty((n, m.nsensordata))
    for i in range(n):
        d.time = playback.time_s[i]
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos[i], qvel[i], qacc[i]
        mujoco.mj_inverse(m, d)
        sensordata[i] = d.sensordata
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(d.warning) if w.number > 0}
    return sensordata, warnings


_KIND = {
    mujoco.mjtJoint.mjJNT_FREE: "free",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
}


def joint_kind(m: mujoco.MjModel, jnt: int) -> str:
    """``free``, ``ball``, ``hinge`` or ``slide``: the kind of joint ``jnt`` of ``m``."""
    return _KIND[mujoco.mjtJoint(int(m.jnt_type[jnt]))]


def joint_of(m: mujoco.MjModel, track: Track, source: str, model_source: str) -> int:
    """The id of the joint a track moves in ``m``.

    Raises:
        InputError: naming the recording, the model and its joints, when the joint is not there or
            not of the track's kind.
    """
    jnt = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, track.joint)
    if jnt < 0:
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
        raise InputError(
            f"{source}: joint {track.joint!r} is not in the model {model_source}; its joints: "
            f"{', '.join(str(x) for x in names)}"
        )
    kind = joint_kind(m, jnt)
    if kind != track.kind:
        raise InputError(
            f"{source}: joint {track.joint!r} is a {kind} joint in the model {model_source}, the recording "
            f"gives {track.kind} coordinates"
        )
    return jnt
