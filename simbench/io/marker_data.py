"""Optical markers of a Dataset: labels, the segment each sits on, positions, and their HDF5 group.

A Dataset may carry ``M`` markers (simulated clusters, :mod:`simbench.sim.marker_clusters`, or
markers read from a recording). In the dataset's HDF5 file they are the optional group
``/markers`` (files without it read as before, with ``Dataset.markers`` ``None``)::

    /markers/labels        (M,)        marker names, unique
    /markers/segment       (M,)        the segment (sensor body) each marker sits on
    /markers/xyz           (F, M, 3)   measured positions in world, m; NaN where not seen
    /markers/xyz_true      (F, M, 3)   optional: exact position of each marker's fixed point on
                                       its segment (no skin motion, no camera noise), m
    /markers/offset_b      (M, 3)      optional: that fixed point in the segment (body) frame, m

Positions are in metres in the dataset's world frame (z up), whatever the tracker's unit scale.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from simbench.errors import InputError

GROUP = "markers"


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)  # an own copy, never a view of the caller's array
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class MarkerData:
    """``M`` optical markers over ``F`` frames (module docstring for the layout).

    Attributes:
        labels: ``(M,)`` unique marker names.
        segment: ``(M,)`` the segment each marker sits on (a sensor name of the dataset).
        xyz: ``(F, M, 3)`` measured marker positions in world, m; NaN where not seen.
        xyz_true: ``(F, M, 3)`` exact positions of the markers' fixed points on their segments,
            m, or ``None`` (real recordings).
        offset_b: ``(M, 3)`` those fixed points in their segment (body) frames, m, or ``None``.
    """

    labels: tuple[str, ...]
    segment: tuple[str, ...]
    xyz: np.ndarray
    xyz_true: np.ndarray | None = None
    offset_b: np.ndarray | None = None

    def __post_init__(self) -> None:
        labels, segment = tuple(self.labels), tuple(self.segment)
        if not all(isinstance(s, str) and s for s in labels + segment):
            raise InputError(f"Expected marker labels and segments to be non-empty names, got {labels}")
        twice = sorted({x for x in labels if labels.count(x) > 1})
        if twice:
            raise InputError(f"Expected unique marker labels, got {twice} more than once")
        m = len(labels)
        if len(segment) != m:
            raise InputError(f"Expected {m} marker segments (one per label), got {len(segment)}")
        xyz = np.asarray(self.xyz)
        if xyz.ndim != 3 or xyz.shape[1:] != (m, 3):
            raise InputError(f"Expected markers xyz to have shape (frames, {m}, 3), got {xyz.shape}")
        if self.xyz_true is not None and np.shape(self.xyz_true) != xyz.shape:
            raise InputError(
                f"Expected markers xyz_true to have shape {xyz.shape} like xyz, got {np.shape(self.xyz_true)}"
            )
        if self.offset_b is not None and np.shape(self.offset_b) != (m, 3):
            raise InputError(
                f"Expected markers offset_b to have shape ({m}, 3), got {np.shape(self.offset_b)}"
            )
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "segment", segment)
        for name in ("xyz", "xyz_true", "offset_b"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _frozen(value))

    @property
    def n_frames(self) -> int:
        """Frames ``F``."""
        return int(self.xyz.shape[0])


def write_markers_group(fh: h5py.File, markers: MarkerData | None) -> None:
    """Write ``/markers`` into an open dataset file (nothing when ``markers`` is ``None``)."""
    if markers is None:
        return
    g = fh.create_group(GROUP)
    g.create_dataset("labels", data=np.array(markers.labels, dtype=h5py.string_dtype()))
    g.create_dataset("segment", data=np.array(markers.segment, dtype=h5py.string_dtype()))
    g.create_dataset("xyz", data=markers.xyz)
    for name in ("xyz_true", "offset_b"):
        value = getattr(markers, name)
        if value is not None:
            g.create_dataset(name, data=value)


def _names(g: h5py.Group, path: Path, name: str) -> tuple[str, ...]:
    item = g.get(name)
    if not isinstance(item, h5py.Dataset):
        raise InputError(f"{path}: /{GROUP}/{name} must be a dataset of names, got {type(item).__name__}")
    return tuple(v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(item[()]))


def _numbers(g: h5py.Group, path: Path, name: str) -> np.ndarray:
    item = g.get(name)
    value = item[()] if isinstance(item, h5py.Dataset) else None
    if not (isinstance(value, np.ndarray) and np.issubdtype(value.dtype, np.number)):
        kind = getattr(value, "dtype", type(item).__name__)
        raise InputError(f"{path}: /{GROUP}/{name} must be an array of numbers (metres), got {kind}")
    return value


def read_markers_group(fh: h5py.File, path: Path, n_frames: int) -> MarkerData | None:
    """``/markers`` of an open dataset file, or ``None`` when the file has none (older files).

    Raises:
        InputError: naming the file and dataset: a missing or malformed field, shapes that do not
            match each other or the dataset's ``n_frames`` frames.
    """
    if GROUP not in fh:
        return None
    g: Any = fh[GROUP]
    if not isinstance(g, h5py.Group):
        raise InputError(f"{path}: /{GROUP} must be a group, got {type(g).__name__}")
    missing = [f"/{GROUP}/{name}" for name in ("labels", "segment", "xyz") if name not in g]
    if missing:
        raise InputError(f"{path}: missing dataset(s) {', '.join(missing)}")
    values = {
        "labels": _names(g, path, "labels"),
        "segment": _names(g, path, "segment"),
        "xyz": _numbers(g, path, "xyz"),
    }
    for name in ("xyz_true", "offset_b"):
        values[name] = _numbers(g, path, name) if name in g else None
    try:
        markers = MarkerData(**values)
    except InputError as exc:
        raise InputError(f"{path}: /{GROUP}: {exc}") from None
    if markers.n_frames != n_frames:
        raise InputError(
            f"{path}: /{GROUP}/xyz holds {markers.n_frames} frames, /time_s {n_frames}; expected the same"
        )
    return markers


__all__ = ["MarkerData", "read_markers_group", "write_markers_group"]
