"""A Dataset into the files other tools read: markers (TRC, C3D), IMU orientations (OpenSense
``.sto``), raw IMU readings (CSV) and the skeleton (MJCF, OpenSim ``.osim``), in one call.

Every requested output is checked before the first file is written (a dataset without markers
asked for a TRC file fails without writing anything), and each file is written atomically. A C3D
recording's own markers go to TRC and C3D without a Dataset (:func:`export_c3d_markers`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text, check_writable
from simbench.io.c3d import C3DMarkers, write_c3d_markers
from simbench.io.calibration_json import read_calibration_json
from simbench.io.dataset import Dataset, truth_calibration_dict
from simbench.io.imu_csv import imu_csv_text
from simbench.io.opensense import sto_text
from simbench.io.skeleton_mjcf import skeleton_mjcf
from simbench.io.skeleton_osim import skeleton_osim
from simbench.io.trc import trc_text

#: Which data an export takes: what the instruments measured, or the exact truth.
SOURCES = ("measured", "truth")

PathLike = str | os.PathLike[str]


def _source(ds: Dataset) -> str:
    return str(ds.meta.get("source", "the dataset"))


def export_markers(ds: Dataset, source: str = "measured") -> tuple[tuple[str, ...], np.ndarray]:
    """Marker labels ``(M,)`` and positions ``(F, M, 3)`` (m, world; NaN = not seen) to export:
    ``measured`` (with skin motion and camera noise) or ``truth`` (exact)."""
    if source not in SOURCES:
        raise InputError(f"Expected the marker source to be one of {SOURCES}, got {source!r}")
    if ds.markers is None:
        raise InputError(
            f"{_source(ds)}: the dataset has no markers (no /markers group); simulate a dataset with "
            "markers with `simbench simulate --markers`, or export a C3D file (its markers as read)"
        )
    if source == "measured":
        return ds.markers.labels, np.array(ds.markers.xyz)
    if ds.markers.xyz_true is None:
        raise InputError(f"{_source(ds)}: the markers have no exact positions (/markers/xyz_true)")
    return ds.markers.labels, np.array(ds.markers.xyz_true)


def export_orientations(ds: Dataset, source: str = "measured") -> np.ndarray:
    """Sensor orientations ``(F, N, 4)`` (wxyz of ``R_w_s``) to export: ``measured`` (the
    tracker's, NaN where a sample is missing) or ``truth`` (the sensors as actually worn)."""
    if source not in SOURCES:
        raise InputError(f"Expected the orientation source to be one of {SOURCES}, got {source!r}")
    if source == "truth":
        if ds.truth is None:
            raise InputError(f"{_source(ds)}: the dataset has no truth: export the measured orientations")
        return np.array(ds.truth.actual.q_w_s)
    m = ds.measured
    return np.where(m.valid[..., None], m.q_w_s, np.nan)


def _imu_readings(ds: Dataset) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = ds.measured
    if not (np.isfinite(m.acc).any() or np.isfinite(m.gyro).any() or np.isfinite(m.mag).any()):
        raise InputError(
            f"{_source(ds)}: the dataset has no inertial readings (acc, gyro and mag are all missing: a "
            "pose recording)"
        )
    return np.array(m.acc), np.array(m.gyro), np.array(m.mag)


def _calibration_doc(ds: Dataset, calibration: PathLike | Mapping[str, Any] | None) -> Mapping[str, Any]:
    if calibration is None:
        if ds.truth is None:
            raise InputError(
                f"{_source(ds)}: the dataset has no truth to build a skeleton from; give a calibration "
                "JSON (`simbench calibrate --json`)"
            )
        return truth_calibration_dict(ds)
    if isinstance(calibration, Mapping):
        return calibration
    return read_calibration_json(calibration)


def marker_locations(ds: Dataset, source: str = "measured") -> list[tuple[str, str, np.ndarray]]:
    """``(label, segment, (3,) location)`` of each optical marker of a dataset in its segment's
    sensor frame, m: the median over frames of ``R_w_s^T (x_w - p_w_s)``, from the measured
    markers and poses (``source="measured"``, what a calibration is made from), or from the truth's
    (the markers' exact fixed points and the sensors' poses on their bones, ``"truth"``). A marker
    never seen with its segment's sensor is left out. ``[]`` without markers."""
    m = ds.markers
    if m is None:
        return []
    if source == "truth" and ds.truth is not None:
        q, p = ds.truth.rigid.q_w_s, ds.truth.rigid.p_w_s
        xyz = m.xyz_true if m.xyz_true is not None else m.xyz
    else:
        q, p, xyz = ds.measured.q_w_s, ds.measured.p_w_s, m.xyz
    out = []
    for k, (label, segment) in enumerate(zip(m.labels, m.segment, strict=True)):
        s = ds.sensors.index(segment)
        R = quat_to_matrix(np.asarray(q[:, s], dtype=float))
        local = np.einsum("fji,fj->fi", R, np.asarray(xyz[:, k], dtype=float) - np.asarray(p[:, s]))
        seen = np.isfinite(local).all(axis=1)
        if seen.any():
            out.append((label, segment, np.median(local[seen], axis=0)))
    return out


def export_dataset(
    ds: Dataset,
    *,
    trc: PathLike | None = None,
    c3d: PathLike | None = None,
    sto: PathLike | None = None,
    imu_csv: PathLike | None = None,
    mjcf: PathLike | None = None,
    osim: PathLike | None = None,
    calibration: PathLike | Mapping[str, Any] | None = None,
    markers: str = "measured",
    orientations: str = "measured",
    trc_units: str = "mm",
    trc_up: str = "z",
) -> dict[str, Path]:
    """Write the requested exports of a dataset.

    Args:
        ds: the dataset.
        trc: markers as TRC text (:mod:`simbench.io.trc`), in ``trc_units``.
        c3d: markers as C3D (:func:`simbench.io.c3d.write_c3d_markers`, mm).
        sto: sensor orientations in OpenSense's ``.sto`` layout (:mod:`simbench.io.opensense`).
        imu_csv: raw accelerometer, gyroscope and magnetometer readings (:mod:`simbench.io.imu_csv`).
        mjcf: the skeleton as MJCF (:mod:`simbench.io.skeleton_mjcf`) of ``calibration`` (a
            calibration JSON path or document), or of the dataset's truth when ``None``.
        osim: the same skeleton as an OpenSim model (:mod:`simbench.io.skeleton_osim`).
        calibration: see ``mjcf``.
        markers: ``"measured"`` or ``"truth"`` marker positions for ``trc`` and ``c3d``.
        orientations: ``"measured"`` or ``"truth"`` orientations for ``sto``.
        trc_units: the TRC file's length unit (``mm``, ``m``, ``cm``, ``in``).
        trc_up: the TRC file's vertical axis: ``z`` (the world's) or ``y`` (OpenSim's;
            :func:`simbench.io.trc.turned`).

    Returns:
        ``{kind: path}`` of the files written (kinds ``trc``, ``c3d``, ``sto``, ``imu_csv``, ``mjcf``,
        ``osim``).

    Raises:
        InputError: nothing to export, or data an export needs that the dataset lacks (nothing is
            written then).
    """
    asked = {"trc": trc, "c3d": c3d, "sto": sto, "imu_csv": imu_csv, "mjcf": mjcf, "osim": osim}
    asked = {k: Path(v) for k, v in asked.items() if v is not None}
    if not asked:
        raise InputError("nothing to export: give at least one of trc, c3d, sto, imu_csv, mjcf, osim")
    if calibration is not None and "mjcf" not in asked and "osim" not in asked:
        raise InputError("a calibration is used only for the skeleton: give mjcf or osim too")
    check_outputs(asked)
    texts: dict[str, str] = {}
    rate = float(ds.meta.get("rate_hz") or 0.0) or None
    if "trc" in asked or "c3d" in asked:
        labels, xyz = export_markers(ds, markers)
        if "trc" in asked:
            texts["trc"] = trc_text(
                labels, ds.time_s, xyz, units=trc_units, rate_hz=rate, name=asked["trc"].name, up=trc_up
            )
    if "sto" in asked:
        texts["sto"] = sto_text(ds.sensors, ds.time_s, export_orientations(ds, orientations), rate_hz=rate)
    if "imu_csv" in asked:
        texts["imu_csv"] = imu_csv_text(ds.sensors, ds.time_s, *_imu_readings(ds))
    if "mjcf" in asked or "osim" in asked:
        doc = _calibration_doc(ds, calibration)
        name = "true_skeleton" if calibration is None else "calibrated_skeleton"  # what it is, named
        if "mjcf" in asked:
            texts["mjcf"] = skeleton_mjcf(doc, model_name=name).xml
        if "osim" in asked:
            located = marker_locations(ds, "truth" if calibration is None else "measured")
            texts["osim"] = skeleton_osim(doc, model_name=name, markers=located)
    for kind, text in texts.items():
        atomic_write_text(asked[kind], text)
    if "c3d" in asked:
        c3d_rate = rate or (ds.time_s.size - 1) / float(ds.time_s[-1] - ds.time_s[0])
        write_c3d_markers(asked["c3d"], list(labels), xyz, c3d_rate)
    return asked


def check_outputs(asked: Mapping[str, Path]) -> None:
    """Refuse, before anything is written, an output that is a folder or in no folder.

    Raises:
        InputError: naming the output path.
    """
    for path in asked.values():
        check_writable(path)


def export_c3d_markers(
    recording: C3DMarkers,
    *,
    trc: PathLike | None = None,
    c3d: PathLike | None = None,
    trc_units: str = "mm",
    trc_up: str = "z",
) -> dict[str, Path]:
    """A C3D recording's markers, as read (:func:`simbench.io.c3d.read_c3d`: metres, gaps and
    invalid or (0, 0, 0) samples missing), to TRC (in ``trc_units``) and C3D (mm): no clusters
    or Dataset needed. Times are ``frame / POINT:RATE`` from 0.

    Raises:
        InputError: no output asked, or one that cannot be written (nothing is written then).
    """
    asked = {k: Path(v) for k, v in {"trc": trc, "c3d": c3d}.items() if v is not None}
    if not asked:
        raise InputError("nothing to export: give trc or c3d for the markers of a C3D file")
    check_outputs(asked)
    if "trc" in asked:
        time_s = np.arange(recording.xyz_m.shape[0]) / recording.rate_hz
        text = trc_text(
            recording.labels,
            time_s,
            recording.xyz_m,
            units=trc_units,
            rate_hz=recording.rate_hz,
            name=asked["trc"].name,
            up=trc_up,
        )
        atomic_write_text(asked["trc"], text)
    if "c3d" in asked:
        write_c3d_markers(asked["c3d"], recording.labels, recording.xyz_m, recording.rate_hz)
    return asked


__all__ = [
    "SOURCES",
    "check_outputs",
    "export_c3d_markers",
    "export_dataset",
    "export_markers",
    "export_orientations",
]
