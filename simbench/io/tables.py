"""A Dataset as a pandas DataFrame or an xarray Dataset (optional dependencies: ``simbench[export]``).

**pandas** (:func:`dataset_to_pandas`, ``Dataset.to_pandas``), one table per ``source``:

- ``"measured"`` (default), ``"truth"`` (bone-rigid sensors) or ``"actual"`` (sensors where they
  sit on the skin): per sensor and sample ``x, y, z`` (position in world: metres, or the tracker's
  units for ``measured`` when ``position_unit_scale`` is not 1), ``qw, qx, qy, qz`` (``R_w_s``),
  ``acc_x..z`` (m/s^2), ``gyro_x..z`` (rad/s), ``mag_x..z`` (uT), sensor frame, and ``valid``;
- ``"markers"``: per marker and sample ``segment``, ``x, y, z`` (world, m; NaN where not seen).

``layout="long"`` (tidy, the default): one row per sample and sensor (or marker), a
``(time_s, sensor)`` (or ``(time_s, marker)``) MultiIndex, the quantities as columns.
``layout="wide"``: one row per sample indexed by ``time_s``, one column per sensor and quantity
named ``<sensor>_<quantity>`` (``pelvis_acc_x``, as in the IMU CSV; markers: ``<marker>_x``).
The table's ``attrs["units"]`` maps each quantity to its unit.

**xarray** (:func:`dataset_to_xarray`, ``Dataset.to_xarray``): one ``xarray.Dataset`` with
dimensions ``time_s``, ``sensor``, ``axis`` (x, y, z), ``quat`` (w, x, y, z), and ``joint``,
``marker`` where present; variables ``p_w_s``, ``q_w_s``, ``valid``, ``acc``, ``gyro``, ``mag``
(measured), the same prefixed ``truth_`` and ``actual_``, ``truth_p_w_b``, ``truth_q_w_b``,
``truth_joint_w`` and ``markers_xyz`` (``markers_xyz_true``) when the dataset has them; each
variable's ``attrs`` give ``units`` and ``frame``; the dataset's metadata is ``attrs["meta"]``
(JSON text).
"""

from __future__ import annotations

import json
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from simbench.errors import InputError

if TYPE_CHECKING:  # the Dataset imports this module
    from simbench.io.dataset import Dataset, SensorData

SOURCES = ("measured", "truth", "actual", "markers")
LAYOUTS = ("long", "wide")
#: ``(column, unit)`` of the sensor tables, in order.
SENSOR_COLUMNS = (
    *((c, "m") for c in ("x", "y", "z")),
    *((c, "1") for c in ("qw", "qx", "qy", "qz")),
    *((f"acc_{a}", "m/s^2") for a in "xyz"),
    *((f"gyro_{a}", "rad/s") for a in "xyz"),
    *((f"mag_{a}", "uT") for a in "xyz"),
    ("valid", "bool"),
)


def _pandas() -> ModuleType:
    try:
        import pandas
    except ImportError:
        raise ImportError(
            "Dataset.to_pandas() needs the optional package 'pandas': pip install 'simbench[export]'"
        ) from None
    return pandas


def _xarray() -> ModuleType:
    try:
        import xarray
    except ImportError:
        raise ImportError(
            "Dataset.to_xarray() needs the optional package 'xarray': pip install 'simbench[export]'"
        ) from None
    return xarray


def _sensor_data(ds: Dataset, source: str) -> SensorData:
    if source == "measured":
        return ds.measured
    if ds.truth is None:
        raise InputError(f"source {source!r} needs a dataset with truth; this one has none (a recording)")
    return ds.truth.rigid if source == "truth" else ds.truth.actual


def _check(source: str, layout: str) -> None:
    if source not in SOURCES:
        raise InputError(f"Expected source to be one of {SOURCES}, got {source!r}")
    if layout not in LAYOUTS:
        raise InputError(f"Expected layout to be one of {LAYOUTS}, got {layout!r}")


