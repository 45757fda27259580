"""The calibrated skeleton as an OpenSim model: OpenSim reads it back, and posed from the truth
(coordinates from the sensors' orientations, OpenSim's body-fixed X-Y-Z angles) its joint centres
and body origins are the truth's; without the opensim package, the document's structure."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.rotations import matrix_to_euler, quat_to_matrix
from simbench.cli import main
from simbench.io.dataset import truth_calibration_dict
from simbench.io.skeleton_mjcf import skeleton_mjcf, skeleton_qpos
from simbench.io.skeleton_osim import skeleton_osim
from simbench.sim.session import SessionConfig, run_session


@pytest.fixture(scope="module", params=["linkage", "dm_control:humanoid_CMU"])
def session(request):
    return run_session(SessionConfig(model=request.param, motion="exercise", duration_s=0.5, seed=1))


def test_document_structure(session):
    doc = truth_calibration_dict(session)
    root = ET.fromstring(skeleton_osim(doc))
    assert root.tag == "OpenSimDocument" and root.find("Model/gravity").text == "0 0 -9.81"
    bodies = [b.get("name") for b in root.iter("Body")]
    assert sorted(bodies) == sorted(session.sensors)
    t = session.truth
    assert len(root.findall("Model/JointSet/objects/PinJoint")) == int(t.single_axis.sum())
    assert len(root.findall("Model/JointSet/objects/BallJoint")) == int((~t.single_axis).sum())
    assert len(root.findall("Model/JointSet/objects/FreeJoint")) == 1


def test_opensim_reads_it_back_and_poses_it(session, tmp_path):
    osim = pytest.importorskip("opensim")
    doc = truth_calibration_dict(session)
    path = tmp_path / "skeleton.osim"
    path.write_text(skeleton_osim(doc))
    model = osim.Model(str(path))
    state = model.initSystem()
    t, names = session.truth, session.sensors
    assert model.getBodySet().getSize() == len(names) and model.getJointSet().getSize() == len(names)
    sk = skeleton_mjcf(doc)  # the same joints, their reference rotations and the hinge angles
    f = session.time_s.size - 1
    values = skeleton_qpos(sk, names, t.rigid.q_w_s, t.rigid.p_w_s[:, names.index(sk.root)])
    coords = model.getCoordinateSet()

    def put(name, value):
        coords.get(name).setValue(state, float(value), False)

    R_root = quat_to_matrix(t.rigid.q_w_s[f, names.index(sk.root)])
    for axis, value in zip("xyz", matrix_to_euler("XYZ", R_root, degrees=False), strict=True):
        put(f"root_r{axis}", value)
    for axis, value in zip("xyz", t.rigid.p_w_s[f, names.index(sk.root)], strict=True):
        put(f"root_t{axis}", value)
    for j in sk.joints:
        v = values[f"{j.child}_joint"][f]
        if j.kind == "ball":  # OpenSim's ball coordinates: body-fixed X-Y-Z angles
            for axis, value in zip(
                "xyz", matrix_to_euler("XYZ", quat_to_matrix(v), degrees=False), strict=True
            ):
                put(f"{j.child}_r{axis}", value)
        else:
            put(f"{j.child}_angle", v[0])
    model.realizePosition(state)

    def vec(v):
        return np.array([v.get(i) for i in range(3)])

    for k, child in enumerate(t.child):
        centre = vec(model.getJointSet().get(f"{child}_joint").getChildFrame().getPositionInGround(state))
        assert_allclose(centre, t.joint_w[f, k], rtol=0, atol=1e-9)  # exact truth: rounding only
    for i, name in enumerate(names):
        assert_allclose(
            vec(model.getBodySet().get(name).getPositionInGround(state)), t.rigid.p_w_s[f, i], atol=1e-9
        )


def test_export_command_writes_it(tmp_path, capsys):
    data = tmp_path / "d.h5"
    assert main(["simulate", "--duration", "0.5", "-o", str(data)]) == 0
    assert main(["export", str(data), "--osim", str(tmp_path / "s.osim")]) == 0
    assert "(osim)" in capsys.readouterr().out
    assert ET.parse(tmp_path / "s.osim").getroot().tag == "OpenSimDocument"
