"""OpenSim joint angles (``.mot``, ``.sto``) drive a session: the humanoid through the mapping table of
OpenSim's gait-model coordinates, any other model through its own joints' names.

The files are written here by hand (small: 40 frames at 60 Hz). The expected poses are built
independently of the reader: rotations composed by hand with scipy about the humanoid's axes (x
forward, y to the left, z up), OpenSim itself posing a model with the gait models' joints (when
the ``opensim`` package is installed), a session's own truth for the exported skeleton.
"""

from __future__ import annotations

import functools
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given
from scipy.spatial.transform import Rotation

import simbench as sb
from calibration.rotations import matrix_to_euler, quat_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.io.dataset import truth_calibration_dict
from simbench.io.opensense import write_opensense_sto
from simbench.io.opensim_motion import read_opensim_motion, read_storage, storage_text
from simbench.io.skeleton_mjcf import skeleton_mjcf, skeleton_qpos
from simbench.io.skeleton_osim import skeleton_osim
from simbench.sim.mjcf import compile_spec, read_spec
from tests.test_fuzz import FIELD_VALUES, PROPERTY, _only_input_errors, mutated

RATE = 60.0
FRAMES = 40
#: simbench's world from OpenSim's ground (x forward, y up, z right), written out.
C = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: The humanoid's axes: forward, to the left, up.
FORWARD, LEFT, UP = np.eye(3)


def _mot(path, columns: dict[str, np.ndarray | float], *, degrees: bool = True, header: str = "") -> str:
    """Write an IK-style ``.mot`` (trailing tabs and all): constant values or ``(FRAMES,)`` series."""
    t = np.arange(FRAMES) / RATE
    values = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (FRAMES,)) for v in columns.values()], 1)
    lines = [
        "Coordinates",
        "version=1",
        f"nRows={FRAMES}",
        f"nColumns={len(columns) + 1}",
        f"inDegrees={'yes' if degrees else 'no'}",
        *([header] if header else []),
        "",
        "Units are S.I. units (second, meters, Newtons, ...)",
        "",
        "endheader",
        "time\t" + "\t".join(columns) + "\t",
    ]
    lines += ["\t".join(f"{x:.10f}" for x in (ti, *row)) + "\t" for ti, row in zip(t, values, strict=True)]
    text = "\n".join(lines) + "\n"
    path.write_text(text)
    return str(path)


def _rot(axis: np.ndarray, deg: float) -> Rotation:
    return Rotation.from_rotvec(np.deg2rad(deg) * np.asarray(axis, dtype=float))


def _angle(R: np.ndarray, expected: Rotation) -> np.ndarray:
    """Angles (rad) between rotation matrices ``(F, 3, 3)`` and one expected rotation."""
    return (expected.inv() * Rotation.from_matrix(R)).magnitude()


def _R(ds, segment: str) -> np.ndarray:
    return quat_to_matrix(ds.truth.q_w_b[:, ds.sensors.index(segment)])


def _p(ds, segment: str) -> np.ndarray:
    return ds.truth.p_w_b[:, ds.sensors.index(segment)]


def _humanoid():
    return compile_spec(read_spec("humanoid"), "humanoid")


def test_hip_flexion_pitches_the_thigh_forward_about_the_lateral_axis(tmp_path):
    ds = sb.simulate(motion=_mot(tmp_path / "hip.mot", {"hip_flexion_r": 30.0}))
    assert ds.meta["model"] == "humanoid" and ds.meta["playback"]["format"] == "opensim"
    assert ds.time_s.size == FRAMES and ds.meta["rate_hz"] == pytest.approx(RATE)
    # the thigh pitched forward 30 deg: a rotation about the humanoid's right (-y)
    assert _angle(_R(ds, "thigh_r"), _rot(-LEFT, 30)).max() < 1e-6
    # the sign: the knee moves forward of the hip, by the thigh's 0.416 m times sin 30 deg
    forward = _p(ds, "shank_r")[:, 0] - _p(ds, "thigh_r")[:, 0]
    assert np.abs(forward - 0.416 * 0.5).max() < 1e-9
    # joints no column moves stay at their reference: the root where it stands, the left leg straight
    np.testing.assert_allclose(_p(ds, "pelvis"), np.tile([0.0, 0.0, 1.05], (FRAMES, 1)), atol=1e-12)
    for segment in ("pelvis", "thigh_l", "chest", "upper_arm_r"):
        assert _angle(_R(ds, segment), Rotation.identity()).max() < 1e-12, segment


