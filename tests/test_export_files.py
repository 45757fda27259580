"""The export formats, each read back: TRC (our reader and OpenSim's), C3D (ezc3d), OpenSense's
``.sto`` (our reader and OpenSim's ``TimeSeriesTableQuaternion``, with OpenSense's rotation to its
y-up ground), raw IMU readings as CSV (exact)."""

from __future__ import annotations

import dataclasses

import ezc3d
import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.errors import InputError
from simbench.io.c3d import read_c3d_markers
from simbench.io.export import export_dataset
from simbench.io.imu_csv import read_imu_csv, write_imu_csv
from simbench.io.opensense import SENSOR_TO_OPENSIM_ROTATIONS, read_opensense_sto, write_opensense_sto
from simbench.io.trc import read_trc, write_trc
from simbench.sim.marker_clusters import MarkerConfig, add_markers
from simbench.sim.session import SessionConfig, run_session


@pytest.fixture(scope="module")
def ds():
    session = run_session(
        SessionConfig(model="linkage", motion="walk", duration_s=2.0, seed=2, sensors="mems-consumer")
    )
    ds = add_markers(session, MarkerConfig(skin_sd_m=0.003, camera_noise_m=0.0002))
    xyz = np.array(ds.markers.xyz)
    xyz[10:20, 3] = np.nan  # a marker not seen for 10 frames
    return dataclasses.replace(ds, markers=dataclasses.replace(ds.markers, xyz=xyz))


def _opensim():
    return pytest.importorskip("opensim")


@pytest.mark.parametrize("units", ["mm", "m"])
def test_trc_round_trip(ds, tmp_path, units):
    path = tmp_path / "m.trc"
    write_trc(path, ds.markers.labels, ds.time_s, ds.markers.xyz, units=units, rate_hz=120.0)
    back = read_trc(path)
    assert back.labels == ds.markers.labels and back.units == units and back.rate_hz == 120.0
    assert np.array_equal(back.time_s, ds.time_s)
    assert np.isnan(back.xyz[10:20, 3]).all() and np.isfinite(back.xyz[:10]).all()
    # 6 decimals in the file's unit: within half of the last digit
    assert_allclose(back.xyz, ds.markers.xyz, rtol=0, atol=0.5e-6 * (1e-3 if units == "mm" else 1.0) * 1.0001)
    lines = path.read_text().splitlines()
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\tm.trc"
    assert lines[2].split("\t")[:5] == ["120", "120", "240", "24", units]
    assert lines[4].split("\t")[:5] == ["", "", "X1", "Y1", "Z1"] and lines[5] == ""
    row = lines[6 + 10].split("\t")  # frame 11: marker 4's fields empty
    assert row[0] == "11" and row[2 + 9 : 2 + 12] == ["", "", ""]


def test_trc_read_by_opensim(ds, tmp_path):
    osim = _opensim()
    path = tmp_path / "m.trc"
    write_trc(path, ds.markers.labels, ds.time_s, ds.markers.xyz, units="mm")
    table = osim.TimeSeriesTableVec3(str(path))
    assert list(table.getColumnLabels()) == list(ds.markers.labels)
    assert table.getNumRows() == 240 and table.getTableMetaDataAsString("Units") == "mm"
    assert_allclose(np.array(table.getIndependentColumn()), ds.time_s, rtol=0, atol=1e-12)
    for k, m in ((0, 0), (57, 5), (15, 3)):
        v = table.getRowAtIndex(k).getElt(0, m)
        got = np.array([v.get(i) for i in range(3)]) * 1e-3
        assert_allclose(got, ds.markers.xyz[k, m], rtol=0, atol=1e-9)  # NaN where not seen, both sides


