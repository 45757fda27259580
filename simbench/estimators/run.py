"""Running any estimator on its data: what it needs checked first, what it returns checked after.

:func:`run_joints` and :func:`run_orientation` give every estimator, built-in or not, the same
treatment: the hierarchy, rate and gyroscope it needs are there, its parameters are its own, and
its result is of the right shape, finite, of the recording's sensors and in the poses' unit. What a
user's estimator does wrong (raises, returns NaN or the wrong sensors, a command that fails) is an
:class:`EstimatorError` naming it; a harness (``simbench bench``, studies) records that as a failure
and goes on.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any

import numpy as np

from calibration import Calibration
from calibration.diagnostics import estimate_warnings, joint_residuals
from calibration.orientation import Skeleton
from calibration.pipeline import default_keep_frame_residuals
from simbench.errors import InputError
from simbench.estimators.builtin import joints_of
from simbench.estimators.command import EstimatorError
from simbench.estimators.registry import Estimator, JointsResult, OrientationResult
from simbench.io.calibration_json import CalibrationJoints, calibration_joints, check_calibration_document
from simbench.io.imu import ImuRecording
from simbench.io.poses import PoseRecording
from simbench.units import LENGTH_UNITS, metres_per_unit


def check_hierarchy(
    hierarchy: Mapping[str, str], names: tuple[str, ...], where: str = "hierarchy"
) -> dict[str, str]:
    """A ``{child: parent}`` of the recording's sensors, as a plain dict.

    Raises:
        InputError: not a mapping of names, a sensor the recording lacks, a sensor its own parent.
    """
    if not isinstance(hierarchy, Mapping) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in hierarchy.items()
    ):
        raise InputError(f"{where}: expected {{child: parent}} of sensor names, got {hierarchy!r}")
    unknown = sorted({s for edge in hierarchy.items() for s in edge} - set(names))
    if unknown:
        raise InputError(f"{where}: sensor(s) {unknown} are not in the recording ({', '.join(names)})")
    own = sorted(c for c, p in hierarchy.items() if c == p)
    if own:
        raise InputError(f"{where}: sensor(s) {own} are their own parent")
    return dict(hierarchy)


class _TimeUp(BaseException):
    """Raised in the main thread when a Python estimator's time limit runs out (a BaseException,
    so that the estimator's own ``except Exception`` does not swallow it)."""


@contextmanager
def _time_limit(seconds: float | None) -> Iterator[None]:
    """Raise :class:`_TimeUp` after ``seconds`` of wall time (POSIX interval timer; only in the
    main thread, where Python delivers signals; elsewhere, or with ``None``, no limit)."""
    if (
        seconds is None
        or threading.current_thread() is not threading.main_thread()
        or not hasattr(signal, "setitimer")
    ):
        yield
        return

    def up(signum: int, frame: object) -> None:
        raise _TimeUp

    previous = signal.signal(signal.SIGALRM, up)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def read_only(data: Any) -> Any:
    """The recording with every array a read-only view: a user's estimator that writes into its
    input raises (named) instead of changing the data the next estimator gets."""
    changes = {}
    for f in dataclasses.fields(data):
        value = getattr(data, f.name)
        if isinstance(value, np.ndarray):
            view = value.view()
            view.flags.writeable = False
            changes[f.name] = view
    return dataclasses.replace(data, **changes)


def _call(est: Estimator, time_limit_s: float | None, data: Any, kwargs: dict[str, Any]) -> Any:
    """Call the estimator on its data (a user's on a read-only view of it); a user's exception,
    or a Python estimator still running after ``time_limit_s`` (a command keeps its own limit),
    becomes an :class:`EstimatorError`."""
    if est.origin == "builtin":
        return est.fn(data, **kwargs)
    data = read_only(data)
    limit = None if est.origin == "command" else time_limit_s
    try:
        with _time_limit(limit):
            return est.fn(data, **kwargs)
    except EstimatorError:
        raise
    except _TimeUp:
        raise EstimatorError(
            f"estimator {est.name!r} did not return within its time limit of {limit:g} s; stopped"
        ) from None
    except Exception as exc:
        raise EstimatorError(f"estimator {est.name!r} raised {type(exc).__name__}: {exc}") from None


def _arguments(
    est: Estimator, params: Mapping[str, Any] | None, time_limit_s: float | None
) -> dict[str, Any]:
    """The estimator's arguments: its defaults, then the time limit for a command that declares
    one, then ``params``."""
    limit = (
        {"time_limit_s": time_limit_s} if time_limit_s is not None and "time_limit_s" in est.defaults else {}
    )
    return est.arguments({**limit, **(params or {})})


