"""The calibration JSON of docs/conventions.md: what ``simbench calibrate --json`` writes.

The fields of docs/conventions.md (``units``, ``root``, ``joints`` with ``parent``, ``child``,
``joint_in_parent``, ``joint_in_child``, ``rms_residual``, ``single_axis``, ``axis_in_parent``,
``axis_in_child``) are kept as they are; everything else is added beside them. Lengths are in
``units`` (always ``"m"`` here); a value JSON cannot hold (an infinite condition number) is
written as ``null``.

Optional fields, present only when the calibration computed them (the reader accepts and
otherwise ignores them):

- per joint ``"uncertainty"`` (``simbench calibrate --intervals``): the centre's covariance and
  95 % intervals and ellipsoids in both sensor frames, metres
  (:func:`calibration.uncertainty.to_json`: ``method``, ``level``, ``dof``, ``cov_in_parent_m2``,
  ``ci95_in_parent_m``, ``ellipsoid95_in_parent``, ... ); for a robust fit it is computed over the
  inlier frames and is conditional on them;
- per joint ``"robust"`` (``--robust``): ``{"loss", "tuning", "scale_m", "n_inliers",
  "inlier_fraction", "n_iter", "converged"}`` of the IRLS fit
  (:class:`calibration.robust.RobustJointFit`); ``rms_residual`` is then over the inlier frames;
- per limb length ``"ci95_m"``: ``[lo, hi]`` its 95 % interval, metres, and ``"uncertainty"``
  (:func:`calibration.uncertainty.length_to_json`), or both ``null`` where a joint of the segment
  has none;
- top level ``"robust"``: the loss, or ``null`` for least squares (written only with ``--robust``);
- per joint ``"orientation_noise_rad2"`` and top level ``"rotation_noise_rad2"``
  (``--correct-rotation-noise``): the rotation-noise variances (rad^2 per rotation-vector
  component) the joint was corrected for, ``[parent, child]``, and every sensor's
  ``{name: variance}`` (:mod:`calibration.eiv`);
- per joint ``"range"`` (written by ``simbench calibrate --json``): the joint's range of motion in
  the calibrated poses as a cone, ``{"centre_in_parent": [w, x, y, z], "radius_deg": r}``: the
  child sensor's frame in the parent's (scalar-first quaternion) at the cone's centre, and the
  largest angle from it seen (:meth:`calibration.orientation.Skeleton.with_ranges`); the
  skeleton orientation estimator keeps the joint inside it.

:func:`read_calibration_json` reads such a file back (checking the fields the readers need) and
:func:`calibration_joints` turns its joints into arrays indexed by a recording's sensors.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration.pipeline import Calibration, Joint
from calibration.rotations import matrix_to_quat
from calibration.slip import SlipReport
from calibration.uncertainty import LengthUncertainty, length_to_json, to_json
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text
from simbench.versions import software_versions

FORMAT = "simbench-calibration"
#: The farthest a joint centre may be from its sensor, in the document's units (1e6: far beyond any
#: body, a corrupt value).
MAX_OFFSET = 1e6
FORMAT_VERSION = 1


def _num(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _vec(v: np.ndarray | None) -> list[float] | None:
    return None if v is None else [float(a) for a in np.asarray(v)]


def _joint_dict(joint: Joint) -> dict[str, Any]:
    """One joint: the fields of docs/conventions.md, then the fit's diagnostics."""
    fit = joint.fit
    s = fit.singular_values
    return {
        "parent": joint.parent,
        "child": joint.child,
        "joint_in_parent": _vec(fit.joint_in_parent),
        "joint_in_child": _vec(fit.joint_in_child),
        "rms_residual": float(fit.rms_residual),
        "single_axis": bool(fit.single_axis),
        "axis_in_parent": _vec(fit.axis_in_parent),
        "axis_in_child": _vec(fit.axis_in_child),
        "max_residual": (
            _num(np.nanmax(fit.frame_residual))
            if fit.frame_residual is not None and np.isfinite(fit.frame_residual).any()
            else None
        ),
        "rank": fit.rank,
        "singular_values_per_sqrt_frame": [float(x) for x in s / math.sqrt(max(fit.n_frames, 1))],
        "condition": _num(fit.condition),
        "n_frames": fit.n_frames,
        "n_dropped": fit.n_dropped,
        **_optional_joint_fields(joint),
    }