def test_knee_flexion_in_both_conventions_swings_the_foot_back(tmp_path):
    gait2392 = sb.simulate(motion=_mot(tmp_path / "g.mot", {"knee_angle_r": -45.0}))
    rajagopal = sb.simulate(
        motion=_mot(tmp_path / "r.mot", {"knee_angle_r": 45.0, "knee_angle_r_beta": 45.0})
    )
    for ds in (gait2392, rajagopal):
        assert _angle(_R(ds, "shank_r"), _rot(LEFT, 45)).max() < 1e-6
        # the ankle behind the knee by the shank's 0.400 m times sin 45 deg
        back = _p(ds, "foot_r")[:, 0] - _p(ds, "shank_r")[:, 0]
        assert np.abs(back + 0.400 * np.sin(np.pi / 4)).max() < 1e-9
    # without Rajagopal's patella column, the sign of the angles says which: flexion past 10 deg
    alone = sb.simulate(motion=_mot(tmp_path / "r2.mot", {"knee_angle_r": 45.0}))
    assert np.abs(alone.truth.q_w_b - rajagopal.truth.q_w_b).max() < 1e-12
    m = _humanoid()
    notes = read_opensim_motion(_mot(tmp_path / "small.mot", {"knee_angle_r": 5.0}), m, "humanoid").notes
    assert any("gait2392's convention (flexion negative), taken" in n for n in notes), notes
    both = _mot(tmp_path / "both.mot", {"knee_angle_r": -30.0, "knee_angle_l": 30.0})
    with pytest.raises(InputError, match=r"knee angles from -30 to 30 deg: neither gait2392's"):
        read_opensim_motion(both, m, "humanoid")


def test_pelvis_and_hips_compose_in_opensims_order(tmp_path):
    columns = {
        "pelvis_tilt": 10.0,
        "pelvis_list": 5.0,
        "pelvis_rotation": 15.0,
        "pelvis_tx": 0.3,
        "pelvis_ty": 0.99,
        "pelvis_tz": -0.2,
        "hip_flexion_r": 30.0,
        "hip_adduction_r": 10.0,
        "hip_rotation_r": 20.0,
        "hip_flexion_l": -15.0,
        "hip_adduction_l": 12.0,
        "hip_rotation_l": -25.0,
    }
    ds = sb.simulate(motion=_mot(tmp_path / "hips.mot", columns))
    # OpenSim's ground_pelvis and hips: about z, then the new x, then the newest y (body-fixed);
    # OpenSim's z is the humanoid's -y, its y the humanoid's z; the left hip's x and y axes negated
    pelvis = _rot(-LEFT, 10) * _rot(FORWARD, 5) * _rot(UP, 15)
    hip_r = _rot(-LEFT, 30) * _rot(FORWARD, 10) * _rot(UP, 20)
    hip_l = _rot(-LEFT, -15) * _rot(-FORWARD, 12) * _rot(-UP, -25)
    assert _angle(_R(ds, "pelvis"), pelvis).max() < 1e-6
    assert _angle(_R(ds, "thigh_r"), pelvis * hip_r).max() < 1e-6
    assert _angle(_R(ds, "thigh_l"), pelvis * hip_l).max() < 1e-6
    # the root: x forward, -z to the left, y up; 0.94 m of OpenSim pelvis height is the humanoid's 1.05
    np.testing.assert_allclose(_p(ds, "pelvis"), np.tile([0.3, 0.2, 1.05 + 0.05], (FRAMES, 1)), atol=1e-9)
    # adduction moves the right knee towards the midline (+y) and the left one too (-y), relative to
    # the pelvis; internal rotation turns the right foot's toes in
    R_p = _R(ds, "pelvis")
    for side, medial in (("r", 1.0), ("l", -1.0)):
        knee_in_pelvis = np.einsum("fji,fj->fi", R_p, _p(ds, f"shank_{side}") - _p(ds, f"thigh_{side}"))
        assert np.all(medial * knee_in_pelvis[:, 1] > 0.05), side
    # radians say the same (written to 10 decimals: 5e-11 rad of rounding)
    metres = ("pelvis_tx", "pelvis_ty", "pelvis_tz")
    radians = {k: (v if k in metres else np.deg2rad(v)) for k, v in columns.items()}
    same = sb.simulate(motion=_mot(tmp_path / "hips_rad.mot", radians, degrees=False))
    assert np.abs(same.truth.q_w_b - ds.truth.q_w_b).max() < 1e-9
    assert np.abs(same.truth.p_w_b - ds.truth.p_w_b).max() < 1e-9


