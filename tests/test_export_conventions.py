"""Exports say what they are: a TRC with OpenSim's y up on request, the truth's skeleton named as the
truth (issue 44)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from calibration.rotations import quat_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.dataset import read_dataset
from simbench.io.export import marker_locations
from simbench.io.trc import read_trc, turned


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("conventions") / "d.h5"
    assert main(["simulate", "--duration", "1", "--markers", "-o", str(path)]) == 0
    return path


def test_turning_to_y_up_puts_the_height_on_y_and_back():
    xyz = np.array([[1.0, 2.0, 3.0], [-0.5, 0.25, 1.75]])
    y_up = turned(xyz, "y")
    assert y_up.tolist() == [[1.0, 3.0, -2.0], [-0.5, 1.75, -0.25]]  # height on y, right-handed
    assert np.linalg.det(np.array([turned(e, "y") for e in np.eye(3)])) == pytest.approx(1.0)
    assert np.array_equal(turned(y_up, "y", back=True), xyz) and turned(xyz, "z") is xyz
    with pytest.raises(InputError, match="up axis to be one of \\['z', 'y'\\], got 'x'"):
        turned(xyz, "x")


def test_a_trc_written_y_up_reads_back_and_holds_the_height_on_y(dataset, tmp_path):
    z_up, y_up = tmp_path / "z.trc", tmp_path / "y.trc"
    assert main(["export", str(dataset), "--trc", str(z_up)]) == 0
    assert main(["export", str(dataset), "--trc", str(y_up), "--trc-up", "y"]) == 0
    world, file_y = read_trc(z_up), read_trc(y_up)  # the second read as stored, z assumed
    np.testing.assert_allclose(file_y.xyz[..., 1], world.xyz[..., 2], atol=1e-9)
    np.testing.assert_allclose(file_y.xyz[..., 2], -world.xyz[..., 1], atol=1e-9)
    np.testing.assert_allclose(read_trc(y_up, up="y").xyz, world.xyz, atol=1e-9)


def test_the_truth_s_skeleton_is_named_the_truth(dataset, tmp_path):
    truth_xml, truth_osim = tmp_path / "truth.xml", tmp_path / "truth.osim"
    assert main(["export", str(dataset), "--mjcf", str(truth_xml), "--osim", str(truth_osim)]) == 0
    assert '<mujoco model="true_skeleton"' in truth_xml.read_text()
    assert 'Model name="true_skeleton"' in truth_osim.read_text()
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(dataset), "--json", str(cal), "--no-slip"]) == 0
    calibrated = tmp_path / "cal.xml"
    assert main(["export", str(dataset), "--mjcf", str(calibrated), "--calibration", str(cal)]) == 0
    assert '<mujoco model="calibrated_skeleton"' in calibrated.read_text()


def test_the_osim_carries_the_markers_so_the_trc_drives_marker_ik(dataset, tmp_path):
    """Each marker in the .osim's MarkerSet, on its segment's body, at its place in that body's
    frame: where the model puts it is where the TRC has it (ideal sensors: to rounding)."""
    osim = tmp_path / "m.osim"
    assert main(["export", str(dataset), "--osim", str(osim)]) == 0
    ds = read_dataset(dataset)
    markers = ET.parse(osim).getroot().findall(".//MarkerSet/objects/Marker")
    assert [m.get("name") for m in markers] == list(ds.markers.labels)
    placed = {lab: (seg, loc) for lab, seg, loc in marker_locations(ds, "truth")}
    for m in markers:
        seg, loc = placed[m.get("name")]
        assert m.findtext("socket_parent_frame") == f"/bodyset/{seg}"
        np.testing.assert_allclose(
            [float(v) for v in m.findtext("location").split()], loc, rtol=0, atol=1e-12
        )
    # the location put back in the world by the truth's poses is the marker, every frame
    k, s = 0, ds.sensors.index(ds.markers.segment[0])
    R = quat_to_matrix(np.asarray(ds.truth.rigid.q_w_s[:, s]))
    world = np.einsum("fij,j->fi", R, placed[ds.markers.labels[k]][1]) + ds.truth.rigid.p_w_s[:, s]
    np.testing.assert_allclose(world, ds.markers.xyz_true[:, k], atol=1e-9)
