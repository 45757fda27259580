"""simbench's own estimators, registered in :data:`simbench.estimators.registry.REGISTRY`.

This module is the one list of the built-in methods: the command line, studies, the baseline, the
validation, ``simbench bench`` and the reports take their names from the registry it fills.

**Joint centres** (kind ``joints``; the contract in :mod:`simbench.estimators.registry`):

- ``obrien``: O'Brien et al. (2000) over the whole recording (:func:`calibration.calibrate`): the
  hierarchy inferred when none is given, each joint's least-squares fit with the single-axis test;
  ``obrien-eiv`` the same corrected for the rotations' noise (:mod:`calibration.eiv`);
  ``obrien-robust`` fitted by IRLS (:mod:`calibration.robust`).
- ``score`` (SCoRE, Ehrig et al. 2006), ``sara`` (SARA, Ehrig et al. 2007),
  ``sphere-gamage-lasenby`` and ``sphere-geometric`` (sphere fits): the joints of a given hierarchy,
  one pair at a time (:mod:`calibration.methods`); a joint a method cannot fit is left out, named.
- ``inertial``: Seel et al. (2012; 2014), the joints of a given hierarchy from gyroscopes and
  accelerometers alone (its data is an IMU recording, not poses).

**Orientation** (kind ``orientation``): ``skeleton`` (the default: every sensor over the whole
recording at once, on a calibrated skeleton when one is given), the per-sample ``fontaine``
(Fontaine et al.), ``triad`` and ``wahba``, and the gyro-aided references ``mahony`` and ``vqf``
(:func:`simbench.orient.estimate`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from calibration import Calibration, CalibrationError
from calibration import calibrate as calibrate_arrays
from calibration.joint import LOCATED_RANK
from calibration.methods import JOINT_METHODS, JointEstimate, estimate_inertial
from calibration.orientation import Priors, Skeleton
from simbench.estimators.catalog import (
    BUILTINS,
    CALIBRATE_MAG,
    DEFAULT_JOINTS,
    DEFAULT_ORIENTATION,
    OBRIEN_PARAMS,
    Builtin,
)
from simbench.estimators.registry import (
    SUFFIX_UNITS,
    Estimator,
    JointsResult,
    OrientationResult,
    Param,
    register,
)
from simbench.io.calibration_json import CalibrationJoints
from simbench.io.imu import ImuRecording
from simbench.io.poses import PoseRecording
from simbench.orient import calibrate_magnetometers, estimate

__all__ = ["DEFAULT_JOINTS", "DEFAULT_ORIENTATION", "OBRIEN_PARAMS", "joints_of", "pair_params", "pairwise"]


def joints_of(cal: Calibration) -> CalibrationJoints:
    """The joints of a calibration as arrays (centres in its input's unit)."""
    index = {n: k for k, n in enumerate(cal.names)}
    return CalibrationJoints(
        parent=tuple(j.parent for j in cal.joints),
        child=tuple(j.child for j in cal.joints),
        parent_index=np.array([index[j.parent] for j in cal.joints], dtype=int),
        child_index=np.array([index[j.child] for j in cal.joints], dtype=int),
        joint_in_parent=np.array([j.fit.joint_in_parent for j in cal.joints], dtype=float).reshape(-1, 3),
        joint_in_child=np.array([j.fit.joint_in_child for j in cal.joints], dtype=float).reshape(-1, 3),
        single_axis=np.array([bool(j.fit.single_axis) for j in cal.joints], dtype=bool),
    )


def _obrien(
    poses: PoseRecording, *, hierarchy: Mapping[str, str] | None = None, **options: Any
) -> JointsResult:
    cal = calibrate_arrays(
        poses.R_w_s, poses.p_w_s, poses.names, valid=poses.valid, parent_of=hierarchy, **options
    )
    # a joint whose motion locates fewer than 5 of its 6 coordinates has no centre to give (the
    # one-pair fit refuses it too): left out of the joints, named; the calibration keeps it
    unlocated = [j for j in cal.joints if j.fit.rank < LOCATED_RANK]
    notes = tuple(
        f"joint {j.name} not located: the motion determines {j.fit.rank} of the 6 coordinates of the "
        f"joint (needs {LOCATED_RANK})"
        for j in unlocated
    )
    joints = joints_of(cal)
    if unlocated:
        keep = np.array([j.fit.rank >= LOCATED_RANK for j in cal.joints])
        joints = CalibrationJoints(
            tuple(p for p, k in zip(joints.parent, keep, strict=True) if k),
            tuple(c for c, k in zip(joints.child, keep, strict=True) if k),
            joints.parent_index[keep],
            joints.child_index[keep],
            joints.joint_in_parent[keep],
            joints.joint_in_child[keep],
            joints.single_axis[keep],
        )
    return JointsResult(joints, calibration=cal, notes=(*cal.warnings, *notes))


def _obrien_variant(**fixed: Any) -> Callable[..., JointsResult]:
    def run(
        poses: PoseRecording, *, hierarchy: Mapping[str, str] | None = None, **options: Any
    ) -> JointsResult:
        return _obrien(poses, hierarchy=hierarchy, **fixed, **options)

    return run


def pairwise(fit: Callable[..., JointEstimate]) -> Callable[..., JointsResult]:
    """A joints estimator of the given hierarchy from a one-pair method of
    :mod:`calibration.methods` (``fit(R_w_p, p_w_p, R_w_c, p_w_c, *, valid, **options)``): every
    joint fitted on the frames where both its sensors are valid; a joint the motion cannot determine
    for the method (:class:`calibration.CalibrationError`) is left out and named in the notes."""

    def run(poses: PoseRecording, *, hierarchy: Mapping[str, str], **options: Any) -> JointsResult:
        rows, notes = [], []
        for child, parent in hierarchy.items():
            p, c = poses.names.index(parent), poses.names.index(child)
            try:
                got = fit(*poses.pair(parent, child), valid=poses.valid[:, p] & poses.valid[:, c], **options)
            except CalibrationError as exc:
                notes.append(f"joint {parent}-{child} not fitted: {exc}")
                continue
            rows.append((parent, child, p, c, got))
        return JointsResult(_pair_joints(rows), notes=tuple(notes))

    return run


def pair_params(fit: Callable[..., JointEstimate]) -> tuple[Param, ...]:
    """The options of a one-pair method, read off its signature: its keyword-only parameters with
    defaults, but ``valid`` (the harness's) and those a ``partial`` fixed (a sphere fit's variant)."""
    fixed = set(getattr(fit, "keywords", {}))
    return tuple(
        Param(p.name, p.default, unit=next((u for s, u in SUFFIX_UNITS if p.name.endswith(s)), "1"))
        for p in inspect.signature(fit).parameters.values()
        if p.kind is p.KEYWORD_ONLY and p.name != "valid" and p.name not in fixed
    )


def _summary(fit: Callable[..., Any]) -> str:
    return (inspect.getdoc(getattr(fit, "func", fit)) or "").split("\n", 1)[0]


def _pair_joints(rows: list[tuple[str, str, int, int, JointEstimate]]) -> CalibrationJoints:
    return CalibrationJoints(
        parent=tuple(r[0] for r in rows),
        child=tuple(r[1] for r in rows),
        parent_index=np.array([r[2] for r in rows], dtype=int),
        child_index=np.array([r[3] for r in rows], dtype=int),
        joint_in_parent=np.array([r[4].joint_in_parent for r in rows], dtype=float).reshape(-1, 3),
        joint_in_child=np.array([r[4].joint_in_child for r in rows], dtype=float).reshape(-1, 3),
        single_axis=np.array([r[4].axis_in_parent is not None for r in rows], dtype=bool),
    )


def _inertial(imu: ImuRecording, *, hierarchy: Mapping[str, str], hinge: bool = False) -> JointsResult:
    rows, notes = [], []
    for child, parent in hierarchy.items():
        p, c = imu.names.index(parent), imu.names.index(child)
        try:
            got = estimate_inertial(
                imu.gyro[:, p],
                imu.gyro[:, c],
                imu.acc[:, p],
                imu.acc[:, c],
                rate_hz=imu.rate_hz,
                hinge=hinge,
                valid=imu.valid[:, p] & imu.valid[:, c],
            )
        except CalibrationError as exc:
            notes.append(f"joint {parent}-{child} not fitted: {exc}")
            continue
        rows.append((parent, child, p, c, got))
    return JointsResult(_pair_joints(rows), notes=tuple(notes))


def _orientation(method: str) -> Callable[..., OrientationResult]:
    def run(
        imu: ImuRecording, *, skeleton: Skeleton | None = None, calibrate_mag: bool = True, **options: Any
    ) -> OrientationResult:
        if "lone_speed_m_per_s" in options:
            options["priors"] = Priors(lone_speed=options.pop("lone_speed_m_per_s"))
        if calibrate_mag:  # as simbench orient and sb.orient do by default
            imu, _ = calibrate_magnetometers(imu)
        got = estimate(imu, method, skeleton=skeleton, **options)
        return OrientationResult(got.q_enu, got.ok, got.field_strength_ut, got.inclination_deg)

    run.__name__ = f"orientation_{method}"
    return run


def _function(b: Builtin) -> Callable[..., Any]:
    """The function of a built-in of :data:`simbench.estimators.catalog.BUILTINS`."""
    if b.name == DEFAULT_JOINTS:
        return _obrien
    if b.name == "obrien-eiv":
        return _obrien_variant(correct_rotation_noise=True)
    if b.name == "obrien-robust":
        return _obrien_variant()
    if b.name == "inertial":
        return _inertial
    if b.name in JOINT_METHODS:
        return pairwise(JOINT_METHODS[b.name])
    return _orientation(b.name)


def _params(b: Builtin) -> tuple[Param, ...]:
    """The parameters the catalog leaves to the code: a one-pair method's, read off its function;
    the skeleton estimator's, whose speed prior's default is the core's."""
    if b.name in JOINT_METHODS:
        return pair_params(JOINT_METHODS[b.name])
    if b.name == DEFAULT_ORIENTATION:
        lone = Param(
            "lone_speed_m_per_s",
            Priors().lone_speed,
            unit="m/s",
            help="the speed prior of a sensor on its own (no skeleton, or a root with no children)",
        )
        return (CALIBRATE_MAG, lone)
    raise KeyError(f"the catalog gives no parameters of {b.name!r} and neither does the code")


def _register_all() -> None:
    """Every entry of the catalog, in its order, with its function."""
    for b in BUILTINS:
        fn = _function(b)
        summary = b.summary or _summary(JOINT_METHODS[b.name])
        params = b.params if b.params is not None else _params(b)
        register(
            Estimator(
                b.name, b.kind, fn, params, b.needs, summary, data=b.data, takes_skeleton=b.takes_skeleton
            )
        )


_register_all()