def test_the_arm_elbow_and_wrist_follow_the_models_axes(tmp_path):
    columns = {
        "arm_flex_r": 40.0,
        "arm_add_r": -30.0,
        "arm_rot_r": 10.0,
        "elbow_flex_r": 90.0,
        "pro_sup_r": 60.0,
        "wrist_flex_r": 20.0,
        "wrist_dev_r": 10.0,
        "ankle_angle_l": 15.0,
        "lumbar_extension": -10.0,
        "lumbar_bending": 5.0,
        "lumbar_rotation": 8.0,
    }
    ds = sb.simulate(motion=_mot(tmp_path / "arm.mot", columns))
    elbow_axis = C @ np.array([0.22604696, 0.022269, 0.97386183])  # the humero-ulnar axis, OpenSim's
    pro_sup_axis = C @ np.array([0.05639803, 0.99840646, 0.001952])
    pro_sup_axis /= np.linalg.norm(pro_sup_axis)
    ankle_axis = C @ np.array([0.10501355, 0.17402245, 0.97912632])  # the left talocrural axis
    trunk = _rot(-LEFT, -10) * _rot(FORWARD, 5) * _rot(UP, 8)
    arm = trunk * _rot(-LEFT, 40) * _rot(FORWARD, -30) * _rot(UP, 10)
    forearm = arm * _rot(elbow_axis / np.linalg.norm(elbow_axis), 90) * _rot(pro_sup_axis, 60)
    hand = forearm * _rot(-LEFT, 20) * _rot(FORWARD, 10)
    for segment, expected in (
        ("chest", trunk),
        ("upper_arm_r", arm),
        ("forearm_r", forearm),
        ("hand_r", hand),
    ):
        assert _angle(_R(ds, segment), expected).max() < 1e-6, segment
    assert _angle(_R(ds, "foot_l"), _rot(ankle_axis / np.linalg.norm(ankle_axis), 15)).max() < 1e-6
    # the sign: abduction (arm_add < 0) lifts the right arm out to the right (-y); dorsiflexion lifts
    # the toes (the foot's forward axis up)
    elbow = _p(ds, "forearm_r") - _p(ds, "upper_arm_r")
    elbow_in_chest = np.einsum("fji,fj->fi", _R(ds, "chest"), elbow)
    assert np.all(elbow_in_chest[:, 1] < -0.1)
    assert np.all(_R(ds, "foot_l")[:, 2, 0] > 0.2)


