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


def _read_input(
    dataset: Path, units: str | None, clusters: str | None, wide: str | None
) -> tuple[Dataset | None, PoseRecording, float]:
    """``(dataset or None, poses, metres per input unit)`` of a simbench dataset or a pose file."""
    if Path(dataset).suffix.lower() in (".h5", ".hdf5"):
        ds = read_dataset(dataset)
        return ds, check_plausible(ds.poses(), dataset), ds.position_unit_scale
    return None, read_poses(str(dataset), units, clusters, wide), 1.0


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
            [f"{key[0]}: {key[1]} / {key[2]}", true_m * 100, computed_m * 100, (true_m - computed_m) * 100]
        )
    results["hierarchy_correct"] = compare_trees(cal.parent_of, ds.truth.parent_of).correct
    results["lengths_cm"] = [
        {"length": r[0], "true": r[1], "computed": r[2], "difference": r[3]} for r in rows
    ]
    return [
        f"Hierarchy: {'correct' if results['hierarchy_correct'] else 'WRONG'} (against the truth).",
        "",
        markdown_table(["length", "true", "computed", "true - computed"], rows),
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
    ds, rec, scale = _read_input(dataset, units, clusters, wide)
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
    plot_residual_histograms(cal.joints, out / "residual_histograms.png", scale)
    residuals_mm = [j.fit.rms_residual * scale * 1e3 for j in cal.joints]
    results: dict[str, Any] = {
        "dataset": str(dataset),
        "calibration": cal.source,
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
        f"Calibration: {cal.source}. Lengths in cm (x {scale:g} to metres).",
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
    lines += _lengths(cal, ds, scale, results)
    lines += ["## Residual norms per joint", "", "![residual norms](residual_histograms.png)", ""]
    return write_report_files(out, "\n".join(lines), results)