def test_c3d_round_trip(ds, tmp_path):
    path = tmp_path / "m.c3d"
    export_dataset(ds, c3d=path)
    labels, xyz, rate = read_c3d_markers(path)
    assert ezc3d.c3d(str(path))["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]  # units explicit
    assert labels == list(ds.markers.labels) and rate == 120.0
    assert np.isnan(xyz[10:20, 3]).all()
    # C3D stores single-precision floats in mm: 1e-4 mm at a metre and a half
    assert_allclose(xyz, ds.markers.xyz, rtol=0, atol=2e-7)


def test_sto_round_trip_is_exact(ds, tmp_path):
    path = tmp_path / "imu.sto"
    q = np.array(ds.truth.actual.q_w_s)
    q[5, 2] = np.nan
    write_opensense_sto(path, ds.sensors, ds.time_s, q)
    back = read_opensense_sto(path)
    assert back.names == ds.sensors and back.rate_hz == pytest.approx(120.0, abs=1e-6)
    assert np.array_equal(back.q_w_s, q, equal_nan=True) and np.array_equal(back.time_s, ds.time_s)
    lines = path.read_text().splitlines()
    assert lines[:5] == [
        "DataRate=120.000000",
        "DataType=Quaternion",
        "version=3",
        "OpenSimVersion=4.5",
        "endheader",
    ]
    assert lines[5] == "time\t" + "\t".join(f"{s}_imu" for s in ds.sensors)
    first = lines[6].split("\t")
    assert len(first) == 7 and [float(v) for v in first[1].split(",")] == list(q[0, 0])  # w first


def test_sto_read_by_opensim_with_opensense_rotation(ds, tmp_path):
    osim = _opensim()
    path = tmp_path / "imu.sto"
    q = np.array(ds.truth.actual.q_w_s)
    write_opensense_sto(path, ds.sensors, ds.time_s, q)
    table = osim.TimeSeriesTableQuaternion(str(path))
    assert list(table.getColumnLabels()) == [f"{s}_imu" for s in ds.sensors]
    assert table.getNumRows() == 240 and table.getTableMetaDataAsString("DataRate") == "120.000000"

    def cell(k, i):
        e = table.getRowAtIndex(k).getElt(0, i)
        return np.array([e.get(j) for j in range(4)])

    for k, i in ((0, 0), (100, 3), (239, 5)):  # OpenSim normalises quaternions: rounding only
        assert_allclose(cell(k, i), q[k, i], rtol=0, atol=1e-12)
    # OpenSense premultiplies by its sensor_to_opensim_rotations: ours take z up to y up
    a = SENSOR_TO_OPENSIM_ROTATIONS
    axes = [osim.CoordinateAxis(i) for i in range(3)]
    rotation = osim.Rotation(osim.SpaceRotationSequence, a[0], axes[0], a[1], axes[1], a[2], axes[2])
    osim.OpenSenseUtilities.rotateOrientationTable(table, rotation)
    R_ground_world = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    assert np.array_equal(R_ground_world @ [0.0, 0.0, 1.0], [0.0, 1.0, 0.0])  # world up is OpenSim's +y
    expected = matrix_to_quat(R_ground_world @ quat_to_matrix(q[100, 3]))
    got = cell(100, 3)
    assert_allclose(got * np.sign(got[0] * expected[0]), expected, rtol=0, atol=1e-12)


def test_imu_csv_round_trip_is_exact(ds, tmp_path):
    path = tmp_path / "imu.csv"
    m = ds.measured
    acc = np.array(m.acc)
    acc[3, 1, 2] = np.nan
    write_imu_csv(path, ds.sensors, ds.time_s, acc, m.gyro, m.mag)
    back = read_imu_csv(path)
    assert back.names == ds.sensors and np.array_equal(back.time_s, ds.time_s)
    assert np.array_equal(back.acc, acc, equal_nan=True)
    assert np.array_equal(back.gyro, m.gyro) and np.array_equal(back.mag, m.mag)
    lines = path.read_text().splitlines()
    assert "acc: m/s^2" in lines[0] and "gyro: rad/s" in lines[0] and "mag: uT" in lines[0]
    assert lines[2].startswith("time_s,chest_acc_x,chest_acc_y,chest_acc_z,chest_gyro_x,")
    assert lines[2].endswith(",forearm_r_mag_z")
    assert lines[3 + 3].split(",")[1 + 9 + 2] == ""  # the NaN: sensor 1's acc_z at frame 3
    pd = pytest.importorskip("pandas")
    df = pd.read_csv(path, comment="#")
    assert np.array_equal(df["head_gyro_y"].to_numpy(), m.gyro[:, 1, 1])


def test_bad_files_are_named(tmp_path):
    bad = tmp_path / "bad.trc"
    bad.write_text("hello\n")
    with pytest.raises(InputError, match="not a TRC file"):
        read_trc(bad)
    write_trc(bad, ["A"], np.arange(3) / 10, np.zeros((3, 1, 3)))
    text = bad.read_text().replace("\tmm\t", "\tfurlong\t")
    bad.write_text(text)
    with pytest.raises(InputError, match=r"line 3: Units is 'furlong'"):
        read_trc(bad)
    write_trc(bad, ["A"], np.arange(3) / 10, np.zeros((3, 1, 3)))
    bad.write_text(bad.read_text() + "4\t0.3\t1\t2\t3\n")
    with pytest.raises(InputError, match="4 frames of data, the header says NumFrames 3"):
        read_trc(bad)
    sto = tmp_path / "bad.sto"
    sto.write_text("DataType=Vec3\nendheader\ntime\ta_imu\n0\t1,2,3\n")
    with pytest.raises(InputError, match="expected DataType=Quaternion, got 'Vec3'"):
        read_opensense_sto(sto)
    sto.write_text("DataType=Quaternion\nendheader\ntime\ta_imu\n0\t1,0,0\n")
    with pytest.raises(InputError, match=r"line 4: expected each cell to be w,x,y,z"):
        read_opensense_sto(sto)
    csv = tmp_path / "bad.csv"
    csv.write_text(
        "time_s," + ",".join(f"a_{q}_{x}" for q in ("acc", "gyro", "magnet") for x in "xyz") + "\n"
    )
    with pytest.raises(InputError, match="column 8 is 'a_magnet_x'; expected 'a_mag_x'"):
        read_imu_csv(csv)
    with pytest.raises(InputError, match=r"Expected markers of shape \(frames, 2, 3\), got \(3, 1, 3\)"):
        write_trc(bad, ["A", "B"], np.arange(3) / 10, np.zeros((3, 1, 3)))
    with pytest.raises(InputError, match=r"Expected q_w_s of shape \(frames, 1, 4\)"):
        write_opensense_sto(sto, ["a"], np.arange(3) / 10, np.zeros((3, 1, 3)))
    with pytest.raises(InputError, match=r"Expected gyro of shape \(3, 1, 3\), got \(3, 1\)"):
        write_imu_csv(
            csv, ["a"], np.arange(3) / 10, np.zeros((3, 1, 3)), np.zeros((3, 1)), np.zeros((3, 1, 3))
        )
