"""The public Python API: simulate -> calibrate -> score -> orient in a handful of lines.

    import simbench as sb

    ds = sb.simulate(model="linkage", motion="exercise", sensors="ascension-flock", duration_s=45, seed=1)
    cal = sb.calibrate(ds)                  # or calibration.calibrate(R_w_s, p_w_s, names) on arrays
    result = sb.score(cal, ds)              # errors per joint and limb, hierarchy right/wrong edges
    ori = sb.orient(ds, method="fontaine")  # orientations and their errors against the truth
    sb.export(ds, sto="imu.sto", mjcf="skeleton.xml")  # files for OpenSim, MuJoCo and others

Everything is in memory (no temporary files) and in SI units; a tracker's unit scale factor is
carried by the Dataset and applied by :func:`score`.

This module is also the command line's one door to the layers below (``tests/
test_cli_through_api.py``): whatever ``simbench`` does, a Python user does here too -- read a
recording (:func:`read_poses`, :func:`read_imu`, :func:`read_hierarchy`), find slips
(:func:`slip_reports`), write the calibration JSON (:func:`calibration_document`,
:func:`write_calibration`), calibrate live (:func:`follow`, :func:`replay`), the unit scale
(:func:`unit_scale`) -- and the names it needs from the estimator registry and the calibration
core are re-exported from here.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration import Calibration, SlipReport, detect_slip
from calibration import calibrate as calibrate_arrays
from calibration import unit_scale as unit_scale_arrays
from calibration.joint import LOCATED_RANK
from calibration.orientation import Priors, Skeleton
from calibration.scale import ScaleEstimate, rigidity
from calibration.slip import FALSE_ALARMS_PER_HOUR, SLIP_WINDOW_S
from calibration.streaming import LiveState, SlipAlert, StreamingCalibrator
from simbench.errors import CalibrationError, CalibrationInputError, InputError
from simbench.estimators import (
    DEFAULT_JOINTS,
    DEFAULT_ORIENTATION,
    TIME_LIMIT_S,
    Estimator,
    JointsResult,
    joints_result,
    orientation_result,
    resolve,
    run_joints,
    run_orientation,
)
from simbench.estimators import names as estimator_names
from simbench.estimators.registry import from_callable
from simbench.estimators.run import with_residuals
from simbench.experiments.live import RATE_FRAMES as LIVE_RATE_FRAMES
from simbench.experiments.live import REFRESH_S as LIVE_REFRESH_S
from simbench.experiments.live import LiveOptions, LiveUpdate
from simbench.experiments.live import follow as follow_file
from simbench.experiments.live import replay as replay_recording
from simbench.experiments.pool import one_blas_thread
from simbench.io.atomic import atomic_write_text, output_set
from simbench.io.c3d import read_c3d
from simbench.io.calibration_json import calibration_to_dict, read_calibration_json
from simbench.io.calibration_json import write_calibration_json as write_calibration
from simbench.io.dataset import Dataset, write_dataset
from simbench.io.dataset import truth_calibration_dict as truth_document
from simbench.io.examples import write_examples
from simbench.io.export import SOURCES as EXPORT_SOURCES
from simbench.io.export import check_outputs, export_c3d_markers, export_dataset
from simbench.io.hierarchy_json import read_hierarchy_json as read_hierarchy
from simbench.io.imu import ImuRecording
from simbench.io.orientation_csv import read_orientation_csv, write_orientation_csv
from simbench.io.poses import PoseRecording, sample_rate, write_pose_csv
from simbench.io.read import POSE_INPUTS, pose_inputs_text, read, read_imu, read_poses, refuse_unlocated
from simbench.orient import (
    OrientationRun,
    calibrate_magnetometers,
    convention_warnings,
    describe_fit,
    disturbed_fraction,
    estimate,
    in_frame,
    input_warnings,
    skeleton_from_calibration,
    skeleton_of,
)
from simbench.report.output import json_safe
from simbench.report.twin import write_twin_report
from simbench.score import CalibrationScore, OrientationScore, score_joints, score_orientation
from simbench.score import score as score_calibration
from simbench.sim.marker_clusters import MarkerConfig, add_markers
from simbench.sim.mjcf import BUILTIN as BUILTIN_MODELS
from simbench.sim.plan import session_defaults
from simbench.sim.playback import DEFAULT_CUTOFF_HZ as BVH_CUTOFF_HZ
from simbench.sim.programs import BUILTIN_PROGRAMS
from simbench.sim.sensor_config import SensorConfig, preset_names
from simbench.sim.session import SessionConfig, run_session
from simbench.twin import DEFAULT_CUTOFF_HZ as TWIN_CUTOFF_HZ
from simbench.twin import DEFAULT_POSITION_CUTOFF_HZ as TWIN_POSITION_CUTOFF_HZ
from simbench.twin import EFFECTS as TWIN_EFFECTS
from simbench.twin import METHODS as TWIN_METHODS
from simbench.twin import TwinResult
from simbench.twin import parse_window as parse_twin_window
from simbench.twin import twin as twin_recording

_DEFAULT = SessionConfig()

#: O'Brien's calibration in the estimator registry: its parameters' defaults are the one place
#: those of :func:`calibrate`, :func:`follow`, :func:`replay` and ``simbench calibrate`` come from.
_OBRIEN = resolve(DEFAULT_JOINTS)

#: The estimator a spec names (``resolve_estimator("obrien").param("hierarchy_method").default``):
#: :func:`simbench.estimators.resolve`.
resolve_estimator = resolve


def _estimator(method: str | Estimator | Callable[..., Any], kind: str) -> Estimator:
    """The estimator of a spec, an :class:`Estimator` or a plain function."""
    if isinstance(method, str | Estimator):
        return resolve(method, kind)
    if callable(method):
        return from_callable(method, getattr(method, "__qualname__", repr(method)), "python", kind)
    raise InputError(f"Expected method to be an estimator spec or a function, got {type(method).__name__}")


def simulate(
    model: str | None = None,
    motion: str = _DEFAULT.motion,
    *,
    sensors: str | SensorConfig = _DEFAULT.sensors,
    duration_s: float | None = None,
    rate_hz: float | None = None,
    seed: int = _DEFAULT.seed,
    sensors_on: Sequence[str] | None = None,
    placement: Mapping[str, Sequence[float]] | None = None,
    markers: MarkerConfig | bool = False,
    motion_units: str | None = None,
    motion_cutoff_hz: float = BVH_CUTOFF_HZ,
    motion_clusters: str | None = None,
    motion_position_cutoff_hz: float | None = None,
) -> Dataset:
    """Simulate a capture session with MuJoCo physics and the chosen sensors, or play back a
    recorded motion.

    Args:
        model: ``linkage`` (the default), ``humanoid``, ``dm_control:NAME`` or an MJCF file path;
            with a recorded motion left out: the model it brings (a BVH clip's skeleton ``bvh``, a
            pose trajectory's bodies ``poses``) or names (a ``qpos`` archive), ``humanoid`` for
            OpenSim joint angles.
        motion: ``exercise``, ``walk``, ``gait`` (humanoids), ``single-axis``, ``static``, a program
            TOML path, or a recorded motion played back kinematically, its poses exact
            (:mod:`simbench.sim.motion_source`): a BVH clip (``.bvh``), a ``qpos`` series
            (``.npz``, ``.csv``), OpenSim joint angles (``.mot``, ``.sto``), pose trajectories (a
            pose CSV, a C3D file of marker clusters, a BROAD-layout ``.hdf5`` trial).
        sensors: a preset name (``ideal``, ``ascension-flock``, ``polhemus-liberty``,
            ``mems-consumer``, ``mems-industrial``, ``skin-paper-human``), a configuration TOML
            path or a :class:`~simbench.sim.sensor_config.SensorConfig`.
        duration_s: session length, s (default 20; a recorded motion: the whole recording).
        rate_hz: capture rate, Hz (default 120; a recorded motion: its own, another one resamples
            its smoothed motion and must be above twice ``motion_cutoff_hz``).
        seed: seed of every random draw of the session (same seed, same data).
        sensors_on: bodies carrying a sensor (default: the model's).
        placement: ``{sensor: (dx, dy, dz)}`` shifts of sensors in their body frames, m.
        markers: optical marker clusters on every sensor's segment (``True``: 4 per segment, no
            skin motion or camera noise; a :class:`~simbench.sim.marker_clusters.MarkerConfig` to
            choose), drawn from their own stream of ``seed``; ``False``: none.
        motion_units: a recorded motion's length unit (``m``, ``cm``, ``mm``, ``in``); default the
            file's convention (BVH centimetres, a pose CSV metres, a C3D file its own).
        motion_cutoff_hz: a recorded motion's smoothing cutoff, Hz: its velocities and
            accelerations (gyroscopes, accelerometers) come from a Savitzky-Golay smoothing below it.
        motion_clusters: a C3D motion's marker cluster spec (TOML); default: found automatically.
        motion_position_cutoff_hz: a recorded motion's positions' own cutoff, Hz (default
            ``motion_cutoff_hz``): accelerations are positions differentiated twice.

    Returns:
        The Dataset: ``measured`` data as the instruments give it (positions in the tracker's
        units: metres / ``position_unit_scale``), the exact ``truth`` and the ``markers`` (m).
    """
    if not isinstance(markers, bool | MarkerConfig):
        raise InputError(
            f"Expected markers to be True, False or a MarkerConfig, got {type(markers).__name__}"
        )
    for name, value in (("model", model), ("motion", motion)):
        if not isinstance(value, str) and not (name == "model" and value is None):
            raise InputError(
                f"Expected {name} to be a name or a file path (a string), got {type(value).__name__}"
            )
    if not isinstance(sensors, str | SensorConfig):
        raise InputError(
            "Expected sensors to be a preset name, a TOML path or a SensorConfig, got "
            f"{type(sensors).__name__}"
        )
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise InputError(f"Expected seed to be an integer, got {seed!r}")
    for name, shift in (placement or {}).items():
        v = np.asarray(shift, dtype=float) if np.ndim(shift) == 1 else None
        if v is None or v.shape != (3,) or not np.isfinite(v).all():
            raise InputError(
                f"placement {name!r}: expected a finite shift (dx, dy, dz) in metres, got {shift!r}"
            )
    for name, value in (
        ("duration_s", duration_s),
        ("rate_hz", rate_hz),
        ("motion_cutoff_hz", motion_cutoff_hz),
        ("motion_position_cutoff_hz", motion_position_cutoff_hz),
    ):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float | np.number)):
            raise InputError(f"Expected {name} to be a number, got {value!r}")
    model, duration_s, rate_hz = session_defaults(
        model,
        motion,
        duration_s,
        rate_hz,
        motion_units,
        None if motion_clusters is None else str(motion_clusters),
    )
    config = SessionConfig(
        model=model,
        motion=motion,
        duration_s=float(duration_s),
        rate_hz=float(rate_hz),
        seed=int(seed),
        sensor_bodies=None if sensors_on is None else tuple(sensors_on),
        sensors=sensors,
        placement=tuple(
            (name, (float(v[0]), float(v[1]), float(v[2]))) for name, v in sorted((placement or {}).items())
        ),
        motion_units=motion_units,
        motion_cutoff_hz=float(motion_cutoff_hz),
        motion_clusters=None if motion_clusters is None else str(motion_clusters),
        motion_position_cutoff_hz=None
        if motion_position_cutoff_hz is None
        else float(motion_position_cutoff_hz),
    )
    ds = run_session(config)
    if markers is False:
        return ds
    return add_markers(ds, MarkerConfig() if markers is True else markers, seed=config.seed)


#: O'Brien's options of :func:`calibrate` at their defaults (refused beside another ``method``):
#: the registry's, least squares (``robust=None``) and no correction for the rotations' noise.
_CALIBRATE_DEFAULTS = {**_OBRIEN.defaults, "robust": None, "correct_rotation_noise": False}


def calibrate(
    data: Dataset | PoseRecording,
    *,
    method: str | Estimator | Callable[..., Any] | None = None,
    params: Mapping[str, Any] | None = None,
    time_limit_s: float | None = None,
    hierarchy: Mapping[str, str] | None = None,
    root: str | None = None,
    hierarchy_method: str = _CALIBRATE_DEFAULTS["hierarchy_method"],
    single_axis_ratio: float = _CALIBRATE_DEFAULTS["single_axis_ratio"],
    robust: str | None = None,
    intervals: bool = False,
    correct_rotation_noise: bool = False,
    drop_noisy_frames: bool = False,
) -> Calibration | JointsResult:
    """Joint centres, hierarchy, limb lengths and sensor placement from a recording's poses
    (O'Brien et al. 2000; :func:`calibration.calibrate` does the same on bare arrays), or the joint
    centres of any other estimator (``method``).

    Args:
        data: a Dataset (simulated or read with :func:`read`) or a pose recording.
        method: ``None`` for O'Brien's calibration with the options below (returns a
            :class:`calibration.Calibration`); or any joints estimator: a built-in's name
            (:func:`simbench.estimators.names`), ``module:function``, ``file.py:function``,
            ``cmd:COMMAND {poses} {hierarchy} {out}``, an installed plugin's name, or a function
            ``fn(poses, *, hierarchy=None, ...)``; returns its
            :class:`simbench.estimators.JointsResult` (centres in the recording's position unit).
        params: with ``method``: the estimator's parameters (its defaults otherwise); the
            options below are O'Brien's and go with ``method=None`` only.
        time_limit_s: with ``method``: a user's estimator's time limit, s (a command's; a Python
            function's wall time in the main thread); ``None``: a command's default, else none.
        hierarchy: a known hierarchy ``{child: parent}``; inferred when ``None``.
        root: root sensor (default: the tree's centre).
        hierarchy_method: how an inferred tree weighs the pairs: ``"misfit"`` (residual less its
            noise) or ``"mst"`` (O'Brien's residual); see :mod:`calibration.hierarchy`.
        single_axis_ratio: see :mod:`calibration.joint`.
        robust: ``"tukey"`` or ``"huber"`` for robust (IRLS) joint fits and hierarchy, ``None`` for
            least squares (:mod:`calibration.robust`).
        intervals: give each joint a covariance with 95 % regions and each limb length a 95 %
            interval (:mod:`calibration.uncertainty`; for robust fits, conditional on the inliers).
        correct_rotation_noise: correct the joints for the noise on the rotations
            (:mod:`calibration.eiv`; not with ``robust``).
        drop_noisy_frames: leave out each sensor's frames whose position noise drowns its others
            (:mod:`calibration.frame_noise`: a magnetic tracker far from its transmitter), with a
            warning; False keeps every valid frame.

    Returns:
        The calibration, lengths in the recording's position units (the tracker's).
    """
    rec = data.poses() if isinstance(data, Dataset) else data
    if not isinstance(rec, PoseRecording):
        raise InputError(f"Expected a Dataset or a PoseRecording, got {type(data).__name__}")
    if method is not None:
        est = _estimator(method, "joints")
        options = {
            "root": root,
            "hierarchy_method": hierarchy_method,
            "single_axis_ratio": single_axis_ratio,
            "robust": robust,
            "intervals": intervals,
            "correct_rotation_noise": correct_rotation_noise,
            "drop_noisy_frames": drop_noisy_frames,
        }
        changed = sorted(k for k, v in options.items() if v != _CALIBRATE_DEFAULTS[k])
        if changed:
            raise InputError(
                f"{', '.join(changed)}: options of O'Brien's calibration (method=None); give an "
                f"estimator's own parameters as params={{...}} ({est.name}: {[p.name for p in est.params]})"
            )
        data_of = rec if est.data == "poses" else data.imu() if isinstance(data, Dataset) else None
        if data_of is None:
            raise InputError(
                f"{est.name!r} estimates joints from IMU data: give a Dataset with inertial data"
            )
        got = run_joints(est, data_of, hierarchy=hierarchy, params=params, time_limit_s=time_limit_s)
        return with_residuals(got, rec) if got.calibration is None and est.data == "poses" else got
    if params is not None:
        raise InputError("params go with method=...: O'Brien's options are the keyword arguments")
    return calibrate_arrays(
        rec.R_w_s,
        rec.p_w_s,
        rec.names,
        valid=rec.valid,
        parent_of=hierarchy,
        root=root,
        hierarchy_method=hierarchy_method,
        single_axis_ratio=single_axis_ratio,
        robust=robust,
        intervals=intervals,
        correct_rotation_noise=correct_rotation_noise,
        drop_noisy_frames=drop_noisy_frames,
    )


def score(
    cal: Calibration | JointsResult | Mapping[str, Any] | str | os.PathLike[str] | np.ndarray | Orientations,
    ds: Dataset | ImuRecording,
    *,
    scale: float | None = None,
) -> CalibrationScore | OrientationScore:
    """An estimate against the truth of the recording it came from.

    Joints: limb lengths, joint centres (both sensor frames), the hierarchy (wrong edges named), in
    metres (``scale`` metres per tracker unit; default the dataset's ``position_unit_scale``).
    Orientations: BROAD's errors (total, heading, inclination RMSE, degrees) over the samples to
    evaluate, against a simulated session's actual orientations or a real recording's reference.

    Args:
        cal: joints: a :class:`calibration.Calibration`, any estimator's
            :class:`simbench.estimators.JointsResult` (:func:`calibrate` with ``method``), or an
            estimate made anywhere: a calibration document (``joints`` with ``parent``, ``child``,
            ``joint_in_parent``, ``joint_in_child``; ``units``) or the path of its JSON file.
            Orientations: :class:`Orientations` (:func:`orient`), or made anywhere: ``(F, N, 4)``
            scalar-first quaternions of ``R_w_s`` in ENU (NaN where not estimated) or the path of
            an orientation CSV (``time,sensor,qw,qx,qy,qz``, ``.csv``).
        ds: the simulated session, or for orientations an IMU recording with a reference (a BROAD
            trial from :func:`read`).
        scale: metres per tracker unit (joints).

    Raises:
        InputError: an estimate of other sensors or samples, quaternions not of unit norm, a
            recording without truth, a file that cannot be read.
    """
    if isinstance(cal, Orientations | np.ndarray | list) or (
        isinstance(cal, str | os.PathLike) and Path(cal).suffix.lower() == ".csv"
    ):
        return _score_orientations(cal, ds)
    if not isinstance(ds, Dataset):
        raise InputError(
            f"joints are scored against a simulated session (a Dataset), got {type(ds).__name__}"
        )
    if scale is not None and not (isinstance(scale, int | float) and np.isfinite(scale) and scale > 0):
        raise InputError(f"Expected scale (metres per tracker unit) to be a finite number > 0, got {scale!r}")
    if isinstance(cal, Calibration):
        if set(cal.names) != set(ds.sensors):
            raise InputError(
                f"the calibration's sensors ({', '.join(cal.names)}) are not the dataset's "
                f"({', '.join(ds.sensors)}): a calibration of another recording?"
            )
        return score_calibration(cal, ds, scale=scale)
    if isinstance(cal, str | os.PathLike):
        cal = read_calibration_json(cal)
    if isinstance(cal, Mapping):
        cal = joints_result(cal, "the calibration given", tuple(ds.sensors), "m")
    if not isinstance(cal, JointsResult):
        raise InputError(
            "Expected a Calibration, a JointsResult, a calibration document or its JSON path, got "
            f"{type(cal).__name__}"
        )
    if cal.calibration is not None:
        return score(cal.calibration, ds, scale=scale)
    wrong = sorted({*cal.joints.parent, *cal.joints.child} - set(ds.sensors))
    if wrong:
        raise InputError(f"the estimate's sensors {wrong} are not the dataset's ({', '.join(ds.sensors)})")
    return score_joints(cal.joints, ds, scale=scale)


@dataclass(frozen=True)
class Orientations:
    """Estimated sensor orientations and, where the recording has a reference, their errors.

    Attributes:
        q_w_s: ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` in ENU; NaN where not estimated.
        ok: ``(F, N)`` estimated.
        names: ``(N,)`` sensor names.
        method: the method used.
        score: errors against the reference (BROAD's definitions), or ``None`` without one.
        magnetometers: per sensor its magnetometer fit
            (:class:`calibration.orientation.MagnetometerCalibration`, applied where
            :func:`simbench.orient.applies`) or why there is none; ``None`` when not asked for.
        disturbed: per sensor, the share of its samples whose magnetometer is still disturbed
            after calibration (:func:`simbench.orient.disturbed_fraction`).
        field_strength_ut, inclination_deg: the reference field a built-in method took from the
            recording, uT and degrees (NaN for other estimators).
        notes: the recording's notes, with what the magnetometer calibration did.
        warnings: inputs that cannot be trusted (:func:`simbench.orient.input_warnings`): an
            axis held at its range, a field strength that drifts, no rest; an estimate that fits
            the accelerometer better read in another convention
            (:func:`simbench.orient.convention_warnings`); and what a built-in method found and
            did about it (:attr:`simbench.orient.OrientationRun.warnings`).
    """

    q_w_s: np.ndarray
    ok: np.ndarray
    names: tuple[str, ...]
    method: str
    score: OrientationScore | None
    magnetometers: dict[str, Any] | None = None
    disturbed: dict[str, float] | None = None
    field_strength_ut: float = math.nan
    inclination_deg: float = math.nan
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def in_frame(self, frame: str = "enu") -> np.ndarray:
        """``(F, N, 4)`` the orientations in world frame ``enu`` or ``ned`` (for
        :func:`write_orientation_csv`)."""
        return in_frame(self.q_w_s, frame)


def _score_orientations(
    estimate: Orientations | np.ndarray | list | str | os.PathLike[str], data: Dataset | ImuRecording
) -> OrientationScore:
    """Orientations made anywhere against a recording's reference (:func:`score`)."""
    rec = data.imu() if isinstance(data, Dataset) else data
    if not isinstance(rec, ImuRecording):
        raise InputError(
            f"orientations are scored against a Dataset or an ImuRecording, got {type(data).__name__}"
        )
    if rec.q_true is None:
        raise InputError(f"{rec.source}: no reference orientations to score against")
    if isinstance(estimate, Orientations):
        if estimate.names != rec.names:
            raise InputError(
                f"orientations of sensors {list(estimate.names)}, not the recording's {list(rec.names)}"
            )
        q = estimate.q_w_s
    elif isinstance(estimate, str | os.PathLike):
        q = read_orientation_csv(estimate, rec.names, rec.time_s)
    else:
        q = estimate
    q = orientation_result(q, "the orientations given", rec).q_enu
    return score_orientation(q, rec.q_true, rec.names, rec.evaluate)


def orient(
    data: Dataset | ImuRecording,
    method: str | Estimator | Callable[..., Any] = DEFAULT_ORIENTATION,
    *,
    params: Mapping[str, Any] | None = None,
    time_limit_s: float | None = None,
    skeleton: Skeleton | Calibration | str | os.PathLike[str] | None = None,
    weighting: bool = True,
    smooth_hz: float | None = None,
    calibrate_mag: bool | None = None,
    priors: Priors | None = None,
) -> Orientations:
    """Sensor orientations from accelerometer and magnetometer, scored against the truth when
    there is one: by default every sensor over the whole recording at once, on the skeleton when
    one is given (``skeleton``); or per sample (Fontaine et al., ``triad``, ``wahba``); or the
    gyro-aided references ``mahony`` and ``vqf``.

    Args:
        data: a Dataset with inertial data, or an IMU recording (e.g. a BROAD trial from :func:`read`).
        method: any orientation estimator: a built-in's name (:func:`simbench.estimators.names`),
            ``module:function``, ``file.py:function``, ``cmd:COMMAND {imu} {out}``, an installed
            plugin's name, or a function ``fn(imu, ...)`` returning ``(F, N, 4)`` quaternions.
        params: the estimator's parameters (:class:`simbench.estimators.Estimator`), for one not
            built in; the built-ins take the options below.
        time_limit_s: a user's estimator's time limit, s (as :func:`calibrate`).
        skeleton: for the ``skeleton`` method, a calibration of the same sensors: a
            :class:`calibration.Calibration` (:func:`calibrate`) or its JSON (``simbench
            calibrate --json``; :func:`simbench.orient.skeleton_from_calibration`), or a
            :class:`calibration.orientation.Skeleton` over the recording's sensors; ``None``:
            each sensor on its own.
        weighting: Fontaine's disturbance weighting.
        smooth_hz: zero-phase smoothing cutoff, Hz (``None``: none).
        calibrate_mag: calibrate each magnetometer from the recording's own samples first
            (:func:`simbench.orient.calibrate_magnetometers`; applied only where it pays);
            ``None``: on for the built-in methods (their ``calibrate_mag`` parameter's default),
            off for a user's estimator, which gets the readings as recorded.
        priors: for the ``skeleton`` method, the residuals' standard deviations
            (:class:`calibration.orientation.Priors`), e.g. ``Priors(lone_speed=1.5)`` for a
            sensor on its own that moves slowly, ``Priors(lone_speed=None)`` for the white prior
            on its acceleration.
    """
    rec = data.imu() if isinstance(data, Dataset) else data
    if not isinstance(rec, ImuRecording):
        raise InputError(f"Expected a Dataset or an ImuRecording, got {type(data).__name__}")
    if skeleton is not None and not isinstance(skeleton, Skeleton):
        skeleton = skeleton_from_calibration(skeleton, rec.names)
    est = _estimator(method, "orientation")
    if est.origin != "builtin" and (not weighting or smooth_hz is not None or priors is not None):
        raise InputError(
            f"weighting, smooth_hz and priors are options of the built-in methods; give {est.name!r} its "
            f"own as params={{...}} ({[p.name for p in est.params]})"
        )
    if est.origin == "builtin" and params is not None:
        raise InputError(f"{est.name!r}: the built-in methods take their options as keyword arguments")
    warned = input_warnings(rec, est.origin == "builtin", "gyro" in est.needs)
    fits = None
    if calibrate_mag is None:
        calibrate_mag = bool(est.defaults.get("calibrate_mag", False))
    if calibrate_mag:
        rec, fits = calibrate_magnetometers(rec)
    if est.origin == "builtin":
        run = estimate(
            rec, est.name, weighting=weighting, smooth_hz=smooth_hz, skeleton=skeleton, priors=priors
        )
    else:
        run = run_orientation(est, rec, skeleton=skeleton, params=params, time_limit_s=time_limit_s)
    scored = None if rec.q_true is None else score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate)
    warned = (*warned, *convention_warnings(rec, run.q_enu))
    return Orientations(
        q_w_s=run.q_enu,
        ok=run.ok,
        names=rec.names,
        method=est.name,
        score=scored,
        magnetometers=fits,
        disturbed=disturbed_fraction(rec),
        field_strength_ut=float(run.field_strength_ut),
        inclination_deg=float(run.inclination_deg),
        notes=tuple(rec.notes),
        warnings=(*warned, *(run.warnings if isinstance(run, OrientationRun) else ())),
    )


def export(
    data: Dataset | str | os.PathLike[str],
    *,
    trc: str | os.PathLike[str] | None = None,
    c3d: str | os.PathLike[str] | None = None,
    sto: str | os.PathLike[str] | None = None,
    imu_csv: str | os.PathLike[str] | None = None,
    mjcf: str | os.PathLike[str] | None = None,
    osim: str | os.PathLike[str] | None = None,
    calibration: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    markers: str = "measured",
    orientations: str = "measured",
    trc_units: str = "mm",
    trc_up: str = "z",
    units: str | None = None,
    clusters: str | os.PathLike[str] | None = None,
    wide: str | os.PathLike[str] | None = None,
) -> dict[str, Path]:
    """Write a dataset (or a recording file) into the formats other tools read: markers to TRC and
    C3D, sensor orientations to OpenSense's ``.sto``, raw IMU readings to CSV, the skeleton (of
    ``calibration``, a calibration JSON, or of the truth) to MJCF and ``.osim``. Arguments and checks:
    :func:`simbench.io.export.export_dataset`; returns ``{kind: path}`` of the files written.

    A file is opened with :func:`read` (``units``, ``clusters``, ``wide`` as there): a simbench
    dataset, or a real recording of poses (pose CSV, wide export, C3D marker clusters), whose
    orientations and calibrated skeleton can be exported (it has no truth or IMU data). A C3D file's
    own markers go to ``trc`` and ``c3d`` as read, without clusters
    (:func:`simbench.io.export.export_c3d_markers`); its other exports come from its clusters' poses.
    """
    if (
        not isinstance(data, Dataset)
        and wide is None
        and Path(data).suffix.lower() == ".c3d"
        and (trc or c3d)
    ):
        if calibration is not None and mjcf is None and osim is None:
            raise InputError("a calibration is used only for the skeleton: give mjcf or osim too")
        if markers == "truth":
            raise InputError(
                f"{data}: a recorded C3D file has measured markers only; their truth comes with a "
                "simulated dataset (simbench simulate --markers)"
            )
        check_outputs({k: Path(v) for k, v in {"trc": trc, "c3d": c3d}.items() if v is not None})
        recording = read_c3d(data)  # before anything is written: a damaged file writes nothing
        rest = {"sto": sto, "imu_csv": imu_csv, "mjcf": mjcf, "osim": osim}
        written = {}
        if any(v is not None for v in rest.values()):
            written = export(
                data,
                **rest,
                calibration=calibration,
                orientations=orientations,
                units=units,
                clusters=clusters,
            )
        return written | export_c3d_markers(recording, trc=trc, c3d=c3d, trc_units=trc_units, trc_up=trc_up)
    ds = data if isinstance(data, Dataset) else read(data, units=units, clusters=clusters, wide=wide)
    if isinstance(ds, ImuRecording):
        raise InputError(
            f"{data}: an inertial recording without poses (a BROAD trial): export takes a simbench dataset "
            "or a recording of poses"
        )
    return export_dataset(
        ds,
        trc=trc,
        c3d=c3d,
        sto=sto,
        imu_csv=imu_csv,
        mjcf=mjcf,
        osim=osim,
        calibration=calibration,
        markers=markers,
        orientations=orientations,
        trc_units=trc_units,
        trc_up=trc_up,
    )


def _positive(name: str, value: Any) -> float:
    """``value`` as a float when it is a finite number > 0, else an :class:`InputError` naming it."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int | float)
        or not (math.isfinite(value) and value > 0)
    ):
        raise InputError(f"Expected {name} to be a finite number > 0, got {value!r}")
    return float(value)


def _recording(data: Dataset | PoseRecording, what: str) -> PoseRecording:
    rec = data.poses() if isinstance(data, Dataset) else data
    if not isinstance(rec, PoseRecording):
        raise InputError(f"{what}: expected a Dataset or a PoseRecording, got {type(data).__name__}")
    return rec


def _same_sensors(rec: PoseRecording, cal: Calibration) -> None:
    if tuple(cal.names) != tuple(rec.names):
        raise InputError(
            f"the calibration's sensors ({', '.join(cal.names)}) are not the recording's "
            f"({', '.join(rec.names)}): a calibration of another recording?"
        )


def slip_reports(
    data: Dataset | PoseRecording,
    cal: Calibration,
    *,
    window_s: float = SLIP_WINDOW_S,
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR,
    series: bool = True,
) -> list[tuple[str, SlipReport]]:
    """Slip detection on every joint of a calibration (O'Brien section 5,
    :func:`calibration.detect_slip`): the reports ``simbench calibrate`` prints and writes.

    Frames the calibration left out for their noise (``drop_noisy_frames=True``) are left out
    here too. The window of ``window_s`` seconds becomes frames at the recording's rate (at
    least 2, at most half the recording). One joint at a time, a chunk of its frames at a time
    (:data:`calibration.slip.CHUNK_FRAMES`): memory is bounded by the chunk, not the recording.

    Args:
        data: the recording that was calibrated (a Dataset: its measured poses).
        cal: its calibration (:func:`calibrate`).
        window_s: the detector's window, s (default :data:`calibration.slip.SLIP_WINDOW_S`).
        false_alarms_per_hour: per joint, the expected false alarms per hour of recording when
            no sensor moves, which sets the threshold (default
            :data:`calibration.slip.FALSE_ALARMS_PER_HOUR`).
        series: keep each report's ``jump`` series (``False``: empty; a frame's worth of memory
            per joint less).

    Returns:
        ``(joint name, report)`` per joint (``parent-child``): the
        :class:`calibration.SlipReport`'s events (frame, jump in the recording's length unit,
        the sensor frame it is steady in, z) and slipped intervals (frames); ``[]`` when the
        recording is too short (fewer than 4 frames).

    Raises:
        InputError: a window or rate that is not a finite number > 0, or a calibration of
            other sensors.
    """
    rec = _recording(data, "slip_reports")
    window_s = _positive("window_s (seconds)", window_s)
    false_alarms_per_hour = _positive("false_alarms_per_hour", false_alarms_per_hour)
    _same_sensors(rec, cal)
    window = round(window_s * rec.rate_hz) if np.isfinite(rec.rate_hz) else 0
    window = min(max(window, 2), rec.n_frames // 2)
    if window < 2:
        return []
    reports = []
    for j in cal.joints:  # one joint at a time, a chunk of its frames at a time (detect_slip)
        drop = None
        if cal.noisy_frames is not None:  # the frames the calibration left out for their noise
            drop = cal.noisy_frames[:, [rec.names.index(j.parent), rec.names.index(j.child)]].any(axis=1)
        report = detect_slip(
            *rec.pair_views(j.parent, j.child, drop),
            j.fit.joint_in_parent,
            j.fit.joint_in_child,
            window=window,
            rate_hz=rec.rate_hz,
            false_alarms_per_hour=false_alarms_per_hour,
            series=series,
        )
        reports.append((j.name, report))
    return reports


def calibration_document(
    cal: Calibration | JointsResult,
    data: Dataset | PoseRecording | None = None,
    *,
    slips: Sequence[tuple[str, SlipReport]] = (),
    ranges: bool = True,
    input_info: Mapping[str, Any] | None = None,
    notes: Sequence[str] | None = None,
    options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The calibration JSON document that ``simbench calibrate --json`` writes
    (:mod:`simbench.io.calibration_json`; :func:`write_calibration` writes it, :func:`score` and
    ``orient(skeleton=...)`` read it back).

    Args:
        cal: O'Brien's calibration (:func:`calibrate`), or any estimator's
            :class:`simbench.estimators.JointsResult` (the whole document of an O'Brien
            variant; the joints alone, in the poses' unit, for the others).
        data: the recording it came from: slip events and intervals get their times in seconds,
            and each joint its range of motion in these poses (``ranges``).
        slips: ``(joint name, report)`` of :func:`slip_reports`.
        ranges: give each joint its range of motion (the skeleton orientation method keeps to
            it); needs ``data``.
        input_info: what was read (source, sensors, frames, rate, units), as the document's
            ``input``.
        notes: what the reader repaired or noticed (default: the recording's notes; for an
            estimator's bare joints, its own notes).
        options: the options the calibration ran with, as the document's ``options``.

    Raises:
        InputError: not a calibration, or a recording of other sensors.
    """
    rec = None if data is None else _recording(data, "calibration_document")
    if isinstance(cal, JointsResult):
        if cal.calibration is None:
            j, r = cal.joints, cal.residuals
            fit = {}  # how each joint fits the poses it was estimated from, where known
            for k in range(len(j.child) if r is not None else 0):
                fit[k] = {
                    "rms_residual": float(r.rms[k]),
                    "max_residual": float(r.max[k]),
                    "n_frames": int(r.frames[k]),
                }
            return {
                "units": cal.unit,
                "joints": [
                    {
                        "parent": j.parent[k],
                        "child": j.child[k],
                        "joint_in_parent": j.joint_in_parent[k].tolist(),
                        "joint_in_child": j.joint_in_child[k].tolist(),
                        "single_axis": bool(j.single_axis[k]),
                        **fit.get(k, {}),
                    }
                    for k in range(len(j.child))
                ],
                "warnings": list(cal.warnings),
                "notes": list(cal.notes if notes is None else notes),
            }
        cal = cal.calibration
    if not isinstance(cal, Calibration):
        raise InputError(f"Expected a Calibration or a JointsResult, got {type(cal).__name__}")
    joint_ranges = None
    if rec is not None:
        _same_sensors(rec, cal)
        if ranges:  # each joint's range of motion in these poses, for the skeleton orientation method
            ranged = skeleton_of(cal).with_ranges(rec.R_w_s, rec.valid)
            joint_ranges = {
                cal.names[c]: (ranged.range_centre[c], float(ranged.range_rad[c])) for c in ranged.children
            }
    return calibration_to_dict(
        cal,
        ranges=joint_ranges,
        time_s=None if rec is None else rec.time_s,
        slips=slips,
        input_info=None if input_info is None else dict(input_info),
        notes=(() if rec is None else rec.notes) if notes is None else notes,
        options=None if options is None else dict(options),
    )


def unit_scale(data: Dataset | PoseRecording, sensors: Sequence[str], distance_m: float) -> ScaleEstimate:
    """The unit scale factor of a capture system from two of its sensors mounted rigidly a known
    distance apart (O'Brien et al. 2000, section 4; ``simbench scale``), over the frames where
    both are seen.

    Args:
        data: the recording (positions as the system reports them).
        sensors: the two sensors' names.
        distance_m: their true distance, m.

    Returns:
        The :class:`calibration.ScaleEstimate`: ``scale`` (multiply reported lengths by it),
        the mean reported distance and its scaled spread, the distance per frame
        (:func:`rigidity` of it says whether the two stayed rigid).

    Raises:
        InputError: not two different sensors of the recording, or a distance not > 0.
        CalibrationError: too few frames with both sensors.
    """
    rec = _recording(data, "unit_scale")
    distance_m = _positive("distance_m", distance_m)
    names = list(sensors)
    if len(names) != 2 or names[0] == names[1]:
        raise InputError(f"unit_scale needs two different sensors, got {names}")
    missing = [name for name in names if name not in rec.names]
    if missing:
        raise InputError(
            f"{rec.source or 'the recording'}: no sensor named {missing}; sensors are {list(rec.names)}"
        )
    a, b = (rec.names.index(name) for name in names)
    both = rec.valid[:, a] & rec.valid[:, b]
    p_w_a = np.where(both[:, None], rec.p_w_s[:, a], np.nan)
    p_w_b = np.where(both[:, None], rec.p_w_s[:, b], np.nan)
    return unit_scale_arrays(p_w_a, p_w_b, distance_m)


def _live_options(
    hierarchy: Mapping[str, str] | None,
    root: str | None,
    hierarchy_method: str,
    single_axis_ratio: float,
    slip: bool,
    false_alarms_per_hour: float,
    refresh_s: float,
) -> LiveOptions:
    _positive("refresh_s (seconds)", refresh_s)
    return LiveOptions(
        slip=bool(slip),
        parent_of=None if hierarchy is None else dict(hierarchy),
        root=root,
        hierarchy_method=hierarchy_method,
        single_axis_ratio=single_axis_ratio,
        false_alarms_per_hour=false_alarms_per_hour,
    )


def follow(
    path: str | os.PathLike[str],
    *,
    units: str = "m",
    rate_hz: float | None = None,
    timeout_s: float | None = None,
    refresh_s: float = LIVE_REFRESH_S,
    hierarchy: Mapping[str, str] | None = None,
    root: str | None = None,
    hierarchy_method: str = _CALIBRATE_DEFAULTS["hierarchy_method"],
    single_axis_ratio: float = _CALIBRATE_DEFAULTS["single_axis_ratio"],
    slip: bool = True,
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[LiveUpdate]:
    """O'Brien's calibration, live, of a pose CSV that a tracker's logger is still appending to
    (``simbench calibrate --follow``; :class:`calibration.streaming.StreamingCalibrator`)::

        for update in sb.follow("poses.csv", timeout_s=600):
            if update.kind == "alert":        # a sensor may have slipped: re-fix it now
                print(update.alert.message)
            elif update.kind in ("state", "final"):
                print(update.state.calibration.parent_of, [c.advice for c in update.state.coverage])

    The file is read every 50 ms, at most 1 MiB at a time; the updates
    (:class:`simbench.experiments.live.LiveUpdate`) come as the frames do: each slip alert when it
    is raised, the calibration so far every ``refresh_s`` seconds of capture (``waiting`` while
    there is none, or while the file does not exist yet), and after ``timeout_s`` seconds of wall
    time or Ctrl-C (a ``stopped`` update) the ``final`` one. Every time reported is a frame's time
    stamp. A file without two complete frames ends with no ``final`` update. The file is read by
    the batch reader's rules (:mod:`simbench.io.follow`), and tracked: truncated, replaced
    (rotated) or rewritten, the follow stops (``stopped``, ``final``, then the error).

    Args:
        path: the pose CSV (``time,sensor,x,y,z,qw,qx,qy,qz``; extra columns ignored).
        units: length unit of its positions (``m``, ``cm``, ``mm``, ``in``).
        rate_hz: the capture rate, Hz (default: from the first 64 frames' time stamps).
        timeout_s: stop after this many seconds of wall time (``None``: at Ctrl-C only).
        refresh_s: seconds of capture between two ``state`` updates.
        hierarchy: a known hierarchy ``{child: parent}``; inferred when ``None``.
        root: the root sensor, as in :func:`calibrate`.
        hierarchy_method: how an inferred tree weighs each pair, as in :func:`calibrate`.
        single_axis_ratio: the single-axis test's floor, as in :func:`calibrate`.
        slip: raise slip alerts (a 0.5 s causal window:
            :data:`calibration.streaming.LIVE_SLIP_WINDOW_S`).
        false_alarms_per_hour: per joint, the rate the alert threshold is set for.
        clock: the wall clock, s (tests pass a fake).

    Raises:
        InputError: (while iterating) a row the batch reader would refuse, naming its line, or
            an option the calibrator refuses; (at the end) a file that never appeared, or one
            truncated, replaced or rewritten while followed
            (:class:`simbench.io.follow.FollowStopped`).
        CalibrationError: (at the end) the frames never gave a calibration, saying why.
    """
    options = _live_options(
        hierarchy, root, hierarchy_method, single_axis_ratio, slip, false_alarms_per_hour, refresh_s
    )
    for name, value in (("rate_hz", rate_hz), ("timeout_s (seconds)", timeout_s)):
        if value is not None:
            _positive(name, value)
    return follow_file(
        path,
        units=units,
        rate_hz=rate_hz,
        timeout_s=timeout_s,
        refresh_s=refresh_s,
        options=options,
        clock=clock,
    )


def replay(
    data: Dataset | PoseRecording | str | os.PathLike[str],
    *,
    units: str | None = None,
    speed: float | None = 1.0,
    refresh_s: float = LIVE_REFRESH_S,
    hierarchy: Mapping[str, str] | None = None,
    root: str | None = None,
    hierarchy_method: str = _CALIBRATE_DEFAULTS["hierarchy_method"],
    single_axis_ratio: float = _CALIBRATE_DEFAULTS["single_axis_ratio"],
    slip: bool = True,
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR,
) -> Iterator[LiveUpdate]:
    """A recorded or simulated session fed frame by frame through the live calibration, paced at
    the capture rate (``simbench replay``): the updates of :func:`follow`, the ``final`` one
    last.

    Args:
        data: a Dataset, a pose recording, or a pose file (:func:`read_poses`).
        units: a file's length unit (:func:`read_poses`).
        speed: a multiple of real time (1.0: the capture rate), or ``None``: as fast as the
            updates are taken.
        refresh_s: as :func:`follow`.
        hierarchy: as :func:`follow`.
        root: as :func:`follow`.
        hierarchy_method: as :func:`follow`.
        single_axis_ratio: as :func:`follow`.
        slip: as :func:`follow`.
        false_alarms_per_hour: as :func:`follow`.

    Raises:
        InputError: fewer than 2 frames, or an option the calibrator refuses.
        CalibrationError: (at the end) the frames never gave a calibration.
    """
    options = _live_options(
        hierarchy, root, hierarchy_method, single_axis_ratio, slip, false_alarms_per_hour, refresh_s
    )
    if speed is not None:
        _positive("speed", speed)
    if isinstance(data, str | os.PathLike):
        rec, source = read_poses(data, units), str(data)
    else:
        rec = _recording(data, "replay")
        source = rec.source or "the recording"
    return replay_recording(rec, source=source, speed=speed, refresh_s=refresh_s, options=options)


def twin(
    recording: str | os.PathLike[str],
    *,
    seed: int = 0,
    window: tuple[float, float] | str | None = None,
    cutoff_hz: float = TWIN_CUTOFF_HZ,
    position_cutoff_hz: float = TWIN_POSITION_CUTOFF_HZ,
    without: Sequence[str] = (),
    methods: Sequence[str] = TWIN_METHODS,
) -> TwinResult:
    """The digital twin of a real IMU recording with the optical pose of its housing (a BROAD
    trial): its readings simulated from the pose, what the real sensor adds identified (biases,
    noise, hard and soft iron, the local field and its gradient, time offsets, axis misalignment,
    lever arm), real and twin compared sample by sample over the motion phase (R^2, rms, the
    difference's spectrum), and the orientation methods scored on both (``docs/twin.md``).

        from simbench.api import twin, write_twin  # (sb.twin is the package simbench.twin)

        result = twin("broad_02_undisturbed_slow_rotation_B.hdf5", seed=1)
        result.readings["gyro"]["r2"], result.orientation["vqf"]["ratio"]
        write_twin(result, json_path="twin.json", out="twin_report")

    Args:
        recording: the trial's HDF5 file.
        seed: the seed of the noise the twin's orientation runs get.
        window: ``(start, end)`` s, or ``"START:END"``, of the report's traces (default: 10 s about
            the middle of the motion phase).
        cutoff_hz: smoothing cutoff of the orientation, Hz.
        position_cutoff_hz: smoothing cutoff of the position, Hz.
        without: effects left out (:data:`simbench.twin.EFFECTS`), to measure what each explains.
        methods: orientation methods to score (names or specs of the estimator registry).

    Raises:
        InputError: the file is not such a trial (naming it and what is missing), a bad option.
    """
    if isinstance(window, str):
        window = parse_twin_window(window)
    return twin_recording(
        recording,
        seed=seed,
        window=window,
        cutoff_hz=cutoff_hz,
        position_cutoff_hz=position_cutoff_hz,
        without=tuple(without),
        methods=tuple(methods),
    )


def write_twin(
    result: TwinResult,
    *,
    json_path: str | os.PathLike[str] | None = None,
    out: str | os.PathLike[str] | None = None,
) -> dict[str, Path]:
    """Write a twin's JSON (:meth:`simbench.twin.TwinResult.as_dict`, NaN as null) and its report
    folder (traces over the window, spectra, tables: :mod:`simbench.report.twin`), each atomically.

    Returns:
        ``{"json": ...}`` and the report's paths (``md``, ``html``, ``json`` as ``report_json``,
        ``traces``, ``spectra``), those written.
    """
    written: dict[str, Path] = {}
    if json_path is not None:
        atomic_write_text(
            json_path, json.dumps(json_safe(result.as_dict()), indent=1, allow_nan=False) + "\n"
        )
        written["json"] = Path(json_path)
    if out is not None:
        paths = write_twin_report(result, Path(out))
        written.update({("report_json" if k == "json" else k): v for k, v in paths.items()})
    return written


__all__ = [
    "BUILTIN_MODELS",
    "BUILTIN_PROGRAMS",
    "BVH_CUTOFF_HZ",
    "DEFAULT_JOINTS",
    "DEFAULT_ORIENTATION",
    "EXPORT_SOURCES",
    "FALSE_ALARMS_PER_HOUR",
    "LIVE_RATE_FRAMES",
    "LIVE_REFRESH_S",
    "LOCATED_RANK",
    "POSE_INPUTS",
    "SLIP_WINDOW_S",
    "TIME_LIMIT_S",
    "TWIN_EFFECTS",
    "TWIN_METHODS",
    "Calibration",
    "CalibrationError",
    "CalibrationInputError",
    "Dataset",
    "Estimator",
    "ImuRecording",
    "InputError",
    "JointsResult",
    "LiveState",
    "LiveUpdate",
    "MarkerConfig",
    "Orientations",
    "PoseRecording",
    "Priors",
    "ScaleEstimate",
    "Skeleton",
    "SlipAlert",
    "SlipReport",
    "StreamingCalibrator",
    "TwinResult",
    "calibrate",
    "calibration_document",
    "describe_fit",
    "estimator_names",
    "export",
    "follow",
    "one_blas_thread",
    "orient",
    "output_set",
    "parse_twin_window",
    "pose_inputs_text",
    "preset_names",
    "read",
    "read_hierarchy",
    "read_imu",
    "read_poses",
    "refuse_unlocated",
    "replay",
    "resolve_estimator",
    "rigidity",
    "sample_rate",
    "score",
    "simulate",
    "skeleton_from_calibration",
    "slip_reports",
    "truth_document",
    "twin",
    "unit_scale",
    "write_calibration",
    "write_dataset",
    "write_examples",
    "write_orientation_csv",
    "write_pose_csv",
    "write_twin",
]