def run_joints(
    est: Estimator,
    data: PoseRecording | ImuRecording,
    *,
    hierarchy: Mapping[str, str] | None = None,
    params: Mapping[str, Any] | None = None,
    time_limit_s: float | None = None,
) -> JointsResult:
    """Run a joints estimator.

    Args:
        est: a ``joints`` estimator.
        data: its data: a pose recording (positions in ``data.unit``), or an IMU recording for an
            estimator whose ``data`` is ``imu``.
        hierarchy: ``{child: parent}``; required when the estimator needs one; an estimator that
            does not take one infers its own tree (given, it is then ignored).
        params: parameter values, over the estimator's defaults.
        time_limit_s: a user's estimator's time limit, s (a command's ``time_limit_s`` parameter;
            a Python one's wall time, where it runs in the main thread); ``None``: none but a
            command's default.

    Returns:
        The joints, centres in the unit of ``data``'s positions (metres for an IMU recording).

    Raises:
        InputError: the data is not what the estimator takes, a hierarchy it needs is missing,
            an unknown parameter; :class:`EstimatorError` for a user's estimator that fails.
    """
    if est.kind != "joints":
        raise InputError(f"{est.name!r} estimates {est.kind}, not joints")
    expected = PoseRecording if est.data == "poses" else ImuRecording
    if not isinstance(data, expected):
        raise InputError(
            f"{est.name!r} estimates from {est.data}: expected a {expected.__name__}, "
            f"got {type(data).__name__}"
        )
    if hierarchy is not None:
        hierarchy = check_hierarchy(hierarchy, data.names)
    elif "hierarchy" in est.needs:
        raise InputError(
            f"{est.name!r} fits the joints of a given hierarchy: give one (--hierarchy FILE.json)"
        )
    _check_needs(est, data)
    kwargs = _arguments(est, params, time_limit_s)
    if est.takes_hierarchy:
        kwargs["hierarchy"] = hierarchy
    got = _call(est, time_limit_s, data, kwargs)
    return joints_result(got, est.name, data.names, getattr(data, "unit", "m"))


def with_residuals(result: JointsResult, rec: PoseRecording) -> JointsResult:
    """``result`` with how its joints fit ``rec``'s poses and the warnings O'Brien's calibration
    gives its own joints (:func:`calibration.diagnostics.joint_residuals` and
    :func:`~calibration.diagnostics.estimate_warnings`: two passes over the poses, which
    :func:`simbench.calibrate` makes for a user and a study does not)."""
    j = result.joints
    res = joint_residuals(
        rec.R_w_s,
        rec.p_w_s,
        j.parent_index,
        j.child_index,
        j.joint_in_parent,
        j.joint_in_child,
        valid=rec.valid,
        keep_frames=default_keep_frame_residuals(rec.R_w_s, len(rec), 2 * len(j.child)),
    )
    pairs = [(int(p), int(c)) for p, c in zip(j.parent_index, j.child_index, strict=True)]
    warnings = estimate_warnings(rec.names, pairs, res, metres_per_unit(rec.unit))
    return dataclasses.replace(result, residuals=res, warnings=tuple(warnings))


def joints_result(got: Any, name: str, names: tuple[str, ...], unit: str = "m") -> JointsResult:
    """What a joints estimator returned, as a checked :class:`JointsResult` in ``unit``: every
    form goes through the calibration document's one check
    (:func:`simbench.io.calibration_json.check_calibration_document`).

    Raises:
        EstimatorError: not one of the accepted types, a malformed document (centres not finite or
            beyond reach, a sensor the child of two joints or joined with itself), sensors the data
            lacks, an unknown unit.
    """
    calibration = None
    notes: tuple[str, ...] = ()
    if isinstance(got, JointsResult):
        calibration, notes, got = got.calibration, got.notes, got.joints
    if isinstance(got, Calibration):
        calibration, notes, got = got, got.warnings, joints_of(got)
    if isinstance(got, CalibrationJoints):
        got = _document(got, unit, name)
    if not isinstance(got, Mapping):
        raise EstimatorError(
            f"estimator {name!r} returned a {type(got).__name__}; expected a calibration document "
            "(dict with 'joints'), a JointsResult, a CalibrationJoints or a Calibration"
        )
    where = f"estimator {name!r}'s result"
    doc_unit = got.get("units", "m")
    if not isinstance(doc_unit, str) or doc_unit not in LENGTH_UNITS:
        raise EstimatorError(f"{where}: expected units one of {list(LENGTH_UNITS)}, got {doc_unit!r}")
    try:
        doc = check_calibration_document(dict(got), where)
        joints = calibration_joints(doc, names, source=where)
    except InputError as exc:
        raise EstimatorError(str(exc)) from None
    factor = metres_per_unit(doc_unit) / metres_per_unit(unit)
    joints = CalibrationJoints(
        joints.parent,
        joints.child,
        joints.parent_index,
        joints.child_index,
        joints.joint_in_parent * factor,
        joints.joint_in_child * factor,
        joints.single_axis,
    )
    return JointsResult(joints, calibration=calibration, notes=tuple(notes), unit=unit)


