"""The Dataset: measured sensor data, exact ground truth and metadata, and its HDF5 file.

HDF5 layout (``format = "simbench-dataset"``, ``format_version = 1``); arrays ``(F, N, ...)``
for ``F`` frames and ``N`` sensors, ``J = N - 1`` joints; quaternions scalar-first ``(w, x, y,
z)``; SI units (m, s, rad, m/s^2, rad/s) and microtesla for magnetic field::

    /                      attrs: format, format_version, meta (JSON: model, program, seed,
                           rate_hz, physics_timestep_s, duration_s, versions, config, warnings)
    /time_s                (F,)        sample times, s
    /sensors               (N,)        sensor names (= the bodies they sit on)
    /measured/p_w_s        (F, N, 3)   sensor positions in world, m
    /measured/q_w_s        (F, N, 4)   sensor orientations (R_w_s), wxyz
    /measured/valid        (F, N)      False where a sample is missing
    /measured/acc          (F, N, 3)   accelerometer: specific force in the sensor frame, m/s^2
    /measured/gyro         (F, N, 3)   angular velocity in the sensor frame, rad/s
    /measured/mag          (F, N, 3)   magnetic field in the sensor frame, uT
    /truth/...             the same six names, exact bone-rigid values (sensor fixed to the bone)
    /truth/actual/...      the same six names, exact values where the sensor actually is (on the
                           skin: soft-tissue mount, artefact, slip); = bone-rigid for ideal skin
    /truth/...             plus:
    /truth/p_w_b, q_w_b    (F, N, 3/4) pose of each sensor's body (segment) frame
    /truth/joint_w         (F, J, 3)   world position of each joint centre, m
    /truth/parent, child   (J,)        sensor names of each joint
    /truth/joint_in_parent (J, 3)      joint centre in the parent sensor's frame, m
    /truth/joint_in_child  (J, 3)      joint centre in the child sensor's frame, m
    /truth/single_axis     (J,)        the joint is a single hinge
    /truth/axis_in_parent, axis_in_child (J, 3)  its axis (NaN when not a hinge)
    /truth/p_b_s, q_b_s    (N, 3/4)    sensor placement in its body frame
    /markers/...           optional: M optical markers (labels, segment, xyz (F, M, 3) m, ...;
                           layout in :mod:`simbench.io.marker_data`); older files have none

The world frame is ENU-like: z up (gravity -z), the Earth field's horizontal part along +y.
Writes are atomic: the file appears complete or not at all.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from calibration.rotations import matrix_to_quat, quat_to_matrix
from calibration.skeleton import joint_arrays, segment_lengths
from simbench.errors import InputError
from simbench.io.atomic import atomic_path
from simbench.io.csv_blocks import CHUNK_FRAMES, IN_MEMORY_BYTES, TemporaryPoses
from simbench.io.hdf5 import open_hdf5
from simbench.io.imu import ImuRecording
from simbench.io.marker_data import MarkerData, read_markers_group, write_markers_group
from simbench.io.poses import PoseRecording, first_bad_time
from simbench.io.tables import dataset_to_pandas, dataset_to_xarray

FORMAT = "simbench-dataset"
FORMAT_VERSION = 1


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a)  # an own copy: a Dataset never shares memory with its inputs
    a.flags.writeable = False
    return a


@dataclass(frozen=True)
class SensorData:
    """Sensor readings, ``(F, N, ...)`` (see the module docstring for units and frames)."""

    p_w_s: np.ndarray
    q_w_s: np.ndarray
    valid: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray
    mag: np.ndarray

    def __post_init__(self) -> None:
        f, n = self.valid.shape
        for name, tail in (("p_w_s", 3), ("q_w_s", 4), ("acc", 3), ("gyro", 3), ("mag", 3)):
            if getattr(self, name).shape != (f, n, tail):
                raise InputError(
                    f"Expected {name} to have shape {(f, n, tail)}, got {getattr(self, name).shape}"
                )
        for x in fields(self):
            object.__setattr__(self, x.name, _frozen(getattr(self, x.name)))


@dataclass(frozen=True)
class Truth:
    """Exact ground truth of a simulated session (module docstring for the fields).

    ``rigid`` holds the sensor data as if each sensor were fixed to its bone (``/truth/...`` in
    the file), ``actual`` where the sensor actually is on the skin (``/truth/actual/...``).
    """

    rigid: SensorData
    actual: SensorData
    p_w_b: np.ndarray
    q_w_b: np.ndarray
    joint_w: np.ndarray
    parent: tuple[str, ...]
    child: tuple[str, ...]
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    single_axis: np.ndarray
    axis_in_parent: np.ndarray
    axis_in_child: np.ndarray
    p_b_s: np.ndarray
    q_b_s: np.ndarray

    def __post_init__(self) -> None:
        for x in fields(self):
            value = getattr(self, x.name)
            if isinstance(value, np.ndarray):
                object.__setattr__(self, x.name, _frozen(value))

    @property
    def parent_of(self) -> dict[str, str]:
        """``{child: parent}``."""
        return dict(zip(self.child, self.parent, strict=True))


@dataclass(frozen=True)
class Dataset:
    """A capture session: times, sensor names, measured data, truth (if simulated), metadata, and
    optionally optical markers (``markers``: :class:`~simbench.io.marker_data.MarkerData`, positions
    in metres whatever ``position_unit_scale`` says of the tracker's)."""

    time_s: np.ndarray
    sensors: tuple[str, ...]
    measured: SensorData
    truth: Truth | None
    meta: dict[str, Any] = field(default_factory=dict)
    #: The tracker's unit scale factor: ``measured.p_w_s`` is in metres / this (1 for metres).
    position_unit_scale: float = 1.0
    markers: MarkerData | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "time_s", _frozen(self.time_s))
        scale = self.position_unit_scale
        if not (isinstance(scale, int | float) and math.isfinite(scale) and scale > 0):
            raise InputError(f"Expected position_unit_scale to be a positive finite number, got {scale!r}")
        f, n = self.measured.valid.shape
        if self.time_s.shape != (f,) or len(self.sensors) != n:
            raise InputError(
                f"Expected {f} times and {n} sensor names, got {self.time_s.shape[0]} and {len(self.sensors)}"
            )
        repeated = sorted({name for name in self.sensors if list(self.sensors).count(name) > 1})
        if repeated:
            raise InputError(f"sensor names must be unique, repeated: {repeated}")
        if self.markers is not None:
            if not isinstance(self.markers, MarkerData):
                raise InputError(
                    f"Expected markers to be MarkerData or None, got {type(self.markers).__name__}"
                )
            if self.markers.n_frames != f:
                raise InputError(f"Expected markers over the {f} frames, got {self.markers.n_frames}")
            unknown = sorted(set(self.markers.segment) - set(self.sensors))
            if unknown:
                raise InputError(
                    f"Expected marker segments among the sensors {list(self.sensors)}, got {unknown}"
                )

    def truth_joint_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """True ``(joint_in_parent, joint_in_child)``, each ``(N, 3)`` indexed by the child sensor
        (the root's row zero): the layout of :func:`calibration.replay.remove_residual` and
        :func:`calibration.posture.joint_positions`."""
        if self.truth is None:
            raise InputError("the dataset has no ground truth")
        t = self.truth
        return joint_arrays(self.sensors, t.child, t.joint_in_parent, t.joint_in_child)

    def imu(self) -> ImuRecording:
        """The measured inertial data, truth the actual (on-skin) sensor orientations; samples
        with an accelerometer axis at the configured range (within one step of its resolution:
        the clipped value is quantised) are marked saturated, and not valid."""
        m = self.measured
        # the inertial samples' own validity: a tracker dropout loses a pose, not the IMU's sample
        valid = np.isfinite(m.acc).all(axis=-1) & np.isfinite(m.mag).all(axis=-1)
        notes = []
        if not valid.all():
            notes.append(
                f"{int((~valid).sum())} sensor samples with NaN accelerometer or magnetometer values"
            )
        imu = self.meta.get("sensor_config", {}).get("imu", {})
        acc_range = float(imu.get("accel_range", 0.0) or 0.0)
        saturated = None
        if acc_range > 0:
            top = acc_range - float(imu.get("accel_resolution", 0.0) or 0.0)
            saturated = valid[..., None] & (np.abs(m.acc) >= top * (1 - 1e-9))
            at_range = saturated.any(axis=2)
            if at_range.any():
                notes.append(
                    f"{int(at_range.sum())} samples with an accelerometer axis at its range "
                    f"(+-{acc_range:g} m/s^2): not valid; the skeleton method uses them"
                )
            valid &= ~at_range
        rate = self._imu_rate()
        return ImuRecording(
            names=self.sensors,
            time_s=np.array(self.time_s),
            acc=np.array(m.acc),
            gyro=np.array(m.gyro),
            mag=np.array(m.mag),
            valid=valid,
            q_true=None if self.truth is None else np.array(self.truth.actual.q_w_s),
            evaluate=None,
            rate_hz=rate,
            source=str(self.meta.get("source", "dataset")),
            notes=tuple(notes),
            saturated=saturated,
        )

    def _imu_rate(self) -> float:
        """The sample rate, Hz: ``meta.rate_hz``, checked against the time stamps' median step
        (agreeing to 0.1 %); the time stamps' where the meta has none.

        Raises:
            InputError: a rate that is not a finite number > 0, or one the time stamps contradict.
        """
        steps = np.diff(np.asarray(self.time_s, dtype=float))
        from_times = 1.0 / float(np.median(steps)) if steps.size and np.median(steps) > 0 else math.nan
        given = self.meta.get("rate_hz")
        if given is None:
            rate = from_times
        else:
            try:
                rate = float(given)
            except (TypeError, ValueError):
                rate = math.nan
            if (
                math.isfinite(rate)
                and rate > 0
                and math.isfinite(from_times)
                and abs(rate / from_times - 1) > 1e-3
            ):
                raise InputError(
                    f"{self.meta.get('source', 'dataset')}: meta rate_hz {rate:g} Hz, but the time stamps "
                    f"step at {from_times:g} Hz"
                )
        if not (math.isfinite(rate) and rate > 0):
            raise InputError(
                f"{self.meta.get('source', 'dataset')}: expected a sample rate (meta rate_hz or time stamps) "
                f"of a finite number of Hz > 0, got {given!r}"
            )
        return rate

    def to_pandas(self, *, layout: str = "long", source: str = "measured") -> Any:
        """The data as a ``pandas.DataFrame``: ``layout`` ``"long"`` (one row per sample and sensor,
        a ``(time_s, sensor)`` index) or ``"wide"`` (one row per sample, ``<sensor>_<quantity>``
        columns); ``source`` ``"measured"``, ``"truth"``, ``"actual"`` or ``"markers"``. Columns and
        units: :mod:`simbench.io.tables`. Needs pandas (``pip install 'simbench[export]'``)."""
        return dataset_to_pandas(self, layout=layout, source=source)

    def to_xarray(self) -> Any:
        """Everything as one ``xarray.Dataset`` (dimensions ``time_s``, ``sensor``, ``axis``, ``quat``,
        ``joint``, ``marker``; :mod:`simbench.io.tables`). Needs xarray (``simbench[export]``)."""
        return dataset_to_xarray(self)

    def poses(self) -> PoseRecording:
        """The measured poses as the calibration reads them."""
        m = self.measured
        R, p = _pose_arrays(m.q_w_s, m.p_w_s, m.valid)
        return PoseRecording(
            names=self.sensors,
            time_s=np.array(self.time_s),
            R_w_s=R,
            p_w_s=p,
            valid=np.array(m.valid),
            source=str(self.meta.get("source", "dataset")),
            notes=_pose_notes(self.position_unit_scale, int((~m.valid).sum())),
        )


