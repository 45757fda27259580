"""A calibration as a skeleton model: an MJCF file MuJoCo loads.

Built from a calibration document -- a calibration JSON (:func:`simbench.io.calibration_json.
read_calibration_json`, ``simbench calibrate --json``) or a session's truth in the same schema
(:func:`simbench.io.dataset.truth_calibration_dict`):

- one body per sensor, in the calibrated hierarchy (the root first, each child inside its parent);
  **a body's frame is its sensor's frame**, the only frame a calibration knows, so the model's
  body poses are the sensors' poses;
- the root body has a free joint (``root``); every other body joins its parent at the calibrated
  joint centre by a ``ball`` joint, or a ``hinge`` about ``axis_in_child`` when the calibration
  found a single-axis joint (and gives its axis in both frames);
- a child body sits where the joint centres coincide: at the reference pose (``qpos0``) its frame
  is turned from its parent's by ``R0`` (the identity for a ball joint; for a hinge the smallest
  rotation taking ``axis_in_child`` to ``axis_in_parent``) and placed at
  ``joint_in_parent - R0 @ joint_in_child`` (in the parent's frame);
- sites: ``sensor_<name>`` at each body's origin (the sensor: simbench's site convention),
  ``joint_<child>`` at each joint centre, and, for a truth document with ``sensor_placement``,
  ``segment_<name>`` at the segment (body) frame the sensor was placed in;
- geoms for a picture and for mass: capsules from a body's joint centre to its children's, a small
  box at the sensor.

Lengths are converted from the document's ``units`` to metres. :func:`skeleton_qpos` gives the
joint values that pose the model from sensor orientations (its joint centres then follow the
calibration exactly).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.rotations import matrix_to_quat, matrix_to_rotvec, quat_to_matrix
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text
from simbench.units import metres_per_unit

#: Radius of the bone capsules and half-size of the sensor boxes, m.
BONE_RADIUS_M = 0.015
SENSOR_HALF_M = (0.02, 0.015, 0.008)


@dataclass(frozen=True)
class SkeletonJoint:
    """One joint of the skeleton model, in metres.

    Attributes:
        parent, child: sensor (body) names.
        kind: ``"ball"`` or ``"hinge"``.
        joint_in_parent, joint_in_child: ``(3,)`` the centre in the parent's and the child's frame.
        axis_in_child: ``(3,)`` unit hinge axis in the child's frame, or ``None``.
        q0: ``(4,)`` wxyz of ``R0``, the child's frame in the parent's at ``qpos0``.
    """

    parent: str
    child: str
    kind: str
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    axis_in_child: np.ndarray | None
    q0: np.ndarray


@dataclass(frozen=True)
class SkeletonModel:
    """A skeleton model: the MJCF text and its joints (``joints`` in depth-first order)."""

    xml: str
    root: str
    joints: tuple[SkeletonJoint, ...]

    @property
    def bodies(self) -> tuple[str, ...]:
        """The bodies in depth-first order, the root first."""
        return (self.root, *(j.child for j in self.joints))


def _f(x: float) -> str:
    return repr(float(x))


def _v(v: Sequence[float]) -> str:
    return " ".join(_f(x) for x in v)


def _unit(v: Any, where: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(a)) if a.shape == (3,) else 0.0
    if not (math.isfinite(n) and n > 0):
        raise InputError(f"{where}: expected an axis of 3 finite numbers, not all zero, got {v!r}")
    return a / n


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """wxyz of the smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-12:  # opposite: half a turn about any axis perpendicular to a
        perp = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return np.array([0.0, *(perp / np.linalg.norm(perp))])
    q = np.array([1.0 + c, *np.cross(a, b)])
    return q / np.linalg.norm(q)