#: A model with the gait models' joints, for OpenSim to pose: ``(joint, parent, child, [(coordinate,
#: axis, coefficient)])``; the axes as gait2392, Hamner and Rajagopal have them (Rajagopal's left hip
#: turns about +x, +y with a coefficient of -1).
X, Y, Z = "1 0 0", "0 1 0", "0 0 1"
GAIT_JOINTS = [
    (
        "ground_pelvis",
        "ground",
        "pelvis",
        [("pelvis_tilt", Z, 1), ("pelvis_list", X, 1), ("pelvis_rotation", Y, 1)],
    ),
    (
        "hip_r",
        "pelvis",
        "femur_r",
        [("hip_flexion_r", Z, 1), ("hip_adduction_r", X, 1), ("hip_rotation_r", Y, 1)],
    ),
    (
        "hip_l",
        "pelvis",
        "femur_l",
        [("hip_flexion_l", Z, 1), ("hip_adduction_l", X, -1), ("hip_rotation_l", Y, -1)],
    ),
    ("knee_r", "femur_r", "tibia_r", [("knee_angle_r", Z, 1)]),
    ("knee_l", "femur_l", "tibia_l", [("knee_angle_l", Z, 1)]),
    ("ankle_r", "tibia_r", "talus_r", [("ankle_angle_r", "-0.10501355 -0.17402245 0.97912632", 1)]),
    ("ankle_l", "tibia_l", "talus_l", [("ankle_angle_l", "0.10501355 0.17402245 0.97912632", 1)]),
    (
        "back",
        "pelvis",
        "torso",
        [("lumbar_extension", Z, 1), ("lumbar_bending", X, 1), ("lumbar_rotation", Y, 1)],
    ),
    ("acromial_r", "torso", "humerus_r", [("arm_flex_r", Z, 1), ("arm_add_r", X, 1), ("arm_rot_r", Y, 1)]),
    (
        "acromial_l",
        "torso",
        "humerus_l",
        [("arm_flex_l", Z, 1), ("arm_add_l", "-1 0 0", 1), ("arm_rot_l", "0 -1 0", 1)],
    ),
    ("elbow_r", "humerus_r", "ulna_r", [("elbow_flex_r", "0.22604696 0.022269 0.97386183", 1)]),
    ("elbow_l", "humerus_l", "ulna_l", [("elbow_flex_l", "-0.22604696 -0.022269 0.97386183", 1)]),
    ("radioulnar_r", "ulna_r", "radius_r", [("pro_sup_r", "0.05639803 0.99840646 0.001952", 1)]),
    ("radioulnar_l", "ulna_l", "radius_l", [("pro_sup_l", "-0.05639803 -0.99840646 0.001952", 1)]),
    ("radius_hand_r", "radius_r", "hand_r", [("wrist_flex_r", Z, 1), ("wrist_dev_r", X, 1)]),
    ("radius_hand_l", "radius_l", "hand_l", [("wrist_flex_l", Z, 1), ("wrist_dev_l", "-1 0 0", 1)]),
]
#: The humanoid's segment each OpenSim body is.
SEGMENT = {
    "pelvis": "pelvis", "femur_r": "thigh_r", "femur_l": "thigh_l", "tibia_r": "shank_r",
    "tibia_l": "shank_l", "talus_r": "foot_r", "talus_l": "foot_l", "torso": "chest",
    "humerus_r": "upper_arm_r", "humerus_l": "upper_arm_l", "radius_r": "forearm_r",
    "radius_l": "forearm_l", "hand_r": "hand_r", "hand_l": "hand_l",
}  # fmt: skip