def _write_group(group: h5py.Group, data: SensorData) -> None:
    for x in fields(data):
        group.create_dataset(x.name, data=getattr(data, x.name))


def write_dataset(path: str | os.PathLike[str], ds: Dataset) -> None:
    """Write a dataset to HDF5 atomically (layout in the module docstring)."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as fh:
        fh.attrs["format"] = FORMAT
        fh.attrs["format_version"] = FORMAT_VERSION
        fh.attrs["meta"] = json.dumps(ds.meta, sort_keys=True)
        fh.attrs["position_unit_scale"] = float(ds.position_unit_scale)
        fh.create_dataset("time_s", data=ds.time_s)
        fh.create_dataset("sensors", data=np.array(ds.sensors, dtype=h5py.string_dtype()))
        _write_group(fh.create_group("measured"), ds.measured)
        if ds.truth is not None:
            g = fh.create_group("truth")
            _write_group(g, ds.truth.rigid)
            _write_group(g.create_group("actual"), ds.truth.actual)
            for x in fields(ds.truth):
                if x.name in ("rigid", "actual"):
                    continue
                value = getattr(ds.truth, x.name)
                if isinstance(value, tuple):
                    value = np.array(value, dtype=h5py.string_dtype())
                g.create_dataset(x.name, data=value)
        write_markers_group(fh, ds.markers)


def _array(node: Any, path: Path, name: str, kind: str = "number") -> np.ndarray:
    """The array at ``node[name]``: numbers (``kind="number"``) or booleans (``"bool"``)."""
    item = node.get(name)
    if not isinstance(item, h5py.Dataset):
        raise InputError(
            f"{path}: {node.name.rstrip('/')}/{name} must be a dataset, got {type(item).__name__}"
        )
    value = item[()]
    dtype = getattr(value, "dtype", None)
    ok = isinstance(value, np.ndarray) and (
        np.issubdtype(dtype, np.bool_) or (kind == "number" and np.issubdtype(dtype, np.number))
    )
    if not ok:
        expected = "numbers" if kind == "number" else "booleans"
        raise InputError(
            f"{path}: {item.name} must be an array of {expected}, got {dtype or type(value).__name__} of "
            "shape "
            f"{getattr(value, 'shape', ())}"
        )
    return value


def _read_sensor_data(group: Any, path: Path) -> SensorData:
    if not isinstance(group, h5py.Group):
        raise InputError(f"{path}: {group.name} must be a group of datasets, got {type(group).__name__}")
    missing = [f"{group.name}/{x.name}" for x in fields(SensorData) if x.name not in group]
    if missing:
        raise InputError(f"{path}: missing dataset(s) {', '.join(missing)}")
    values = {
        x.name: _array(group, path, x.name, "bool" if x.name == "valid" else "number")
        for x in fields(SensorData)
    }
    if values["valid"].ndim != 2:
        raise InputError(
            f"{path}: {group.name}/valid must be (frames, sensors), got shape {values['valid'].shape}"
        )
    try:
        return SensorData(**values)
    except InputError as exc:
        raise InputError(f"{path}: {group.name}: {exc}") from None


def _header(fh: h5py.File, path: Path) -> tuple[dict[str, Any], float, tuple[str, ...], np.ndarray]:
    """``(meta, position_unit_scale, sensors, time_s)`` of an open dataset, checked.

    Raises:
        InputError: not a simbench dataset, a newer format, missing or malformed fields.
    """
    if fh.attrs.get("format") != FORMAT:
        raise InputError(f"{path}: not a simbench dataset (format attribute {fh.attrs.get('format')!r})")
    try:
        version = int(fh.attrs.get("format_version", 0))
    except (TypeError, ValueError):
        raise InputError(
            f"{path}: format_version must be an integer, got {fh.attrs.get('format_version')!r}"
        ) from None
    if version > FORMAT_VERSION:
        raise InputError(f"{path}: dataset format version {version} is newer than this simbench reads")
    missing = [f"/{name}" for name in ("sensors", "time_s", "measured") if name not in fh]
    missing += ["the meta attribute"] if "meta" not in fh.attrs else []
    if missing:
        raise InputError(f"{path}: not a complete simbench dataset: missing {', '.join(missing)}")
    try:
        meta = json.loads(fh.attrs["meta"])
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: the meta attribute is not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise InputError(f"{path}: the meta attribute is not a JSON object, got {type(meta).__name__}")
    try:
        # format 1 files written before the typed field kept the factor in meta
        scale = float(fh.attrs.get("position_unit_scale", meta.pop("position_unit_scale", 1.0)))
    except (TypeError, ValueError):
        raise InputError(f"{path}: position_unit_scale is not a number") from None
    if not isinstance(fh["sensors"], h5py.Dataset):
        raise InputError(f"{path}: /sensors must be a dataset of names")
    sensors = tuple(s.decode() if isinstance(s, bytes) else str(s) for s in np.atleast_1d(fh["sensors"][()]))
    time_s = fh["time_s"][()] if isinstance(fh["time_s"], h5py.Dataset) else None
    if not (isinstance(time_s, np.ndarray) and time_s.ndim == 1 and np.issubdtype(time_s.dtype, np.number)):
        kind = getattr(time_s, "dtype", type(time_s).__name__)
        raise InputError(
            f"{path}: /time_s must be a 1-D array of numbers (seconds), got {kind} of shape "
            f"{getattr(time_s, 'shape', ())}"
        )
    _check_times(time_s, path)
    return meta, scale, sensors, time_s


def read_dataset_poses(path: str | os.PathLike[str], *, in_memory: bool | None = None) -> PoseRecording:
    """The measured poses of a dataset, as :meth:`Dataset.poses` gives them, without reading the
    rest (truth, inertial data) and, for a large file, a chunk of frames at a time.

    Args:
        path: a file written by :func:`write_dataset`.
        in_memory: poses in arrays (True: ``read_dataset(path).poses()``), or in an unlinked
            temporary HDF5 file (False: ``R_w_s`` and ``p_w_s`` are h5py datasets, as the pose CSV
            reader gives for a large file); ``None`` chooses by size
            (:data:`~simbench.io.csv_blocks.IN_MEMORY_BYTES` of rotations and positions).

    Raises:
        InputError: as :func:`read_dataset`, and for a sample marked valid without a finite
            position and a non-zero quaternion.
    """
    path = Path(path)
    if in_memory is None:
        with open_hdf5(path) as fh:
            valid = fh.get("measured/valid")
            shape = valid.shape if isinstance(valid, h5py.Dataset) else ()
        in_memory = len(shape) != 2 or shape[0] * shape[1] * 12 * 8 <= IN_MEMORY_BYTES
    if in_memory:
        return read_dataset(path).poses()
    with open_hdf5(path) as fh:
        _, scale, sensors, time_s = _header(fh, path)
        g = fh["measured"]
        n_frames, n = time_s.size, len(sensors)
        for name, tail in (("valid", ()), ("q_w_s", (4,)), ("p_w_s", (3,))):
            item = g.get(name) if isinstance(g, h5py.Group) else None
            if not isinstance(item, h5py.Dataset) or item.shape != (n_frames, n, *tail):
                got = getattr(item, "shape", type(item).__name__)
                raise InputError(f"{path}: /measured/{name} must be {(n_frames, n, *tail)}, got {got}")
        valid = _array(g, path, "valid", "bool")
        store = TemporaryPoses(n_frames, n)
        bad, first = 0, None
        for start in range(0, n_frames, CHUNK_FRAMES):
            frames = slice(start, min(start + CHUNK_FRAMES, n_frames))
            q, p, v = g["q_w_s"][frames], g["p_w_s"][frames], valid[frames]
            if not (np.issubdtype(q.dtype, np.number) and np.issubdtype(p.dtype, np.number)):
                raise InputError(f"{path}: /measured/q_w_s and /measured/p_w_s must be arrays of numbers")
            wrong = _unusable(q, p, v)
            if wrong.any():
                bad += int(wrong.sum())
                first = first or tuple(int(x) for x in np.argwhere(wrong)[0] + (start, 0))
                continue
            store.R[frames], store.p[frames] = _pose_arrays(q, p, v)
        if bad:
            f, k = first
            raise _unusable_error(path, bad, sensors[k], float(time_s[f]))
    R_w_s, p_w_s = store.arrays()
    return PoseRecording(
        names=sensors,
        time_s=time_s,
        R_w_s=R_w_s,
        p_w_s=p_w_s,
        valid=valid,
        source=str(path),
        notes=_pose_notes(scale, int((~valid).sum())),
    )


def _pose_arrays(q_w_s: np.ndarray, p_w_s: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R_w_s`` ``(frames, sensors, 3, 3)`` and ``p_w_s`` ``(frames, sensors, 3)`` as the calibration
    reads them, NaN where a sample is not ``valid``, from the stored quaternions (w first) and
    positions."""
    R = quat_to_matrix(np.where(valid[..., None], q_w_s, [1.0, 0.0, 0.0, 0.0]))
    return np.where(valid[..., None, None], R, np.nan), np.where(valid[..., None], p_w_s, np.nan)


