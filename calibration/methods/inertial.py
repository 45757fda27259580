"""Joint position and hinge axis from gyroscopes and accelerometers alone (Seel et al.).

References: T. Seel, T. Schauer, J. Raisch, "Joint axis and position estimation from inertial
measurement data by exploiting kinematic constraints", 2012 IEEE International Conference on
Control Applications (CCA), Dubrovnik, 45-49; T. Seel, J. Raisch, T. Schauer, "IMU-based joint
angle measurement for gait analysis", Sensors 14 (2014) 6891-6909.

Two inertial sensors, a parent ``p`` and a child ``c``, sit on the two segments of a joint. No
pose is used: each sensor gives its angular velocity ``w`` (rad/s) and specific force ``f``
(m/s^2), both in its own frame, at every sample; the angular acceleration ``dw`` (rad/s^2) is
given or taken from ``w`` by Seel's five-point central difference (:func:`angular_acceleration`).

**Joint position.** A point at ``o`` in a sensor's frame (metres) has specific force
``f + Gamma_w(o)`` in that frame, with ``Gamma_w(o) = w x (w x o) + dw x o`` (the centripetal
and tangential terms). The joint centre is one point of both segments, and its specific force
has the same length in both frames, so ``o_p`` and ``o_c`` minimise (Seel et al. 2012; 2014)::

    sum_f ( |f_p[f] + Gamma_{w_p[f]}(o_p)| - |f_c[f] + Gamma_{w_c[f]}(o_c)| )^2

solved here by :func:`scipy.optimize.least_squares` (Levenberg-Marquardt, analytic Jacobian).

**Sign convention (read this before comparing with the papers).** Here ``f = R_w_s^T (a - g)``
is the specific force (an accelerometer at rest reads ``+9.81`` m/s^2 along up; ``g`` points
down) and ``o`` is the joint centre's position in the sensor frame, from the sensor to the joint
(``joint_in_parent`` and ``joint_in_child`` of the project's conventions); with these, the joint's
specific force is ``f + Gamma(o)``. The papers write ``a - Gamma(o)``, the same equation with
``o`` measured the other way (from the joint to the sensor): their ``o`` is the negative of ours.

**Hinge joints.** Every point of a hinge's axis satisfies the constraint, so the cost is flat
along ``[j_p; j_c]`` (the axis in both frames) and the solver stops anywhere on that line. Given
the axis, Seel et al. (2014) shift the solution to the point closest to both sensors,
``o_i <- o_i - j_i (o_p . j_p + o_c . j_c) / 2``: the minimum-norm point, O'Brien's choice too;
the fit is then refined with that direction held out. The axis comes from the gyroscopes alone
(:func:`seel_joint_axis`, Seel et al. 2012; 2014): ``|w_p x j_p| = |w_c x j_c|`` at
every sample, fitted on spherical coordinates. Each axis's sign is undetermined by the gyroscopes
(the cost is even in ``j_p`` and in ``j_c`` separately); the *relative* sign the shift needs is
taken from the accelerometer cost, as the direction ``[j_p; +-j_c]`` along which it is flat.

**Caveats.** The cost is not convex: a poor start can end in a local minimum (the default
start is both sensors' origins; :attr:`InertialFit.rms_residual_mps2` near the
sensors' noise says a fit is the global one). Gyroscope noise enters the regressors
``Gamma`` (errors in variables), the finite-difference ``dw`` amplifying it by about the sample
rate: the centre is pulled towards the sensor by a bias that more samples do not remove (in the
tests' motions, 0.01 rad/s of gyroscope noise at 100 Hz shortens ``|o|`` by 0.3-4 mm, while
0.05 m/s^2 of accelerometer noise alone costs a fraction of a millimetre); low-pass filter ``w``
(zero phase) before differentiating, or give ``dw``. Without relative rotation (or without
rotation at all) the position is undetermined: :class:`CalibrationError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import LOCATED_RANK
from calibration.methods.score import check_finite, check_valid
from calibration.rotations import skew

#: Fewest used samples the inertial fits accept (six unknowns, and noise to average).
MIN_FRAMES = 10

#: Directions of the position whose Jacobian singular value is below this fraction of the
#: largest are undetermined (noise-free data give about 1e-12 along a hinge's axis).
RANK_RATIO = 1e-6

#: Starting directions of the axis fit, as spherical coordinates ``(phi, theta)`` (rad): the
#: three coordinate axes, tilted off the pole of the parametrisation; every pair is tried.
AXIS_STARTS = ((0.0, 0.0), (0.0, np.pi / 2), (1.2, 0.3))

_TOL = {"xtol": 1e-15, "ftol": 1e-15, "gtol": 1e-15}


def angular_acceleration(w: np.ndarray, rate_hz: float) -> np.ndarray:
    """Angular acceleration by Seel's five-point central difference (fourth order).

    ``dw[t] = (w[t-2] - 8 w[t-1] + 8 w[t+1] - w[t+2]) / (12 dt)``

    Args:
        w: ``(frames, 3)`` angular velocity, rad/s, sampled uniformly.
        rate_hz: sample rate, Hz.

    Returns:
        ``(frames, 3)`` angular acceleration, rad/s^2; NaN at the first and last two frames.
    """
    w = np.asarray(w, dtype=float)
    out = np.full(w.shape, np.nan)
    if w.shape[0] >= 5:
        out[2:-2] = (w[:-4] - 8.0 * w[1:-3] + 8.0 * w[3:-1] - w[4:]) * (rate_hz / 12.0)
    return out


def _as_frames3(name: str, a: np.ndarray, n: int | None) -> np.ndarray:
    try:
        x = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise CalibrationInputError(f"Expected {name} to be a numeric array, got {type(a).__name__}") from exc
    if x.ndim != 2 or x.shape[1] != 3:
        raise CalibrationInputError(f"Expected {name} to have shape (frames, 3), got {x.shape}")
    if n is not None and x.shape[0] != n:
        raise CalibrationInputError(f"Expected {name} to have {n} frames like w_p, got {x.shape[0]}")
    return x


def _unit(name: str, a: np.ndarray) -> np.ndarray:
    x = np.asarray(a, dtype=float)
    if x.shape != (3,) or not np.isfinite(x).all() or np.linalg.norm(x) == 0.0:
        raise CalibrationInputError(f"Expected {name} to be a finite non-zero (3,) vector, got {x!r}")
    return x / np.linalg.norm(x)


def _require_frames(used: np.ndarray) -> int:
    n = int(np.count_nonzero(used))
    if n < MIN_FRAMES:
        raise CalibrationInputError(f"Expected at least {MIN_FRAMES} used samples, got {n}")
    return n


def _fix_sign(axis_p: np.ndarray, axis_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both axes flipped together so that the parent axis's largest component is positive."""
    if axis_p[np.argmax(np.abs(axis_p))] < 0.0:
        return -axis_p, -axis_c
    return axis_p, axis_c


