"""Inputs that cannot be trusted: a sensor held at its range, a field that drifts, no rest.

Each test looks at one sensor's samples and says what it found, for a caller to warn with
(:func:`simbench.orient.input_warnings`):

- **Saturation** (:func:`saturated_axes`): an axis of a gyroscope or accelerometer beyond its
  range reads the range, a constant extreme. A continuous reading reaches its largest magnitude
  once (BROAD's 22 trials: every axis of both sensors at 1 or 2 samples); an axis whose largest
  magnitude (within :data:`SAME_VALUE` of it, relative: the same number) is held by at least
  :data:`SATURATED_FRACTION` of the samples, and :data:`SATURATED_MIN` of them, is at its range.
  Some sensors clip to a value that still carries a little noise (RepoIMU's Xsens gyroscope:
  7.36-7.37 rad/s on 0.8-9 % of the samples of six trials, no value repeated), so an axis is also
  at its range when its samples pile up at the top: with ``s`` the larger of the axis's white
  noise (from its second differences, robust) and its resolution (the smallest step between its
  values), a smooth extreme, a parabola ``top - c t^2``, spends time proportional to ``sqrt(h)``
  within ``h`` of its top, so of the samples within :data:`PLATEAU_SIGMAS` ``s`` of the top and in
  the next band as wide below, at most ``sqrt(3) / sqrt(6) = 0.71`` fall in the top band, however
  many such extremes the recording has (a lower one holds less). More is tested by a one-sided
  binomial test at :data:`PLATEAU_FALSE_ALARM` per axis, with at least :data:`SATURATED_MIN`
  samples at the top. On 714 axes of real recordings (BROAD's 22 trials and the two of
  ``../shared/data``, RepoIMU's 29 stick and 67 pendulum files) this test alone finds the six
  clipped gyroscope axes (p at most 3e-7) and nothing else (the next, p = 1e-3: a static axis's
  sparse quantised tail). The repeated value finds none of the six; it finds a simulated clip
  that lasts a few samples, which the pile-up test cannot tell from a smooth extreme, and it also
  flags 154 of RepoIMU's pendulum axes, whose coarse quantisation repeats the largest level of a
  smooth swing (left as it is: a coarsely quantised reading is named, not silently trusted); a
  still axis whose noise spans a few quantisation levels only piles up in both tests. A
  motion that dwells at its fastest (a turntable at a constant rate) looks the same as a clipped
  one: the warning says the axis is held there.
  Unit-free: no range has to be known.
- **A drifting field** (:func:`field_drift`): the field strength ``|m|`` is the Earth's, constant,
  whatever the sensor does; a magnetometer whose gain or offset drifts (temperature) or a sensor
  carried into another field shows a trend. The trend is the Theil-Sen slope through the medians
  of ``|m|`` over :data:`DRIFT_BLOCKS` consecutive blocks (robust to a disturbance in a few of
  them), its change over the recording compared with the robust spread of ``|m|`` about the
  trend (1.4826 MAD: the noise and the orientation's own share): a drift of more than
  :data:`DRIFT_SPREADS` of them (BROAD's 22 trials: 0.01-0.73).
- **No rest** (:func:`longest_rest`): the reference gravity and the field's dip are taken from
  the recording (medians), which sustained motion biases, and a gyro-aided method estimates its
  gyroscope's bias at rest. A rest is :data:`REST_S` during which the gyroscope's rate,
  averaged over :data:`REST_FILTER_S`, stays under :data:`REST_GYRO_RAD_S` and the accelerometer
  within :data:`REST_ACC_M_S2` of its own average over that time: VQF's rest detection's
  published defaults (Laidig and Seel 2023: 2 deg/s, 0.5 m/s^2, 1.5 s, a 0.5 s low-pass), so that
  "rest" means what the gyro-aided reference takes it to mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.special import betainc

from calibration.errors import CalibrationInputError

#: Readings within this fraction of the largest magnitude count as the same value.
SAME_VALUE = 1e-9

#: An axis is at its range when its largest magnitude is held by at least this share of the samples
#: (0.1 %), and by at least :data:`SATURATED_MIN` of them; or when its samples pile up at the top.
SATURATED_FRACTION = 1e-3
SATURATED_MIN = 5

#: The top band of the pile-up test (module docstring): this many white-noise standard deviations
#: below the largest magnitude; the next band is as wide.
PLATEAU_SIGMAS = 3.0

#: The largest share of the two bands' samples a smooth (parabolic) extreme puts in the top band.
SMOOTH_TOP_SHARE = float(np.sqrt(0.5))

#: False-alarm rate per axis of the pile-up test: a recording of 16 sensors tests 96 axes, so
#: about one in a hundred such recordings gets a false warning.
PLATEAU_FALSE_ALARM = 1e-4

#: Blocks of the recording whose medians of ``|m|`` the trend goes through.
DRIFT_BLOCKS = 20

#: A trend of ``|m|`` whose change over the recording exceeds this many robust standard deviations
#: of ``|m|`` about it is a drift.
DRIFT_SPREADS = 3.0

#: A rest (module docstring): VQF's rest detection defaults.
REST_S = 1.5
REST_GYRO_RAD_S = float(np.deg2rad(2.0))
REST_ACC_M_S2 = 0.5
REST_FILTER_S = 0.5


@dataclass(frozen=True)
class Saturation:
    """An axis held at its largest magnitude.

    Attributes:
        axis: 0, 1 or 2.
        value: the magnitude it is held at, in the samples' unit.
        fraction: share of the usable samples at it (either sign).
    """

    axis: int
    value: float
    fraction: float


def _vectors(x: np.ndarray, valid: np.ndarray | None, name: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise CalibrationInputError(f"Expected {name} of shape (frames, 3), got {x.shape}")
    use = np.isfinite(x).all(axis=1)
    if valid is not None:
        v = np.asarray(valid, dtype=bool)
        if v.shape != use.shape:
            raise CalibrationInputError(f"Expected valid of shape {use.shape}, got {v.shape}")
        use &= v
    return x, use


def saturated_axes(x: np.ndarray, valid: np.ndarray | None = None) -> list[Saturation]:
    """The axes of one sensor's ``(F, 3)`` readings (any unit) held at their largest magnitude
    (module docstring); ``valid`` ``(F,)`` optional. An axis that never moves from zero is not
    saturated (no reading at all)."""
    x, use = _vectors(x, valid, "readings")
    n = int(use.sum())
    out = []
    if n == 0:
        return out
    a = np.abs(x[use])
    for j in range(3):
        top = float(a[:, j].max())
        if not top > 0:
            continue
        count = int(np.count_nonzero(a[:, j] >= top * (1.0 - SAME_VALUE)))
        if count >= max(SATURATED_MIN, SATURATED_FRACTION * n):
            out.append(Saturation(j, top, count / n))
            continue
        piled = _piled_up(x[use, j], a[:, j], top)
        if piled:
            out.append(Saturation(j, top, piled / n))
    return out


def _piled_up(x: np.ndarray, a: np.ndarray, top: float) -> int:
    """The samples of one axis within :data:`PLATEAU_SIGMAS` white-noise standard deviations of
    its largest magnitude ``top`` when more of them are there than a smooth extreme allows
    (module docstring); 0 otherwise. ``x`` the axis's samples in order, ``a`` their magnitudes."""
    if x.size < 3:
        return 0
    d2 = np.diff(x, 2)
    noise = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0)
    levels = np.unique(a)
    step = float(np.diff(levels).min()) if levels.size > 1 else 0.0  # the reading's resolution
    band = PLATEAU_SIGMAS * max(noise, step)
    at_top = int(np.count_nonzero(a >= top - band))
    below = int(np.count_nonzero((a >= top - 2.0 * band) & (a < top - band)))
    if at_top < SATURATED_MIN:
        return 0
    # P(at least at_top of at_top + below in the top band) for a share SMOOTH_TOP_SHARE
    p = float(betainc(at_top, below + 1, SMOOTH_TOP_SHARE))
    return at_top if p < PLATEAU_FALSE_ALARM else 0