def skeleton_joints(doc: Mapping[str, Any]) -> tuple[str, tuple[SkeletonJoint, ...]]:
    """The root and the joints of a calibration document, depth-first from the root, in metres.

    Raises:
        InputError: no joints, a root that is a child, sensors not connected to the root.
    """
    entries = doc.get("joints")
    if not isinstance(entries, list) or not entries:
        raise InputError('Expected a calibration document with a non-empty "joints" list')
    scale = metres_per_unit(str(doc.get("units", "m")))
    twice = sorted({j["child"] for j in entries if [k["child"] for k in entries].count(j["child"]) > 1})
    if twice:
        raise InputError(f"Expected each sensor to be the child of one joint; children of two: {twice}")
    children: dict[str, list[dict]] = {}
    parent_joint = {j["child"]: j for j in entries}
    for j in entries:
        children.setdefault(j["parent"], []).append(j)
    child_names = {j["child"] for j in entries}
    roots = sorted(set(children) - child_names)
    root = doc.get("root") or (roots[0] if len(roots) == 1 else None)
    if root is None or root in child_names:
        raise InputError(
            f"Expected one root sensor that is no joint's child, got {doc.get('root')!r} ({roots})"
        )
    dfs: list[SkeletonJoint] = []
    stack = [root]
    while stack:  # depth-first, children in the document's order (MuJoCo's qpos order)
        name = stack.pop()
        if name != root:
            dfs.append(_joint(parent_joint[name], scale))
        stack.extend(j["child"] for j in reversed(children.get(name, [])))
    unreached = sorted(child_names - {j.child for j in dfs})
    if unreached:
        raise InputError(f"Expected every sensor connected to the root {root!r}; not connected: {unreached}")
    return root, tuple(dfs)


def _joint(j: Mapping[str, Any], scale: float) -> SkeletonJoint:
    where = f"joint {j['parent']} - {j['child']}"
    jip = np.asarray(j["joint_in_parent"], dtype=float) * scale
    jic = np.asarray(j["joint_in_child"], dtype=float) * scale
    hinge = (
        bool(j.get("single_axis"))
        and j.get("axis_in_parent") is not None
        and j.get("axis_in_child") is not None
    )
    if not hinge:
        return SkeletonJoint(j["parent"], j["child"], "ball", jip, jic, None, np.array([1.0, 0.0, 0.0, 0.0]))
    a_p = _unit(j["axis_in_parent"], f"{where}, axis_in_parent")
    a_c = _unit(j["axis_in_child"], f"{where}, axis_in_child")
    return SkeletonJoint(j["parent"], j["child"], "hinge", jip, jic, a_c, rotation_between(a_c, a_p))


def _bone_geoms(body: ET.Element, start: np.ndarray, ends: list[np.ndarray], name: str) -> None:
    for k, end in enumerate(ends):
        if np.linalg.norm(end - start) > 2 * BONE_RADIUS_M:
            ET.SubElement(
                body,
                "geom",
                name=f"bone_{name}_{k}",
                type="capsule",
                fromto=_v([*start, *end]),
                size=_f(BONE_RADIUS_M),
            )
    ET.SubElement(body, "geom", name=f"sensor_{name}", type="box", size=_v(SENSOR_HALF_M), rgba="0.9 0.6 0 1")