def _positive(axis: np.ndarray) -> np.ndarray:
    """The axis with its largest component positive (a sign the data leave free)."""
    return -axis if axis[np.argmax(np.abs(axis))] < 0.0 else axis


def _spherical(phi: float, theta: float) -> np.ndarray:
    return np.array([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)])


@dataclass(frozen=True)
class InertialAxis:
    """A hinge axis found from two gyroscopes (Seel et al. 2012; 2014).

    Attributes:
        axis_in_parent: ``(3,)`` unit axis in the parent sensor's frame, largest component positive.
        axis_in_child: ``(3,)`` unit axis in the child sensor's frame, largest component positive.
            The gyroscopes do not fix its sign relative to ``axis_in_parent``
            (:func:`seel_joint_position` fixes it from the accelerometers).
        rms_residual_rad_s: rms of ``|w_p x j_p| - |w_c x j_c|`` over the used samples, rad/s.
        n_frames: samples used.
    """

    axis_in_parent: np.ndarray
    axis_in_child: np.ndarray
    rms_residual_rad_s: float
    n_frames: int


def seel_joint_axis(w_p: np.ndarray, w_c: np.ndarray, *, valid: np.ndarray | None = None) -> InertialAxis:
    """A hinge's axis in both sensor frames from the gyroscopes alone (Seel et al. 2012; 2014).

    Minimises ``sum_f (|w_p[f] x j_p| - |w_c[f] x j_c|)^2`` over unit ``j_p``, ``j_c`` on spherical
    coordinates, from every pair of :data:`AXIS_STARTS`, keeping the best.

    Args:
        w_p: ``(frames, 3)`` parent sensor angular velocity in its own frame, rad/s.
        w_c: ``(frames, 3)`` child sensor angular velocity in its own frame, rad/s.
        valid: optional ``(frames,)`` bool; samples marked False are not used (and may hold NaN).

    Returns:
        The axis in both frames (each sign fixed by its largest component), and the residual.

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used sample, too few samples.
        CalibrationError: the sensors do not rotate.
    """
    w_p = _as_frames3("w_p", w_p, None)
    w_c = _as_frames3("w_c", w_c, w_p.shape[0])
    used = check_valid(valid, w_p.shape[0])
    check_finite("w_p", w_p, used)
    check_finite("w_c", w_c, used)
    _require_frames(used)
    wp, wc = w_p[used], w_c[used]
    if not (np.any(wp) and np.any(wc)):
        raise CalibrationError(
            "The joint axis needs both sensors to rotate: a gyroscope reads zero throughout"
        )
    Kp, Kc = skew(wp), skew(wc)

    def residual(x: np.ndarray) -> np.ndarray:
        up = np.cross(wp, _spherical(x[0], x[1]))
        uc = np.cross(wc, _spherical(x[2], x[3]))
        return np.linalg.norm(up, axis=1) - np.linalg.norm(uc, axis=1)

    def jacobian(x: np.ndarray) -> np.ndarray:
        J = np.empty((wp.shape[0], 4))
        for col, (K, phi, theta, sign) in enumerate(((Kp, x[0], x[1], 1.0), (Kc, x[2], x[3], -1.0))):
            u = K @ _spherical(phi, theta)
            n = np.maximum(np.linalg.norm(u, axis=1), np.finfo(float).tiny)
            g = np.einsum("fi,fij->fj", u / n[:, None], K)  # d|w x j| / dj
            d_phi = np.array([-np.sin(phi) * np.cos(theta), -np.sin(phi) * np.sin(theta), np.cos(phi)])
            d_theta = np.array([-np.cos(phi) * np.sin(theta), np.cos(phi) * np.cos(theta), 0.0])
            J[:, 2 * col] = sign * (g @ d_phi)
            J[:, 2 * col + 1] = sign * (g @ d_theta)
        return J

    best = None
    for sp in AXIS_STARTS:
        for sc in AXIS_STARTS:
            sol = least_squares(residual, np.array([*sp, *sc]), jac=jacobian, method="lm", **_TOL)
            if best is None or sol.cost < best.cost:
                best = sol
    assert best is not None  # AXIS_STARTS is not empty
    j_p = _spherical(best.x[0], best.x[1])
    j_c = _spherical(best.x[2], best.x[3])
    j_p, j_c = _positive(j_p), _positive(j_c)
    return InertialAxis(j_p, j_c, float(np.sqrt(2.0 * best.cost / wp.shape[0])), int(wp.shape[0]))


