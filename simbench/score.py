"""Scoring estimates against the exact truth of a simulated session.

Public, one place for every comparison that the validation, the baseline, studies and reports
make: limb lengths, joint centres, the hierarchy (as an undirected tree, wrong edges named) and
orientations (BROAD's error definitions). Estimates in the tracker's units are converted to metres
with the dataset's ``position_unit_scale`` unless another factor is given (the validation uses the
factor measured by the rigid-pair experiment, as O'Brien et al. did).

A limb is keyed ``(segment, joint_a, joint_b)``; a joint is named ``parent-child``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.orientation import orientation_errors
from calibration.pipeline import Calibration
from calibration.skeleton import joint_name, segment_lengths
from simbench.errors import InputError
from simbench.io.dataset import Dataset, Truth

LimbKey = tuple[str, str, str]


def truth_lengths(ds: Dataset) -> dict[LimbKey, float]:
    """True distance between every two joints of a segment, m."""
    t = _truth(ds)
    index = {n: k for k, n in enumerate(ds.sensors)}
    joints = [(index[p], index[c]) for p, c in zip(t.parent, t.child, strict=True)]
    return {
        (x.segment, x.joint_a, x.joint_b): x.length
        for x in segment_lengths(ds.sensors, joints, t.joint_in_parent, t.joint_in_child)
    }


def estimated_lengths(cal: Calibration) -> dict[LimbKey, float]:
    """A calibration's limb lengths, in its input units."""
    return {(x.segment, x.joint_a, x.joint_b): x.length for x in cal.lengths}


def length_of(table: Mapping[LimbKey, float], key: LimbKey) -> float:
    """The length of a limb in either joint order; NaN where the table does not have it (the
    estimated tree gave that segment other joints)."""
    segment, a, b = key
    return table.get(key, table.get((segment, b, a), float("nan")))


@dataclass(frozen=True)
class TreeScore:
    """An estimated hierarchy against the true one, compared as undirected trees.

    Attributes:
        correct: the same undirected edges.
        wrong_edges: estimated joints (``parent-child``) that are not joints of the truth.
        missed_edges: true joints (``parent-child``) that the estimate does not have.
    """

    correct: bool
    wrong_edges: tuple[str, ...]
    missed_edges: tuple[str, ...]


def compare_trees(estimated: Mapping[str, str], true: Mapping[str, str]) -> TreeScore:
    """Compare two ``{child: parent}`` hierarchies as undirected trees."""
    est_edges = {frozenset((c, p)): f"{p}-{c}" for c, p in estimated.items()}
    true_edges = {frozenset((c, p)): f"{p}-{c}" for c, p in true.items()}
    wrong = sorted(name for e, name in est_edges.items() if e not in true_edges)
    missed = sorted(name for e, name in true_edges.items() if e not in est_edges)
    return TreeScore(correct=not wrong and not missed, wrong_edges=tuple(wrong), missed_edges=tuple(missed))


@dataclass(frozen=True)
class LimbScore:
    """One limb: true and estimated length (m) and ``true - estimated`` (m; NaN if not estimated)."""

    segment: str
    joint_a: str
    joint_b: str
    true_m: float
    estimated_m: float

    @property
    def error_m(self) -> float:
        return self.true_m - self.estimated_m


@dataclass(frozen=True)
class JointScore:
    """One estimated joint against the truth (m): the centre's distance from the true one in the
    parent's and in the child's sensor frame, and the fit's rms residual. Distances are NaN for
    a joint the truth does not have."""

    name: str
    centre_error_in_parent_m: float
    centre_error_in_child_m: float
    rms_residual_m: float
    condition: float