def _document(joints: CalibrationJoints, unit: str, name: str) -> dict[str, Any]:
    """A :class:`CalibrationJoints` as the calibration document (in ``unit``) it stands for.

    Raises:
        EstimatorError: arrays that do not agree with the joints' names.
    """
    n = len(joints.child)
    jp = np.asarray(joints.joint_in_parent, dtype=float)
    jc = np.asarray(joints.joint_in_child, dtype=float)
    if (
        jp.shape != (n, 3)
        or jc.shape != (n, 3)
        or len(joints.parent) != n
        or np.shape(joints.single_axis) != (n,)
    ):
        raise EstimatorError(
            f"estimator {name!r}: expected {n} joints' joint_in_parent and joint_in_child of shape ({n}, 3), "
            f"got {jp.shape} and {jc.shape} for {len(joints.parent)} parents"
        )
    return {
        "units": unit,
        "joints": [
            {
                "parent": joints.parent[k],
                "child": joints.child[k],
                "joint_in_parent": jp[k].tolist(),
                "joint_in_child": jc[k].tolist(),
                "single_axis": bool(joints.single_axis[k]),
            }
            for k in range(n)
        ],
    }


def run_orientation(
    est: Estimator,
    imu: ImuRecording,
    *,
    skeleton: Skeleton | None = None,
    params: Mapping[str, Any] | None = None,
    time_limit_s: float | None = None,
) -> OrientationResult:
    """Run an orientation estimator.

    Args:
        est: an ``orientation`` estimator.
        imu: the recording.
        skeleton: the calibrated skeleton, for an estimator that takes one.
        params: parameter values, over the estimator's defaults.
        time_limit_s: a user's estimator's time limit, s (as :func:`run_joints`).

    Returns:
        ``(F, N, 4)`` quaternions of ``R_w_s`` in ENU and where they were estimated.

    Raises:
        InputError: a skeleton for an estimator that takes none, an unknown parameter;
            :class:`EstimatorError` for a user's estimator that fails.
    """
    if est.kind != "orientation":
        raise InputError(f"{est.name!r} estimates {est.kind}, not orientation")
    if not isinstance(imu, ImuRecording):
        raise InputError(f"{est.name!r}: expected an ImuRecording, got {type(imu).__name__}")
    if skeleton is not None and not est.takes_skeleton:
        raise InputError(f"a skeleton is used by estimators that take one ({est.name!r} does not)")
    _check_needs(est, imu)
    kwargs = _arguments(est, params, time_limit_s)
    if est.takes_skeleton:
        kwargs["skeleton"] = skeleton
    got = _call(est, time_limit_s, imu, kwargs)
    return orientation_result(got, est.name, imu)


def orientation_result(got: Any, name: str, imu: ImuRecording) -> OrientationResult:
    """What an orientation estimator returned, as a checked :class:`OrientationResult`.

    Raises:
        EstimatorError: not quaternions of shape ``(F, N, 4)``, quaternions not of unit norm (to
            1e-3), nothing estimated.
    """
    if isinstance(got, OrientationResult):
        q = got.q_enu
    elif hasattr(got, "q_enu"):
        q = got.q_enu
    else:
        q = got
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError):
        raise EstimatorError(
            f"estimator {name!r} returned a {type(got).__name__}; expected (F, N, 4) quaternions"
        ) from None
    shape = (imu.time_s.size, len(imu.names), 4)
    if q.shape != shape:
        raise EstimatorError(f"estimator {name!r}: expected quaternions of shape {shape}, got {q.shape}")
    ok = np.isfinite(q).all(axis=-1)
    if not ok.any():
        raise EstimatorError(f"estimator {name!r} estimated no sample (every quaternion NaN)")
    norm = np.linalg.norm(q[ok], axis=-1)
    off = np.abs(norm - 1)
    if off.max() > 1e-3:
        raise EstimatorError(
            f"estimator {name!r}: expected unit quaternions (qw, qx, qy, qz), got norms from "
            f"{norm.min():.6g} to {norm.max():.6g}"
        )
    if isinstance(got, OrientationResult):
        return OrientationResult(q, ok, got.field_strength_ut, got.inclination_deg)
    return OrientationResult(
        q,
        ok,
        float(getattr(got, "field_strength_ut", math.nan)),
        float(getattr(got, "inclination_deg", math.nan)),
    )


def _check_needs(est: Estimator, data: PoseRecording | ImuRecording) -> None:
    if "rate" in est.needs and not (math.isfinite(data.rate_hz) and data.rate_hz > 0):
        raise InputError(
            f"{est.name!r} needs a sample rate; the recording's time stamps give {data.rate_hz!r} Hz"
        )
    if "gyro" in est.needs and not np.isfinite(getattr(data, "gyro", np.nan)).any():
        raise InputError(f"{est.name!r} needs gyroscope readings; the recording has none")