def field_drift(mag: np.ndarray, time_s: np.ndarray, valid: np.ndarray | None = None) -> tuple[float, float]:
    """The change of one magnetometer's field strength over the recording along its robust trend,
    and the robust spread of ``|m|`` about that trend (module docstring), both in the samples'
    unit; ``(0, nan)`` with too few samples.

    Args:
        mag: ``(F, 3)`` samples, any unit.
        time_s: ``(F,)`` their times, s.
        valid: optional ``(F,)`` mask.
    """
    mag, use = _vectors(mag, valid, "mag")
    t = np.asarray(time_s, dtype=float)
    if t.shape != (mag.shape[0],):
        raise CalibrationInputError(f"Expected time_s of shape ({mag.shape[0]},), got {t.shape}")
    use &= np.isfinite(t)
    if use.sum() < 2 * DRIFT_BLOCKS:
        return 0.0, float("nan")
    n = np.linalg.norm(mag[use], axis=1)
    tt = t[use]
    blocks = np.array_split(np.arange(n.size), DRIFT_BLOCKS)
    med = np.array([np.median(n[b]) for b in blocks])
    tm = np.array([np.median(tt[b]) for b in blocks])
    i, k = np.triu_indices(DRIFT_BLOCKS, 1)
    dt = tm[k] - tm[i]
    slope = float(np.median((med[k] - med[i])[dt > 0] / dt[dt > 0]))
    res = n - slope * tt
    spread = float(1.4826 * np.median(np.abs(res - np.median(res))))
    return slope * float(tt[-1] - tt[0]), spread


def longest_rest(acc: np.ndarray, gyro: np.ndarray, rate_hz: float, valid: np.ndarray | None = None) -> float:
    """The longest rest of one sensor (module docstring), s.

    Args:
        acc: ``(F, 3)`` specific force, m/s^2.
        gyro: ``(F, 3)`` angular rate, rad/s (NaN where there is none).
        rate_hz: sample rate, Hz.
        valid: optional ``(F,)`` mask.
    """
    acc, use = _vectors(acc, valid, "acc")
    gyro, g_use = _vectors(gyro, None, "gyro")
    if gyro.shape != acc.shape:
        raise CalibrationInputError(f"Expected gyro of shape {acc.shape}, got {gyro.shape}")
    use &= g_use
    if acc.shape[0] < 2:
        return 0.0
    f = max(1, round(REST_FILTER_S * rate_hz))
    a = np.where(use[:, None], acc, 0.0)
    g = uniform_filter1d(np.where(use[:, None], gyro, 0.0), f, axis=0, mode="nearest")
    calm = use & (np.linalg.norm(g, axis=1) < REST_GYRO_RAD_S)
    calm &= np.linalg.norm(a - uniform_filter1d(a, f, axis=0, mode="nearest"), axis=1) < REST_ACC_M_S2
    d = np.diff(np.r_[0, calm.astype(np.int8), 0])
    runs = np.flatnonzero(d == -1) - np.flatnonzero(d == 1)
    return float(runs.max(initial=0)) / rate_hz