def _gait_osim() -> str:
    """The ``.osim`` of :data:`GAIT_JOINTS`: OpenSim 4 ``CustomJoint``s, nominal masses."""
    doc = ET.Element("OpenSimDocument", Version="40000")
    model = ET.SubElement(doc, "Model", name="gait_joints")
    bodies = ET.SubElement(ET.SubElement(model, "BodySet", name="bodyset"), "objects")
    for child in [j[2] for j in GAIT_JOINTS]:
        body = ET.SubElement(bodies, "Body", name=child)
        ET.SubElement(body, "mass").text = "1"
        ET.SubElement(body, "inertia").text = "0.01 0.01 0.01 0 0 0"
    joints = ET.SubElement(ET.SubElement(model, "JointSet", name="jointset"), "objects")
    for name, parent, child, coords in GAIT_JOINTS:
        joint = ET.SubElement(joints, "CustomJoint", name=name)
        ET.SubElement(joint, "socket_parent_frame").text = f"{parent}_{name}"
        ET.SubElement(joint, "socket_child_frame").text = f"{child}_{name}"
        box = ET.SubElement(joint, "coordinates")
        names = [c for c, _, _ in coords] + (
            ["pelvis_tx", "pelvis_ty", "pelvis_tz"] if parent == "ground" else []
        )
        for c in names:
            ET.SubElement(ET.SubElement(box, "Coordinate", name=c), "range").text = "-10 10"
        frames = ET.SubElement(joint, "frames")
        for frame, body in ((f"{parent}_{name}", parent), (f"{child}_{name}", child)):
            f = ET.SubElement(frames, "PhysicalOffsetFrame", name=frame)
            ET.SubElement(f, "socket_parent").text = "/ground" if body == "ground" else f"/bodyset/{body}"
        st = ET.SubElement(joint, "SpatialTransform")
        # a joint of fewer than three rotations: constant ones about principal axes away from its own
        others = [a for a in (X, Y, Z) if all(abs(_vec(a) @ _vec(b)) < 0.5 for _, b, _ in coords)]
        axes = coords + [("", a, 0) for a in others][: 3 - len(coords)]
        trans = [("pelvis_tx", X, 1), ("pelvis_ty", Y, 1), ("pelvis_tz", Z, 1)]
        if parent != "ground":
            trans = [("", a, 0) for _, a, _ in trans]
        for k, (c, a, coefficient) in enumerate(axes + trans):
            axis = ET.SubElement(
                st, "TransformAxis", name=f"{'rotation' if k < 3 else 'translation'}{k % 3 + 1}"
            )
            ET.SubElement(axis, "coordinates").text = c
            ET.SubElement(axis, "axis").text = a
            function = ET.SubElement(axis, "function")
            if c:
                ET.SubElement(
                    ET.SubElement(function, "LinearFunction"), "coefficients"
                ).text = f"{coefficient} 0"
            else:
                ET.SubElement(ET.SubElement(function, "Constant"), "value").text = "0"
    return ET.tostring(doc, encoding="unicode")


def _vec(text: str) -> np.ndarray:
    return np.array([float(x) for x in text.split()])


def test_the_humanoid_turns_as_opensim_poses_the_gait_models_joints(tmp_path):
    osim = pytest.importorskip("opensim")
    rng = np.random.default_rng(7)
    coords = [c for _, _, _, cs in GAIT_JOINTS for c, _, _ in cs]
    values = {c: float(rng.uniform(-0.6, 0.6)) for c in coords}
    values["knee_angle_r"], values["knee_angle_l"] = -1.1, -0.4  # gait2392's flexion
    values |= {"pelvis_tx": 0.7, "pelvis_ty": 0.9, "pelvis_tz": -0.3}
    path = tmp_path / "gait_joints.osim"
    path.write_text(_gait_osim())
    model = osim.Model(str(path))
    state = model.initSystem()
    for c, v in values.items():
        coordinate = model.getCoordinateSet().get(c)
        coordinate.setLocked(state, False)
        coordinate.setValue(state, v, False)
    model.realizePosition(state)
    # the file: written by OpenSim itself (its STOFileAdapter: a version 3 header, no nRows)
    table = osim.TimeSeriesTable()
    table.setColumnLabels(list(values))
    for t in np.arange(FRAMES) / RATE:
        table.appendRow(float(t), osim.RowVector(list(values.values())))
    table.addTableMetaDataString("inDegrees", "no")
    mot = str(tmp_path / "written_by_opensim.sto")
    osim.STOFileAdapter.write(table, mot)
    assert read_storage(mot).header["DataType"] == "double"
    ds = sb.simulate(motion=mot)
    for body, segment in SEGMENT.items():
        frame = model.getBodySet().get(body).getTransformInGround(state)
        R_o = np.array([[frame.R().get(i, j) for j in range(3)] for i in range(3)])
        assert _angle(_R(ds, segment), Rotation.from_matrix(C @ R_o @ C.T)).max() < 1e-6, segment
    pelvis = model.getBodySet().get("pelvis").getPositionInGround(state)
    p_o = np.array([pelvis.get(i) for i in range(3)])
    np.testing.assert_allclose(_p(ds, "pelvis")[0], C @ p_o + [0, 0, 1.05 - 0.94], atol=1e-9)