@dataclass(frozen=True)
class CalibrationScore:
    """A calibration scored against a simulated session's truth (all in metres)."""

    limbs: tuple[LimbScore, ...]
    joints: tuple[JointScore, ...]
    tree: TreeScore
    scale: float

    def _abs_limb_errors(self) -> np.ndarray:
        return np.abs([x.error_m for x in self.limbs])

    @property
    def max_length_error_m(self) -> float:
        """Largest absolute limb-length error (NaN if a limb was not estimated)."""
        return float(np.max(self._abs_limb_errors()))

    @property
    def mean_length_error_m(self) -> float:
        """Mean absolute limb-length error."""
        return float(np.mean(self._abs_limb_errors()))

    @property
    def mean_centre_error_m(self) -> float:
        """Mean distance of the estimated from the true joint centres, in the parent's frame."""
        return float(np.mean([j.centre_error_in_parent_m for j in self.joints]))


def score(cal: Calibration, ds: Dataset, *, scale: float | None = None) -> CalibrationScore:
    """Score a calibration of ``ds``'s measured poses against its truth.

    Args:
        cal: the calibration (lengths in the tracker's units).
        ds: the simulated session it was computed from (must have truth).
        scale: metres per tracker unit; default ``ds.position_unit_scale``.
    """
    fits = {(j.parent, j.child): j.fit for j in cal.joints}
    return score_joints(
        JointArrays.of(cal),
        ds,
        scale=scale,
        residual={k: f.rms_residual for k, f in fits.items()},
        condition={k: float(f.condition) for k, f in fits.items()},
    )


@dataclass(frozen=True)
class JointArrays:
    """Joints of any estimator as arrays: ``parent``, ``child`` ``(J,)`` sensor names and the
    centres ``joint_in_parent``, ``joint_in_child`` ``(J, 3)`` in the sensors' frames (in the
    estimate's unit). :class:`simbench.io.calibration_json.CalibrationJoints` is one."""

    parent: tuple[str, ...]
    child: tuple[str, ...]
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray

    @classmethod
    def of(cls, cal: Calibration) -> JointArrays:
        """A calibration's joints."""
        return cls(
            tuple(j.parent for j in cal.joints),
            tuple(j.child for j in cal.joints),
            np.array([j.fit.joint_in_parent for j in cal.joints], dtype=float).reshape(-1, 3),
            np.array([j.fit.joint_in_child for j in cal.joints], dtype=float).reshape(-1, 3),
        )


def score_joints(
    joints: JointArrays | Any,
    ds: Dataset,
    *,
    scale: float | None = None,
    residual: Mapping[tuple[str, str], float] | None = None,
    condition: Mapping[tuple[str, str], float] | None = None,
) -> CalibrationScore:
    """Score any estimator's joints against ``ds``'s truth: each joint's centre in both sensor
    frames, the limb lengths between a segment's joints, the tree (as undirected edges).

    Args:
        joints: anything with ``parent``, ``child``, ``joint_in_parent``, ``joint_in_child``
            (:class:`JointArrays`, :class:`simbench.io.calibration_json.CalibrationJoints`), in the
            recording's position unit.
        ds: the simulated session (must have truth).
        scale: metres per position unit; default ``ds.position_unit_scale``.
        residual, condition: ``{(parent, child): value}`` each joint's rms residual (position unit)
            and condition number where the estimator gives them (NaN elsewhere).

    Returns:
        The score; a true limb the estimate lacks a joint of has NaN as its estimated length.
    """
    t = _truth(ds)
    scale = ds.position_unit_scale if scale is None else float(scale)
    names = list(ds.sensors)
    pairs = [(names.index(p), names.index(c)) for p, c in zip(joints.parent, joints.child, strict=True)]
    jip = np.asarray(joints.joint_in_parent, dtype=float).reshape(-1, 3)
    jic = np.asarray(joints.joint_in_child, dtype=float).reshape(-1, 3)
    got = {(x.segment, x.joint_a, x.joint_b): x.length for x in segment_lengths(ds.sensors, pairs, jip, jic)}
    limbs = tuple(
        LimbScore(key[0], key[1], key[2], value, length_of(got, key) * scale)
        for key, value in truth_lengths(ds).items()
    )
    true_joints = {(p, c): k for k, (p, c) in enumerate(zip(t.parent, t.child, strict=True))}
    out = []
    for k, (parent, child) in enumerate(zip(joints.parent, joints.child, strict=True)):
        i = true_joints.get((parent, child))
        lp = lc = float("nan")
        if i is not None:
            lp = float(np.linalg.norm(jip[k] * scale - t.joint_in_parent[i]))
            lc = float(np.linalg.norm(jic[k] * scale - t.joint_in_child[i]))
        r = (residual or {}).get((parent, child), float("nan")) * scale
        out.append(
            JointScore(
                joint_name(parent, child), lp, lc, r, (condition or {}).get((parent, child), float("nan"))
            )
        )
    return CalibrationScore(
        limbs=limbs,
        joints=tuple(out),
        tree=compare_trees(dict(zip(joints.child, joints.parent, strict=True)), t.parent_of),
        scale=scale,
    )