def skeleton_mjcf(doc: Mapping[str, Any], *, model_name: str = "calibrated_skeleton") -> SkeletonModel:
    """The skeleton model of a calibration document (module docstring).

    Args:
        doc: a calibration JSON document or :func:`~simbench.io.dataset.truth_calibration_dict`.
        model_name: the MJCF ``model`` attribute.

    Raises:
        InputError: a document that is not a tree of joints (see :func:`skeleton_joints`).
    """
    root, joints = skeleton_joints(doc)
    placement = {p["sensor"]: p for p in doc.get("sensor_placement") or [] if isinstance(p, dict)}
    mj = ET.Element("mujoco", model=model_name)
    ET.SubElement(mj, "compiler", angle="radian")
    ET.SubElement(mj, "option", gravity="0 0 -9.81")
    world = ET.SubElement(mj, "worldbody")
    ET.SubElement(world, "light", pos="0 0 3", dir="0 0 -1")
    bodies: dict[str, ET.Element] = {}
    own_centre = {root: np.zeros(3)}
    ends: dict[str, list[np.ndarray]] = {}
    for j in joints:
        own_centre[j.child] = j.joint_in_child
        ends.setdefault(j.parent, []).append(j.joint_in_parent)
    bodies[root] = ET.SubElement(world, "body", name=root)
    ET.SubElement(bodies[root], "freejoint", name="root")
    for j in joints:
        pos = j.joint_in_parent - quat_to_matrix(j.q0) @ j.joint_in_child
        body = ET.SubElement(bodies[j.parent], "body", name=j.child, pos=_v(pos), quat=_v(j.q0))
        attrs = {"name": f"{j.child}_joint", "type": j.kind, "pos": _v(j.joint_in_child)}
        if j.axis_in_child is not None:
            attrs["axis"] = _v(j.axis_in_child)
        ET.SubElement(body, "joint", **attrs)
        ET.SubElement(body, "site", name=f"joint_{j.child}", pos=_v(j.joint_in_child), size="0.012")
        bodies[j.child] = body
    for name, body in bodies.items():
        ET.SubElement(body, "site", name=f"sensor_{name}", pos="0 0 0", size="0.01")
        if name in placement:  # the segment frame in the sensor's: the inverse of (p_b_s, q_b_s)
            R_b_s = quat_to_matrix(np.asarray(placement[name]["q_b_s"], dtype=float))
            p_s_b = -R_b_s.T @ np.asarray(placement[name]["p_b_s"], dtype=float)
            ET.SubElement(
                body,
                "site",
                name=f"segment_{name}",
                pos=_v(p_s_b),
                quat=_v(matrix_to_quat(R_b_s.T)),
                size="0.008",
            )
        _bone_geoms(body, own_centre[name], ends.get(name, []), name)
    ET.indent(mj)
    comment = (
        "<!-- simbench: a calibrated skeleton. Body frames are sensor frames; lengths in metres; "
        "root free joint, ball or hinge joints at the calibrated joint centres. -->\n"
    )
    return SkeletonModel(xml=comment + ET.tostring(mj, encoding="unicode") + "\n", root=root, joints=joints)


def write_skeleton_mjcf(path: str | os.PathLike[str], doc: Mapping[str, Any]) -> SkeletonModel:
    """Write the skeleton model of a calibration document to an MJCF file atomically."""
    model = skeleton_mjcf(doc)
    atomic_write_text(path, model.xml)
    return model


def skeleton_qpos(
    model: SkeletonModel, names: Sequence[str], q_w_s: np.ndarray, p_w_root: np.ndarray
) -> dict[str, np.ndarray]:
    """Joint values that pose the model from sensor orientations and the root's position.

    Args:
        model: the skeleton model.
        names: ``(N,)`` the sensor names indexing ``q_w_s``.
        q_w_s: ``(F, N, 4)`` wxyz orientations ``R_w_s`` of the sensors.
        p_w_root: ``(F, 3)`` the root sensor's position in world, m.

    Returns:
        ``{joint name: values}``: ``root`` ``(F, 7)`` (position, wxyz), each ball joint ``(F, 4)``
        (wxyz of the child in the parent after ``R0``), each hinge ``(F, 1)`` (angle, rad, the
        relative rotation's component about the axis). Set them at ``model.jnt_qposadr``.
    """
    index = {n: k for k, n in enumerate(names)}
    missing = [b for b in model.bodies if b not in index]
    if missing:
        raise InputError(f"Expected orientations of every body of the model; missing {missing}")
    q = np.asarray(q_w_s, dtype=float)
    p = np.asarray(p_w_root, dtype=float)
    if q.ndim != 3 or q.shape[1:] != (len(names), 4) or p.shape != (q.shape[0], 3):
        raise InputError(
            f"Expected q_w_s (frames, {len(names)}, 4) and p_w_root (frames, 3), got {q.shape} and {p.shape}"
        )
    R = quat_to_matrix(q)
    out = {"root": np.concatenate([p, q[:, index[model.root]]], axis=1)}
    for j in model.joints:
        R_p_c = np.einsum("fji,fjk->fik", R[:, index[j.parent]], R[:, index[j.child]])
        rel = np.einsum("ji,fjk->fik", quat_to_matrix(j.q0), R_p_c)  # R0^T R_p_c
        if j.kind == "ball":
            out[f"{j.child}_joint"] = matrix_to_quat(rel)
        else:
            out[f"{j.child}_joint"] = (matrix_to_rotvec(rel) @ j.axis_in_child)[:, None]
    return out


__all__ = [
    "SkeletonJoint",
    "SkeletonModel",
    "rotation_between",
    "skeleton_joints",
    "skeleton_mjcf",
    "skeleton_qpos",
    "write_skeleton_mjcf",
]