def test_skipped_and_state_columns_and_the_female_variant(tmp_path):
    columns = {
        "/jointset/hip_r/hip_flexion_r/value": 0.5,
        "/jointset/hip_r/hip_flexion_r/speed": 0.0,
        "/forceset/soleus_r/activation": 0.2,
        "subtalar_angle_r": 0.1,
        "mtp_angle_l": 0.2,
        "pelvis_ty": 0.94,
    }
    path = _mot(tmp_path / "states.sto", columns, degrees=False)
    rec = read_opensim_motion(path, _humanoid(), "humanoid")
    assert set(rec.joints) == {"root", "hip_r"} and rec.format == "opensim"
    notes = " ".join(rec.notes)
    assert "subtalar_angle_r (the humanoid's foot is one body)" in notes and "mtp_angle_l" in notes
    assert "state columns that are not coordinate values skipped: 2" in notes
    female = sb.simulate("humanoid-female", path)
    height = compile_spec(read_spec("humanoid-female"), "humanoid-female").qpos0[2]
    assert height < 1.04
    np.testing.assert_allclose(_p(female, "pelvis")[:, 2], height, atol=1e-12)
    assert _angle(_R(female, "thigh_r"), Rotation.from_rotvec(-0.5 * LEFT)).max() < 1e-9


def test_the_exported_skeletons_coordinates_play_on_its_mjcf(tmp_path):
    """A session's truth as the exported skeleton (MJCF and ``.osim``): its joint values as the
    ``.osim``'s coordinates play on the MJCF, and the sensors move as in the session."""
    session = sb.simulate("linkage", "exercise", duration_s=1.0, seed=2)
    doc = truth_calibration_dict(session)
    sk = skeleton_mjcf(doc)
    xml = tmp_path / "skeleton.xml"
    xml.write_text(sk.xml)
    t, names = session.truth, session.sensors
    root = names.index(sk.root)
    values = skeleton_qpos(sk, names, t.rigid.q_w_s, t.rigid.p_w_s[:, root])
    columns = {}  # rotations in degrees (inDegrees=yes), translations in metres
    euler = matrix_to_euler("XYZ", quat_to_matrix(t.rigid.q_w_s[:, root]), degrees=True)
    columns |= {f"root_r{a}": euler[:, i] for i, a in enumerate("xyz")}
    columns |= {f"root_t{a}": t.rigid.p_w_s[:, root, i] for i, a in enumerate("xyz")}
    for j in sk.joints:
        v = values[f"{j.child}_joint"]
        if j.kind == "ball":  # OpenSim's BallJoint: body-fixed X-Y-Z angles
            angles = matrix_to_euler("XYZ", quat_to_matrix(v), degrees=True)
            columns |= {f"{j.child}_r{a}": angles[:, i] for i, a in enumerate("xyz")}
        else:
            columns[f"{j.child}_angle"] = np.rad2deg(v[:, 0])
    osim_names = {c.get("name") for c in ET.fromstring(skeleton_osim(doc)).iter("Coordinate")}
    assert set(columns) == osim_names  # the export's own coordinate names
    labels = list(columns)
    table = np.stack([columns[c] for c in labels], 1)
    mot = tmp_path / "skeleton_ik.mot"
    mot.write_text(storage_text(labels, session.time_s, table, in_degrees=True))
    ds = sb.simulate(str(xml), str(mot))
    assert ds.sensors == names
    assert np.abs(quat_to_matrix(ds.truth.rigid.q_w_s) - quat_to_matrix(t.rigid.q_w_s)).max() < 1e-9
    assert np.abs(ds.truth.rigid.p_w_s - t.rigid.p_w_s).max() < 1e-9


MJCF_HINGE_SLIDE = """<mujoco><worldbody><body name="base"><joint name="slider" type="slide" axis="1 0 0"/>
<geom size="0.05"/><site name="sensor_base"/><body name="arm" pos="0 0 0.3">
<joint name="elbow_joint" type="hinge" axis="0 1 0"/><geom size="0.04"/><site name="sensor_arm"/>
</body></body></worldbody></mujoco>"""


