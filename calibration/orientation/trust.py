"""Inputs that cannot be trusted: a sensor held at its range, a field that drifts, no rest.

Each test looks at one sensor's samples and says what it found, for a caller to warn with
(:func:`simbench.orient.input_warnings`):

- **Saturation** (:func:`saturated_axes`): an axis of a gyroscope or accelerometer beyond its
  range reads the range, a constant extreme. A continuous reading reaches its largest magnitude
  once (BROAD's 22 trials: every axis of both sensors at 1 or 2 samples); an axis whose largest
  magnitude (within :data:`SAME_VALUE` of it, relative: the same number) is held by at least
  :data:`SATURATED_FRACTION` of the samples, and :data:`SATURATED_MIN` of them, is at its range.
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

from calibration.errors import CalibrationInputError

#: Readings within this fraction of the largest magnitude count as the same value.
SAME_VALUE = 1e-9

#: An axis is at its range when its largest magnitude is held by at least this share of the samples
#: (0.1 %), and by at least :data:`SATURATED_MIN` of them.
SATURATED_FRACTION = 1e-3
SATURATED_MIN = 5

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
    return out


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
