"""Orientation estimation over recordings: method dispatch, scoring and the orientation CSV.

Errors follow BROAD's definitions (:func:`calibration.orientation.orientation_errors`): total,
heading (about the vertical) and inclination, as RMSE in degrees over the samples to evaluate
where both estimate and reference exist. Estimates are made and scored in ENU; the truth of
simbench datasets and BROAD's optical reference are ENU, so the frames match without any
alignment (an output in NED is converted after scoring).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.orientation import (
    Weighting,
    change_frame,
    fontaine,
    mahony,
    reference_from_data,
    smooth_vectors,
    triad,
    wahba,
)
from simbench.errors import InputError
from simbench.io.imu import ImuRecording

METHODS = ("fontaine", "triad", "wahba", "mahony")


@dataclass(frozen=True)
class OrientationRun:
    """Estimated orientations of a recording.

    Attributes:
        q_enu: ``(F, N, 4)`` ``R_w_s`` in ENU, NaN where not estimable.
        ok: ``(F, N)`` estimated.
        method: the method.
        field_strength_ut, inclination_deg: the reference field used.
    """

    q_enu: np.ndarray
    ok: np.ndarray
    method: str
    field_strength_ut: float
    inclination_deg: float


def estimate(
    rec: ImuRecording, method: str = "fontaine", *, weighting: bool = True, smooth_hz: float | None = None
) -> OrientationRun:
    """Estimate every sensor's orientation at every sample (ENU).

    The reference field (strength, inclination) and gravity are taken from the recording itself
    by :func:`calibration.orientation.reference_from_data` -- one rule for all data.

    Args:
        rec: the recording.
        method: ``fontaine``, ``triad``, ``wahba`` or ``mahony`` (gyro-aided reference).
        weighting: Fontaine's disturbance weighting (``fontaine`` and ``wahba``).
        smooth_hz: zero-phase smoothing cutoff, Hz: weighted by the disturbance weights for
            ``fontaine``, plain low-pass of the inputs for the others.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}: expected one of {', '.join(METHODS)}")
    acc, mag = rec.acc, rec.mag
    if smooth_hz and method != "fontaine":  # Fontaine's estimator smooths with its weights
        acc = smooth_vectors(acc, rec.rate_hz, smooth_hz)
        mag = smooth_vectors(mag, rec.rate_hz, smooth_hz)
    ref = reference_from_data(rec.acc, rec.mag, "enu", valid=rec.valid)
    w = Weighting() if weighting else None
    if method == "triad":
        est = triad(acc, mag, ref, valid=rec.valid)
    elif method == "wahba":
        weights = w.weights(acc, mag, ref) if w is not None else None
        est = wahba(acc, mag, ref, weights=weights, valid=rec.valid)
    elif method == "fontaine":
        est = fontaine(
            acc, mag, ref, weighting=w, valid=rec.valid, rate_hz=rec.rate_hz, temporal_hz=smooth_hz or None
        )
    else:
        est = mahony(acc, rec.gyro, mag, rec.rate_hz, ref, valid=rec.valid)
    return OrientationRun(
        est.q_w_s, est.ok, method, float(np.linalg.norm(ref.field_w)), float(np.rad2deg(ref.inclination))
    )


def in_frame(q_enu: np.ndarray, frame: str) -> np.ndarray:
    """Orientations in the output frame (``enu`` or ``ned``)."""
    return change_frame(q_enu, "enu", frame)
