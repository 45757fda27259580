"""``Dataset.to_pandas()`` (long and wide) and ``Dataset.to_xarray()``: the same numbers as the
dataset's arrays, in the documented places; a clear ImportError without the optional packages."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import simbench as sb
from simbench.errors import InputError
from simbench.io.dataset import dataset_from_poses
from simbench.sim.marker_clusters import MarkerConfig

pd = pytest.importorskip("pandas")
xr = pytest.importorskip("xarray")


@pytest.fixture(scope="module")
def ds():
    return sb.simulate(
        "linkage",
        "exercise",
        sensors="ascension-flock",  # dropouts: valid is not all True
        duration_s=2.0,
        seed=4,
        markers=MarkerConfig(skin_sd_m=0.002),
    )


def test_long_table_rows_are_sample_and_sensor(ds):
    df = ds.to_pandas()
    f, n = ds.measured.valid.shape
    assert df.shape == (f * n, 17) and df.index.names == ["time_s", "sensor"]
    k, i = 7, 3  # any frame and sensor
    row = df.loc[(ds.time_s[k], ds.sensors[i])]
    m = ds.measured
    assert np.array_equal(row[["x", "y", "z"]].to_numpy(float), m.p_w_s[k, i], equal_nan=True)
    assert np.array_equal(row[["qw", "qx", "qy", "qz"]].to_numpy(float), m.q_w_s[k, i], equal_nan=True)
    assert np.array_equal(row[["mag_x", "mag_y", "mag_z"]].to_numpy(float), m.mag[k, i])
    assert df["valid"].dtype == bool
    assert np.array_equal(df["valid"].to_numpy().reshape(f, n), m.valid)
    assert df.attrs["units"]["acc_x"] == "m/s^2" and df.attrs["units"]["mag_z"] == "uT"


def test_wide_table_rows_are_samples(ds):
    df = ds.to_pandas(layout="wide", source="truth")
    f, n = ds.measured.valid.shape
    assert df.shape == (f, 17 * n) and df.index.name == "time_s"
    assert np.array_equal(df.index.to_numpy(), ds.time_s)
    s = ds.sensors[2]
    acc = df[[f"{s}_acc_x", f"{s}_acc_y", f"{s}_acc_z"]].to_numpy()
    assert np.array_equal(acc, ds.truth.rigid.acc[:, 2])
    assert df[f"{s}_valid"].all()


def test_marker_tables(ds):
    long = ds.to_pandas(source="markers")
    m = ds.markers
    assert list(long.columns) == ["segment", "x", "y", "z"]
    assert np.array_equal(long[["x", "y", "z"]].to_numpy().reshape(m.xyz.shape), m.xyz)
    assert long.loc[(ds.time_s[0], "head_M2"), "segment"] == "head"
    wide = ds.to_pandas(layout="wide", source="markers")
    assert np.array_equal(wide["forearm_l_M4_z"].to_numpy(), m.xyz[:, m.labels.index("forearm_l_M4"), 2])


def test_xarray_holds_everything(ds):
    x = ds.to_xarray()
    assert dict(x.sizes) == {"time_s": 240, "sensor": 6, "axis": 3, "quat": 4, "joint": 5, "marker": 24}
    assert np.array_equal(
        x["q_w_s"].sel(sensor="head", quat="w").to_numpy(), ds.measured.q_w_s[:, 1, 0], equal_nan=True
    )
    assert np.array_equal(x["truth_joint_w"].sel(joint="forearm_r").to_numpy(), ds.truth.joint_w[:, 4])
    assert np.array_equal(x["markers_xyz_true"].to_numpy(), ds.markers.xyz_true)
    assert x["acc"].attrs == {"units": "m/s^2", "frame": "sensor (specific force)"}
    assert x["joint_parent"].sel(joint="forearm_r").item() == "upper_arm_r"
    assert '"seed": 4' in x.attrs["meta"]


def test_tables_do_not_share_the_datasets_memory(ds):
    for source, held in (("measured", ds.measured.p_w_s), ("markers", ds.markers.xyz)):
        for layout in ("long", "wide"):
            df = ds.to_pandas(source=source, layout=layout)
            numbers = df.select_dtypes("number")
            assert not any(np.shares_memory(numbers[c].to_numpy(), held) for c in numbers.columns)
    x = ds.to_xarray()  # xarray keeps the arrays it is given: they must be copies
    assert not np.shares_memory(x["markers_xyz"].to_numpy(), ds.markers.xyz)
    assert not np.shares_memory(x["truth_joint_w"].to_numpy(), ds.truth.joint_w)
    assert not np.shares_memory(x["p_w_s"].to_numpy(), ds.measured.p_w_s)


def test_bad_requests(ds):
    with pytest.raises(InputError, match=r"Expected layout to be one of \('long', 'wide'\), got 'tall'"):
        ds.to_pandas(layout="tall")
    with pytest.raises(InputError, match="Expected source to be one of"):
        ds.to_pandas(source="estimated")
    rec = dataset_from_poses(ds.poses())  # a recording: no truth, no markers
    with pytest.raises(InputError, match="source 'truth' needs a dataset with truth"):
        rec.to_pandas(source="truth")
    with pytest.raises(InputError, match="simbench simulate --markers"):
        rec.to_pandas(source="markers")


@pytest.mark.parametrize(("method", "module"), [("to_pandas", "pandas"), ("to_xarray", "xarray")])
def test_missing_optional_package_names_the_extra(ds, monkeypatch, method, module):
    monkeypatch.setitem(sys.modules, module, None)  # import now raises ImportError
    with pytest.raises(
        ImportError, match=rf"needs the optional package '{module}': pip install 'simbench\[export\]'"
    ):
        getattr(ds, method)()
