"""Orientation estimation over recordings: method dispatch, scoring and the orientation CSV.

The gyro-free methods are the calibration core's (:mod:`calibration.orientation`): the default,
``skeleton``, estimates every sensor over the whole recording at once, on the skeleton of a
calibration when one is given (:func:`skeleton_from_calibration`), each sensor on its own
otherwise; the per-sample ``fontaine``, ``triad`` and ``wahba`` stay as named methods. The gyro-aided
references are Mahony's complementary filter (the core's, hand-written) and VQF (Laidig and Seel,
"VQF: Highly accurate IMU orientation estimation with bias estimation and magnetic disturbance
rejection", Information Fusion 91, 2023; the authors' ``vqf`` package, its offline variant, which
also uses the samples after each one), by the authors of the BROAD benchmark.

Errors follow BROAD's definitions (:func:`calibration.orientation.orientation_errors`): total,
heading (about the vertical) and inclination, as RMSE in degrees over the samples to evaluate
where both estimate and reference exist. Estimates are made and scored in ENU; the truth of
simbench datasets and BROAD's optical reference are ENU, so the frames match without any
alignment (an output in NED is converted after scoring).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import vqf

from calibration import Calibration
from calibration.errors import CalibrationError
from calibration.orientation import (
    REST_S,
    Estimate,
    MagnetometerCalibration,
    Priors,
    Reference,
    Skeleton,
    SpanCalibration,
    Weighting,
    change_frame,
    disturbed_spans,
    field_drift,
    fit_circle_hard_iron,
    fit_disturbed_spans,
    fit_magnetometer,
    follow_fits,
    fontaine,
    lever_compensated,
    longest_rest,
    mahony,
    reference_from_data,
    rotation_acceleration,
    saturated_axes,
    skeleton_orientation,
    smooth_vectors,
    triad,
    wahba,
)
from calibration.orientation.convention import better_reading
from calibration.orientation.lever import FALSE_ALARM as LEVER_FALSE_ALARM
from calibration.orientation.rotation_acc import FALSE_ALARM as ROTATION_FALSE_ALARM
from calibration.orientation.rotation_acc import WINDOW_S as ROTATION_WINDOW_S
from calibration.orientation.trust import DRIFT_SPREADS
from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.calibration_json import (
    calibration_joints,
    calibration_to_dict,
    check_calibration_document,
    read_calibration_json,
)
from simbench.io.imu import ImuRecording


@dataclass(frozen=True)
class OrientationRun:
    """Estimated orientations of a recording.

    Attributes:
        q_enu: ``(F, N, 4)`` ``R_w_s`` in ENU, NaN where not estimable.
        ok: ``(F, N)`` estimated.
        method: the method.
        field_strength_ut, inclination_deg: the reference field used.
        warnings: what the method found in the data and did about it, one line each (e.g. a
            sustained acceleration of a sensor away from the centre of rotation,
            :func:`rotation_corrected`).
    """

    q_enu: np.ndarray
    ok: np.ndarray
    method: str
    field_strength_ut: float
    inclination_deg: float
    warnings: tuple[str, ...] = ()


def check_recording(rec: ImuRecording) -> None:
    """Refuse a recording whose arrays do not agree: ``acc``, ``gyro``, ``mag`` ``(F, N, 3)``,
    ``valid`` ``(F, N)``, ``time_s`` ``(F,)`` and ``N`` distinct names (``q_true`` ``(F, N, 4)``
    when given); or whose rate is not a finite number of Hz > 0.

    Raises:
        InputError: naming each array's expected and actual shape, or the rate.
    """
    if not (isinstance(rec.rate_hz, int | float) and math.isfinite(rec.rate_hz) and rec.rate_hz > 0):
        raise InputError(
            f"{rec.source}: expected a sample rate of a finite number of Hz > 0, got {rec.rate_hz!r}"
        )
    n, f = len(rec.names), np.shape(rec.time_s)[0] if np.ndim(rec.time_s) == 1 else -1
    if len(set(rec.names)) != n:
        raise InputError(f"{rec.source}: sensor names must be unique, got {list(rec.names)}")
    expected = {"acc": (f, n, 3), "gyro": (f, n, 3), "mag": (f, n, 3), "valid": (f, n)}
    if rec.q_true is not None:
        expected["q_true"] = (f, n, 4)
    for name, shape in expected.items():
        x = getattr(rec, name)
        if not isinstance(x, np.ndarray) or x.shape != shape or f < 0:
            got = x.shape if isinstance(x, np.ndarray) else type(x).__name__
            raise InputError(
                f"{rec.source}: expected {name} as an array of shape {shape} ({f} samples of time_s, "
                f"{n} names), got {got}"
            )


def estimate(
    rec: ImuRecording,
    method: str,
    *,
    weighting: bool = True,
    smooth_hz: float | None = None,
    skeleton: Skeleton | None = None,
    priors: Priors | None = None,
) -> OrientationRun:
    """Estimate every sensor's orientation at every sample (ENU).

    The reference field (strength, inclination) and gravity are taken from the recording itself
    by :func:`calibration.orientation.reference_from_data` -- one rule for all data.

    Args:
        rec: the recording.
        method: a built-in orientation method (registered in :mod:`simbench.estimators.builtin`,
            which runs every one through here).
        weighting: Fontaine's disturbance weighting (``fontaine`` and ``wahba``).
        smooth_hz: zero-phase smoothing cutoff, Hz: weighted by the disturbance weights for
            ``fontaine``, plain low-pass of the inputs for the others; not for ``skeleton``,
            which low-passes its inputs level by level itself (refused).
        skeleton: for ``skeleton``, the body's tree and joints over ``rec``'s sensors (e.g.
            :func:`skeleton_from_calibration`); ``None``: every sensor on its own. The reference
            field then comes from the roots' samples.
        priors: for ``skeleton``, the residuals' standard deviations
            (:class:`calibration.orientation.Priors`; default ``Priors()``), e.g. a sensor on its
            own's speed prior (``lone_speed``).
    """
    check_recording(rec)
    if skeleton is not None and method != "skeleton":
        raise InputError(f"a skeleton is used by the skeleton method only, not {method!r}")
    if priors is not None and method != "skeleton":
        raise InputError(f"priors are used by the skeleton method only, not {method!r}")
    if smooth_hz is not None and method == "skeleton":
        raise InputError(
            "smoothing (smooth_hz) is for the per-sample and gyro-aided methods: the skeleton method "
            "low-passes its inputs level by level itself"
        )
    if method == "skeleton":
        # a sensor on its own away from the centre of a fast rotation: that acceleration removed
        acc, warned = rotation_corrected(rec, skeleton or Skeleton.none(len(rec.names)))
        # the reference from the roots' samples, as skeleton_orientation would take it
        roots = (skeleton or Skeleton.none(len(rec.names))).roots
        ref = reference_from_data(acc[:, roots], rec.mag[:, roots], "enu", valid=rec.valid[:, roots])
        # samples with an accelerometer axis at its range: the axis filled from the joints
        # (skeleton_orientation's acc_clipped), the rest of the sample used as measured
        valid = magnetometer_valid(rec)
        est = skeleton_orientation(
            acc,
            rec.mag,
            rec.rate_hz,
            skeleton,
            ref,
            valid=valid,
            priors=priors,
            acc_clipped=rec.saturated,
        )
        # the other lone sensors: a lever fitted to the estimate's own rates, where it settles
        corrected = [k for k in range(len(rec.names)) if not np.array_equal(acc[:, k], rec.acc[:, k])]
        tree = skeleton or Skeleton.none(len(rec.names))
        q, levers = lever_corrected(rec, tree, est.q_w_s, ref, priors, skip=corrected)
        return OrientationRun(
            q,
            est.ok,
            method,
            float(np.linalg.norm(ref.field_w)),
            float(np.rad2deg(ref.inclination)),
            warned + levers,
        )
    acc, mag = rec.acc, rec.mag
    if smooth_hz and method != "fontaine":  # Fontaine's estimator smooths with its weights
        acc = smooth_vectors(acc, rec.rate_hz, smooth_hz)
        mag = smooth_vectors(mag, rec.rate_hz, smooth_hz)
    ref = reference_from_data(rec.acc, rec.mag, "enu", valid=rec.valid)
    w = Weighting() if weighting else None
    if method == "triad":
        est = triad(acc, mag, ref, valid=rec.valid)
    elif method == "wahba":
        # a sample whose vectors are not finite has NaN weights: it is not used (not valid) anyway
        weights = np.nan_to_num(w.weights(acc, mag, ref), nan=0.0) if w is not None else None
        est = wahba(acc, mag, ref, weights=weights, valid=rec.valid)
    elif method == "fontaine":
        est = fontaine(
            acc, mag, ref, weighting=w, valid=rec.valid, rate_hz=rec.rate_hz, temporal_hz=smooth_hz or None
        )
    elif method == "mahony":
        est = mahony(acc, rec.gyro, mag, rec.rate_hz, ref, valid=rec.valid)
    elif method == "vqf":
        est = vqf_offline(acc, rec.gyro, mag, rec.rate_hz, valid=rec.valid)
    else:
        raise InputError(f"unknown orientation method {method!r} (simbench.estimators.names('orientation'))")
    return OrientationRun(
        est.q_w_s, est.ok, method, float(np.linalg.norm(ref.field_w)), float(np.rad2deg(ref.inclination))
    )


def rotation_corrected(rec: ImuRecording, skeleton: Skeleton) -> tuple[np.ndarray, tuple[str, ...]]:
    """The accelerometers with the sustained sensor-frame acceleration of each sensor on its own
    (:attr:`calibration.orientation.Skeleton.lone`) removed where the data show one
    (:func:`calibration.orientation.rotation_acceleration`: a sensor away from the centre of a
    fast rotation), and a warning per sensor where they do.

    Returns:
        ``(F, N, 3)`` the accelerometers, m/s^2, and the warnings.
    """
    acc = np.array(rec.acc, dtype=float)
    warned = []
    for k in skeleton.lone:
        found = rotation_acceleration(rec.acc[:, k], rec.mag[:, k], rec.rate_hz, rec.valid[:, k])
        if not found.fired:
            continue
        acc[:, k] -= found.offset
        warned.append(
            f"{rec.names[k]}: a sustained acceleration in the sensor frame (a sensor away from the centre "
            f"of a fast rotation) in {found.fired} of {found.windows} windows of {ROTATION_WINDOW_S:g} s "
            f"({100 * found.detected.mean():.2g} % of the samples; false alarm {ROTATION_FALSE_ALARM:g} "
            f"per window), median {found.median_m_s2:.2g} m/s^2: subtracted from the accelerometer there "
            "before the estimate"
        )
    return acc, tuple(warned)


def lever_corrected(
    rec: ImuRecording,
    skeleton: Skeleton,
    q_first: np.ndarray,
    ref: Reference,
    priors: Priors | None,
    skip: tuple[int, ...] | list[int] = (),
) -> tuple[np.ndarray, tuple[str, ...]]:
    """Each sensor on its own (:attr:`calibration.orientation.Skeleton.lone`) estimated again with
    the acceleration of its rotation about a centre away from it removed, where the data show a
    lever that settles (:func:`calibration.orientation.lever_compensated`), and a warning per
    sensor where a lever fires (applied, or not settled and left out).

    Args:
        rec: the recording.
        skeleton: the skeleton the first estimate was made on.
        q_first: ``(F, N, 4)`` the first estimate, ENU.
        ref: the reference it was made with.
        priors: the priors it was made with.
        skip: sensors left as they are (those whose sustained acceleration
            :func:`rotation_corrected` removed: one correction per sensor).

    Returns:
        ``(F, N, 4)`` the orientations, ENU, and the warnings.
    """
    valid = magnetometer_valid(rec)

    def again(acc: np.ndarray, sensors: list[int]) -> np.ndarray:
        clipped = None if rec.saturated is None else rec.saturated[:, sensors]
        # gravity and the dip taken again from the corrected readings (the lever biases both)
        own = reference_from_data(acc, rec.mag[:, sensors], "enu", valid=rec.valid[:, sensors])
        return skeleton_orientation(
            acc,
            rec.mag[:, sensors],
            rec.rate_hz,
            None,
            own,
            valid=valid[:, sensors],
            priors=priors,
            acc_clipped=clipped,
        ).q_w_s

    q, levers = lever_compensated(
        rec.acc,
        q_first,
        [k for k in skeleton.lone if k not in skip],
        ref.gravity,
        rec.rate_hz,
        again,
        valid=rec.valid,
    )
    warned = []
    for lever in levers:
        r = ", ".join(f"{x:.2f}" for x in lever.r_m)
        sd = max(lever.sd_m)
        head = (
            f"{rec.names[lever.sensor]}: an acceleration of rotation about a centre away from the sensor "
            f"(a lever of ({r}) m +- {sd:.2g} in the sensor frame, from the estimate's rates; false alarm "
            f"{LEVER_FALSE_ALARM:g})"
        )
        if lever.applied:
            warned.append(
                f"{head}: removed from the accelerometer and the sensor estimated again (the lever "
                f"refitted from that estimate agrees, chi-square {lever.moved:.3g}, and explains the "
                "accelerometer better)"
            )
        else:
            why = (
                "the corrected estimate explains the accelerometer no better"
                if lever.settled
                else f"the lever refitted from the corrected estimate moves (chi-square {lever.moved:.3g})"
            )
            warned.append(f"{head}: not removed ({why}), the estimate is the first one")
    return q, tuple(warned)


def vqf_offline(
    acc: np.ndarray, gyro: np.ndarray, mag: np.ndarray, rate_hz: float, *, valid: np.ndarray | None = None
) -> Estimate:
    """VQF's offline 9D orientation of each sensor (ENU, magnetic north along y, as ours).

    Args:
        acc, gyro, mag: ``(F, N, 3)`` in the sensor frame: m/s^2, rad/s, and any unit (uT).
        rate_hz: sample rate, Hz.
        valid: optional ``(F, N)`` mask. VQF runs through every sample, so a sample that is
            masked or not finite is filled by linear interpolation in time from its neighbours
            (held at the ends) and comes back NaN.

    Returns:
        The orientations ``R_w_s`` as ``(F, N, 4)`` scalar-first quaternions.
    """
    if not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and rate_hz > 0):
        # VQF asserts it in C++, which ends the process
        raise InputError(f"Expected rate_hz a finite number of Hz > 0, got {rate_hz!r}")
    acc, gyro, mag = (np.asarray(x, dtype=float) for x in (acc, gyro, mag))
    if not (acc.shape == gyro.shape == mag.shape and acc.ndim == 3 and acc.shape[-1] == 3):
        raise InputError(
            f"Expected acc, gyro and mag of one shape (frames, sensors, 3), got {acc.shape}, {gyro.shape}, "
            f"{mag.shape}"
        )
    ok = np.isfinite(acc).all(axis=-1) & np.isfinite(gyro).all(axis=-1) & np.isfinite(mag).all(axis=-1)
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool)
    out = np.full((*acc.shape[:-1], 4), np.nan)
    frames = np.arange(acc.shape[0], dtype=float)
    for k in range(acc.shape[1]):
        use = ok[:, k]
        if use.sum() < 2:
            continue
        filled = [
            np.ascontiguousarray(
                np.column_stack([np.interp(frames, frames[use], x[use, k, i]) for i in range(3)])
            )
            for x in (gyro, acc, mag)
        ]
        q = vqf.offlineVQF(*filled, 1.0 / rate_hz)["quat9D"]
        out[use, k] = q[use]
    return Estimate(out, ok, "enu")


def skeleton_of(cal: Calibration) -> Skeleton:
    """The tree and joints of a calibration in memory (:func:`calibration.calibrate`, e.g. of a
    session's own tracker poses) as the skeleton method's skeleton, over the calibration's sensors.
    Its single-axis joints are not made hinges here (:func:`skeleton_from_calibration` does):
    a still session's fits turn single-axis for want of motion."""
    lp, lc = cal.joint_arrays()
    return Skeleton(np.asarray(cal.hierarchy.parent), lp, lc)


def skeleton_from_calibration(
    source: str | os.PathLike[str] | Calibration | Mapping[str, Any], names: tuple[str, ...]
) -> Skeleton:
    """The skeleton of a calibration JSON (``simbench calibrate --json``, or a dataset's
    ``--truth-json``), or of a calibration in memory (:func:`simbench.calibrate`, or a calibration
    document such as :func:`simbench.io.dataset.truth_calibration_dict`'s, read as its JSON would
    be), over a recording's sensors: its tree and its joints in the sensors' frames.

    The calibration must be of the same sensors mounted as in the recording (e.g. made from the
    session's magnetic-tracker poses, or from an earlier session without re-mounting). Sensors
    that the calibration leaves out are their own roots; a joint it found single-axis is a hinge
    about its axis (``axis_in_parent``, ``axis_in_child``); a joint with a ``range`` keeps to it
    (a file's: ``simbench calibrate`` writes the ranges its poses show; one in memory has none).

    Raises:
        InputError: the file is not a calibration JSON, is not in metres, names sensors the
            recording lacks, or its joints do not form a tree; ``source`` is neither a path nor a
            calibration.
    """
    if isinstance(source, Calibration):  # the checks a file gets (e.g. a centre not finite)
        where: str | os.PathLike[str] = "the calibration given"
        doc = check_calibration_document(calibration_to_dict(source), where)
    elif isinstance(source, str | os.PathLike):
        doc = read_calibration_json(source)
        where = source
    elif isinstance(source, Mapping):
        where = "the calibration given"
        doc = check_calibration_document(dict(source), where)
    else:
        raise InputError(
            "skeleton: expected a Skeleton, a Calibration (simbench.calibrate), a calibration document "
            f"or the path of a calibration JSON, got {type(source).__name__}"
        )
    units = doc.get("units", "m")
    if units != "m":
        raise InputError(f"{where}, key units: expected 'm', got {units!r}")
    joints = calibration_joints(doc, names, source=where)
    n = len(names)
    parent = np.full(n, -1)
    lp = np.zeros((n, 3))
    lc = np.zeros((n, 3))
    parent[joints.child_index] = joints.parent_index
    lp[joints.child_index] = joints.joint_in_parent
    lc[joints.child_index] = joints.joint_in_child
    a_p = np.zeros((n, 3))
    a_c = np.zeros((n, 3))
    centre = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    radius = np.full(n, np.inf)
    for k, entry in enumerate(doc["joints"]):
        if entry.get("range") is not None:  # checked by read_calibration_json
            centre[joints.child_index[k]] = quat_to_matrix(np.asarray(entry["range"]["centre_in_parent"]))
            radius[joints.child_index[k]] = np.deg2rad(entry["range"]["radius_deg"])
    for k, entry in enumerate(doc["joints"]):
        if not joints.single_axis[k]:
            continue
        axes = [entry.get("axis_in_parent"), entry.get("axis_in_child")]
        if not all(_is_vector(a) for a in axes):
            raise InputError(
                f"{where}: joints[{k}] is single-axis but its axis_in_parent and axis_in_child are not "
                f"3 finite numbers each: {axes}"
            )
        a_p[joints.child_index[k]], a_c[joints.child_index[k]] = (
            np.asarray(a) / np.linalg.norm(a) for a in axes
        )
    ranges = (centre, radius) if np.isfinite(radius).any() else (None, None)
    try:
        return Skeleton(parent, lp, lc, a_p, a_c, *ranges)
    except CalibrationError as exc:
        raise InputError(f"{where}: the joints are not a tree over the recording's sensors: {exc}") from None


def _is_vector(a: object) -> bool:
    """3 finite numbers, not all zero."""
    return (
        isinstance(a, list)
        and len(a) == 3
        and all(isinstance(x, int | float) and not isinstance(x, bool) and np.isfinite(x) for x in a)
        and any(x != 0 for x in a)
    )


def in_frame(q_enu: np.ndarray, frame: str) -> np.ndarray:
    """Orientations in the output frame (``enu`` or ``ned``)."""
    return change_frame(q_enu, "enu", frame)


#: A fit is applied only where it at least halves the spread of the field strength: raw samples
#: that are already as steady are already calibrated (BROAD's: 2.0 % -> 1.8 %), and a fit would
#: only add its own error.
SPREAD_GAIN = 0.5


def calibrate_magnetometers(
    rec: ImuRecording,
) -> tuple[ImuRecording, dict[str, MagnetometerCalibration | str]]:
    """Each sensor's magnetometer calibrated from its own samples (hard and soft iron by an
    ellipsoid fit, :func:`calibration.orientation.fit_magnetometer`), applied where it is worth
    it (:func:`applies`); then each span where the field strength departs from the recording's
    (a magnet attached to the sensor for a while) fitted on its own samples where they determine
    it (:func:`calibration.orientation.fit_disturbed_spans`), and those fits applied from the
    magnet's putting-on to its taking-off (:func:`calibration.orientation.follow_fits`; the
    recording's notes say where).

    Returns:
        The recording with the calibrated magnetometers (a sensor whose fit does not apply keeps
        its raw samples), and per sensor its fit or why there is none.
    """
    check_recording(rec)
    mag = np.array(rec.mag, dtype=float)
    valid = magnetometer_valid(rec)
    fits: dict[str, MagnetometerCalibration | str] = {}
    for k, name in enumerate(rec.names):
        try:
            fit = fit_magnetometer(rec.mag[:, k], valid[:, k])
        except CalibrationError as exc:
            fits[name] = str(exc)
            continue
        fits[name] = fit
        if applies(fit):
            mag[:, k] = fit.apply(rec.mag[:, k])
    _circles(rec, mag, fits, valid)
    applied = [n for n, f in fits.items() if not isinstance(f, str) and applies(f)]
    notes = [
        f"magnetometers calibrated from the recording: {len(applied)} of {len(fits)} "
        f"({', '.join(applied) or 'none'})"
    ]
    for k, name in enumerate(rec.names):
        spans = fit_disturbed_spans(mag[:, k], rec.rate_hz, valid[:, k])
        fitted = [s.fit for s in spans if s.applied]
        follows = follow_fits(mag[:, k], rec.rate_hz, fitted, valid[:, k])
        before = mag[:, k].copy()
        for i, fit in enumerate(fitted):
            mag[follows == i, k] = fit.apply(before[follows == i])
        if spans:
            notes.append(describe_spans(name, spans, rec.time_s, follows))
    return dataclasses.replace(rec, mag=mag, notes=(*rec.notes, *notes)), fits


def _circles(
    rec: ImuRecording, mag: np.ndarray, fits: dict[str, MagnetometerCalibration | str], valid: np.ndarray
) -> None:
    """The sensors whose sphere the samples do not determine (turns about one axis), calibrated
    by the circle and the dip (:func:`calibration.orientation.fit_circle_hard_iron`) on their
    magnetometer's ``valid`` ``(F, N)`` samples, the field's strength and dip from the sensors
    calibrated already; ``mag`` and ``fits`` updated in place."""
    done = [
        k
        for k, n in enumerate(rec.names)
        if not isinstance(fits[n], str) and applies(fits[n]) and not fits[n].left_out
    ]
    if not done:
        return
    ref = reference_from_data(rec.acc[:, done], mag[:, done], "enu", valid=rec.valid[:, done])
    for k, name in enumerate(rec.names):
        fit = fits[name]
        if k in done or (not isinstance(fit, str) and fit.determined and not fit.left_out):
            continue
        up = np.nanmean(np.where(rec.valid[:, k, None], rec.acc[:, k], np.nan), axis=0)
        try:
            circle = fit_circle_hard_iron(rec.mag[:, k], up, ref.inclination, valid[:, k])
        except CalibrationError:
            continue
        if applies(circle):
            fits[name] = dataclasses.replace(circle, left_out=())
            mag[:, k] = circle.apply(rec.mag[:, k])


def magnetometer_valid(rec: ImuRecording) -> np.ndarray:
    """``(F, N)`` the samples whose magnetometer is usable: the valid ones and those left out
    for an accelerometer axis at its range only (:attr:`ImuRecording.saturated`)."""
    if rec.saturated is None:
        return rec.valid
    saturated = np.asarray(rec.saturated)
    if saturated.dtype != bool or saturated.shape != (*rec.valid.shape, 3):
        raise InputError(
            f"{rec.source}: expected saturated as booleans of shape {(*rec.valid.shape, 3)} "
            f"(frames, sensors, axes), got {saturated.dtype} {saturated.shape}"
        )
    return rec.valid | saturated.any(axis=-1)


def disturbed_fraction(rec: ImuRecording) -> dict[str, float]:
    """Per sensor, the fraction of its usable samples whose field strength still departs from the
    recording's (:func:`calibration.orientation.disturbed_spans`, after whatever calibration
    ``rec`` carries): where the magnetometer is disturbed and nothing recalibrated it, the
    heading rests on the other terms (joints, smoothness) and on a disturbed field."""
    out = {}
    valid = magnetometer_valid(rec)
    for k, name in enumerate(rec.names):
        spans, _ = disturbed_spans(rec.mag[:, k], rec.rate_hz, valid[:, k])
        inside = np.zeros(valid.shape[0], dtype=bool)
        for a, b in spans:
            inside[a:b] = True
        usable = valid[:, k] & np.isfinite(rec.mag[:, k]).all(axis=1)
        out[name] = float((inside & usable).sum() / max(int(usable.sum()), 1))
    return out


def describe_spans(name: str, spans: list[SpanCalibration], time_s: np.ndarray, follows: np.ndarray) -> str:
    """One line on a sensor's spans of a different field: which were fitted on their own samples,
    and where the fits were applied (``follows``, :func:`calibration.orientation.follow_fits`
    over the fitted spans in order)."""
    parts = []
    fitted = [s for s in spans if s.applied]
    for s in spans:
        when = f"{time_s[s.start]:.1f}-{time_s[s.stop - 1]:.1f} s"
        if s.applied:
            parts.append(f"{when} fitted ({s.fit.model}, |b| spread {100 * s.fit.spread_after:.2g} %)")
        else:
            parts.append(f"{when} not fitted")
    line = f"magnetometer {name}: field strength departs in {len(spans)} span(s): " + "; ".join(parts)
    edges = np.flatnonzero(np.diff(follows) != 0) + 1
    runs = [
        (a, b, int(follows[a]))
        for a, b in zip(np.r_[0, edges], np.r_[edges, follows.size], strict=True)
        if follows[a] >= 0
    ]
    applied = [
        f"{time_s[a]:.1f}-{time_s[b - 1]:.1f} s (the fit of "
        f"{time_s[fitted[i].start]:.1f}-{time_s[fitted[i].stop - 1]:.1f} s)"
        for a, b, i in runs
    ]
    return line + "; recalibrated " + (", ".join(applied) if applied else "nowhere: left to the estimator")


def applies(fit: MagnetometerCalibration) -> bool:
    """The samples determine the fit, and it makes the field strength steadier by
    :data:`SPREAD_GAIN` at least."""
    return fit.determined and fit.spread_after <= SPREAD_GAIN * fit.spread_before


def describe_fit(fit: MagnetometerCalibration | str) -> str:
    """One line on a sensor's magnetometer fit (or why there is none)."""
    if isinstance(fit, str):
        return f"not calibrated: {fit}"
    if applies(fit):
        verdict = {
            "ellipsoid": "applied",
            "hard iron": "applied (hard iron only: too few directions for the soft iron)",
        }.get(fit.model, "applied (hard iron only, turns about one axis: the circle and the field's dip)")
    elif not fit.determined:
        verdict = "not applied: the samples determine none of its parameters"
    else:
        verdict = "not applied: the raw field strength is about as steady (already calibrated)"
    soft = float(np.linalg.norm(fit.soft_iron - np.eye(3), 2))
    hard = ", ".join(f"{x:.3g}" for x in fit.hard_iron)
    return (
        f"{verdict}; hard iron ({hard}), soft iron {100 * soft:.2g} % from identity, field "
        f"{fit.field_strength:.4g}; |m| spread {100 * fit.spread_before:.2g} % -> "
        f"{100 * fit.spread_after:.2g} %; "
        f"directions covered {', '.join(f'{x:.2f}' for x in fit.coverage)} (0.58 each all round)"
        + "".join(f"; left out, not determined: {x}" for x in fit.left_out)
    )


def convention_warnings(rec: ImuRecording, q_enu: np.ndarray) -> tuple[str, ...]:
    """A warning for each sensor whose estimate fits the accelerometer significantly better read in
    another common convention than the stated one (scalar-first, sensor to world, ENU):
    :func:`calibration.orientation.convention.better_reading`.

    Args:
        rec: the recording the estimate was made from.
        q_enu: ``(F, N, 4)`` the estimate, as the estimator returned it.
    """
    out = []
    for k, name in enumerate(rec.names):
        got = better_reading(q_enu[:, k], rec.acc[:, k], rec.rate_hz, rec.valid[:, k])
        if got is not None:
            out.append(
                f"{name}: the estimate fits the accelerometer better read as {got.alternative} (median "
                f"tilt error {got.alternative_deg:.3g} deg against {got.stated_deg:.3g} deg as given; "
                f"better in {got.blocks_better} of {got.blocks} one-second blocks, sign test "
                f"p = {got.p_value:.2g}): "
                "orientations are scalar-first quaternions of sensor to world in ENU (docs/conventions.md)"
            )
    return tuple(out)


def input_warnings(rec: ImuRecording, builtin: bool = False, gyro_aided: bool = False) -> tuple[str, ...]:
    """Warnings on inputs that cannot be trusted (:mod:`calibration.orientation.trust`), one
    line each, sensor by sensor: a gyroscope or accelerometer axis held at its range
    (saturated), a magnetometer whose field strength drifts, and -- for a built-in method, which
    takes the reference gravity and field dip from the recording -- a recording with no rest
    (a gyro-aided one also estimates its gyroscope's bias at rest). A user's estimator's needs
    are not known: no rest is not named for it.

    Args:
        rec: the recording as read (before any magnetometer calibration).
        builtin: the method is a built-in one.
        gyro_aided: the method integrates the gyroscope (the registry's ``needs``).
    """
    check_recording(rec)
    out = []
    xyz = "xyz"
    for k, name in enumerate(rec.names):
        valid = rec.valid[:, k]
        for what, x, unit, use in (
            ("gyroscope", rec.gyro[:, k], "rad/s", None),
            ("accelerometer", rec.acc[:, k], "m/s^2", magnetometer_valid(rec)[:, k]),
        ):
            for s in saturated_axes(x, use):
                out.append(
                    f"{name}: {what} axis {xyz[s.axis]} held at +-{s.value:.4g} {unit} on "
                    f"{100 * s.fraction:.2g} % of the samples: saturated (its range), the reading there "
                    "is not the motion's"
                    + (" (the gyro-aided methods integrate it)" if what == "gyroscope" else "")
                )
        change, spread = field_drift(rec.mag[:, k], rec.time_s, magnetometer_valid(rec)[:, k])
        if spread > 0 and abs(change) > DRIFT_SPREADS * spread:
            out.append(
                f"{name}: the magnetometer's field strength drifts by {change:+.3g} uT over the recording "
                f"({abs(change) / spread:.1f} times its spread about the trend): a gain or offset that "
                "changes, or a field that does; the heading rests on it"
            )
        if builtin:
            rest = longest_rest(rec.acc[:, k], rec.gyro[:, k], rec.rate_hz, valid)
            if rest < REST_S:
                bias = " and the gyroscope's bias is not estimated at rest" if gyro_aided else ""
                out.append(
                    f"{name}: no rest of {REST_S:g} s in the recording (longest {rest:.2g} s): the "
                    f"reference gravity and the field's dip are taken from moving samples{bias}"
                )
    return tuple(out)