@dataclass(frozen=True)
class InertialFit:
    """The joint position Seel's method found in both sensor frames.

    Attributes:
        joint_in_parent: ``(3,)`` joint centre in the parent sensor's frame (from the sensor to the
            joint), metres.
        joint_in_child: ``(3,)`` joint centre in the child sensor's frame, metres.
        rms_residual_mps2: rms over used samples of the difference of the joint's specific-force
            lengths in the two frames, m/s^2.
        frame_residual_mps2: ``(frames,)`` that difference per sample, m/s^2; NaN where unused.
        singular_values: ``(6,)`` singular values of the cost's Jacobian at the solution (before
            any hinge shift), descending, 1/s^2 (m/s^2 per metre).
        rank: directions the motion determines (:data:`RANK_RATIO`): 6 for a ball joint, 5 for a
            hinge.
        axis_in_parent: ``(3,)`` unit hinge axis in the parent frame when a hinge axis was given,
            else ``None``; sign as :func:`calibration.joint.read_spectrum`.
        axis_in_child: ``(3,)`` the same axis in the child frame, sign consistent with the parent's
            (the cost is flat along ``[axis_in_parent; axis_in_child]``), or ``None``.
        n_frames: samples used.
        nfev: cost evaluations of the solver.
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    rms_residual_mps2: float
    frame_residual_mps2: np.ndarray
    singular_values: np.ndarray
    rank: int
    axis_in_parent: np.ndarray | None
    axis_in_child: np.ndarray | None
    n_frames: int
    nfev: int


def seel_joint_position(
    w_p: np.ndarray,
    w_c: np.ndarray,
    f_p: np.ndarray,
    f_c: np.ndarray,
    *,
    rate_hz: float | None = None,
    dw_p: np.ndarray | None = None,
    dw_c: np.ndarray | None = None,
    hinge_axes: tuple[np.ndarray, np.ndarray] | None = None,
    start: np.ndarray | None = None,
    valid: np.ndarray | None = None,
) -> InertialFit:
    """The joint centre in both sensor frames from inertial data alone (Seel et al. 2012; 2014).

    Args:
        w_p: ``(frames, 3)`` parent sensor angular velocity in its own frame, rad/s.
        w_c: ``(frames, 3)`` child sensor angular velocity in its own frame, rad/s.
        f_p: ``(frames, 3)`` parent sensor specific force in its own frame (reads +9.81 m/s^2
            along up at rest), m/s^2.
        f_c: ``(frames, 3)`` child sensor specific force in its own frame, m/s^2.
        rate_hz: sample rate, Hz; needed (and only used) when ``dw_p``/``dw_c`` are not given,
            to differentiate ``w`` (:func:`angular_acceleration`, whose two edge samples at each
            end are then not used).
        dw_p: optional ``(frames, 3)`` parent angular acceleration, rad/s^2 (with ``dw_c``).
        dw_c: optional ``(frames, 3)`` child angular acceleration, rad/s^2 (with ``dw_p``).
        hinge_axes: optional ``(axis_in_parent, axis_in_child)``, each ``(3,)`` (normalised here;
            signs free, e.g. from :func:`seel_joint_axis`): shift the centre along the axis to the
            point closest to both sensors and refine with the axis held out (module docstring).
        start: optional ``(6,)`` ``[o_p; o_c]`` to start from, metres; default zeros.
        valid: optional ``(frames,)`` bool; samples marked False are not used (and may hold NaN).

    Returns:
        The centre in both frames, residuals, the Jacobian's singular values and rank, and the
        hinge axis (sign-consistent) when one was given.

    Raises:
        CalibrationInputError: malformed arrays or options, NaN in a used sample, too few samples,
            neither ``rate_hz`` nor both ``dw_p`` and ``dw_c``.
        CalibrationError: the sensors do not rotate, or not relative to each other (fewer than
            five directions determined); the solver failed.
    """
    w_p = _as_frames3("w_p", w_p, None)
    n_total = w_p.shape[0]
    w_c = _as_frames3("w_c", w_c, n_total)
    f_p = _as_frames3("f_p", f_p, n_total)
    f_c = _as_frames3("f_c", f_c, n_total)
    used = check_valid(valid, n_total).copy()
    if (dw_p is None) != (dw_c is None):
        raise CalibrationInputError("Expected both dw_p and dw_c or neither, got only one")
    if dw_p is None or dw_c is None:
        if rate_hz is None or not np.isfinite(rate_hz) or rate_hz <= 0.0:
            raise CalibrationInputError(
                f"Expected rate_hz > 0 to differentiate w (or dw_p and dw_c given), got {rate_hz}"
            )
        dw_p, dw_c = angular_acceleration(w_p, rate_hz), angular_acceleration(w_c, rate_hz)
        used[:2] = used[-2:] = False  # the stencil's edges
    else:
        dw_p = _as_frames3("dw_p", dw_p, n_total)
        dw_c = _as_frames3("dw_c", dw_c, n_total)
    for name, a in (("w_p", w_p), ("w_c", w_c), ("f_p", f_p), ("f_c", f_c), ("dw_p", dw_p), ("dw_c", dw_c)):
        check_finite(name, a, used)
    n = _require_frames(used)
    x0 = np.zeros(6)
    if start is not None:
        x0 = np.asarray(start, dtype=float)
        if x0.shape != (6,) or not np.isfinite(x0).all():
            raise CalibrationInputError(
                f"Expected start to be a finite (6,) [o_p; o_c], got shape {x0.shape}"
            )
    axes = None
    if hinge_axes is not None:
        if len(hinge_axes) != 2:
            raise CalibrationInputError(
                f"Expected hinge_axes to be (axis_in_parent, axis_in_child), got {hinge_axes!r}"
            )
        axes = (_unit("hinge_axes[0]", hinge_axes[0]), _unit("hinge_axes[1]", hinge_axes[1]))
    if not (np.any(w_p[used]) and np.any(w_c[used])):
        raise CalibrationError(
            "The joint position needs both sensors to rotate: a gyroscope reads zero throughout"
        )

    Kp, Kc = skew(w_p[used]), skew(w_c[used])
    Gp = Kp @ Kp + skew(dw_p[used])  # Gamma_w(o) = G o
    Gc = Kc @ Kc + skew(dw_c[used])
    fp, fc = f_p[used], f_c[used]

    def parts(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        jp = fp + Gp @ x[:3]
        jc = fc + Gc @ x[3:]
        return jp, np.linalg.norm(jp, axis=1), jc, np.linalg.norm(jc, axis=1)

    def residual(x: np.ndarray) -> np.ndarray:
        _, np_, _, nc = parts(x)
        return np_ - nc

    def jacobian(x: np.ndarray) -> np.ndarray:
        jp, np_, jc, nc = parts(x)
        tiny = np.finfo(float).tiny
        J = np.empty((n, 6))
        J[:, :3] = np.einsum("fi,fij->fj", jp / np.maximum(np_, tiny)[:, None], Gp)
        J[:, 3:] = -np.einsum("fi,fij->fj", jc / np.maximum(nc, tiny)[:, None], Gc)
        return J

    sol = least_squares(residual, x0, jac=jacobian, method="lm", **_TOL)
    if sol.status <= 0 or not np.isfinite(sol.x).all():
        raise CalibrationError(f"The inertial joint fit did not converge: {sol.message}")
    x, nfev = sol.x, int(sol.nfev)
    J = jacobian(x)
    s = np.linalg.svd(J, compute_uv=False)
    rank = int(np.count_nonzero(s >= RANK_RATIO * s[0])) if s[0] > 0 else 0
    if rank < LOCATED_RANK:
        raise CalibrationError(
            f"The inertial joint fit needs the sensors to rotate relative to each other: the motion "
            f"determines {rank} of the 6 coordinates (needs 5; s_5/s_max = {s[4] / max(s[0], 1e-300):.2e}, "
            f"floor {RANK_RATIO:.0e})"
        )
    axis_p = axis_c = None
    if axes is not None:
        axis_p, axis_c = axes
        if np.linalg.norm(J @ np.concatenate([axis_p, -axis_c])) < np.linalg.norm(
            J @ np.concatenate([axis_p, axis_c])
        ):
            axis_c = -axis_c  # the cost is flat along [j_p; j_c] with the consistent sign
        axis_p, axis_c = _fix_sign(axis_p, axis_c)
        v = np.concatenate([axis_p, axis_c]) / np.sqrt(2.0)
        x = x - v * (v @ x)  # Seel 2014: o_i - j_i (o_p . j_p + o_c . j_c) / 2
        basis = np.linalg.svd(np.eye(6) - np.outer(v, v))[0][:, :5]  # the complement of v
        sub = least_squares(
            lambda y: residual(x + basis @ y),
            np.zeros(5),
            jac=lambda y: jacobian(x + basis @ y) @ basis,
            method="lm",
            **_TOL,
        )
        x, nfev = x + basis @ sub.x, nfev + int(sub.nfev)
    frame_residual = np.full(n_total, np.nan)
    frame_residual[used] = residual(x)
    return InertialFit(
        joint_in_parent=x[:3].copy(),
        joint_in_child=x[3:].copy(),
        rms_residual_mps2=float(np.sqrt(np.mean(frame_residual[used] ** 2))),
        frame_residual_mps2=frame_residual,
        singular_values=s,
        rank=rank,
        axis_in_parent=axis_p,
        axis_in_child=axis_c,
        n_frames=n,
        nfev=nfev,
    )
