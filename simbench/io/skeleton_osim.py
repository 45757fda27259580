"""A calibration as an OpenSim model (``.osim``), the same skeleton as the MJCF export.

The bodies, joint centres, joint kinds and reference pose are those of
:mod:`simbench.io.skeleton_mjcf` (:func:`~simbench.io.skeleton_mjcf.skeleton_joints`): one body per
sensor whose frame is the sensor's frame, a ``FreeJoint`` ``root`` from ground to the root sensor,
and per joint a ``BallJoint``, or a ``PinJoint`` for a single-axis joint, between offset frames at
the joint centre on the parent (``joint_in_parent``) and on the child (``joint_in_child``):

- ball: both offset frames parallel to their body's, so all coordinates zero is the reference pose
  (the child's frame parallel to the parent's);
- pin: OpenSim turns a ``PinJoint`` about its frames' common z axis; the child's offset frame has
  its z along ``axis_in_child`` (the smallest rotation from z), the parent's is that frame turned
  by ``R0`` (the smallest rotation taking ``axis_in_child`` to ``axis_in_parent``), so the
  coordinate is the MJCF hinge's angle.

Ground is simbench's world: z up, gravity ``0 0 -9.81`` (OpenSim's models are y up; this one is
not: drive it with a z-up TRC, ``simbench export --trc``). Masses are nominal (1 kg, 0.01 kg m^2):
the model is for kinematics. Offset-frame orientations are OpenSim's body-fixed X-Y-Z angles,
radians. Optical markers given (``markers``: label, body, location in that body's frame) become its
``MarkerSet``, so that the exported TRC drives OpenSim's marker inverse kinematics.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from calibration.rotations import matrix_to_euler, quat_to_matrix
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text
from simbench.io.skeleton_mjcf import SkeletonJoint, rotation_between, skeleton_joints

#: ``<OpenSimDocument Version=...>`` of OpenSim 4.
DOCUMENT_VERSION = "40000"


def _v(v: Any) -> str:
    return " ".join(repr(float(x)) for x in np.asarray(v, dtype=float).ravel())


def _offset_frame(name: str, parent: str, translation: np.ndarray, R: np.ndarray) -> ET.Element:
    frame = ET.Element("PhysicalOffsetFrame", name=name)
    ET.SubElement(frame, "socket_parent").text = parent
    ET.SubElement(frame, "translation").text = _v(translation)
    ET.SubElement(frame, "orientation").text = _v(matrix_to_euler("XYZ", R, degrees=False))
    return frame


def _coordinates(joint: ET.Element, names: list[str], translational: set[str]) -> None:
    box = ET.SubElement(joint, "coordinates")
    for name in names:
        c = ET.SubElement(box, "Coordinate", name=name)
        ET.SubElement(c, "default_value").text = "0"
        limit = "10" if name in translational else "6.2831853071795862"
        ET.SubElement(c, "range").text = f"-{limit} {limit}"
        ET.SubElement(c, "clamped").text = "false"


def _joint_element(j: SkeletonJoint) -> ET.Element:
    if j.kind == "ball":
        R_parent_frame = R_child_frame = np.eye(3)
        element = ET.Element("BallJoint", name=f"{j.child}_joint")
        names = [f"{j.child}_rx", f"{j.child}_ry", f"{j.child}_rz"]
    else:
        R_child_frame = quat_to_matrix(rotation_between(np.array([0.0, 0.0, 1.0]), j.axis_in_child))
        R_parent_frame = quat_to_matrix(j.q0) @ R_child_frame
        element = ET.Element("PinJoint", name=f"{j.child}_joint")
        names = [f"{j.child}_angle"]
    ET.SubElement(element, "socket_parent_frame").text = f"{j.parent}_{j.child}_offset"
    ET.SubElement(element, "socket_child_frame").text = f"{j.child}_offset"
    _coordinates(element, names, set())
    frames = ET.SubElement(element, "frames")
    frames.append(
        _offset_frame(
            f"{j.parent}_{j.child}_offset", f"/bodyset/{j.parent}", j.joint_in_parent, R_parent_frame
        )
    )
    frames.append(_offset_frame(f"{j.child}_offset", f"/bodyset/{j.child}", j.joint_in_child, R_child_frame))
    return element


def skeleton_osim(
    doc: Mapping[str, Any],
    *,
    model_name: str = "calibrated_skeleton",
    markers: Sequence[tuple[str, str, np.ndarray]] = (),
) -> str:
    """The OpenSim model (``.osim`` XML text) of a calibration document (module docstring).

    Args:
        doc: the calibration document (``simbench calibrate --json``, or a dataset's truth).
        model_name: the model's name.
        markers: ``(label, body, (3,) location)`` of optical markers: the body a sensor name of
            the skeleton, the location in its (sensor) frame, metres; a marker on another body is
            refused.

    Raises:
        InputError: a document that is not a tree of joints
            (:func:`~simbench.io.skeleton_mjcf.skeleton_joints`).
    """
    root, joints = skeleton_joints(doc)
    document = ET.Element("OpenSimDocument", Version=DOCUMENT_VERSION)
    model = ET.SubElement(document, "Model", name=model_name)
    ET.SubElement(model, "gravity").text = "0 0 -9.81"
    ET.SubElement(model, "length_units").text = "meters"
    ET.SubElement(model, "force_units").text = "N"
    bodyset = ET.SubElement(ET.SubElement(model, "BodySet", name="bodyset"), "objects")
    for name in (root, *(j.child for j in joints)):
        body = ET.SubElement(bodyset, "Body", name=name)
        ET.SubElement(body, "mass").text = "1"
        ET.SubElement(body, "mass_center").text = "0 0 0"
        ET.SubElement(body, "inertia").text = "0.01 0.01 0.01 0 0 0"
    jointset = ET.SubElement(ET.SubElement(model, "JointSet", name="jointset"), "objects")
    free = ET.SubElement(jointset, "FreeJoint", name="root")
    ET.SubElement(free, "socket_parent_frame").text = "ground_offset"
    ET.SubElement(free, "socket_child_frame").text = f"{root}_offset"
    translations = {"root_tx", "root_ty", "root_tz"}
    _coordinates(free, ["root_rx", "root_ry", "root_rz", "root_tx", "root_ty", "root_tz"], translations)
    frames = ET.SubElement(free, "frames")
    frames.append(_offset_frame("ground_offset", "/ground", np.zeros(3), np.eye(3)))
    frames.append(_offset_frame(f"{root}_offset", f"/bodyset/{root}", np.zeros(3), np.eye(3)))
    for j in joints:
        jointset.append(_joint_element(j))
    bodies = {root, *(j.child for j in joints)}
    if markers:
        markerset = ET.SubElement(ET.SubElement(model, "MarkerSet", name="markerset"), "objects")
        for label, body, location in markers:
            if body not in bodies:
                raise InputError(
                    f"marker {label!r} is on {body!r}, not a body of the skeleton ({sorted(bodies)})"
                )
            marker = ET.SubElement(markerset, "Marker", name=label)
            ET.SubElement(marker, "socket_parent_frame").text = f"/bodyset/{body}"
            ET.SubElement(marker, "location").text = _v(location)
            ET.SubElement(marker, "fixed").text = "false"
    ET.indent(document)
    return '<?xml version="1.0" encoding="UTF-8" ?>\n' + ET.tostring(document, encoding="unicode") + "\n"


def write_skeleton_osim(path: str | os.PathLike[str], doc: Mapping[str, Any]) -> None:
    """Write the OpenSim model of a calibration document atomically."""
    atomic_write_text(path, skeleton_osim(doc))


__all__ = ["DOCUMENT_VERSION", "skeleton_osim", "write_skeleton_osim"]
