"""Optical marker recordings (C3D) as segment poses, for the same calibration.

Markers are read with the ``c3d`` package (a maintained pure-Python C3D reader); positions are
converted to metres from the file's ``POINT:UNITS``; samples the file marks invalid (negative
residual) are missing. Markers are grouped into rigid clusters -- by a specification naming the
markers of each segment (TOML ``[clusters] thigh_r = ["RTHI1", "RTHI2", "RTHI3"]``), or
automatically from the constancy of their mutual distances -- and each cluster's pose at every
frame comes from a least-squares rigid fit (:mod:`calibration.clusters`). The resulting
:class:`PoseRecording` feeds the calibration like any tracker's poses; its notes say what was
read: clusters, frames, rate, gaps and each cluster's rigidity residual.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import c3d
import numpy as np

from calibration.clusters import group_markers, reference_shape, rigid_fit
from calibration.errors import CalibrationError
from simbench.errors import InputError, load_toml
from simbench.io.atomic import atomic_open
from simbench.io.poses import PoseRecording
from simbench.units import LENGTH_UNITS


def read_c3d_markers(path: str | os.PathLike[str]) -> tuple[list[str], np.ndarray, float]:
    """Marker labels, positions ``(F, M, 3)`` in metres (NaN where invalid) and the rate (Hz)."""
    path = Path(path)
    try:
        fh = path.open("rb")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    with fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "no analog data" and similar notices
        try:
            reader = c3d.Reader(fh)
            labels = [str(label).strip() for label in reader.point_labels]
            units_param = reader.get("POINT:UNITS")
            units = units_param.string_value.strip().lower() if units_param is not None else "mm"
            frames = [points.copy() for _, points, _ in reader.read_frames()]
            rate = float(reader.point_rate)
        except Exception as exc:  # the c3d package raises assorted errors on damaged files
            raise InputError(f"{path}: not a readable C3D file ({type(exc).__name__}: {exc})") from None
    if units not in LENGTH_UNITS:
        raise InputError(f"{path}: POINT:UNITS is {units!r}; expected one of {sorted(LENGTH_UNITS)}")
    if not frames:
        raise InputError(f"{path}: no frames")
    data = np.stack(frames)  # (F, M, >=4): x, y, z, residual, ...
    xyz = data[:, :, :3] * LENGTH_UNITS[units]
    xyz[data[:, :, 3] < 0] = np.nan
    return labels, xyz, rate


def read_cluster_spec(path: str | os.PathLike[str]) -> dict[str, list[str]]:
    """``{segment: [marker labels]}`` from a TOML file with a ``[clusters]`` table."""
    path = Path(path)
    doc = load_toml(path)
    clusters = doc.get("clusters")
    if not isinstance(clusters, dict) or not clusters:
        raise InputError(f'{path}: expected a [clusters] table: segment = ["MARKER1", "MARKER2", "MARKER3"]')
    for name, labels in clusters.items():
        if not isinstance(labels, list) or len(labels) < 3 or not all(isinstance(x, str) for x in labels):
            raise InputError(f"{path}: clusters.{name}: expected a list of at least 3 marker labels")
    return clusters


def c3d_poses(
    path: str | os.PathLike[str], *, clusters: dict[str, list[str]] | None = None, tol_m: float = 0.003
) -> PoseRecording:
    """Segment poses from the marker clusters of a C3D file (module docstring).

    Args:
        path: the C3D file.
        clusters: ``{segment: [labels]}``; ``None`` to find clusters automatically.
        tol_m: automatic grouping: largest spread of a within-cluster distance, m.
    """
    labels, xyz, rate = read_c3d_markers(path)
    index = {label: k for k, label in enumerate(labels)}
    notes = []
    if clusters is None:
        groups = group_markers(xyz, tol_m=tol_m)
        if len(groups) < 2:
            raise InputError(
                f"{path}: found {len(groups)} rigid marker cluster(s); calibration needs 2 or more"
            )
        clusters = {"+".join(labels[k] for k in g): [labels[k] for k in g] for g in groups}
        notes.append(f"clusters found automatically (distances steady within {tol_m * 1e3:g} mm)")
    missing = sorted({m for ms in clusters.values() for m in ms} - index.keys())
    if missing:
        raise InputError(f"{path}: no markers named {missing}; markers: {labels}")
    names = tuple(clusters)
    f = xyz.shape[0]
    R = np.full((f, len(names), 3, 3), np.nan)
    p = np.full((f, len(names), 3), np.nan)
    valid = np.zeros((f, len(names)), dtype=bool)
    for k, (name, marker_labels) in enumerate(clusters.items()):
        x = xyz[:, [index[m] for m in marker_labels]]
        try:
            shape = reference_shape(x)
        except CalibrationError as exc:
            raise InputError(f"{path}: cluster {name}: {exc}") from None
        fit = rigid_fit(shape, x)
        R[:, k], p[:, k], valid[:, k] = fit.R_w_c, fit.p_w_c, fit.valid
        gaps = int((~fit.valid).sum())
        notes.append(
            f"cluster {name} ({', '.join(marker_labels)}): rigidity residual median "
            f"{np.nanmedian(fit.rms_residual) * 1e3:.2f} mm, {gaps} of {f} frames without a pose"
        )
    notes.insert(0, f"read {len(labels)} markers, {f} frames at {rate:g} Hz; {len(names)} clusters")
    return PoseRecording(
        names=names,
        time_s=np.arange(f) / rate,
        R_w_s=R,
        p_w_s=p,
        valid=valid,
        source=str(path),
        notes=tuple(notes),
    )


def write_c3d_markers(
    path: str | os.PathLike[str], labels: list[str], xyz_m: np.ndarray, rate_hz: float
) -> None:
    """Write markers ``(F, M, 3)`` (metres; NaN = not seen) to a C3D file in mm, atomically."""
    xyz = np.asarray(xyz_m, dtype=float)
    if xyz.ndim != 3 or xyz.shape[1] != len(labels) or xyz.shape[2] != 3:
        raise InputError(f"Expected markers of shape (frames, {len(labels)}, 3), got {xyz.shape}")
    writer = c3d.Writer(point_rate=float(rate_hz), point_units="mm  ")
    writer.set_point_labels(list(labels))
    frames = []
    for f in range(xyz.shape[0]):
        pts = np.zeros((len(labels), 5), dtype=np.float32)
        seen = np.isfinite(xyz[f]).all(axis=1)
        pts[seen, :3] = xyz[f, seen] * 1000.0
        pts[~seen, 3] = -1.0  # C3D's mark for an invalid sample
        frames.append((pts, np.zeros((0, 0), dtype=np.float32)))
    writer.add_frames(frames)
    with atomic_open(path, "wb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        writer.write(fh)