def _optional_joint_fields(joint: Joint) -> dict[str, Any]:
    """``"uncertainty"`` and ``"robust"`` when the joint has them (module docstring)."""
    out: dict[str, Any] = {}
    if joint.uncertainty is not None:
        out["uncertainty"] = to_json(joint.uncertainty)
    if max(joint.fit.orientation_noise_rad2) > 0.0:
        out["orientation_noise_rad2"] = [float(v) for v in joint.fit.orientation_noise_rad2]
    rob = joint.robust_fit
    if rob is not None:
        out["robust"] = {
            "loss": rob.loss,
            "tuning": float(rob.tuning),
            "scale_m": _num(rob.scale_m),
            "n_inliers": rob.n_inliers,
            "inlier_fraction": _num(rob.inlier_fraction),
            "n_iter": int(rob.n_iter),
            "converged": bool(rob.converged),
        }
    return out


def _limb_lengths(cal: Calibration) -> list[dict[str, Any]]:
    """The limb lengths, each with its interval when the calibration has intervals."""
    out = []
    for k, x in enumerate(cal.lengths):
        entry: dict[str, Any] = {
            "segment": x.segment,
            "joint_a": x.joint_a,
            "joint_b": x.joint_b,
            "length": x.length,
        }
        if cal.length_uncertainty:
            unc: LengthUncertainty | None = cal.length_uncertainty[k]
            entry["ci95_m"] = None if unc is None else [_num(v) for v in unc.interval_m]
            entry["uncertainty"] = None if unc is None else length_to_json(unc)
        out.append(entry)
    return out


def _slip_dict(name: str, rep: SlipReport, time_s: np.ndarray | None) -> dict[str, Any]:
    """Slip detection on one joint; times in seconds when ``time_s`` is given, else ``None``."""

    def t(frame: int) -> float | None:
        if time_s is None:
            return None
        return float(time_s[min(frame, len(time_s) - 1)])

    def t_end(stop: int) -> float | None:
        if time_s is None:
            return None
        return float(time_s[stop - 1])

    return {
        "joint": name,
        "window_frames": rep.window,
        "noise": float(rep.noise),
        "events": [
            {
                "frame": ev.frame,
                "time_s": t(ev.frame),
                "jump": ev.jump,
                "sensor": ev.sensor_frame,
                "z": _num(ev.z),
            }
            for ev in rep.events
        ],
        "intervals": [
            {"start_frame": a, "stop_frame": b, "start_s": t(a), "end_s": t_end(b)} for a, b in rep.intervals
        ],
    }


