"""Sourceless orientation from accelerometer and magnetometer (Fontaine et al.), and references.

A tracker of three accelerometers and three magnetometers, no gyroscope, no source: at every
sample the accelerometer's specific force points up (when the sensor does not accelerate) and the
magnetometer sees the Earth field; the orientation ``R_w_s`` (sensor to world) is the rotation
that best carries those two measured vectors onto the world's up and field directions.

**Frames.** World ENU by default (x east, y north, z up; the field points north and down by its
inclination ``I``: ``b_w = (0, cos I, -sin I)``), or NED (x north, y east, z down). Every result
says its frame. Quaternions are scalar-first ``(w, x, y, z)`` of ``R_w_s``. All functions are
vectorised over any leading ``(...)`` axes (frames, sensors).

**Modules**, one concept each (every public name is importable from this package):

- :mod:`.world`: the reference vectors of a frame (:func:`reference`,
  :func:`reference_from_data`, :func:`change_frame`), the common result :class:`Estimate`, and
  BROAD's error angles (:func:`orientation_errors`).
- :mod:`.two_vector`: :func:`triad` (the accelerometer primary) and :func:`wahba` (the optimal
  weighted two-observation solution, closed form or SVD).
- :mod:`.disturbance`: Fontaine's disturbance weighting (:class:`Weighting`, section 2.1.2) and
  zero-phase temporal smoothing (:func:`smooth_vectors`, :func:`weighted_smooth`).
- :mod:`.gauss_newton`: :func:`fontaine`, Fontaine et al.'s iterative estimator, Gauss-Newton on
  a rotation vector, started from TRIAD; both it and :func:`wahba` take the weights.
- :mod:`.magnetometer`: :func:`fit_magnetometer`, hard and soft iron from a recording's own
  samples by an ellipsoid fit, with whether the samples determine it and how steady it makes
  the field strength (:class:`MagnetometerCalibration`); and spans of the recording where
  the field strength departs (a magnet attached for a while), each recalibrated on its own
  samples where they determine it (:func:`fit_disturbed_spans`), the fits followed from the
  magnet's putting-on to its taking-off (:func:`follow_fits`).
- :mod:`.skeleton`: :func:`skeleton_orientation`, every segment at once over the whole
  recording, on the calibrated skeleton (:class:`Skeleton`): each sensor's linear acceleration
  predicted from the chain's motion instead of ignored, heading carried across spans the data do
  not determine; without a skeleton, a smoother with priors on acceleration (:class:`Priors`).
- :mod:`.rotation_acc`: :func:`rotation_acceleration`, the acceleration that rotation itself
  makes at a sensor away from the centre of rotation, sustained in the sensor frame, where the
  data show one (a test with a stated false-alarm rate per window), for the caller to remove.
- :mod:`.lever`: :func:`lever_compensated`, the acceleration of rotation about a centre away
  from the sensor (a lever fixed in the sensor frame, fitted to an estimate's own rates), removed
  and the sensor estimated again where the lever settles (the refit agrees, a stated test).
- :mod:`.trust`: inputs that cannot be trusted: an axis held at its range
  (:func:`saturated_axes`), a field strength that drifts (:func:`field_drift`), no rest
  (:func:`longest_rest`).
- :mod:`.complementary`: :func:`mahony`, a gyro-aided reference (Mahony's explicit
  complementary filter), so users can see how far gyro-free estimation is from an established
  fusion filter.

Samples that cannot be estimated -- NaN input, a zero or near-zero vector, accelerometer and
magnetometer (nearly) parallel, or masked out -- come back as NaN, never dropped, so outputs stay
aligned with inputs.
"""

from calibration.orientation.complementary import mahony
from calibration.orientation.disturbance import Weighting, smooth_vectors, weighted_smooth
from calibration.orientation.gauss_newton import fontaine
from calibration.orientation.lever import Lever, LeverFit, fit_lever, lever_compensated
from calibration.orientation.magnetometer import (
    MagnetometerCalibration,
    SpanCalibration,
    disturbed_spans,
    fit_circle_hard_iron,
    fit_disturbed_spans,
    fit_magnetometer,
    follow_fits,
)
from calibration.orientation.rotation_acc import RotationAcceleration, rotation_acceleration
from calibration.orientation.skeleton import Priors, Skeleton, skeleton_orientation
from calibration.orientation.trust import REST_S, Saturation, field_drift, longest_rest, saturated_axes
from calibration.orientation.two_vector import MIN_SIN_ANGLE, triad, wahba
from calibration.orientation.world import (
    FRAMES,
    GRAVITY,
    MIN_NORM_FRACTION,
    R_NED_ENU,
    Estimate,
    Reference,
    change_frame,
    orientation_errors,
    reference,
    reference_from_data,
)

__all__ = [
    "FRAMES",
    "GRAVITY",
    "MIN_NORM_FRACTION",
    "MIN_SIN_ANGLE",
    "REST_S",
    "R_NED_ENU",
    "Estimate",
    "Lever",
    "LeverFit",
    "MagnetometerCalibration",
    "Priors",
    "Reference",
    "RotationAcceleration",
    "Saturation",
    "Skeleton",
    "SpanCalibration",
    "Weighting",
    "change_frame",
    "disturbed_spans",
    "field_drift",
    "fit_circle_hard_iron",
    "fit_disturbed_spans",
    "fit_lever",
    "fit_magnetometer",
    "follow_fits",
    "fontaine",
    "lever_compensated",
    "longest_rest",
    "mahony",
    "orientation_errors",
    "reference",
    "reference_from_data",
    "rotation_acceleration",
    "saturated_axes",
    "skeleton_orientation",
    "smooth_vectors",
    "triad",
    "wahba",
    "weighted_smooth",
]