def _pose_notes(scale: float, missing: int) -> tuple[str, ...]:
    """The notes of a dataset's poses: the tracker's unit, the missing samples."""
    notes = []
    if scale != 1.0:
        notes.append(
            f"positions are in the simulated tracker's units (metres / {scale:g}): lengths below are "
            "in those units; `simbench scale` estimates the factor from two rigidly mounted sensors"
        )
    if missing:
        notes.append(f"{missing} sensor samples are missing (tracker dropouts or latency)")
    return tuple(notes)


def read_dataset(path: str | os.PathLike[str]) -> Dataset:
    """Read a dataset written by :func:`write_dataset`.

    Raises:
        InputError: not an HDF5 file, not a simbench dataset, a newer format, missing fields.
    """
    path = Path(path)
    with open_hdf5(path) as fh:
        meta, scale, sensors, time_s = _header(fh, path)
        measured = _read_sensor_data(fh["measured"], path)
        _check_poses(measured, time_s, sensors, path)
        truth = None
        if "truth" in fh:
            g = fh["truth"]
            values: dict[str, Any] = {"rigid": _read_sensor_data(g, path)}
            values["actual"] = _read_sensor_data(g["actual"], path) if "actual" in g else values["rigid"]
            for x in fields(Truth):
                if x.name in ("rigid", "actual"):
                    continue
                if x.name not in g:
                    raise InputError(f"{path}: missing dataset /truth/{x.name}")
                if x.name in ("parent", "child"):
                    if not isinstance(g[x.name], h5py.Dataset):
                        raise InputError(f"{path}: /truth/{x.name} must be a dataset of names")
                    value = tuple(
                        v.decode() if isinstance(v, bytes) else str(v) for v in np.atleast_1d(g[x.name][()])
                    )
                else:
                    value = _array(g, path, x.name, "bool" if x.name == "single_axis" else "number")
                values[x.name] = value
            for name in ("rigid", "actual"):
                if values[name].valid.shape != measured.valid.shape:
                    raise InputError(
                        f"{path}: /truth ({name}) holds {values[name].valid.shape} (frames, sensors), "
                        f"/measured {measured.valid.shape}"
                    )
            truth = Truth(**values)
        markers = read_markers_group(fh, path, time_s.size)
    meta["source"] = str(path)
    try:
        return Dataset(
            time_s=time_s,
            sensors=sensors,
            measured=measured,
            truth=truth,
            meta=meta,
            position_unit_scale=scale,
            markers=markers,
        )
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _check_poses(m: SensorData, time_s: np.ndarray, sensors: tuple[str, ...], path: Path) -> None:
    """A sample marked valid must have a finite position and a non-zero finite quaternion."""
    if m.valid.shape != (time_s.size, len(sensors)):
        raise InputError(
            f"{path}: /measured holds {m.valid.shape} (frames, sensors); /time_s and /sensors say "
            f"{(time_s.size, len(sensors))}"
        )
    bad = _unusable(m.q_w_s, m.p_w_s, m.valid)
    if bad.any():
        f, k = np.argwhere(bad)[0]
        raise _unusable_error(path, int(bad.sum()), sensors[k], float(time_s[f]))


