"""Figures of merit of one simulated session, shared by the accuracy baseline and studies.

Each function runs an estimator on a Dataset with truth and scores it (:mod:`simbench.score`);
all figures are "lower is better" except ``hierarchy_correct``. SI units.
"""

from __future__ import annotations

import numpy as np

from calibration import calibrate
from calibration.errors import CalibrationError
from calibration.methods import JOINT_METHODS
from calibration.skeleton import segment_lengths
from simbench.io.dataset import Dataset
from simbench.orient import estimate
from simbench.score import compare_trees, score, score_orientation

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


def orientation_metrics(ds: Dataset, method: str) -> dict[str, float]:
    """Orientation RMSE (total, heading, inclination; degrees) of one method over every sensor and
    sample of a simulated session, against the actual sensor orientations."""
    rec = ds.imu()
    run = estimate(rec, method)
    scored = score_orientation(run.q_enu, rec.q_true, rec.names)
    return {
        "total_rmse_deg": scored.total_rmse_deg,
        "heading_rmse_deg": scored.heading_rmse_deg,
        "inclination_rmse_deg": scored.inclination_rmse_deg,
    }


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


def joint_method_metrics(ds: Dataset, method: str) -> dict[str, float]:
    """One joint-centre method of :data:`calibration.methods.JOINT_METHODS` on every joint of the
    true hierarchy of a simulated session, scored as :func:`calibration_metrics` scores O'Brien's
    (centres in the parent's frame, limb lengths between a segment's joints; metres through the
    dataset's unit scale). A joint the method cannot fit (e.g. a sphere fit of a hinge) is
    counted in ``failed_joints`` and left out of the means (NaN when all fail)."""
    if ds.truth is None:
        raise ValueError("joint_method_metrics needs a dataset with truth (a simulated session)")
    fit = JOINT_METHODS[method]
    rec = ds.poses()
    scale = ds.position_unit_scale
    true_p, true_c = ds.truth_joint_arrays()
    pairs = true_joints(ds)
    est_p, est_c, keep = [], [], []
    failed = 0
    for parent, child in pairs:
        try:
            got = fit(
                rec.R_w_s[:, parent],
                rec.p_w_s[:, parent],
                rec.R_w_s[:, child],
                rec.p_w_s[:, child],
                valid=rec.valid[:, parent] & rec.valid[:, child],
            )
        except CalibrationError:
            failed += 1
            est_p.append(np.full(3, np.nan))
            est_c.append(np.full(3, np.nan))
            keep.append(False)
            continue
        est_p.append(got.joint_in_parent * scale)
        est_c.append(got.joint_in_child * scale)
        keep.append(True)
    children = [c for _, c in pairs]
    est_p, est_c, keep = np.array(est_p), np.array(est_c), np.array(keep)
    centre = np.linalg.norm(est_p - true_p[children], axis=1)[keep]
    truth = segment_lengths(rec.names, pairs, true_p[children], true_c[children])
    got = segment_lengths(rec.names, pairs, est_p, est_c)
    length = np.array([abs(g.length - t.length) for g, t in zip(got, truth, strict=True)])
    length = length[np.isfinite(length)]
    return {
        "joint_centre_error_m": float(np.mean(centre)) if centre.size else float("nan"),
        "limb_length_error_m": float(np.mean(length)) if length.size else float("nan"),
        "failed_joints": float(failed),
    }