@dataclass(frozen=True)
class OrientationScore:
    """Orientation errors (BROAD's definitions, degrees): RMSE over the scored samples.

    Attributes:
        per_sensor: ``{sensor: {"total_deg", "heading_deg", "inclination_deg", "samples"}}``.
        total_rmse_deg, heading_rmse_deg, inclination_rmse_deg: over all sensors and samples.
        per_frame_deg: ``(F,)`` total RMSE over sensors at each frame (NaN where none).
    """

    per_sensor: dict[str, dict[str, float]]
    total_rmse_deg: float
    heading_rmse_deg: float
    inclination_rmse_deg: float
    per_frame_deg: np.ndarray


def score_orientation(
    q_est: np.ndarray, q_true: np.ndarray, names: Sequence[str], evaluate: np.ndarray | None = None
) -> OrientationScore:
    """Score estimated orientations against reference ones.

    Args:
        q_est, q_true: ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` in the same world frame
            (NaN where not estimated / no reference).
        names: ``(N,)`` sensor names.
        evaluate: ``(F,)`` samples to score (e.g. BROAD's ``movement``), default all.
    """
    q_est, q_true = np.asarray(q_est), np.asarray(q_true)
    if q_est.shape != q_true.shape or q_est.ndim != 3 or q_est.shape[1:] != (len(names), 4):
        raise InputError(
            f"Expected estimate and reference of shape (F, {len(names)}, 4), got {q_est.shape} and "
            f"{q_true.shape}"
        )
    err = np.rad2deg(orientation_errors(q_est, q_true))  # (F, N, 3): total, heading, inclination
    use = np.isfinite(err).all(axis=2)
    if evaluate is not None:
        use &= np.asarray(evaluate, dtype=bool)[:, None]
    per_sensor = {}
    for k, name in enumerate(names):
        e = err[use[:, k], k]
        rmse = np.sqrt(np.mean(e**2, axis=0)) if len(e) else np.full(3, np.nan)
        per_sensor[name] = {
            "total_deg": float(rmse[0]),
            "heading_deg": float(rmse[1]),
            "inclination_deg": float(rmse[2]),
            "samples": int(use[:, k].sum()),
        }
    scored = np.where(use[..., None], err, np.nan)
    with warnings.catch_warnings():  # a sensor or frame with nothing scored is NaN, said as such
        warnings.simplefilter("ignore", RuntimeWarning)
        totals = np.sqrt(np.nanmean(scored.reshape(-1, 3) ** 2, axis=0))
        per_frame = np.sqrt(np.nanmean(scored[..., 0] ** 2, axis=1))
    return OrientationScore(per_sensor, float(totals[0]), float(totals[1]), float(totals[2]), per_frame)


def _truth(ds: Dataset) -> Truth:
    if ds.truth is None:
        raise InputError(f"{ds.meta.get('source', 'dataset')}: no ground truth to score against")
    return ds.truth
