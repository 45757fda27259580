"""Figures of merit of one simulated session, shared by the accuracy baseline and studies.

Each function runs an estimator on a Dataset with truth and scores it (:mod:`simbench.score`);
all figures are "lower is better" except ``hierarchy_correct``. SI units.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from calibration import calibrate
from calibration.orientation import Skeleton
from simbench.errors import InputError
from simbench.estimators import Estimator, resolve, run_joints, run_orientation
from simbench.io.dataset import Dataset, truth_calibration_dict
from simbench.io.imu import ImuRecording
from simbench.orient import skeleton_from_calibration
from simbench.score import compare_trees, score, score_joints, score_orientation

#: What :func:`calibration_metrics` returns.
CALIBRATION_METRICS = {
    "joint_centre_error_m": "mean distance of estimated from true joint centres (parent frame), m",
    "limb_length_error_m": "mean absolute limb-length error, m",
    "max_limb_length_error_m": "largest absolute limb-length error, m",
    "hierarchy_correct": "1 if the inferred hierarchy equals the truth (as undirected tree)",
    "residual_m": "mean rms joint residual, m",
    "condition": "mean condition number of the joint fits",
}

#: Condition numbers are capped here before averaging (a single-axis joint's is infinite).
CONDITION_CAP = 1e12


def calibration_metrics(ds: Dataset) -> dict[str, float]:
    """Calibrate the measured poses twice: with the hierarchy inferred (scored: is the tree right)
    and with the true hierarchy given (scored: joint centres, limb lengths, residual, conditioning;
    lengths in metres through the dataset's unit scale)."""
    if ds.truth is None:
        raise ValueError("calibration_metrics needs a dataset with truth (a simulated session)")
    rec = ds.poses()
    inferred = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    given = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, parent_of=ds.truth.parent_of)
    scored = score(given, ds)
    return {
        "joint_centre_error_m": scored.mean_centre_error_m,
        "limb_length_error_m": scored.mean_length_error_m,
        "max_limb_length_error_m": scored.max_length_error_m,
        "hierarchy_correct": float(compare_trees(inferred.parent_of, ds.truth.parent_of).correct),
        "residual_m": float(np.mean([j.rms_residual_m for j in scored.joints])),
        "condition": float(np.mean([min(j.condition, CONDITION_CAP) for j in scored.joints])),
    }


def orientation_metrics(
    ds: Dataset | ImuRecording,
    method: str | Estimator,
    params: Mapping[str, Any] | None = None,
    *,
    time_limit_s: float | None = None,
    skeleton: Skeleton | None = None,
) -> dict[str, float]:
    """Orientation RMSE (total, heading, inclination; degrees) of one estimator (any spec of
    :func:`simbench.estimators.resolve`) over every sensor and sample of a simulated session,
    against the actual sensor orientations, or of a real recording against its reference over its
    samples to evaluate (BROAD's ``movement``); ``params`` over the estimator's defaults, and a
    user's estimator's time limit (:func:`simbench.estimators.run_orientation`); ``skeleton``
    goes to an estimator that takes one (:func:`true_skeleton` for the session's own)."""
    rec = ds.imu() if isinstance(ds, Dataset) else ds
    if rec.q_true is None:
        raise InputError(f"{rec.source}: no reference orientations to score against")
    est = resolve(method, "orientation")
    skeleton = skeleton if est.takes_skeleton else None
    run = run_orientation(est, rec, skeleton=skeleton, params=params, time_limit_s=time_limit_s)
    scored = score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate)
    return {
        "total_rmse_deg": scored.total_rmse_deg,
        "heading_rmse_deg": scored.heading_rmse_deg,
        "inclination_rmse_deg": scored.inclination_rmse_deg,
    }


def true_skeleton(ds: Dataset) -> Skeleton:
    """A simulated session's true skeleton over its IMUs (its true tree and joint centres in the
    sensors' frames): what an orientation estimator that takes a skeleton is given where a
    scenario scores on the truth, as a joints estimator is given the true tree."""
    return skeleton_from_calibration(truth_calibration_dict(ds), tuple(ds.sensors))


#: What :func:`joint_method_metrics` returns.
JOINT_METHOD_METRICS = {
    "joint_centre_error_m": "mean distance of estimated from true joint centres (parent frame), m",
    "limb_length_error_m": "mean absolute limb-length error, m",
    "failed_joints": "joints the method could not fit (left out of the means)",
}


def true_joints(ds: Dataset) -> list[tuple[int, int]]:
    """``(parent, child)`` sensor indices of every joint of a simulated session's true hierarchy,
    children in sensor order."""
    names = list(ds.sensors)
    return [(names.index(p), c) for c, n in enumerate(names) if (p := ds.truth.parent_of.get(n)) is not None]


def joint_method_metrics(
    ds: Dataset,
    method: str | Estimator,
    params: Mapping[str, Any] | None = None,
    *,
    time_limit_s: float | None = None,
) -> dict[str, float]:
    """One joints estimator (any spec of :func:`simbench.estimators.resolve`) on the true
    hierarchy of a simulated session, scored as :func:`calibration_metrics` scores O'Brien's
    (centres in the parent's frame, limb lengths between a segment's joints; metres through the
    dataset's unit scale). A joint the estimator does not return (e.g. a sphere fit of a hinge) is
    counted in ``failed_joints`` and left out of the means (NaN when all fail); an estimator that
    infers its own tree is given none and scored on the joints it has. ``params`` go to the
    estimator over its defaults; ``time_limit_s`` limits a user's estimator
    (:func:`simbench.estimators.run_joints`)."""
    if ds.truth is None:
        raise ValueError("joint_method_metrics needs a dataset with truth (a simulated session)")
    est = resolve(method, "joints")
    data = ds.poses() if est.data == "poses" else ds.imu()
    hierarchy = ds.truth.parent_of if est.takes_hierarchy else None
    got = run_joints(est, data, hierarchy=hierarchy, params=params, time_limit_s=time_limit_s)
    scored = score_joints(got.joints, ds, scale=ds.position_unit_scale if est.data == "poses" else 1.0)
    centre = np.array([j.centre_error_in_parent_m for j in scored.joints])
    centre = centre[np.isfinite(centre)]
    length = np.abs([x.error_m for x in scored.limbs])
    length = length[np.isfinite(length)]
    found = {(p, c) for p, c in zip(got.joints.parent, got.joints.child, strict=True)}
    failed = sum((p, c) not in found for c, p in ds.truth.parent_of.items())
    return {
        "joint_centre_error_m": float(np.mean(centre)) if centre.size else float("nan"),
        "limb_length_error_m": float(np.mean(length)) if length.size else float("nan"),
        "failed_joints": float(failed),
    }
