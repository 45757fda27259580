"""One entry for every recording simbench reads, chosen by the file's type and contents.

- pose CSV (``.csv``, ``.txt``; positions in ``units``), a wide tracker export (``wide=`` a spec
  TOML), optical markers (``.c3d``, ``.trc``, clustered by ``clusters=`` a spec TOML or
  automatically):
  a :class:`~simbench.io.dataset.Dataset` of measured poses (inertial data NaN, no truth);
- a simbench dataset (``.h5``/``.hdf5`` with ``format = "simbench-dataset"``): the Dataset;
- a BROAD trial (``.h5``/``.hdf5`` otherwise): an :class:`~simbench.io.imu.ImuRecording`
  (accelerometer, gyroscope, magnetometer and the optical reference orientation).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from calibration import Calibration
from calibration.diagnostics import rotation_ranges
from calibration.joint import LOCATED_RANK
from calibration.poses import CHUNK_FRAMES
from simbench.errors import InputError
from simbench.io.c3d import c3d_poses, read_cluster_spec, trc_poses
from simbench.io.dataset import FORMAT as DATASET_FORMAT
from simbench.io.dataset import Dataset, dataset_from_poses, read_dataset, read_dataset_poses
from simbench.io.hdf5 import open_hdf5
from simbench.io.imu import ImuRecording, read_broad
from simbench.io.inputs import POSE_INPUTS as POSE_INPUTS
from simbench.io.inputs import pose_inputs_text as pose_inputs_text
from simbench.io.poses import PoseRecording, read_pose_csv
from simbench.io.wide_csv import read_wide_csv, read_wide_spec

POSE_SUFFIXES = (".csv", ".txt", ".c3d", ".trc", ".h5", ".hdf5")


def is_simbench_dataset(path: str | os.PathLike[str]) -> bool:
    """True for an HDF5 file written by :func:`~simbench.io.dataset.write_dataset`."""
    with open_hdf5(path) as fh:
        return fh.attrs.get("format") == DATASET_FORMAT


def read_poses(
    path: str | os.PathLike[str],
    units: str | None = None,
    clusters: str | os.PathLike[str] | None = None,
    wide: str | os.PathLike[str] | None = None,
) -> PoseRecording:
    """A pose recording from a pose CSV, a wide export, a C3D or TRC file or a simbench dataset.

    Args:
        path: the file.
        units: length unit of the positions (``m``, ``cm``, ``mm``, ``in``); ``None``: metres for
            a CSV, the file's ``POINT:UNITS`` for a C3D file and ``Units`` for a TRC file (a unit
            given overrides it, with a note); datasets hold metres.
        clusters: for ``.c3d`` and ``.trc``: a TOML ``[clusters]`` spec (default: found automatically).
        wide: a wide-export spec TOML: read ``path`` as a wide export.
    """
    return check_plausible(_read_poses(path, units, clusters, wide), path)


#: Positions farther than this from the origin, in metres, are not a capture (1000 km; 1e6 of a
#: metre-sized unit): refused.
MAX_COORDINATE_M = 1e6


#: The finest median time step of a recording, s: motion capture runs at hertz to kilohertz; a
#: megahertz rate means times in another unit (or a counter), not seconds.
MIN_STEP_S = 1e-6

#: The coarsest median time step that passes without a note, s: below 1 Hz no motion capture
#: system samples; such steps are most often times in milliseconds read as seconds.
MAX_STEP_S = 1.0


def check_plausible(rec: PoseRecording, path: str | os.PathLike[str]) -> PoseRecording:
    """Refuse a recording nothing sensible can come from: no valid pose at all, a median time
    step below :data:`MIN_STEP_S`, or positions beyond :data:`MAX_COORDINATE_M` (a corrupt
    value, or a unit far off); note a median step above :data:`MAX_STEP_S`.

    Raises:
        InputError: naming the file, and the sensor and frame of the first far position.
    """
    if not rec.valid.any():
        raise InputError(f"{path}: no valid pose in {rec.n_frames} frame(s) of {len(rec.names)} sensor(s)")
    if rec.n_frames > 1:
        step = float(np.median(np.diff(rec.time_s)))
        if step < MIN_STEP_S:
            raise InputError(
                f"{path}: time steps of {step:.3g} s (a rate of {1 / step:.3g} Hz; expected below "
                f"{1 / MIN_STEP_S:g} Hz): are the times in seconds?"
            )
        if step > MAX_STEP_S:
            rec = dataclasses.replace(
                rec,
                notes=(
                    *rec.notes,
                    f"time steps of {step:.4g} s (a rate of {1 / step:.3g} Hz): are the times in seconds? "
                    "(milliseconds give steps 1000 times too long)",
                ),
            )
    far = np.zeros(rec.valid.shape, dtype=bool)
    for start in range(0, rec.n_frames, CHUNK_FRAMES):  # the positions may be larger than memory
        frames = slice(start, start + CHUNK_FRAMES)
        far[frames] = rec.valid[frames] & ~(np.abs(np.asarray(rec.p_w_s[frames])) <= MAX_COORDINATE_M).all(
            axis=2
        )
    if far.any():
        f, k = np.argwhere(far)[0]
        size = np.abs(rec.p_w_s[f, k]).max()
        raise InputError(
            f"{path}: sensor {rec.names[k]!r} at t = {rec.time_s[f]:g} s is {size:.3g} m "
            f"from the origin (expected within {MAX_COORDINATE_M:g} m; {int(far.sum())} such pose(s)): a "
            "corrupt value, or the wrong --units?"
        )
    return rec


def _read_poses(
    path: str | os.PathLike[str],
    units: str | None,
    clusters: str | os.PathLike[str] | None,
    wide: str | os.PathLike[str] | None,
) -> PoseRecording:
    suffix = Path(path).suffix.lower()
    if wide is not None:
        return read_wide_csv(path, read_wide_spec(wide))
    if suffix == ".c3d":
        return c3d_poses(path, clusters=read_cluster_spec(clusters) if clusters else None, units=units)
    if suffix == ".trc":
        return trc_poses(path, clusters=read_cluster_spec(clusters) if clusters else None, units=units)
    if suffix in (".csv", ".txt"):
        return read_pose_csv(path, units=units or "m")
    if suffix in (".h5", ".hdf5"):
        if units not in (None, "m"):
            raise InputError(f"{path}: simbench datasets hold metres; --units {units} does not apply")
        return read_dataset_poses(path)  # a large file: a chunk of frames at a time
    raise InputError(f"{path}: unknown pose file type {suffix!r}; expected {pose_inputs_text()}")


def read_imu(path: str | os.PathLike[str]) -> ImuRecording:
    """Inertial data from a simbench dataset or a BROAD trial, told apart by their contents."""
    return read_dataset(path).imu() if is_simbench_dataset(path) else read_broad(path)


def read(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    clusters: str | os.PathLike[str] | None = None,
    wide: str | os.PathLike[str] | None = None,
) -> Dataset | ImuRecording:
    """Open any supported recording (module docstring): poses become a Dataset, a simbench
    dataset is returned as it is, a BROAD trial becomes an ImuRecording."""
    suffix = Path(path).suffix.lower()
    if wide is None and suffix in (".h5", ".hdf5"):
        if units not in (None, "m"):
            raise InputError(f"{path}: HDF5 recordings hold SI units; units={units!r} does not apply")
        return read_dataset(path) if is_simbench_dataset(path) else read_broad(path)
    return dataset_from_poses(read_poses(path, units, clusters, wide))


def refuse_unlocated(rec: PoseRecording, cal: Calibration | Any, source: str) -> None:
    """Refuse a calibration (anything with its ``joints``) in which no joint centre is located (a
    recording that does not move).

    A joint's centre is located when the motion determines at least 5 of the fit's 6 directions
    (:mod:`calibration.joint`: 6 for a ball joint, 5 for a single axis); with fewer (the joint
    turned too little against its noise, e.g. a body or a file that never moves) its numbers are
    a minimum-norm point, not a measurement. When some joints are located the others are marked
    ``none`` in the table (their lengths and offsets ``not located``) and named in the warnings;
    when none is, there is nothing to report.

    Raises:
        InputError: naming the file, each joint with the directions its motion determines and its
            range of relative rotation (degrees, along its principal axes).
    """
    if not cal.joints or any(j.fit.rank >= LOCATED_RANK for j in cal.joints):
        return
    index = {name: k for k, name in enumerate(rec.names)}
    parent = np.array([index[j.parent] for j in cal.joints])
    child = np.array([index[j.child] for j in cal.joints])
    ranges = rotation_ranges(rec.R_w_s, parent, child, valid=rec.valid)
    joints = "; ".join(
        f"{j.name}: {j.fit.rank} of 6, rotation range {', '.join(f'{x:.1f}' for x in r)} deg"
        for j, r in zip(cal.joints, ranges, strict=True)
    )
    raise InputError(
        f"{source}: no joint centre is determined: every joint's motion fixes fewer than 5 of the fit's 6 "
        f"directions ({joints}); the sensors barely turn against each other. Record the joints moving "
        "through tens of degrees in two or more directions"
    )