def calibration_to_dict(
    cal: Calibration,
    *,
    time_s: np.ndarray | None = None,
    slips: Sequence[tuple[str, SlipReport]] = (),
    input_info: dict[str, Any] | None = None,
    notes: Sequence[str] = (),
    options: dict[str, Any] | None = None,
    ranges: dict[str, tuple[np.ndarray, float]] | None = None,
) -> dict[str, Any]:
    """The calibration as a JSON-ready dict (schema: module docstring and docs/conventions.md).

    Args:
        cal: the calibration.
        time_s: ``(frames,)`` times, seconds, to give slip events and intervals in seconds.
        slips: ``(joint name, report)`` of slip detection per joint.
        input_info: what was read (source, sensors, frames, rate, units).
        notes: what the reader repaired or noticed.
        options: the options the calibration ran with.
        ranges: per child sensor, its joint's range of motion: the centre rotation ``(3, 3)``
            of its frame in its parent's and the radius, rad (module docstring).
    """
    doc = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "units": "m",
        "root": cal.root,
        "hierarchy": "given" if cal.hierarchy_given else "inferred",
        "joints": [_joint_dict(j) for j in cal.joints],
        "limb_lengths": _limb_lengths(cal),
        "sensor_offsets": [
            {
                "sensor": pl.sensor,
                "joints": list(pl.joints),
                "offsets": [_vec(o) for o in pl.offsets],
                "distances": [float(d) for d in pl.distances],
            }
            for pl in cal.placements
        ],
        "loop_candidates": [{"a": a, "b": b, "rms_residual": r} for a, b, r in cal.loop_candidates],
        "slip": [_slip_dict(name, rep, time_s) for name, rep in slips],
        "warnings": list(cal.warnings),
        "notes": list(notes),
        "input": dict(input_info or {}),
        "options": dict(options or {}),
        "timing_s": dict(cal.seconds),
        "software": software_versions(),
    }
    for entry in doc["joints"]:
        if ranges and entry["child"] in ranges and math.isfinite(ranges[entry["child"]][1]):
            centre, radius = ranges[entry["child"]]
            entry["range"] = {
                "centre_in_parent": _vec(matrix_to_quat(np.asarray(centre))),
                "radius_deg": float(np.rad2deg(radius)),
            }
    if cal.robust is not None:
        doc["robust"] = cal.robust
    if cal.rotation_noise_rad2:
        doc["rotation_noise_rad2"] = {k: float(v) for k, v in cal.rotation_noise_rad2.items()}
    return doc


def write_calibration_json(path: str | os.PathLike[str], doc: dict[str, Any]) -> None:
    """Write a calibration dict as JSON, atomically."""
    atomic_write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")


def _check_joint(path: str | os.PathLike[str], k: int, joint: Any) -> None:
    """Raise an :class:`InputError` naming what ``joints[k]`` lacks."""
    where = f"{path}: not a calibration JSON: joints[{k}]"
    if not isinstance(joint, dict):
        raise InputError(f"{where} is not an object")
    for key in ("parent", "child"):
        if not isinstance(joint.get(key), str):
            raise InputError(f"{where} has no sensor name {key!r}")
    for key in ("joint_in_parent", "joint_in_child"):
        value = joint.get(key)
        if not (
            isinstance(value, list)
            and len(value) == 3
            and all(isinstance(x, int | float) and not isinstance(x, bool) for x in value)
        ):
            raise InputError(f"{where}: expected {key!r} to be a list of 3 numbers, got {value!r}")
        if not all(math.isfinite(x) and abs(x) <= MAX_OFFSET for x in value):
            raise InputError(
                f"{where}: expected {key!r} to be 3 finite numbers within {MAX_OFFSET:g} of the sensor, "
                f"got {value!r}"
            )
    if not isinstance(joint.get("single_axis", False), bool | None):
        raise InputError(f"{where}: expected 'single_axis' to be true or false, got {joint['single_axis']!r}")
    rng = joint.get("range")
    if rng is not None:
        q = rng.get("centre_in_parent") if isinstance(rng, dict) else None
        r = rng.get("radius_deg") if isinstance(rng, dict) else None
        if not (
            isinstance(q, list)
            and len(q) == 4
            and all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in q)
            and abs(math.hypot(*q) - 1.0) < 1e-6
            and isinstance(r, int | float)
            and not isinstance(r, bool)
            and 0 < r <= 180
        ):
            raise InputError(
                f"{where}: expected 'range' to be {{'centre_in_parent': a unit quaternion [w, x, y, z], "
                f"'radius_deg': a number in (0, 180]}}, got {rng!r}"
            )
    for key in ("uncertainty", "robust"):  # optional: accepted, not used by the readers
        if not isinstance(joint.get(key), dict | None):
            raise InputError(f"{where}: expected {key!r} to be an object or null, got {joint[key]!r}")
    noise = joint.get("orientation_noise_rad2")
    if noise is not None and not (
        isinstance(noise, list)
        and len(noise) == 2
        and all(isinstance(x, int | float) and not isinstance(x, bool) and 0 <= x < math.inf for x in noise)
    ):
        raise InputError(
            f"{where}: expected 'orientation_noise_rad2' to be two variances >= 0 (rad^2) or null, "
            f"got {noise!r}"
        )