def test_another_model_takes_its_own_joint_names(tmp_path):
    xml = tmp_path / "two.xml"
    xml.write_text(MJCF_HINGE_SLIDE)
    m = compile_spec(read_spec(str(xml)), "two")
    mot = _mot(tmp_path / "two.mot", {"slider": 0.25, "elbow_angle": 30.0})  # degrees: the hinge only
    rec = read_opensim_motion(mot, m, "two")
    tracks = {t.joint: t.values for t in rec.tracks}
    np.testing.assert_allclose(tracks["slider"], 0.25, atol=0)
    np.testing.assert_allclose(tracks["elbow_joint"], np.deg2rad(30.0), atol=1e-15)
    gait = _mot(tmp_path / "gait.mot", {"hip_flexion_r": 30.0})
    with pytest.raises(
        InputError, match=r"'hip_flexion_r' is a coordinate of OpenSim's gait models: they map onto humanoid"
    ):
        sb.simulate("linkage", gait)
    linkage = compile_spec(read_spec("linkage"), "linkage")
    part = _mot(tmp_path / "part.mot", {"neck_rx": 3.0})
    with pytest.raises(
        InputError, match=r"ball joint 'neck' needs coordinates \['neck_rx', 'neck_ry', 'neck_rz'\]"
    ):
        read_opensim_motion(part, linkage, "linkage")


#: Bad files: an edit of a good one (lines 1-9 the header, 10 the labels, 11-50 the rows) and the
#: error's text after the file's name.
BAD_FILES = {
    "no endheader": (
        lambda ls: [x for x in ls if x != "endheader"],
        r": not an OpenSim storage file: no line 'endheader'",
    ),
    "field count": (
        lambda ls: [*ls[:11], "0.2\t1.0", *ls[12:]],
        r", line 12: 2 fields; the column labels \(line 10\) name 3",
    ),
    "NaN": (
        lambda ls: [*ls[:12], ls[12].replace("30.0000000000", "NaN"), *ls[13:]],
        r", line 13, column 'hip_flexion_r': 'NaN' is not a finite number",
    ),
    "not a number": (
        lambda ls: [*ls[:12], ls[12].replace("30.0000000000", "3O"), *ls[13:]],
        r", line 13, column 'hip_flexion_r': '3O' is not a number",
    ),
    "unknown": (
        lambda ls: [*ls[:9], ls[9].replace("knee_angle_r", "knee_flexion_r"), *ls[10:]],
        r", line 10: column\(s\) \['knee_flexion_r'\] name no coordinate of the mapping table onto the hum",
    ),
    "nRows": (lambda ls: [*ls[:2], "nRows=41", *ls[3:]], r", line 3: nRows=41, but the table has 40 rows"),
    "nColumns": (
        lambda ls: [*ls[:3], "nColumns=4", *ls[4:]],
        r", line 4: nColumns=4, but the table has 3 columns",
    ),
    "no time": (
        lambda ls: [*ls[:9], ls[9].replace("time", "t"), *ls[10:]],
        r", line 10: expected the first column 'time', got 't'",
    ),
    "irregular": (
        lambda ls: [*ls[:20], "0.1750000000" + ls[20][12:], *ls[21:]],
        r", line 21: time 0.175 s is off the recording's frame grid",
    ),
    "time back": (
        lambda ls: [*ls[:20], "0.1500000000" + ls[20][12:], *ls[21:]],
        r", line 21: time 0.15 s does not follow 0.15 s",
    ),
    "inDegrees": (
        lambda ls: [*ls[:4], "inDegrees=maybe", *ls[5:]],
        r", line 5: inDegrees='maybe'; expected yes or no",
    ),
    "half a turn": (
        lambda ls: [*ls[:4], "inDegrees=no", *ls[5:]],
        r", line 11, column 'hip_flexion_r': 30 rad is beyond half a turn.*say inDegrees=yes\)$",
    ),
}


