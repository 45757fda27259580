"""The report of one recording: joint residuals, hierarchy and limb lengths; scored if simulated.

:func:`dataset_report` calibrates the recording (or reads a calibration JSON and recomputes its
residuals on the recording) and writes ``index.md``, a self-contained ``index.html``,
``results.json`` and the residual histograms beside them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration import CalibrationError, calibrate, frame_residuals
from calibration.hierarchy import hierarchy_from_parents
from calibration.joint import JointFit
from calibration.pipeline import Joint
from calibration.skeleton import SegmentLength, segment_lengths
from simbench.errors import InputError
from simbench.io.c3d import dataset_marker_poses
from simbench.io.calibration_json import calibration_joints, read_calibration_json
from simbench.io.dataset import Dataset, read_dataset
from simbench.io.poses import PoseRecording
from simbench.io.read import check_plausible, read_poses, refuse_unlocated
from simbench.report.markdown import markdown_table
from simbench.report.output import write_report_files
from simbench.report.plots import plot_residual_histograms
from simbench.score import compare_trees, estimated_lengths, length_of, truth_lengths
from simbench.units import implausible_lengths
from simbench.versions import software_versions

#: Metadata of a simbench dataset that the report repeats.
META_KEYS = ("model", "program", "seed", "rate_hz", "sensor_model")


@dataclass(frozen=True)
class ReportedCalibration:
    """The joints a report shows (what the plots and the scoring need of a ``Calibration``).

    Attributes:
        joints: the joints; locations and residuals in the recording's units.
        lengths: limb lengths, in the recording's units.
        parent_of: ``{child: parent}`` of the hierarchy.
        source: where the joints came from, for the reader.
        warnings: the calibration's warnings (what the data could not determine, joints that
            are probably not neighbours), in plain language.
    """

    joints: tuple[Joint, ...]
    lengths: tuple[SegmentLength, ...]
    parent_of: dict[str, str]
    source: str
    warnings: tuple[str, ...] = ()


#: What a simbench dataset's report calibrates: ``auto`` (its markers when it has them, else its
#: sensors' poses), ``poses`` or ``markers``.
SOURCES = ("auto", "poses", "markers")


def _read_input(
    dataset: Path, units: str | None, clusters: str | None, wide: str | None, source: str = "auto"
) -> tuple[Dataset | None, PoseRecording, float]:
    """``(dataset or None, poses, metres per input unit)`` of a simbench dataset (its sensors' poses,
    or its markers' clusters: ``source``) or a pose file."""
    if source not in SOURCES:
        raise InputError(f"--source must be one of {', '.join(SOURCES)}, got {source!r}")
    if Path(dataset).suffix.lower() in (".h5", ".hdf5"):
        ds = read_dataset(dataset)
        if source == "markers" or (source == "auto" and ds.markers is not None):
            if ds.markers is None:
                raise InputError(f"{dataset}: --source markers, but the dataset has no markers")
            return ds, dataset_marker_poses(ds.markers, ds.time_s, str(dataset)), 1.0
        return ds, check_plausible(ds.poses(), dataset), ds.position_unit_scale
    if source == "markers":
        raise InputError(f"{dataset}: --source markers is for a simbench dataset with markers")
    return None, read_poses(str(dataset), units, clusters, wide), 1.0


def joint_centre_errors(
    cal: ReportedCalibration, rec: PoseRecording, ds: Dataset, scale: float
) -> dict[tuple[str, str], float]:
    """``{(parent, child): rms error, m}`` of each joint the truth has: the estimated centre in the
    world (the midpoint of where the parent's and the child's pose put it) against the truth's
    ``joint_w``, rms over the frames where both poses are valid. In the world, so that joints found
    in marker clusters' frames are scored as those found in the sensors'."""
    assert ds.truth is not None
    t = ds.truth
    index = {name: k for k, name in enumerate(rec.names)}
    true = {(a, b): i for i, (a, b) in enumerate(zip(t.parent, t.child, strict=True))}
    out = {}
    for j in cal.joints:
        i = true.get((j.parent, j.child))
        if i is None:
            continue
        a, b = index[j.parent], index[j.child]
        both = np.asarray(rec.valid[:, a]) & np.asarray(rec.valid[:, b])
        R_a, R_b = np.asarray(rec.R_w_s[:, a])[both], np.asarray(rec.R_w_s[:, b])[both]
        p_a, p_b = np.asarray(rec.p_w_s[:, a])[both], np.asarray(rec.p_w_s[:, b])[both]
        at = 0.5 * (R_a @ j.fit.joint_in_parent + p_a + R_b @ j.fit.joint_in_child + p_b) * scale
        error = np.linalg.norm(at - np.asarray(t.joint_w)[both, i], axis=1)
        out[(j.parent, j.child)] = float(np.sqrt(np.mean(error**2))) if error.size else float("nan")
    return out


def _calibrated_here(rec: PoseRecording, drop_noisy_frames: bool = False) -> ReportedCalibration:
    """Calibrate the recording, hierarchy inferred (its noisiest frames left out if asked:
    :mod:`calibration.frame_noise`)."""
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, drop_noisy_frames=drop_noisy_frames)
    how = "hierarchy inferred, noisy frames left out" if drop_noisy_frames else "hierarchy inferred"
    return ReportedCalibration(
        tuple(cal.joints),
        tuple(cal.lengths),
        cal.parent_of,
        f"calibrated here ({how})",
        tuple(cal.warnings),
    )


