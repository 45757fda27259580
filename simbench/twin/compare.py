"""Real readings against simulated ones, sample by sample: R^2, rms and the difference's spectrum.

All functions take ``(F, 3)`` readings of one sensor kind (one unit: m/s^2, rad/s or uT) and a
``(F,)`` mask of the samples to compare (the twin's: BROAD's ``movement`` samples, less those
near an optical gap).

- :func:`r2`: the share of the real reading's variance the simulated one explains,
  ``1 - sum |real - sim|^2 / sum |real - mean(real)|^2``, the sums over the samples and the three
  axes (pooled), ``mean(real)`` each axis's own mean over the samples: 1 for identical signals,
  about 0 for a simulation that knows nothing but the mean, below 0 for one worse than that.
- :func:`r2_ceiling`: the R^2 of a simulation exact but for the sensor's white noise (of the
  standard deviation identified at rest): ``1 - N sum_axes sigma^2 / sum |real - mean(real)|^2``.
  A deterministic twin cannot do better; where the motion moves a reading little (a trial that
  translates more than it turns, for the magnetometer) the noise alone keeps R^2 low.
- :func:`rms`: ``sqrt(mean |real - sim|^2)``, the norm of the difference vector, the unit's.
- :func:`spectrum` and :func:`spectrum_summary`: Welch's power spectral density of a signal
  (summed over the axes) over the contiguous runs of the compared samples, each at least one
  segment (:data:`SEGMENT_S`) long, averaged weighted by their segments; the summary gives the
  median frequency (half the power below), the dominant peak and the share of the power in
  :data:`BANDS_HZ`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simbench.errors import InputError
from simbench.twin.identify import runs

#: Welch segments of this length, s (0.25 Hz resolution).
SEGMENT_S = 4.0
#: The bands of the spectrum summary, Hz (the last one up to the Nyquist frequency).
BANDS_HZ = ((0.0, 1.0), (1.0, 5.0), (5.0, 15.0), (15.0, np.inf))


def _pair(real: np.ndarray, sim: np.ndarray, use: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    real, sim = np.asarray(real, dtype=float), np.asarray(sim, dtype=float)
    if real.ndim != 2 or real.shape[1] != 3 or sim.shape != real.shape:
        raise InputError(
            f"expected real and simulated readings of one shape (F, 3), got {real.shape} and {sim.shape}"
        )
    ok = np.isfinite(real).all(axis=1) & np.isfinite(sim).all(axis=1)
    if use is not None:
        use = np.asarray(use)
        if use.shape != (real.shape[0],):
            raise InputError(f"expected the mask of shape ({real.shape[0]},), got {use.shape}")
        ok &= use.astype(bool)
    if ok.sum() < 2:
        raise InputError(f"expected at least 2 samples to compare, got {int(ok.sum())}")
    return real[ok], sim[ok]


def r2(real: np.ndarray, sim: np.ndarray, use: np.ndarray | None = None) -> float:
    """The share of the real reading's variance explained (module docstring), unit-free."""
    a, b = _pair(real, sim, use)
    total = float(np.sum((a - a.mean(axis=0)) ** 2))
    if total <= 0:
        raise InputError("the real reading does not vary over the samples compared: R^2 is undefined")
    return 1.0 - float(np.sum((a - b) ** 2)) / total


def r2_ceiling(real: np.ndarray, noise_std: np.ndarray, use: np.ndarray | None = None) -> float:
    """The R^2 left by white noise of ``noise_std`` ``(3,)`` per axis alone (module docstring)."""
    a, _ = _pair(real, real, use)
    total = float(np.sum((a - a.mean(axis=0)) ** 2))
    if total <= 0:
        raise InputError("the real reading does not vary over the samples compared: R^2 is undefined")
    return 1.0 - a.shape[0] * float(np.sum(np.asarray(noise_std, dtype=float) ** 2)) / total


def rms(real: np.ndarray, sim: np.ndarray, use: np.ndarray | None = None) -> float:
    """``sqrt(mean |real - sim|^2)`` over the samples, the readings' unit."""
    a, b = _pair(real, sim, use)
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def spectrum(x: np.ndarray, rate_hz: float, use: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(f, psd)``: Welch's power spectral density of ``x`` ``(F, 3)`` summed over the axes
    (unit^2/Hz), over the runs of ``use`` (module docstring); each run's mean removed.

    Raises:
        InputError: no run of ``use`` as long as one segment.
    """
    from scipy.signal import welch  # scipy.signal: 0.6 s of every start of the command line

    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3:
        raise InputError(f"expected x of shape (F, 3), got {x.shape}")
    nperseg = round(SEGMENT_S * rate_hz)
    mask = np.isfinite(x).all(axis=1) & (np.ones(x.shape[0], bool) if use is None else np.asarray(use, bool))
    total, weight, f = None, 0, None
    for a, b in runs(mask):
        if b - a < nperseg:
            continue
        seg = x[a:b]
        f, p = welch(seg - seg.mean(axis=0), fs=rate_hz, nperseg=nperseg, axis=0)
        k = 1 + 2 * ((b - a) - nperseg) // nperseg  # Welch's segments at half overlap
        total = p.sum(axis=1) * k if total is None else total + p.sum(axis=1) * k
        weight += k
    if total is None or f is None:
        raise InputError(f"no stretch of {SEGMENT_S:g} s of samples to compare: no spectrum")
    return f, total / weight


def spectrum_summary(x: np.ndarray, rate_hz: float, use: np.ndarray | None = None) -> dict[str, Any]:
    """Median frequency, dominant peak and band shares of ``x``'s spectrum (module docstring).

    Returns:
        ``median_frequency_hz``, ``peak_frequency_hz``, ``power`` (the PSD's integral,
        unit^2), ``band_share`` ``{"0-1 Hz": ..., ...}`` (fractions summing to 1).
    """
    f, p = spectrum(x, rate_hz, use)
    df = f[1] - f[0]
    c = np.cumsum(p)
    median = float(np.interp(0.5, c / c[-1], f)) if c[-1] > 0 else 0.0
    shares = {}
    for lo, hi in BANDS_HZ:
        label = f"{lo:g}-{hi:g} Hz" if np.isfinite(hi) else f"above {lo:g} Hz"
        inside = (f >= lo) & (f < hi)
        shares[label] = float(p[inside].sum() / c[-1]) if c[-1] > 0 else 0.0
    return {
        "median_frequency_hz": median,
        "peak_frequency_hz": float(f[int(np.argmax(p))]),
        "power": float(c[-1] * df),
        "band_share": shares,
    }
