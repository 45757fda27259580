"""The capture system's unit scale factor from two rigidly mounted sensors (O'Brien section 4).

Two sensors fixed a known distance apart are moved through the capture volume. The factor that
turns the system's reported units into true lengths is the known distance over the mean
reported distance; the spread of the reported distance, scaled by that factor, measures the
system's position noise (O'Brien: factor 0.94, scaled standard deviation 0.7 cm, 56.5 cm apart).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.quantiles import mad_std


@dataclass(frozen=True)
class ScaleEstimate:
    """Attributes:
    scale: multiply reported lengths by this to get true lengths.
    scaled_std: standard deviation of the reported distance times ``scale``, in the unit of
        the known distance.
    mean_reported: mean reported distance, in the system's units.
    distances: ``(frames,)`` reported distance per frame (NaN where a position is missing).
    n_frames: frames used.
    """

    scale: float
    scaled_std: float
    mean_reported: float
    distances: np.ndarray
    n_frames: int


def unit_scale(p_w_a: np.ndarray, p_w_b: np.ndarray, known_distance: float) -> ScaleEstimate:
    """Estimate the unit scale factor from two sensors rigidly ``known_distance`` apart.

    Args:
        p_w_a: ``(frames, 3)`` reported positions of sensor a, in the system's units.
        p_w_b: ``(frames, 3)`` reported positions of sensor b, the same units.
        known_distance: the true distance between the sensor origins (e.g. metres).
    """
    a = np.asarray(p_w_a, dtype=float)
    b = np.asarray(p_w_b, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3 or a.shape != b.shape:
        raise CalibrationInputError(
            f"Expected two position arrays of shape (frames, 3), got {a.shape} and {b.shape}"
        )
    if not np.isfinite(known_distance) or known_distance <= 0:
        raise CalibrationInputError(f"known_distance must be a positive length, got {known_distance}")
    d = np.linalg.norm(a - b, axis=1)
    ok = np.isfinite(d)
    if np.count_nonzero(ok) < 2:
        raise CalibrationError(f"need at least 2 frames with both positions, got {np.count_nonzero(ok)}")
    mean = float(np.mean(d[ok]))
    if mean == 0.0:
        raise CalibrationError("the two sensors are reported at the same place: no scale to estimate")
    scale = known_distance / mean
    return ScaleEstimate(
        scale=scale,
        scaled_std=float(scale * np.std(d[ok], ddof=1)),
        mean_reported=mean,
        distances=d,
        n_frames=int(np.count_nonzero(ok)),
    )


def rigidity(d: np.ndarray) -> tuple[float, float]:
    """``(spread, noise)`` of a distance series ``(frames,)`` (NaN where unknown), in its unit:
    its robust spread about the median (1.4826 MAD) and that of its frame-to-frame changes over
    sqrt(2) -- equal, to sampling error, for a fixed distance measured with white noise; a
    distance that changes (a loose mount, a distorted field) spreads far more than its noise."""
    d = d[np.isfinite(d)]
    if d.size < 3:
        return 0.0, 0.0
    spread = mad_std(d)
    noise = mad_std(np.diff(d)) / np.sqrt(2.0)
    return spread, noise