@pytest.mark.parametrize("case", list(BAD_FILES))
def test_bad_files_are_one_line_errors_naming_file_and_line(tmp_path, case):
    edit, message = BAD_FILES[case]
    good = tmp_path / "good.mot"
    _mot(good, {"hip_flexion_r": 30.0, "knee_angle_r": -20.0})
    read_opensim_motion(str(good), _humanoid(), "humanoid")  # the edit, not the file, is wrong
    bad = tmp_path / "bad.mot"
    bad.write_text("\n".join(edit(good.read_text().splitlines())) + "\n")
    with pytest.raises(InputError) as err:
        read_opensim_motion(str(bad), _humanoid(), "humanoid")
    text = str(err.value)
    assert "\n" not in text and re.match(re.escape(str(bad)) + message, text), text


def test_an_opensense_export_is_orientations_not_coordinates(tmp_path):
    sto = tmp_path / "orientations.sto"
    write_opensense_sto(sto, ["pelvis"], np.arange(3) / RATE, np.tile([1.0, 0, 0, 0], (3, 1, 1)))
    with pytest.raises(InputError, match=r"line 2: DataType=Quaternion \(OpenSense's sensor orientations"):
        sb.simulate(motion=str(sto))


def test_cli_simulate_motion_mot_writes_a_dataset(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    t = np.arange(FRAMES) / RATE
    walk = {
        "pelvis_tx": 1.2 * t,
        "pelvis_ty": 0.94 + 0.02 * np.sin(4 * np.pi * t),
        "hip_flexion_r": 25 * np.sin(2 * np.pi * t),
        "hip_flexion_l": -25 * np.sin(2 * np.pi * t),
        "knee_angle_r": -30 - 25 * np.cos(2 * np.pi * t),
        "knee_angle_l": -30 + 25 * np.cos(2 * np.pi * t),
        "arm_flex_r": -20 * np.sin(2 * np.pi * t),
        "elbow_flex_r": 30.0,
    }
    _mot(tmp_path / "walk.mot", walk)
    assert main(["simulate", "--motion", "walk.mot", "-o", "out.h5"]) == 0
    out = capsys.readouterr().out
    assert "model humanoid, motion opensim:walk.mot" in out, out
    ds = sb.read_dataset(tmp_path / "out.h5")
    assert ds.time_s.size == FRAMES and ds.meta["playback"]["format"] == "opensim"
    np.testing.assert_allclose(_p(ds, "pelvis")[:, 0], 1.2 * t, atol=1e-9)
    code = main(["simulate", "--motion", "walk.mot", "--model", "linkage", "-o", "x.h5"])
    assert code != 0 and "map onto humanoid" in capsys.readouterr().err


SMALL_MOT = """Coordinates
version=1
nRows=4
nColumns=5
inDegrees=yes
endheader
time\tpelvis_ty\thip_flexion_r\tknee_angle_r\tsubtalar_angle_r
0.00\t0.94\t10.0\t-20.0\t1.0
0.01\t0.95\t11.0\t-21.0\t1.0
0.02\t0.96\t12.0\t-22.0\t1.0
0.03\t0.97\t13.0\t-23.0\t1.0
"""


@PROPERTY
@given(data=mutated(SMALL_MOT, separator="\t", values=FIELD_VALUES))
def test_mutated_files_give_a_motion_or_name_the_file(tmp_path_factory, data: bytes) -> None:
    path = tmp_path_factory.mktemp("mot") / "motion.mot"
    path.write_bytes(data)
    got = _only_input_errors(path, lambda: read_opensim_motion(path, _humanoid_model(), "humanoid"))
    if got is not None:
        assert got.frame_time_s > 0 and got.valid.shape == (got.n_frames,)
        for track in got.tracks:
            assert np.isfinite(track.values).all()
            q = track.quaternion_columns
            np.testing.assert_allclose(np.linalg.norm(track.values[:, q], axis=1), 1.0, atol=1e-9)


@functools.cache
def _humanoid_model():
    return _humanoid()