def read_calibration_json(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a calibration JSON (``simbench calibrate --json``, ``simbench simulate --truth-json``).

    Checks what readers of the file rely on: a JSON object with a ``joints`` list whose entries
    name their ``parent`` and ``child`` sensors and give ``joint_in_parent`` and
    ``joint_in_child`` as 3 numbers each (in the document's ``units``).

    Returns:
        The document as parsed.

    Raises:
        InputError: naming the file and what is wrong (cannot read, not JSON, a missing field, a
            location that is not finite or beyond :data:`MAX_OFFSET`, a sensor the child of two
            joints or joined with itself).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a calibration JSON: not UTF-8 text") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}, line {exc.lineno}: not a calibration JSON: not valid JSON: {exc.msg}"
        ) from None
    return check_calibration_document(doc, path)


def check_calibration_document(doc: Any, path: str | os.PathLike[str]) -> dict[str, Any]:
    """The checks of :func:`read_calibration_json` on a parsed document (or one made in memory,
    :func:`calibration_to_dict`), naming ``path`` (where it came from) in the error; returns it.

    Raises:
        InputError: as :func:`read_calibration_json`.
    """
    if not isinstance(doc, dict) or not isinstance(doc.get("joints"), list):
        raise InputError(f'{path}: not a calibration JSON: expected an object with a "joints" list')
    for k, joint in enumerate(doc["joints"]):
        _check_joint(path, k, joint)
    children = [j["child"] for j in doc["joints"]]
    twice = sorted({c for c in children if children.count(c) > 1})
    if twice:
        raise InputError(f"{path}: not a calibration JSON: sensors that are the child of two joints: {twice}")
    own = sorted(j["child"] for j in doc["joints"] if j["child"] == j["parent"])
    if own:
        raise InputError(f"{path}: not a calibration JSON: joints of a sensor with itself: {own}")
    return doc


@dataclass(frozen=True)
class CalibrationJoints:
    """The joints of a calibration JSON as arrays, indexed by a recording's sensors.

    Attributes:
        parent, child: ``(J,)`` sensor names of each joint.
        parent_index, child_index: ``(J,)`` indices of those sensors in the recording.
        joint_in_parent, joint_in_child: ``(J, 3)`` joint centres in the parent's and the child's
            sensor frame, in the document's ``units``.
        single_axis: ``(J,)`` whether the joint was found to turn about one axis only.
    """

    parent: tuple[str, ...]
    child: tuple[str, ...]
    parent_index: np.ndarray
    child_index: np.ndarray
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    single_axis: np.ndarray

    @property
    def parent_of(self) -> dict[str, str]:
        """``{child: parent}``."""
        return dict(zip(self.child, self.parent, strict=True))


def calibration_joints(
    doc: dict[str, Any], names: Sequence[str], *, source: str | os.PathLike[str] = "the calibration"
) -> CalibrationJoints:
    """The joints of a calibration document (:func:`read_calibration_json`) as arrays.

    Args:
        doc: the document.
        names: the recording's sensor names, which the joints' sensors index into.
        source: where the document came from (its path), for messages.

    Raises:
        InputError: a joint names a sensor that ``names`` lacks.
    """
    entries = doc["joints"]
    index = {name: k for k, name in enumerate(names)}
    unknown = sorted({name for j in entries for name in (j["parent"], j["child"])} - index.keys())
    if unknown:
        raise InputError(f"{source}: names sensors the data lacks: {unknown} (sensors are {list(names)})")
    return CalibrationJoints(
        parent=tuple(j["parent"] for j in entries),
        child=tuple(j["child"] for j in entries),
        parent_index=np.array([index[j["parent"]] for j in entries], dtype=int),
        child_index=np.array([index[j["child"]] for j in entries], dtype=int),
        joint_in_parent=np.array([j["joint_in_parent"] for j in entries], dtype=float).reshape(-1, 3),
        joint_in_child=np.array([j["joint_in_child"] for j in entries], dtype=float).reshape(-1, 3),
        single_axis=np.array([bool(j.get("single_axis")) for j in entries], dtype=bool),
    )
