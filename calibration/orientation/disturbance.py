"""Disturbances: Fontaine's weighting of disturbed samples, and zero-phase smoothing over time.

- **Disturbance weighting** (Fontaine 2.1.2, :class:`Weighting`): the accelerometer is
  down-weighted as ``|a|`` departs from ``g`` (the sensor accelerates), the magnetometer as
  ``|m|`` departs from the field's strength or its dip from the inclination (a ferromagnetic
  disturbance): ``w = 1 / (1 + (x / tau)^2)`` for each departure ``x``, tolerances ``tau``
  configurable.
- :func:`smooth_vectors`: temporal smoothing of measured vectors by a zero-phase
  (forward-backward) Butterworth low-pass: no lag behind a real rotation.
- :func:`weighted_smooth`: the same low-pass weighted by the disturbance weights (normalised
  convolution), which is where the weighting pays: a sample whose accelerometer sees the body's
  acceleration takes "up" from its calmer neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.orientation.world import Reference


@dataclass(frozen=True)
class Weighting:
    """Fontaine's disturbance weighting: ``w = 1 / (1 + (x / tau)^2)`` per departure ``x``.

    Attributes:
        acc_tol: ``tau`` of ``| |a| - g | / g`` (relative).
        mag_tol: ``tau`` of ``| |m| - |B| | / |B|`` (relative).
        dip_tol_deg: ``tau`` of the measured dip's departure from the inclination, degrees.
    """

    acc_tol: float = 0.05
    mag_tol: float = 0.05
    dip_tol_deg: float = 3.0

    def __post_init__(self) -> None:
        for name in ("acc_tol", "mag_tol", "dip_tol_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise CalibrationInputError(f"Weighting.{name} must be > 0, got {v}")

    def weights(self, acc: np.ndarray, mag: np.ndarray, ref: Reference) -> np.ndarray:
        """``(..., 2)`` accelerometer and magnetometer weights in (0, 1] of measured ``acc`` and
        ``mag`` ``(..., 3)`` (m/s^2, uT); NaN where a vector is not finite."""
        g = ref.gravity
        b = ref.field_strength
        xa = (np.linalg.norm(acc, axis=-1) - g) / g
        xm = (np.linalg.norm(mag, axis=-1) - b) / b
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.sum(acc * mag, axis=-1) / (np.linalg.norm(acc, axis=-1) * np.linalg.norm(mag, axis=-1))
        dip = np.arcsin(np.clip(-cos, -1.0, 1.0))
        xd = np.rad2deg(dip - ref.inclination)
        wa = 1.0 / (1.0 + (xa / self.acc_tol) ** 2)
        wm = 1.0 / (1.0 + (xm / self.mag_tol) ** 2) / (1.0 + (xd / self.dip_tol_deg) ** 2)
        return np.stack([wa, wm], axis=-1)


def smooth_vectors(x: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase (forward-backward) 2nd-order Butterworth low-pass along axis 0.

    No lag behind a real rotation (the phase of the forward pass is undone by the backward one).
    NaN samples are filled by linear interpolation for filtering and set back to NaN. A series
    too short for the filter's padding comes back unchanged.

    Args:
        x: ``(F, ...)`` values, frames first.
        rate_hz: sample rate, Hz.
        cutoff_hz: cutoff, Hz, below the Nyquist frequency ``rate_hz / 2``.
    """
    x = np.asarray(x, dtype=float)
    if not 0 < cutoff_hz < rate_hz / 2:
        raise CalibrationInputError(f"cutoff_hz must be in (0, {rate_hz / 2}), got {cutoff_hz}")
    flat = x.reshape(x.shape[0], -1).copy()
    bad = ~np.isfinite(flat)
    idx = np.arange(flat.shape[0])
    for k in np.flatnonzero(bad.any(axis=0)):
        good = ~bad[:, k]
        flat[:, k] = np.interp(idx, idx[good], flat[good, k]) if good.any() else 0.0
    # here, not at the top: scipy.signal costs 0.6 s at every start of the command line
    from scipy.signal import butter, filtfilt

    b, a = butter(2, cutoff_hz / (rate_hz / 2))
    if flat.shape[0] <= 3 * max(len(a), len(b)):
        return x.copy()
    try:
        out = filtfilt(b, a, flat, axis=0)
    except np.linalg.LinAlgError:  # the filter's start-up state: poles too near 1 to solve for
        raise CalibrationInputError(
            f"cutoff_hz {cutoff_hz:g} Hz is too low a low-pass at {rate_hz:g} Hz to compute "
            f"(cutoff / Nyquist = {cutoff_hz / (rate_hz / 2):.1e})"
        ) from None
    out[bad] = np.nan
    return out.reshape(x.shape)


def weighted_smooth(x: np.ndarray, w: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Normalised convolution: ``LP(w x) / LP(w)`` with :func:`smooth_vectors`' zero-phase
    low-pass along axis 0; samples of low weight take their value from their neighbours.

    Args:
        x: ``(F, ..., 3)`` values. w: ``(F, ...)`` weights >= 0.
        rate_hz: as in :func:`smooth_vectors`.
        cutoff_hz: as in :func:`smooth_vectors`.
    """
    num = smooth_vectors(x * w[..., None], rate_hz, cutoff_hz)
    den = smooth_vectors(w[..., None], rate_hz, cutoff_hz)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-9, num / den, x)
