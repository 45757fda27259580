"""A sensor on a lever: the acceleration of rotation about a centre away from it, from the estimate.

A sensor at ``r`` (sensor frame) from a centre of rotation fixed in the body feels, besides
gravity and the centre's own acceleration, ``dw/dt x r + w x (w x r)`` (``w`` the body rate in
the sensor frame): a stick swung back and forth with the IMU 0.28 m from the wrist (RepoIMU's
tests 6 and 7) feels 2-5 m/s^2 of it, sustained in the sensor frame over its swings. The
gyro-free estimators take it for tilt; :mod:`.rotation_acc` finds it only where the field turns a
full turn in a window (06_2 of RepoIMU's 28 trials).

**The model.** Given an orientation estimate ``R(t)``, its rate ``w`` and ``dw/dt`` in the sensor
frame are taken by central differences, smoothed over :data:`SMOOTH_S` (a slowly varying error of
the estimate in the world frame leaves them unchanged). The linear acceleration the estimate
leaves, ``a - R^T g up``, is fitted by least squares with ``(K(dw/dt) + K(w)^2) r`` (``K`` the cross
product matrix): three unknowns, linear. The covariance of ``r`` is the least-squares one times
the residuals' long-run variance factor (:func:`.rotation_acc.long_run_factor`, largest over the
axes: the rest of the motion is correlated, not white); ``r^T Cov^-1 r`` is chi-square with 3
degrees of freedom without a lever and fires at :data:`FALSE_ALARM`.

**Settled and explaining better, or not applied.** ``w`` comes from an estimate that the
lever's acceleration itself has tilted, so ``r`` is biased (towards zero by the noise in ``w``,
and anywhere where the estimate is wrong in ways the model does not describe). The acceleration
``M r`` is subtracted from the accelerometer, the estimate made again (its gravity and dip taken
again from the corrected readings), and ``r`` fitted again from it. The new estimate is kept when
(1) the refit agrees with the lever it was made with (a fixed point):
``(r_1 - r_0)^T (C_1 + C_0)^-1 (r_1 - r_0)`` below its chi-square quantile (3 degrees of freedom,
:data:`FALSE_ALARM`; a conservative variance, the fits share their samples); a lever fitted to the
rest of the motion moves (RepoIMU's test 10, the stick rolled about its own axis, along which no
lever is seen: 0.86 m, then 0.32 m); and (2) the new estimate with its lever explains the
accelerometer better than the first with its own: a smaller mean square of
``a - R^T g up - M r`` (the same three unknowns each: no threshold). A small correction changes
the estimate little, so (1) alone passes it whether it helps or not (BROAD's trial 30, its box
turned fast near a magnet: 0.23 -> 0.30 x TRIAD with (1) alone; its residual grows by 28 %).
Otherwise the first estimate is kept, and the caller says so.

**Measured** (``docs/repoimu.md``): RepoIMU's 28 T-stick trials, applied on 7 (07_1-07_3
1.09/1.04/1.14 -> 1.01/0.99/1.01 x plain TRIAD, 05_3 1.08 -> 1.01, 11_1 0.46 -> 0.34; 02_2,
05_2 within 2 %), the rest unchanged; the simulated swinging stick of ``tests/test_lever.py``
(seeds 0-4, 0.2-0.4 m): applied on 6 of 15, each 3-14 % better. Tried and dropped: two or three
passes (test 10 settled on wrong levers, 0.11 -> 0.31 and 0.61 x TRIAD); the lever's acceleration
averaged over 2 s (only the sustained part: 06_1 1.07 -> 0.88 x, but tests 8-10 0.11-0.22 ->
0.11-0.31 x); a lever fitted to the 2 s means only, or the centripetal part only (test 10 up to
0.25 x).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.stats import chi2

from calibration.errors import CalibrationInputError
from calibration.orientation.rotation_acc import long_run_factor
from calibration.rotations import quat_to_matrix

#: The rates' smoothing (a Gaussian's standard deviation), s: the estimate's sample-to-sample
#: noise differenced twice is large at an IMU's rate; a hand's swing (<= 2 Hz) passes.
SMOOTH_S = 0.03

#: The false-alarm rate of both tests (a lever where there is none; a settled lever taken for one
#: that moves).
FALSE_ALARM = 1e-3

#: Estimates made again at most, each with the last fit's lever removed.
PASSES = 1


@dataclass(frozen=True)
class LeverFit:
    """One sensor's lever from one estimate.

    Attributes:
        r_m: ``(3,)`` the lever, sensor frame, m (from the centre of rotation to the sensor).
        cov: ``(3, 3)`` its covariance, m^2.
        statistic: ``r^T cov^-1 r`` (chi-square, 3 degrees of freedom, without a lever).
        model: ``(F, 3)`` ``dw/dt x r + w x (w x r)``, sensor frame, m/s^2 (0 where not estimated).
        residual_var: the mean square of ``a - R^T g up - model`` over the samples used,
            (m/s^2)^2: how well the estimate and its lever explain the accelerometer.
    """

    r_m: np.ndarray
    cov: np.ndarray
    statistic: float
    model: np.ndarray
    residual_var: float = float("nan")


@dataclass(frozen=True)
class Lever:
    """What :func:`lever_compensated` found for one sensor.

    Attributes:
        sensor: its index.
        fit: the first estimate's fit.
        applied: the lever settled and its acceleration was removed.
        passes: estimates made again for it.
        r_m: ``(3,)`` the lever removed (``applied``) or the last one fitted, m.
        sd_m: ``(3,)`` its standard deviations, m.
        moved: the last comparison's chi-square (``nan`` before any).
        explains: the last corrected estimate with its lever explains the accelerometer better
            than the estimate it was made from with its own (a smaller residual mean square).
        settled: the last refit agreed with the lever removed (``moved`` below its quantile).
    """

    sensor: int
    fit: LeverFit
    applied: bool
    passes: int
    r_m: np.ndarray
    sd_m: np.ndarray
    moved: float
    explains: bool = False
    settled: bool = False


def skew(v: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` cross-product matrices ``K(v) x = v x x`` of ``(..., 3)`` vectors."""
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def body_rates(q_w_s: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sensor-frame rate and its derivative of an orientation sequence.

    Args:
        q_w_s: ``(F, 4)`` scalar-first ``R_w_s``, NaN where not estimated.
        rate_hz: sample rate, Hz.

    Returns:
        ``w`` ``(F, 3)`` rad/s, ``dw/dt`` ``(F, 3)`` rad/s^2 (central differences of ``R``,
        smoothed over :data:`SMOOTH_S`), and ``(F,)`` where both are estimated: the samples whose
        smoothing reaches no missing estimate (within 4 standard deviations and two samples).
    """
    f = q_w_s.shape[0]
    ok = np.isfinite(q_w_s).all(axis=1)
    R = np.zeros((f, 3, 3))
    R[ok] = quat_to_matrix(q_w_s[ok])
    w = np.zeros((f, 3))
    if f >= 3:
        W = np.einsum("fji,fjk->fik", R[1:-1], (R[2:] - R[:-2]) * (rate_hz / 2.0))
        w[1:-1] = 0.5 * np.c_[W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]]
    good = ok.copy()
    good[1:-1] &= ok[2:] & ok[:-2]
    good[[0, -1]] = False
    w[~good] = 0.0
    sigma = SMOOTH_S * rate_hz
    w = gaussian_filter1d(w, sigma, axis=0, mode="nearest")
    wd = np.gradient(w, 1.0 / rate_hz, axis=0) if f >= 2 else np.zeros_like(w)
    reach = int(np.ceil(4.0 * sigma)) + 2
    bad = np.convolve((~good).astype(float), np.ones(2 * reach + 1), mode="same") > 0
    return w, wd, ~bad


def fit_lever(
    acc: np.ndarray, q_w_s: np.ndarray, gravity: float, rate_hz: float, valid: np.ndarray | None = None
) -> LeverFit:
    """One sensor's lever from its accelerometer and an orientation estimate (module docstring).

    Args:
        acc: ``(F, 3)`` specific force, sensor frame, m/s^2.
        q_w_s: ``(F, 4)`` the estimate, ``R_w_s`` in a z-up world (ENU), scalar first.
        gravity: m/s^2 (> 0).
        rate_hz: sample rate, Hz (> 0).
        valid: optional ``(F,)`` mask of usable samples.

    Raises:
        CalibrationInputError: shapes, gravity or rate not as stated.
    """
    acc = np.asarray(acc, dtype=float)
    q_w_s = np.asarray(q_w_s, dtype=float)
    if acc.ndim != 2 or acc.shape[1] != 3 or q_w_s.shape != (acc.shape[0], 4):
        raise CalibrationInputError(
            f"Expected acc (frames, 3) and q_w_s (frames, 4), got {acc.shape} and {q_w_s.shape}"
        )
    if not (np.isfinite(rate_hz) and rate_hz > 0 and np.isfinite(gravity) and gravity > 0):
        raise CalibrationInputError(
            f"Expected rate_hz and gravity finite and > 0, got {rate_hz!r} and {gravity!r}"
        )
    f = acc.shape[0]
    w, wd, use = body_rates(q_w_s, rate_hz)
    use &= np.isfinite(acc).all(axis=1)
    if valid is not None:
        v = np.asarray(valid, dtype=bool)
        if v.shape != (f,):
            raise CalibrationInputError(f"Expected valid of shape ({f},), got {v.shape}")
        use &= v
    M = skew(wd) + skew(w) @ skew(w)
    none = LeverFit(np.zeros(3), np.full((3, 3), np.nan), 0.0, np.zeros((f, 3)))
    if use.sum() < 10:
        return none
    R = quat_to_matrix(np.where(np.isfinite(q_w_s), q_w_s, [1.0, 0.0, 0.0, 0.0]))
    up = R[:, 2, :]  # R^T e_z
    lin = (acc - gravity * up)[use]
    A = M[use]
    N = np.einsum("nki,nkj->ij", A, A)
    if not np.linalg.cond(N) < 1e12:
        return none
    r = np.linalg.solve(N, np.einsum("nki,nk->i", A, lin))
    res = lin - A @ r
    inflate = max(long_run_factor(res[:, i]) for i in range(3))
    cov = np.linalg.inv(N) * float(np.mean(res**2)) * inflate
    model = np.where(use[:, None], M @ r, 0.0)
    return LeverFit(r, cov, float(r @ np.linalg.solve(cov, r)), model, float(np.mean(res**2)))


def moved(a: LeverFit, b: LeverFit) -> float:
    """How far two fits' levers are apart: chi-square with 3 degrees of freedom when both
    estimate one lever (module docstring)."""
    d = b.r_m - a.r_m
    return float(d @ np.linalg.solve(a.cov + b.cov, d))


def lever_compensated(
    acc: np.ndarray,
    q_first: np.ndarray,
    sensors: Sequence[int],
    gravity: float,
    rate_hz: float,
    estimate: Callable[[np.ndarray, list[int]], np.ndarray],
    valid: np.ndarray | None = None,
) -> tuple[np.ndarray, list[Lever]]:
    """Each given sensor's estimate made again with its lever's acceleration removed where the
    data show a lever that settles (module docstring).

    Args:
        acc: ``(F, N, 3)`` specific force, sensor frames, m/s^2 (as measured: the lever is fitted
            to it and removed from it).
        q_first: ``(F, N, 4)`` the first estimate, ``R_w_s`` in ENU, scalar first.
        sensors: the sensors to look at, each estimated on its own.
        gravity: m/s^2.
        rate_hz: sample rate, Hz.
        estimate: the estimator of the sensors listed in its second argument on their own:
            their ``(F, K, 3)`` accelerometers to their ``(F, K, 4)`` orientations.
        valid: optional ``(F, N)`` mask of usable samples.

    Returns:
        ``(F, N, 4)`` the orientations (the first estimate's where no lever is applied) and, for
        each sensor whose first fit fires, what was found and done.
    """
    acc = np.asarray(acc, dtype=float)
    q_first = np.asarray(q_first, dtype=float)
    if acc.ndim != 3 or acc.shape[2] != 3 or q_first.shape != (*acc.shape[:2], 4):
        raise CalibrationInputError(
            f"Expected acc (frames, sensors, 3) and q_first (frames, sensors, 4), got {acc.shape} "
            f"and {q_first.shape}"
        )
    if valid is None:
        valid = np.ones(acc.shape[:2], dtype=bool)
    limit = chi2.isf(FALSE_ALARM, 3)
    q_out = q_first.copy()
    first: dict[int, LeverFit] = {}
    for k in sensors:
        fit = fit_lever(acc[:, k], q_first[:, k], gravity, rate_hz, valid[:, k])
        if fit.statistic > limit:
            first[k] = fit
    last = dict(first)
    pending = set(first)
    done: dict[int, Lever] = {}
    stat: dict[int, float] = {k: float("nan") for k in first}
    explains: dict[int, bool] = {k: False for k in first}
    for p in range(1, PASSES + 1):
        if not pending:
            break
        todo = sorted(pending)
        q = estimate(np.stack([acc[:, k] - last[k].model for k in todo], axis=1), todo)
        for j, k in enumerate(todo):
            refit = fit_lever(acc[:, k], q[:, j], gravity, rate_hz, valid[:, k])
            stat[k] = moved(last[k], refit)
            better = refit.residual_var < last[k].residual_var
            if stat[k] < limit and better:  # settled, and it explains the accelerometer better
                q_out[:, k] = q[:, j]
                done[k] = Lever(
                    k, first[k], True, p, last[k].r_m, np.sqrt(np.diag(last[k].cov)), stat[k], True
                )
                pending.discard(k)
            else:
                explains[k] = better
                last[k] = refit
    for k in pending:
        done[k] = Lever(
            k,
            first[k],
            False,
            PASSES,
            last[k].r_m,
            np.sqrt(np.diag(last[k].cov)),
            stat[k],
            explains[k],
            stat[k] < limit,
        )
    return q_out, [done[k] for k in sorted(done)]
