"""``simbench export`` and ``sb.export``: every format from one dataset file, read back; clear
errors that name what is missing, and nothing written when any requested output cannot be."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest
from numpy.testing import assert_allclose

import simbench as sb
from calibration.rotations import rotvec_to_matrix
from simbench.cli import main
from simbench.io.c3d import read_c3d_markers, write_c3d_markers
from simbench.io.dataset import read_dataset
from simbench.io.imu_csv import read_imu_csv
from simbench.io.opensense import read_opensense_sto
from simbench.io.poses import write_pose_csv
from simbench.io.trc import read_trc


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    common = ["simulate", "--duration", "1.5", "--seed", "7"]
    assert main([*common, "--markers", "--marker-skin", "2", "-o", str(folder / "m.h5")]) == 0
    assert main([*common, "-o", str(folder / "plain.h5"), "--truth-json", str(folder / "truth.json")]) == 0
    return folder


def test_export_everything(files, tmp_path, capsys):
    out = {k: tmp_path / f"out.{k}" for k in ("trc", "c3d", "sto", "csv", "xml")}
    argv = ["export", str(files / "m.h5"), "--trc", str(out["trc"]), "--c3d", str(out["c3d"])]
    argv += ["--sto", str(out["sto"]), "--imu-csv", str(out["csv"]), "--mjcf", str(out["xml"])]
    assert main([*argv, "--trc-units", "m", "--orientations", "truth"]) == 0
    printed = capsys.readouterr().out
    assert all(f"wrote {p}" in printed for p in out.values())
    ds = read_dataset(files / "m.h5")
    trc = read_trc(out["trc"])
    assert trc.units == "m" and trc.labels == ds.markers.labels
    assert_allclose(trc.xyz, ds.markers.xyz, rtol=0, atol=5.1e-7)  # 6 decimals of a metre
    labels, xyz, _ = read_c3d_markers(out["c3d"])
    assert labels == list(ds.markers.labels)
    assert_allclose(xyz, ds.markers.xyz, rtol=0, atol=2e-7)  # float32 millimetres
    sto = read_opensense_sto(out["sto"])
    assert np.array_equal(sto.q_w_s, ds.truth.actual.q_w_s)  # --orientations truth
    imu = read_imu_csv(out["csv"])
    assert np.array_equal(imu.acc, ds.measured.acc) and np.array_equal(imu.mag, ds.measured.mag)
    model = mujoco.MjModel.from_xml_path(str(out["xml"]))
    assert model.nbody == len(ds.sensors) + 1


def test_export_truth_markers_and_a_calibration_skeleton(files, tmp_path):
    cal = tmp_path / "cal.json"
    doc = json.loads((files / "truth.json").read_text())
    doc["joints"][0]["joint_in_parent"] = [0.5, 0.0, 0.0]  # a calibration that differs from the truth
    cal.write_text(json.dumps(doc))
    written = sb.export(
        files / "m.h5", trc=tmp_path / "t.trc", mjcf=tmp_path / "s.xml", calibration=cal, markers="truth"
    )
    assert set(written) == {"trc", "mjcf"}
    ds = read_dataset(files / "m.h5")
    assert_allclose(
        read_trc(written["trc"]).xyz, ds.markers.xyz_true, rtol=0, atol=5.1e-10
    )  # 6 decimals of a mm
    model = mujoco.MjModel.from_xml_path(str(written["mjcf"]))
    child = doc["joints"][0]["child"]
    expected = np.array([0.5, 0.0, 0.0]) - np.array(doc["joints"][0]["joint_in_child"])
    assert_allclose(model.body(child).pos, expected, rtol=0, atol=1e-15)  # the calibration's, not the truth's


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["plain.h5", "--trc", "OUT/x.trc"],
            "no markers (no /markers group); simulate a dataset with markers",
        ),
        (["plain.h5", "--c3d", "OUT/x.c3d"], "simbench simulate --markers"),
        (
            ["m.h5", "--sto", "OUT/x.sto", "--calibration", "c.json"],
            "--calibration gives the skeleton of --mjcf",
        ),
        (["m.h5", "--trc", "OUT/nowhere/x.trc"], "folder OUT/nowhere does not exist"),
        (["m.h5", "--mjcf", "OUT/x.xml", "--calibration", "OUT/none.json"], "none.json: cannot read"),
        (["missing.h5", "--trc", "OUT/x.trc"], "missing.h5: cannot read: no such file"),
    ],
)
def test_bad_requests_exit_2_and_write_nothing(files, tmp_path, capsys, args, message):
    argv = [a.replace("OUT", str(tmp_path)) for a in args]
    argv[0] = str(files / argv[0])
    # with a good output beside the bad one: nothing may be written
    assert main(["export", *argv, "--imu-csv", str(tmp_path / "ok.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("simbench: error: ") and message.replace("OUT", str(tmp_path)) in err
    assert not list(tmp_path.iterdir())


def test_nothing_to_export(files, capsys):
    assert main(["export", str(files / "m.h5")]) == 2
    assert (
        "nothing to export: give one or more of --trc, --c3d, --sto, --imu-csv, --mjcf"
        in capsys.readouterr().err
    )


def test_a_real_recording_of_poses_exports_its_orientations_and_calibrated_skeleton(files, tmp_path, capsys):
    """A pose CSV in mm (as a tracker logger writes it; no truth, markers or IMU data): its
    orientations to .sto and the skeleton of its calibration JSON to MJCF; what it lacks is named."""
    ds = read_dataset(files / "plain.h5")
    rec = ds.poses()
    csv = tmp_path / "poses.csv"
    write_pose_csv(csv, rec, units="mm")
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(csv), "--units", "mm", "--json", str(cal), "--no-slip"]) == 0
    sto, xml = tmp_path / "o.sto", tmp_path / "s.xml"
    argv = [
        "export",
        str(csv),
        "--units",
        "mm",
        "--sto",
        str(sto),
        "--mjcf",
        str(xml),
        "--calibration",
        str(cal),
    ]
    assert main(argv) == 0
    back = read_opensense_sto(sto)
    assert back.names == ds.sensors
    q = np.where(back.q_w_s[..., :1] < 0, -back.q_w_s, back.q_w_s)  # one sign of each quaternion
    q_ds = np.where(ds.measured.q_w_s[..., :1] < 0, -ds.measured.q_w_s, ds.measured.q_w_s)
    assert_allclose(q, q_ds, atol=1e-9)
    assert mujoco.MjModel.from_xml_path(str(xml)).njnt == len(ds.sensors)  # a free root and a joint per child
    capsys.readouterr()
    assert main(["export", str(csv), "--units", "mm", "--mjcf", str(xml)]) == 2
    assert "no truth to build a skeleton from; give a calibration JSON" in capsys.readouterr().err
    assert main(["export", str(csv), "--units", "mm", "--trc", str(tmp_path / "m.trc")]) == 2
    assert "no markers" in capsys.readouterr().err


def test_a_c3d_file_exports_its_markers_as_read(tmp_path, capsys):
    """A C3D file's markers to TRC and C3D without clusters or a Dataset (it used to say "the
    dataset has no markers (no /markers group)" of a file holding them); gaps stay gaps, and
    nothing is written when one output cannot be."""
    rng = np.random.default_rng(8)
    frames = 200
    R = rotvec_to_matrix(np.linspace(0.0, 1.0, frames)[:, None] * rng.normal(size=3))
    shape = rng.normal(0.0, 0.1, (5, 3))
    xyz = np.einsum("fij,kj->fki", R, shape) + np.array([0.0, 0.0, 1.0])
    xyz[50:60, 2] = np.nan
    src = tmp_path / "in.c3d"
    write_c3d_markers(src, ["A", "B", "C", "D", "E"], xyz, 150.0)
    trc, c3d = tmp_path / "out.trc", tmp_path / "out.c3d"
    assert main(["export", str(src), "--trc", str(trc), "--c3d", str(c3d)]) == 0, capsys.readouterr().err
    back = read_trc(trc)
    assert list(back.labels) == ["A", "B", "C", "D", "E"]
    assert np.array_equal(np.isnan(back.xyz), np.isnan(xyz))
    assert_allclose(back.xyz[np.isfinite(xyz)], xyz[np.isfinite(xyz)], atol=1e-6)
    _, again, rate = read_c3d_markers(c3d)
    assert rate == 150.0 and np.array_equal(np.isnan(again), np.isnan(xyz))
    refused = [
        (["--markers", "truth"], "a recorded C3D file has measured markers only"),
        (["--c3d", str(tmp_path / "no" / "x.c3d")], "folder"),
    ]
    for k, (extra, message) in enumerate(refused):
        out = tmp_path / f"refused{k}"
        out.mkdir()
        assert (
            main(["export", str(src), "--trc", str(out / "x.trc"), "--imu-csv", str(out / "i.csv"), *extra])
            == 2
        )
        assert message in capsys.readouterr().err and not list(out.iterdir())
