"""Reading a calibration JSON back (what ``simbench report --calibration`` reads)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from simbench.errors import InputError
from simbench.io.calibration_json import calibration_joints, read_calibration_json

JOINTS = [
    {"parent": "pelvis", "child": "thigh_l", "joint_in_parent": [0.1, 0.0, -0.05],
     "joint_in_child": [0.0, 0.0, 0.2], "rms_residual": 0.001, "single_axis": False,
     "axis_in_parent": None, "axis_in_child": None},
    {"parent": "thigh_l", "child": "shank_l", "joint_in_parent": [0, 0, -0.2],
     "joint_in_child": [0.0, 0.01, 0.21], "rms_residual": 0.002, "single_axis": True,
     "axis_in_parent": [1.0, 0.0, 0.0], "axis_in_child": [1.0, 0.0, 0.0]},
]  # fmt: skip


def write(tmp_path, doc, name="cal.json"):
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc), encoding="utf-8")
    return path


def test_reads_joints_into_arrays_indexed_by_the_recording(tmp_path):
    doc = read_calibration_json(write(tmp_path, {"units": "m", "root": "pelvis", "joints": JOINTS}))
    joints = calibration_joints(doc, ["shank_l", "pelvis", "thigh_l"])
    assert joints.parent == ("pelvis", "thigh_l") and joints.child == ("thigh_l", "shank_l")
    np.testing.assert_array_equal(joints.parent_index, [1, 2])
    np.testing.assert_array_equal(joints.child_index, [2, 0])
    np.testing.assert_array_equal(joints.joint_in_parent, [[0.1, 0.0, -0.05], [0.0, 0.0, -0.2]])
    np.testing.assert_array_equal(joints.joint_in_child, [[0.0, 0.0, 0.2], [0.0, 0.01, 0.21]])
    np.testing.assert_array_equal(joints.single_axis, [False, True])
    assert joints.parent_of == {"thigh_l": "pelvis", "shank_l": "thigh_l"}


def test_no_joints_gives_empty_arrays(tmp_path):
    joints = calibration_joints(read_calibration_json(write(tmp_path, {"joints": []})), ["a"])
    assert joints.joint_in_parent.shape == (0, 3) and joints.parent_index.shape == (0,)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(InputError, match=r"missing\.json: cannot read: No such file"):
        read_calibration_json(tmp_path / "missing.json")


def test_not_json_names_file_and_line(tmp_path):
    path = write(tmp_path, '{"joints": [\n  {"parent": }\n]}')
    with pytest.raises(InputError, match=r"cal\.json, line 2: not a calibration JSON: not valid JSON"):
        read_calibration_json(path)


@pytest.mark.parametrize("doc", [{}, [], {"joints": {"parent": "a"}}, "3"])
def test_missing_joints_list(tmp_path, doc):
    message = r'cal\.json: not a calibration JSON: expected an object with a "joints" list'
    with pytest.raises(InputError, match=message):
        read_calibration_json(write(tmp_path, doc))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"child": None}, r"joints\[1\] has no sensor name 'child'"),
        ({"parent": 3}, r"joints\[1\] has no sensor name 'parent'"),
        ({"joint_in_parent": [0.0, 0.1]}, r"joints\[1\]: expected 'joint_in_parent' to be a list of 3"),
        ({"joint_in_child": [0, "x", 0]}, r"joints\[1\]: expected 'joint_in_child' to be a list of 3"),
        ({"joint_in_child": None}, r"joints\[1\]: expected 'joint_in_child' to be .* numbers, got None"),
        ({"single_axis": "yes"}, r"joints\[1\]: expected 'single_axis' to be true or false"),
    ],
)
def test_malformed_joint_is_named(tmp_path, change, message):
    doc = {"joints": [JOINTS[0], {**JOINTS[1], **change}]}
    with pytest.raises(InputError, match=r"cal\.json: not a calibration JSON: " + message):
        read_calibration_json(write(tmp_path, doc))


def test_joint_that_is_not_an_object(tmp_path):
    with pytest.raises(InputError, match=r"joints\[0\] is not an object"):
        read_calibration_json(write(tmp_path, {"joints": [["pelvis", "thigh_l"]]}))


def test_unknown_sensors_are_named(tmp_path):
    path = write(tmp_path, {"joints": JOINTS})
    with pytest.raises(InputError, match=r"cal\.json: names sensors the data lacks: \['shank_l'\]"):
        calibration_joints(read_calibration_json(path), ["pelvis", "thigh_l"], source=path)