def _from_file(rec: PoseRecording, calibration_file: str | os.PathLike[str]) -> ReportedCalibration:
    """The joints of a calibration JSON, their residuals recomputed on the recording.

    The file's joint locations are taken to be in the recording's units. Its hierarchy must be a
    tree over the recording's sensors.
    """
    doc = read_calibration_json(calibration_file)
    units = doc.get("units", "m")
    if units != "m":
        raise InputError(
            f"{calibration_file}, key units: expected 'm' (the joint locations are taken in the recording's "
            f"units, metres), got {units!r}"
        )
    stated = doc.get("warnings", [])
    if stated is not None and not (isinstance(stated, list) and all(isinstance(w, str) for w in stated)):
        raise InputError(f"{calibration_file}, key warnings: expected a list of strings, got {stated!r}")
    located = calibration_joints(doc, rec.names, source=calibration_file)
    hierarchy_from_parents(located.parent_of, rec.names)  # checks the names and the tree
    rms, per_frame = frame_residuals(
        rec.R_w_s,
        rec.p_w_s,
        located.parent_index,
        located.child_index,
        located.joint_in_parent,
        located.joint_in_child,
        valid=rec.valid,
    )
    joints = tuple(
        Joint(
            parent,
            child,
            JointFit(
                joint_in_parent=located.joint_in_parent[k],
                joint_in_child=located.joint_in_child[k],
                rms_residual=float(rms[k]),
                frame_residual=per_frame[:, k],
                singular_values=np.full(6, np.nan),  # the file does not say
                rank=6,
                single_axis=bool(located.single_axis[k]),
                axis_in_parent=None,
                axis_in_child=None,
                n_frames=rec.n_frames,
                n_dropped=0,
            ),
        )
        for k, (parent, child) in enumerate(zip(located.parent, located.child, strict=True))
    )
    pairs = list(zip(located.parent_index.tolist(), located.child_index.tolist(), strict=True))
    lengths = segment_lengths(rec.names, pairs, located.joint_in_parent, located.joint_in_child)
    warnings = tuple(stated or [])  # as the file states them
    source = f"from {calibration_file}"
    return ReportedCalibration(joints, tuple(lengths), located.parent_of, source, warnings)


def _lengths(
    cal: ReportedCalibration, ds: Dataset | None, scale: float, results: dict[str, Any]
) -> list[str]:
    """The limb-length section (cm), scored against the truth when the dataset has one; adds
    ``lengths_cm`` (and ``hierarchy_correct``) to ``results``."""
    if ds is None or ds.truth is None:
        rows = [[f"{x.segment}: {x.joint_a} / {x.joint_b}", x.length * scale * 100] for x in cal.lengths]
        results["lengths_cm"] = [{"length": r[0], "computed": r[1]} for r in rows]
        return [markdown_table(["length", "computed"], rows), ""]
    got = estimated_lengths(cal)  # duck-typed: a ReportedCalibration has the ``lengths`` it reads
    rows = []
    for key, true_m in truth_lengths(ds).items():
        computed_m = length_of(got, key) * scale
        rows.append(
            [f"{key[0]}: {key[1]} / {key[2]}", true_m * 100, computed_m * 100, (computed_m - true_m) * 100]
        )
    results["hierarchy_correct"] = compare_trees(cal.parent_of, ds.truth.parent_of).correct
    results["lengths_cm"] = [
        {"length": r[0], "true": r[1], "computed": r[2], "difference": r[3]} for r in rows
    ]
    return [
        f"Hierarchy: {'correct' if results['hierarchy_correct'] else 'WRONG'} (against the truth).",
        "",
        markdown_table(["length", "true", "computed", "computed - true"], rows),
        "",
    ]