def _unusable(q_w_s: np.ndarray, p_w_s: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``(frames, sensors)``: samples marked valid without a finite position and a non-zero finite
    quaternion (``(frames, sensors, 4)``, ``(frames, sensors, 3)``, ``(frames, sensors)``)."""
    q_ok = np.isfinite(q_w_s).all(axis=-1) & (np.linalg.norm(np.nan_to_num(q_w_s), axis=-1) > 0)
    return valid & ~(q_ok & np.isfinite(p_w_s).all(axis=-1))


def _unusable_error(path: Path, count: int, sensor: str, t: float) -> InputError:
    return InputError(
        f"{path}: /measured: {count} sample(s) marked valid without a finite position and a "
        f"non-zero quaternion (the first: sensor {sensor!r} at t = {t:g} s)"
    )


def _check_times(time_s: np.ndarray, path: Path) -> None:
    """Sample times must be finite and strictly increasing."""
    wrong = first_bad_time(time_s)
    if wrong is not None:
        raise InputError(f"{path}: /time_s[{wrong[0]}]: {wrong[1]}")


def truth_calibration_dict(ds: Dataset) -> dict[str, Any]:
    """The truth in the calibration JSON schema of docs/conventions.md, to compare field by field."""
    if ds.truth is None:
        raise InputError("the dataset has no ground truth")
    t = ds.truth
    index = {name: k for k, name in enumerate(ds.sensors)}
    joints = [(index[p], index[c]) for p, c in zip(t.parent, t.child, strict=True)]
    root = next(s for s in ds.sensors if s not in t.child)

    def vec(v: np.ndarray) -> list[float] | None:
        return None if not np.all(np.isfinite(v)) else [float(x) for x in v]

    return {
        "format": "simbench-calibration",
        "format_version": 1,
        "units": "m",
        "root": root,
        "hierarchy": "truth",
        "joints": [
            {
                "parent": p,
                "child": c,
                "joint_in_parent": vec(t.joint_in_parent[k]),
                "joint_in_child": vec(t.joint_in_child[k]),
                "rms_residual": 0.0,
                "single_axis": bool(t.single_axis[k]),
                "axis_in_parent": vec(t.axis_in_parent[k]),
                "axis_in_child": vec(t.axis_in_child[k]),
            }
            for k, (p, c) in enumerate(zip(t.parent, t.child, strict=True))
        ],
        "limb_lengths": [
            {"segment": x.segment, "joint_a": x.joint_a, "joint_b": x.joint_b, "length": x.length}
            for x in segment_lengths(ds.sensors, joints, t.joint_in_parent, t.joint_in_child)
        ],
        "sensor_placement": [
            {"sensor": s, "p_b_s": [float(v) for v in t.p_b_s[k]], "q_b_s": [float(v) for v in t.q_b_s[k]]}
            for k, s in enumerate(ds.sensors)
        ],
        "meta": {k: v for k, v in ds.meta.items() if k in ("model", "program", "seed", "rate_hz")},
    }


__all__ = [
    "Dataset",
    "SensorData",
    "Truth",
    "read_dataset",
    "truth_calibration_dict",
    "write_dataset",
]


def dataset_from_poses(rec: PoseRecording) -> Dataset:
    """A Dataset holding a recording's poses (a tracker export, optical clusters): the same
    container the simulator writes, without inertial data (NaN) or truth."""
    valid = np.array(rec.valid)
    q = matrix_to_quat(np.where(valid[..., None, None], rec.R_w_s, np.eye(3)))
    q[~valid] = np.nan
    nan3 = np.full((*valid.shape, 3), np.nan)
    measured = SensorData(p_w_s=np.array(rec.p_w_s), q_w_s=q, valid=valid, acc=nan3, gyro=nan3, mag=nan3)
    return Dataset(
        time_s=np.array(rec.time_s),
        sensors=rec.names,
        measured=measured,
        truth=None,
        meta={"source": rec.source, "notes": list(rec.notes)},
    )
