"""Limb lengths and sensor placement from fitted joints (O'Brien section 3, Figure 3).

A segment carries one sensor. Its joints are its inboard joint (where it hangs from its parent)
and its outboard joints (where its children hang), all located in the segment's sensor frame by
the joint fits, so the distance between any two of them is a length of that segment: the upper
arm's shoulder-to-elbow length, or for O'Brien's linkage the chest bar's neck-to-shoulder and
shoulder-to-shoulder distances.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np


@dataclass(frozen=True)
class SegmentLength:
    """The distance between two joints of one segment.

    Attributes:
        segment: the segment's sensor name.
        joint_a: name of the first joint (``"parent-child"``).
        joint_b: name of the second joint.
        length: metres.
    """

    segment: str
    joint_a: str
    joint_b: str
    length: float


@dataclass(frozen=True)
class SensorPlacement:
    """Where a sensor sits relative to its segment's joints.

    Attributes:
        sensor: sensor name.
        joints: names of the joints on its segment (inboard first).
        offsets: ``(len(joints), 3)`` each joint's location in the sensor frame, metres.
        distances: ``(len(joints),)`` distance from the sensor origin to each joint, metres.
    """

    sensor: str
    joints: tuple[str, ...]
    offsets: np.ndarray
    distances: np.ndarray


def joint_name(parent: str, child: str) -> str:
    """The name of the joint between ``parent`` and ``child``: ``"parent-child"``."""
    return f"{parent}-{child}"


def segment_joints(
    names: Sequence[str],
    joints: Sequence[tuple[int, int]],
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> dict[int, list[tuple[str, np.ndarray]]]:
    """The joints on each sensor's segment and their location in that sensor's frame.

    Args:
        names: sensor names.
        joints: ``(parent, child)`` sensor indices of each joint.
        joint_in_parent, joint_in_child: ``(J, 3)`` joint centres in each sensor frame, metres.

    Returns:
        ``{sensor index: [(joint name, (3,) location), ...]}``, the inboard joint first.
    """
    found: dict[int, list[tuple[str, np.ndarray]]] = {k: [] for k in range(len(names))}
    for k, (p, c) in enumerate(joints):
        found[c].insert(0, (joint_name(names[p], names[c]), np.asarray(joint_in_child[k])))
    for k, (p, c) in enumerate(joints):
        found[p].append((joint_name(names[p], names[c]), np.asarray(joint_in_parent[k])))
    return found


def segment_lengths(
    names: Sequence[str],
    joints: Sequence[tuple[int, int]],
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> list[SegmentLength]:
    """Distances between every two joints of each segment (limb lengths), metres."""
    out = []
    for sensor, located in segment_joints(names, joints, joint_in_parent, joint_in_child).items():
        for (name_a, loc_a), (name_b, loc_b) in combinations(located, 2):
            out.append(SegmentLength(names[sensor], name_a, name_b, float(np.linalg.norm(loc_a - loc_b))))
    return out


def sensor_placements(
    names: Sequence[str],
    joints: Sequence[tuple[int, int]],
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> list[SensorPlacement]:
    """Each sensor's offsets to the joints of its segment (sensor-to-joint vectors), metres."""
    out = []
    for sensor, located in segment_joints(names, joints, joint_in_parent, joint_in_child).items():
        offsets = np.array([loc for _, loc in located]).reshape(-1, 3)
        out.append(
            SensorPlacement(
                sensor=names[sensor],
                joints=tuple(name for name, _ in located),
                offsets=offsets,
                distances=np.linalg.norm(offsets, axis=1),
            )
        )
    return out


def joint_arrays(
    names: Sequence[str],
    children: Sequence[str],
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint locations indexed by the child sensor: the layout of
    :func:`calibration.replay.remove_residual` and :func:`calibration.posture.joint_positions`.

    Args:
        names: ``(N,)`` sensor names.
        children: ``(J,)`` the child sensor of each joint.
        joint_in_parent, joint_in_child: ``(J, 3)`` each joint in its parent's / child's sensor
            frame.

    Returns:
        ``(joint_in_parent, joint_in_child)``, each ``(N, 3)``: row ``k`` is the joint whose child
        is sensor ``k``; the root's row (no joint) is zero.
    """
    index = {name: k for k, name in enumerate(names)}
    lp, lc = np.zeros((len(names), 3)), np.zeros((len(names), 3))
    for k, child in enumerate(children):
        lp[index[child]] = joint_in_parent[k]
        lc[index[child]] = joint_in_child[k]
    return lp, lc