def dataset_report(
    dataset: Path,
    out: Path,
    calibration_file: Path | None = None,
    *,
    units: str | None = None,
    clusters: str | None = None,
    wide: str | None = None,
    drop_noisy_frames: bool = False,
    source: str = "auto",
) -> dict[str, Path]:
    """The report of one recording: residuals, hierarchy and lengths; scored when it has truth.

    Args:
        dataset: a simbench dataset (HDF5), or any pose input ``simbench calibrate`` reads (pose
            CSV, wide tracker export with ``wide``, C3D markers with ``clusters``).
        out: report folder (made if missing).
        calibration_file: a calibration JSON (``simbench calibrate --json``) to report instead of
            calibrating the recording here.
        units, clusters, wide, drop_noisy_frames: as for ``simbench calibrate``
            (``drop_noisy_frames`` only for a calibration made here).
        source: of a simbench dataset, what is calibrated (:data:`SOURCES`): by default its
            optical markers' clusters when it has markers, else its sensors' poses.

    Returns:
        ``{"md": ..., "html": ..., "json": ...}``: the paths written (the PNG lies beside them).

    Raises:
        InputError: an input file is missing or malformed, the calibration JSON's hierarchy is
            not a tree over the sensors, or the recording cannot be calibrated (each naming the
            file); ``drop_noisy_frames`` with a calibration file.
    """
    if drop_noisy_frames and calibration_file is not None:
        raise InputError(
            f"--drop-noisy-frames leaves frames out of a calibration made here; {calibration_file} is "
            "reported as it is (give one or the other)"
        )
    ds, rec, scale = _read_input(dataset, units, clusters, wide, source)
    what = "marker clusters" if rec.source.endswith("(markers)") else "sensor poses"
    try:
        cal = (
            _calibrated_here(rec, drop_noisy_frames)
            if calibration_file is None
            else _from_file(rec, calibration_file)
        )
    except CalibrationError as exc:  # what the data (or the file's hierarchy) cannot give
        raise InputError(f"{calibration_file or dataset}: {exc}") from None
    if calibration_file is None:  # as simbench calibrate: a recording that locates no joint centre
        refuse_unlocated(rec, cal, str(dataset))
    odd = implausible_lengths(list(cal.lengths), units, dataset, wide=wide is not None)
    warnings = [*cal.warnings, *([odd] if odd else [])]
    out.mkdir(parents=True, exist_ok=True)
    plot_residual_histograms(
        cal.joints, out / "residual_histograms.png", scale, f"{Path(dataset).name}, {what}"
    )
    residuals_mm = [j.fit.rms_residual * scale * 1e3 for j in cal.joints]
    results: dict[str, Any] = {
        "dataset": str(dataset),
        "calibration": cal.source,
        "poses": what,
        "sensors": list(rec.names),
        "frames": rec.n_frames,
        "position_unit_scale": scale,
        "joints": [
            {"parent": j.parent, "child": j.child, "rms_residual_mm": r}
            for j, r in zip(cal.joints, residuals_mm, strict=True)
        ],
        "versions": software_versions(),
        "meta": {} if ds is None else {k: ds.meta.get(k) for k in META_KEYS},
        "read": list(rec.notes),
        "warnings": warnings,
    }
    lines = [
        f"# simbench report: {dataset}",
        "",
        f"Calibration: {cal.source}, of the {what}. Lengths in cm (x {scale:g} to metres).",
        "",
        markdown_table(
            ["joint", "rms residual (mm)"],
            [[f"{j.parent} -> {j.child}", r] for j, r in zip(cal.joints, residuals_mm, strict=True)],
        ),
        "",
    ]
    if rec.notes:
        lines += ["What was read:", "", *[f"- {note}" for note in rec.notes], ""]
    if warnings:
        lines += ["## Warnings", "", *[f"- {w}" for w in warnings], ""]
    if ds is not None and ds.truth is not None:
        errors = joint_centre_errors(cal, rec, ds, scale)
        results["joint_centre_error_mm"] = {f"{a}-{b}": e * 1e3 for (a, b), e in errors.items()}
        lines += [
            "## Joint centres against the truth",
            "",
            "Estimate in the world (midpoint of the two segments' placings) against the true centre, rms "
            "over frames.",
            "",
            markdown_table(
                ["joint", "error, rms (mm)"], [[f"{a} -> {b}", e * 1e3] for (a, b), e in errors.items()]
            ),
            "",
        ]
    lines += _lengths(cal, ds, scale, results)
    lines += ["## Residual norms per joint", "", "![residual norms](residual_histograms.png)", ""]
    return write_report_files(out, "\n".join(lines), results)