def dataset_to_pandas(ds: Dataset, *, layout: str = "long", source: str = "measured") -> Any:
    """The dataset as a ``pandas.DataFrame`` (module docstring for the layouts and columns).

    Args:
        ds: the dataset.
        layout: ``"long"`` (one row per sample and sensor) or ``"wide"`` (one row per sample).
        source: ``"measured"``, ``"truth"``, ``"actual"`` or ``"markers"``.

    Raises:
        ImportError: pandas is not installed (``pip install 'simbench[export]'``).
        InputError: an unknown layout or source; truth or markers asked of a dataset without them.
    """
    _check(source, layout)
    pd = _pandas()
    f = ds.time_s.size
    if source == "markers":
        if ds.markers is None:
            raise InputError(
                "the dataset has no markers (/markers); simulate them with `simbench simulate --markers`"
            )
        names, columns = ds.markers.labels, ["x", "y", "z"]
        values = np.array(ds.markers.xyz)  # an own copy: the table never shares the dataset's memory
        units = {"time_s": "s", "x": "m", "y": "m", "z": "m"}
        key = "marker"
    else:
        d = _sensor_data(ds, source)
        names, columns = ds.sensors, [c for c, _ in SENSOR_COLUMNS]
        values = np.concatenate([d.p_w_s, d.q_w_s, d.acc, d.gyro, d.mag, d.valid[..., None]], axis=2)
        units = {"time_s": "s", **dict(SENSOR_COLUMNS)}
        if source == "measured" and ds.position_unit_scale != 1.0:
            units.update({c: f"m / {ds.position_unit_scale:g}" for c in "xyz"})
        key = "sensor"
    n = len(names)
    if layout == "long":
        index = pd.MultiIndex.from_product([np.asarray(ds.time_s), list(names)], names=["time_s", key])
        df = pd.DataFrame(values.reshape(f * n, len(columns)), index=index, columns=columns)
        if source == "markers":
            df.insert(0, "segment", np.tile(np.array(ds.markers.segment, dtype=object), f))
    else:
        flat = [f"{name}_{c}" for name in names for c in columns]
        df = pd.DataFrame(
            values.reshape(f, n * len(columns)),
            index=pd.Index(np.asarray(ds.time_s), name="time_s"),
            columns=flat,
        )
    if source != "markers":  # the flag column as booleans
        valid_cols = ["valid"] if layout == "long" else [f"{name}_valid" for name in names]
        df[valid_cols] = df[valid_cols].astype(bool)
    df.attrs["units"] = units
    df.attrs["source"] = source
    return df


def _attrs(units: str, frame: str) -> dict[str, str]:
    return {"units": units, "frame": frame}


def dataset_to_xarray(ds: Dataset) -> Any:
    """The dataset as an ``xarray.Dataset`` (module docstring for dimensions and variables).

    Raises:
        ImportError: xarray is not installed (``pip install 'simbench[export]'``).
    """
    xr = _xarray()
    dims3, dims4 = ("time_s", "sensor", "axis"), ("time_s", "sensor", "quat")
    position_units = "m" if ds.position_unit_scale == 1.0 else f"m / {ds.position_unit_scale:g}"
    variables: dict[str, Any] = {}

    def sensor_vars(prefix: str, d: SensorData, p_units: str) -> None:
        variables[f"{prefix}p_w_s"] = (dims3, np.array(d.p_w_s), _attrs(p_units, "world (z up)"))
        variables[f"{prefix}q_w_s"] = (dims4, np.array(d.q_w_s), _attrs("1", "R_w_s, sensor to world, wxyz"))
        variables[f"{prefix}valid"] = (("time_s", "sensor"), np.array(d.valid), _attrs("bool", ""))
        variables[f"{prefix}acc"] = (dims3, np.array(d.acc), _attrs("m/s^2", "sensor (specific force)"))
        variables[f"{prefix}gyro"] = (dims3, np.array(d.gyro), _attrs("rad/s", "sensor"))
        variables[f"{prefix}mag"] = (dims3, np.array(d.mag), _attrs("uT", "sensor"))

    sensor_vars("", ds.measured, position_units)
    coords: dict[str, Any] = {
        "time_s": ("time_s", np.array(ds.time_s), {"units": "s"}),
        "sensor": list(ds.sensors),
        "axis": ["x", "y", "z"],
        "quat": ["w", "x", "y", "z"],
    }
    t = ds.truth
    if t is not None:
        sensor_vars("truth_", t.rigid, "m")
        sensor_vars("actual_", t.actual, "m")
        variables["truth_p_w_b"] = (dims3, np.array(t.p_w_b), _attrs("m", "world: segment (body) origin"))
        variables["truth_q_w_b"] = (dims4, np.array(t.q_w_b), _attrs("1", "R_w_b, segment to world, wxyz"))
        variables["truth_joint_w"] = (
            ("time_s", "joint", "axis"),
            np.array(t.joint_w),
            _attrs("m", "world: joint centres"),
        )
        coords["joint"] = list(t.child)
        coords["joint_parent"] = ("joint", list(t.parent))
    if ds.markers is not None:
        mk = ds.markers
        coords["marker"] = list(mk.labels)
        coords["marker_segment"] = ("marker", list(mk.segment))
        variables["markers_xyz"] = (
            ("time_s", "marker", "axis"),
            np.array(mk.xyz),
            _attrs("m", "world (z up)"),
        )
        if mk.xyz_true is not None:
            variables["markers_xyz_true"] = (
                ("time_s", "marker", "axis"),
                np.array(mk.xyz_true),
                _attrs("m", "world (z up), exact"),
            )
    meta = json.dumps(ds.meta, sort_keys=True, default=str)
    return xr.Dataset(
        variables, coords=coords, attrs={"meta": meta, "position_unit_scale": ds.position_unit_scale}
    )


__all__ = ["LAYOUTS", "SOURCES", "dataset_to_pandas", "dataset_to_xarray"]
