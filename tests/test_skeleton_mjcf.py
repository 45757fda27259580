"""The calibrated skeleton as MJCF: MuJoCo loads it, and posed from the sensors' orientations its
joint centres are the calibration's (the truth's to rounding; a calibration JSON's by its own
joint locations)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from numpy.testing import assert_allclose

import simbench as sb
from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.calibration_json import calibration_to_dict, read_calibration_json, write_calibration_json
from simbench.io.dataset import truth_calibration_dict
from simbench.io.skeleton_mjcf import skeleton_mjcf, skeleton_qpos, write_skeleton_mjcf
from simbench.sim.session import SessionConfig, run_session


def _posed(sk, names, q_w_s, p_w_root, frames):
    """MuJoCo's joint anchors ``{child: (frames, 3)}`` and sensor sites ``{name: (frames, 3)}``."""
    m = mujoco.MjModel.from_xml_string(sk.xml)
    d = mujoco.MjData(m)
    values = skeleton_qpos(sk, names, q_w_s, p_w_root)
    anchors = {j.child: [] for j in sk.joints}
    sites = {b: [] for b in sk.bodies}
    for f in frames:
        for name, v in values.items():
            adr = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]
            d.qpos[adr : adr + v.shape[1]] = v[f]
        mujoco.mj_kinematics(m, d)
        for child in anchors:
            anchors[child].append(
                d.xanchor[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{child}_joint")].copy()
            )
        for b in sites:
            sites[b].append(d.site_xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"sensor_{b}")].copy())
    return m, {k: np.array(v) for k, v in anchors.items()}, {k: np.array(v) for k, v in sites.items()}


@pytest.mark.parametrize(("model", "hinges"), [("linkage", 0), ("dm_control:humanoid_CMU", 10)])
def test_truth_skeleton_reproduces_the_joint_centres(model, hinges, tmp_path):
    ds = run_session(SessionConfig(model=model, motion="exercise", duration_s=0.5, seed=1))
    t = ds.truth
    assert int(t.single_axis.sum()) == hinges  # the CMU knees, elbows...: single hinges
    sk = write_skeleton_mjcf(tmp_path / "skeleton.xml", truth_calibration_dict(ds))
    assert (tmp_path / "skeleton.xml").read_text() == sk.xml
    root = sk.root
    frames = range(0, ds.time_s.size, 5)
    m, anchors, sites = _posed(
        sk, ds.sensors, t.rigid.q_w_s, t.rigid.p_w_s[:, ds.sensors.index(root)], frames
    )
    assert m.nbody == len(ds.sensors) + 1 and m.njnt == len(ds.sensors)
    assert int((m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE).sum()) == hinges
    assert int((m.jnt_type == mujoco.mjtJoint.mjJNT_BALL).sum()) == len(t.child) - hinges
    for k, child in enumerate(t.child):
        # rigid truth: joints exact to rounding; the issue asks 1e-9 m
        assert_allclose(anchors[child], t.joint_w[list(frames), k], rtol=0, atol=1e-9)
    for i, name in enumerate(ds.sensors):  # body frames are sensor frames
        assert_allclose(sites[name], t.rigid.p_w_s[list(frames), i], rtol=0, atol=1e-9)


def test_segment_sites_sit_at_the_segment_frames():
    ds = run_session(SessionConfig(model="humanoid", motion="exercise", duration_s=0.3, seed=2))
    t = ds.truth
    sk = skeleton_mjcf(truth_calibration_dict(ds))
    m = mujoco.MjModel.from_xml_string(sk.xml)
    d = mujoco.MjData(m)
    for name, v in skeleton_qpos(sk, ds.sensors, t.rigid.q_w_s, t.rigid.p_w_s[:, 0]).items():
        adr = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)]
        d.qpos[adr : adr + v.shape[1]] = v[-1]
    mujoco.mj_kinematics(m, d)
    for i, name in enumerate(ds.sensors):
        sid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"segment_{name}")
        assert_allclose(d.site_xpos[sid], t.p_w_b[-1, i], rtol=0, atol=1e-9)
        assert_allclose(d.site_xmat[sid].reshape(3, 3), quat_to_matrix(t.q_w_b[-1, i]), rtol=0, atol=1e-9)


def test_calibration_json_skeleton(tmp_path):
    ds = sb.simulate("linkage", "exercise", duration_s=10.0, seed=3)
    cal = sb.calibrate(ds)
    path = tmp_path / "cal.json"
    write_calibration_json(path, calibration_to_dict(cal))
    doc = read_calibration_json(path)
    sk = skeleton_mjcf(doc)
    assert sk.root == doc["root"]
    names, m = ds.sensors, ds.measured
    frames = list(range(0, ds.time_s.size, 97))
    _, anchors, sites = _posed(sk, names, m.q_w_s, m.p_w_s[:, names.index(sk.root)], frames)
    # the reference: the joint centres chained from the root with the calibration's locations
    R = quat_to_matrix(m.q_w_s[frames])
    p = {sk.root: m.p_w_s[frames, names.index(sk.root)]}
    for j in sk.joints:
        R_p, R_c = R[:, names.index(j.parent)], R[:, names.index(j.child)]
        centre = R_p @ j.joint_in_parent + p[j.parent]
        assert_allclose(anchors[j.child], centre, rtol=0, atol=1e-9)
        p[j.child] = centre - R_c @ j.joint_in_child
        assert_allclose(sites[j.child], p[j.child], rtol=0, atol=1e-9)
        # ideal sensors: the calibration is the truth to well under a micrometre
        k = ds.truth.child.index(j.child)
        assert_allclose(anchors[j.child], ds.truth.joint_w[frames, k], rtol=0, atol=1e-6)


def test_units_and_bad_documents():
    joint = {"parent": "a", "child": "b", "joint_in_parent": [10.0, 0, 0], "joint_in_child": [0, 0, -5.0]}
    sk = skeleton_mjcf({"units": "cm", "root": "a", "joints": [joint]})
    m = mujoco.MjModel.from_xml_string(sk.xml)
    assert_allclose(m.body("b").pos, [0.1, 0.0, 0.05], rtol=0, atol=1e-15)  # cm to m
    assert_allclose(m.jnt_pos[m.joint("b_joint").id], [0.0, 0.0, -0.05], rtol=0, atol=1e-15)
    with pytest.raises(InputError, match='non-empty "joints" list'):
        skeleton_mjcf({"joints": []})
    with pytest.raises(InputError, match=r"children of two: \['b'\]"):
        skeleton_mjcf({"joints": [joint, {**joint, "parent": "c"}]})
    with pytest.raises(InputError, match="Expected one root sensor"):
        skeleton_mjcf({"root": "b", "joints": [joint]})
    with pytest.raises(InputError, match=r"not connected: \['d', 'e'\]"):
        skeleton_mjcf(
            {
                "root": "a",
                "joints": [
                    joint,
                    {**joint, "parent": "d", "child": "e"},
                    {**joint, "parent": "e", "child": "d"},
                ],
            }
        )
    hinge = {**joint, "single_axis": True, "axis_in_parent": [0, 0, 0], "axis_in_child": [0, 1, 0]}
    with pytest.raises(
        InputError, match="axis_in_parent: expected an axis of 3 finite numbers, not all zero"
    ):
        skeleton_mjcf({"joints": [hinge]})
