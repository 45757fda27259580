"""The acceleration that rotation itself makes at a sensor away from the centre of rotation.

A sensor held at a lever ``r`` from the centre of a body that turns at ``w`` feels, besides
gravity, ``w x (w x r) + dw/dt x r``: centripetal, towards the centre, fixed in the *sensor*
frame while the rotation is steady (a stick swung round at 5 rad/s with the IMU 20 cm from the
wrist: 5 m/s^2 for seconds on end). A hand cannot accelerate one way for seconds in the world
frame, so the world-frame priors of the gyro-free estimators (a lone sensor's speed prior, a
root's white acceleration) do not see it and take it as tilt (issue 43: the default was worse
than a per-sample two-vector fix).

**The model.** Over a window of :data:`WINDOW_S` the accelerometer reads
``a(t) = c + R(t)^T g up + e(t)``: a constant sensor-frame acceleration ``c`` plus gravity, ``e``
the rest of the motion. Two facts hold whatever the orientation, each linear in ``c`` at every
sample:

- the sphere: ``|a - c| = g``, i.e. ``2 a . c - u = |a|^2 - g^2`` with ``u = |c|^2`` taken as a
  free unknown (so the radius is free and the accelerometer's scale does not enter);
- the dip: the angle between gravity and the Earth field is the field's,
  ``(a - c) . m_hat = -g sin I`` with ``m_hat`` the magnetometer's direction.

Both are residuals in m/s^2 (the sphere's divided by ``2 g``: ``|a - c| - g`` to first order).
While the sensor turns, the samples' directions cover the sphere and ``c`` is determined; still,
or turning about the vertical only, it is not (and the test below does not fire).

**Determined.** A window is used only where the readings can tell ``c`` from tilt and from the
rest of the motion: the field's direction turns through a full turn (:data:`TURN_STEP_S`,
:func:`field_turn`; before a full turn a constant in the sensor frame is also one in the world
over part of a turn, which a hand makes), the accelerometer's readings spread over a circle
beyond their white noise (:func:`noise_variance`, chi-square at :data:`FALSE_ALARM`) and, after
the fit, beyond the sphere's residual variance (an F-test at :data:`DETERMINATION` with the
residuals' effective number of samples: hand accelerations spread the readings too, and a fit
of an arc they made is biased); and the field has no sustained offset of its own there (the
same sphere test on the magnetometer: a magnet carried with the sensor that the calibration left
breaks the dip).

**The test.** ``c`` is fitted by Gauss-Newton from zero, each kind of residual weighted by its
own robust scale (1.4826 MAD). Its covariance is the least-squares one times the residuals'
long-run variance factor (``1 + 2 sum rho_k``, the lag autocorrelations summed until the first
that is not positive: the rest of the motion is correlated, not white). ``c^T Cov^-1 c`` is
chi-square with 3 degrees of freedom without a sustained acceleration; a window beyond its
``1 - FALSE_ALARM`` quantile fires. A lever fixed in the sensor and a rotation about a steady
axis make ``c`` point one way all along: the windows that fire are kept only when their
directions share one (Rayleigh's test, :func:`consistent`). The gravity and the field's dip
(:func:`calibration.orientation.reference_from_data`) are themselves biased by the acceleration
(medians of ``|a|`` and of the dip, 11.1 m/s^2 and 58 degrees on the swung stick): they are
taken again from the corrected readings and the fit repeated (:data:`ITERATIONS` times).

**The correction.** The windows' ``c`` (zero where a determined window does not fire; a window
that does not determine ``c`` takes its neighbours' when both fire) interpolated linearly
between the windows' centres is what :func:`rotation_acceleration` returns; the caller subtracts
it from the accelerometer before its estimate (:func:`simbench.orient.estimate` does for the
default method's sensors on their own).

**Measured.** The swung stick of ``tests/test_fast_rotation.py`` (5 rad/s, IMU 0.2-0.4 m from
the wrist, seeds 0-4): the default 0.48-0.85 x plain TRIAD (was 0.87-1.06 x: worse on 3 of 15).
BROAD's 22 trials: fires on none (each figure unchanged). Tried and dropped: the sphere with a
free radius, and no test of the readings' spread against the rest of the motion (fired on
every BROAD trial, c of 4-30 m/s^2 where the truth's 2 s means are below 0.5); no test of the
field's own offset (fired on trial 36, whose 5 cm magnet the calibration leaves: 0.36 -> 1.39 x
TRIAD); the sphere alone without the dip (fired on 07, 31, 36); no filling of undetermined
windows (the stick up to 1.02 x TRIAD).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2
from scipy.stats import f as f_dist

from calibration.errors import CalibrationInputError
from calibration.orientation.world import reference_from_data

#: Window over which the sensor-frame acceleration is taken as constant, s: shorter than a change
#: of the rotation's rate, long enough for the samples to cover the sphere at a fast rotation.
WINDOW_S = 2.0

#: The test's false-alarm rate per window.
FALSE_ALARM = 1e-3

#: The level of the test that a window's readings turn on the sphere beyond the rest of the
#: motion's spread (an F-test, :func:`_fit_window`): a gate before the detection's own test.
DETERMINATION = 0.01

#: Fits, each with the gravity and dip taken again from the readings corrected by the last.
ITERATIONS = 3

#: The field's direction is followed in steps of this long (its samples averaged), s.
TURN_STEP_S = 0.05

#: Gauss-Newton steps of a window's fit, from ``c = 0``.
GN_STEPS = 6

#: A window whose fit's normal matrix is worse conditioned than this is not determined.
MAX_CONDITION = 1e8


@dataclass(frozen=True)
class RotationAcceleration:
    """One sensor's sustained sensor-frame acceleration.

    Attributes:
        offset: ``(F, 3)`` the acceleration to subtract from the accelerometer, sensor frame,
            m/s^2; zero away from the windows where the test fires.
        detected: ``(F,)`` samples in a window where the test fires.
        windows: number of windows tested (determined or not).
        fired: number of windows where the test fires.
        median_m_s2: the median ``|c|`` over the windows that fire, m/s^2 (0 when none).
    """

    offset: np.ndarray
    detected: np.ndarray
    windows: int
    fired: int
    median_m_s2: float


def long_run_factor(r: np.ndarray) -> float:
    """``1 + 2 sum rho_k`` of a residual series, summed while ``rho_k > 0`` (at least 1)."""
    r = r - r.mean()
    v = float(r @ r)
    if not v > 0:
        return 1.0
    total = 1.0
    for k in range(1, r.size // 2):
        rho = float(r[:-k] @ r[k:]) / v
        if rho <= 0:
            break
        total += 2.0 * rho
    return total


def noise_variance(acc: np.ndarray, use: np.ndarray) -> float:
    """The accelerometer's white-noise variance per axis, (m/s^2)^2: from the second differences
    of consecutive usable samples (``6 sigma^2`` for white noise; the motion's share is small at
    an IMU's rate), robustly (1.4826 MAD), the mean over the axes."""
    ok = use[2:] & use[1:-1] & use[:-2]
    d2 = (acc[2:] - 2.0 * acc[1:-1] + acc[:-2])[ok]
    if d2.shape[0] < 3:
        return float("nan")
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return float(np.mean((1.4826 * mad) ** 2) / 6.0)


def field_turn(
    m_hat: np.ndarray, use: np.ndarray, rate_hz: float, starts: np.ndarray, size: int
) -> np.ndarray:
    """``(W,)`` how far the field's direction turns in the sensor frame in each window, rad: the
    length of its path on the unit sphere, its samples averaged over :data:`TURN_STEP_S` (the
    noise's share of the path small) and taken every :data:`TURN_STEP_S`; the usable samples only."""
    k = max(1, round(TURN_STEP_S * rate_hz))
    blocks = m_hat.shape[0] // k
    sums = m_hat[: blocks * k].reshape(blocks, k, 3).sum(axis=1)
    counts = use[: blocks * k].reshape(blocks, k).sum(axis=1)
    n = np.linalg.norm(sums, axis=1)
    ok = (counts == k) & (n > 0)
    u = sums / np.where(n > 0, n, 1.0)[:, None]
    step = np.where(ok[1:] & ok[:-1], np.linalg.norm(np.diff(u, axis=0), axis=1), 0.0)
    path = np.r_[0.0, np.cumsum(step)]  # path[b]: up to block b
    first = np.minimum(-(-starts // k), blocks - 1)
    last = np.minimum((starts + size) // k - 1, blocks - 1)
    return np.where(last > first, path[last] - path[first], 0.0)


def _fit_window(
    a: np.ndarray, m_hat: np.ndarray | None, g: float, sin_i: float, noise_var: float
) -> tuple[np.ndarray, float]:
    """``c`` ``(3,)`` of one window's ``a`` ``(n, 3)`` and ``m_hat`` ``(n, 3)`` (module docstring;
    ``None``: the sphere alone), and its chi-square statistic (NaN when not determined: the
    readings do not spread over a circle beyond their noise and the rest of the motion)."""
    n = a.shape[0]
    kinds = 1 if m_hat is None else 2
    spread = np.linalg.eigvalsh(np.cov(a.T))  # ascending
    if not spread[1] > noise_var * chi2.isf(FALSE_ALARM, n - 1) / (n - 1):
        return np.zeros(3), float("nan")

    def residuals(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = a - c
        dn = np.linalg.norm(d, axis=1)
        if m_hat is None:
            return dn - g, -d / dn[:, None]
        return np.r_[dn - g, np.sum(d * m_hat, axis=1) + g * sin_i], -np.vstack([d / dn[:, None], m_hat])

    c = np.zeros(3)
    w = np.ones(kinds)
    N = np.eye(3)
    for it in range(GN_STEPS):
        r, J = residuals(c)
        if it == 1:  # each kind of row by its own robust scale, from the first step's residuals
            for k in range(kinds):
                rows = r[k * n : (k + 1) * n]
                s = 1.4826 * float(np.median(np.abs(rows - np.median(rows))))
                if not s > 0:
                    return np.zeros(3), float("nan")
                w[k] = 1.0 / s
        wr = np.repeat(w, n)
        Jw = J * wr[:, None]
        N = Jw.T @ Jw
        if not np.linalg.cond(N) < MAX_CONDITION:
            return np.zeros(3), float("nan")
        c = c - np.linalg.solve(N, Jw.T @ (r * wr))
    r, _ = residuals(c)
    rw = r * np.repeat(w, n)
    inflate = max(long_run_factor(rw[k * n : (k + 1) * n]) for k in range(kinds))
    # the readings must turn on the sphere beyond what the rest of the motion spreads them: the
    # spread of a in its second direction against the sphere's residual variance, F-test with
    # the residuals' effective number of samples (the rest of the motion is in a as well)
    dof = n / inflate - 1.0
    s2 = float(np.mean((rw[:n] / w[0]) ** 2))
    if not (dof >= 1 and spread[1] > s2 * f_dist.isf(DETERMINATION, dof, dof)):
        return np.zeros(3), float("nan")
    cov = np.linalg.inv(N) * float(np.mean(rw**2)) * inflate
    return c, float(c @ np.linalg.solve(cov, c))


def _fit(
    acc: np.ndarray,
    m_hat: np.ndarray,
    use: np.ndarray,
    starts: np.ndarray,
    size: int,
    offset: np.ndarray,
    noise_var: float,
    turn: np.ndarray,
    field_offset: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Every window's ``c`` ``(W, 3)`` and statistic ``(W,)``, the gravity and dip from
    ``acc - offset``."""
    ref = reference_from_data(acc - offset, m_hat, "enu", valid=use)
    g, sin_i = ref.gravity, float(np.sin(ref.inclination))
    cs = np.zeros((starts.size, 3))
    stat = np.full(starts.size, np.nan)
    for j, s in enumerate(starts):
        ok = use[s : s + size]
        if ok.sum() < size // 2 or turn[j] < 2.0 * np.pi:
            continue
        cs[j], stat[j] = _fit_window(acc[s : s + size][ok], m_hat[s : s + size][ok], g, sin_i, noise_var)
        if np.isfinite(stat[j]) and field_offset[j]:
            stat[j] = np.nan  # the dip needs the Earth's field: not determined here
    return cs, stat


def _field_offsets(
    mag: np.ndarray, use: np.ndarray, starts: np.ndarray, size: int, turn: np.ndarray
) -> np.ndarray:
    """``(W,)`` the windows whose magnetometer holds a sustained sensor-frame offset of its own
    (a magnet carried with the sensor that the calibration left): the sphere test of
    :func:`_fit_window` on the field, its radius the median ``|m|``."""
    strength = float(np.median(np.linalg.norm(mag[use], axis=1)))
    noise = noise_variance(mag, use)
    limit = chi2.isf(FALSE_ALARM, 3)
    out = np.zeros(starts.size, dtype=bool)
    for j, s in enumerate(starts):
        ok = use[s : s + size]
        if ok.sum() < size // 2 or turn[j] < 2.0 * np.pi:
            continue
        _, stat = _fit_window(mag[s : s + size][ok], None, strength, 0.0, noise)
        out[j] = bool(stat > limit)
    return out


def _offsets(
    cs: np.ndarray, fire: np.ndarray, determined: np.ndarray, centres: np.ndarray, f: int
) -> np.ndarray:
    """``(F, 3)`` the windows' ``c`` ``(W, 3)`` where they ``fire``, zero where they are
    ``determined`` and do not, linearly between the windows' ``centres``: a window that does not
    determine ``c`` takes its neighbours' when the determined windows on both sides of it fire,
    zero otherwise (and at the recording's ends)."""
    idx = np.flatnonzero(determined)
    anchor = determined.copy()
    if idx.size:
        before = np.searchsorted(idx, np.arange(fire.size), side="right") - 1
        after = np.searchsorted(idx, np.arange(fire.size), side="left")
        inside = (before >= 0) & (after < idx.size)
        bridged = np.zeros(fire.size, dtype=bool)
        lo, hi = idx[before[inside]], idx[np.minimum(after[inside], idx.size - 1)]
        bridged[inside] = fire[lo] & fire[hi]
        anchor |= ~bridged
    x = np.r_[-1.0, centres[anchor], float(f)]
    y = np.vstack([np.zeros(3), np.where(fire[:, None], cs, 0.0)[anchor], np.zeros(3)])
    frames = np.arange(f)
    return np.column_stack([np.interp(frames, x, y[:, i]) for i in range(3)])


def consistent(cs: np.ndarray) -> bool:
    """The directions of the windows' ``c`` ``(K, 3)`` that fire share one direction: Rayleigh's
    test of uniform directions on the sphere (``3 n Rbar^2`` chi-square with 3 degrees of
    freedom; ``n`` half the windows, as half-overlapping windows share half their samples)
    rejected at :data:`FALSE_ALARM`. A lever fixed in the sensor and a rotation about a steady
    axis make ``c`` point one way; a false alarm points anywhere."""
    u = cs / np.linalg.norm(cs, axis=1, keepdims=True)
    n = cs.shape[0] / 2.0
    r = float(np.linalg.norm(u.mean(axis=0)))
    return 3.0 * n * r * r > chi2.isf(FALSE_ALARM, 3)


def rotation_acceleration(
    acc: np.ndarray, mag: np.ndarray, rate_hz: float, valid: np.ndarray | None = None
) -> RotationAcceleration:
    """One sensor's sustained sensor-frame acceleration where the data show one (module docstring).

    Args:
        acc: ``(F, 3)`` specific force, sensor frame, m/s^2.
        mag: ``(F, 3)`` magnetic field, sensor frame, any unit (its direction is used).
        rate_hz: sample rate, Hz (> 0).
        valid: optional ``(F,)`` mask of usable samples.

    Raises:
        CalibrationInputError: shapes or rate not as stated.
    """
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    if acc.ndim != 2 or acc.shape[1] != 3 or mag.shape != acc.shape:
        raise CalibrationInputError(
            f"Expected acc and mag of one shape (frames, 3), got {acc.shape} and {mag.shape}"
        )
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise CalibrationInputError(f"Expected rate_hz a finite number of Hz > 0, got {rate_hz!r}")
    f = acc.shape[0]
    a_n = np.linalg.norm(acc, axis=1)
    m_n = np.linalg.norm(mag, axis=1)
    use = np.isfinite(a_n) & np.isfinite(m_n) & (a_n > 0) & (m_n > 0)
    if valid is not None:
        v = np.asarray(valid, dtype=bool)
        if v.shape != (f,):
            raise CalibrationInputError(f"Expected valid of shape ({f},), got {v.shape}")
        use &= v
    size = max(8, round(WINDOW_S * rate_hz))
    none = RotationAcceleration(np.zeros((f, 3)), np.zeros(f, dtype=bool), 0, 0, 0.0)
    if f < size or use.sum() < size:
        return none
    acc = np.where(use[:, None], acc, 0.0)
    m_hat = np.where(use[:, None], mag / np.where(m_n > 0, m_n, 1.0)[:, None], 0.0)
    starts = np.arange(0, f - size + 1, size // 2)
    centres = starts + (size - 1) / 2.0
    limit = chi2.isf(FALSE_ALARM, 3)
    noise = noise_variance(acc, use)
    turn = field_turn(m_hat, use, rate_hz, starts, size)
    held = _field_offsets(np.where(use[:, None], mag, 0.0), use, starts, size, turn)
    offset = np.zeros((f, 3))
    fire = np.zeros(starts.size, dtype=bool)
    cs = np.zeros((starts.size, 3))
    for _ in range(ITERATIONS):
        cs, stat = _fit(acc, m_hat, use, starts, size, offset, noise, turn, held)
        fire = np.isfinite(stat) & (stat > limit)
        if not (fire.any() and consistent(cs[fire])):
            fire[:] = False
            break
        offset = _offsets(cs, fire, np.isfinite(stat), centres, f)
    if not fire.any():
        return dataclasses.replace(none, windows=int(starts.size))
    detected = np.zeros(f, dtype=bool)
    for s in starts[fire]:
        detected[s : s + size] = True
    return RotationAcceleration(
        offset,
        detected,
        int(starts.size),
        int(fire.sum()),
        float(np.median(np.linalg.norm(cs[fire], axis=1))),
    )
