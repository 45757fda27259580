"""Posture from orientations (Fontaine et al. 3.2): each bone takes its tracker's rotation.

With sourceless trackers there are no positions, only orientations. A tree-structured skeleton
turns them into a posture: every segment takes its sensor's rotation (after the sensor-to-segment
alignment), and forward kinematics from the root places every joint.

- **Sensor-to-segment alignment**: from a reference pose whose segment orientations are known
  (standing, or the model's reference pose in simulation), ``R_b_s = R_w_b_ref^T R_w_s_ref``;
  then ``R_w_b(t) = R_w_s(t) R_b_s^T`` (:func:`segment_alignment`, :func:`segment_rotations`).
- **Forward kinematics** (:func:`joint_positions`): with each joint located in its parent's and
  child's sensor frames (O'Brien's calibration gives exactly that, or the truth in simulation),
  joint ``c``'s centre is ``J_c = J_p + R_w_p (joint_in_parent_c - joint_in_child_p)``: the
  parent's inboard joint plus the parent segment's vector to this joint, rotated by the parent
  sensor's orientation. The root's inboard point is given (``root_w``, e.g. a fixed point or a
  measured position).
"""

from __future__ import annotations

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.hierarchy import Hierarchy


def segment_alignment(R_w_s_ref: np.ndarray, R_w_b_ref: np.ndarray) -> np.ndarray:
    """``R_b_s`` ``(N, 3, 3)`` from one reference pose's sensor and segment orientations."""
    R_w_s_ref = np.asarray(R_w_s_ref, dtype=float)
    R_w_b_ref = np.asarray(R_w_b_ref, dtype=float)
    if R_w_s_ref.shape != R_w_b_ref.shape or R_w_s_ref.shape[-2:] != (3, 3):
        raise CalibrationInputError(
            f"Expected two (N, 3, 3) arrays of the same shape, got {R_w_s_ref.shape} and {R_w_b_ref.shape}"
        )
    return np.swapaxes(R_w_b_ref, -1, -2) @ R_w_s_ref


def segment_rotations(R_w_s: np.ndarray, R_b_s: np.ndarray) -> np.ndarray:
    """Segment orientations ``(F, N, 3, 3)`` from sensor orientations and alignment ``R_b_s``."""
    return np.asarray(R_w_s, dtype=float) @ np.swapaxes(np.asarray(R_b_s, dtype=float), -1, -2)


def joint_positions(
    R_w_s: np.ndarray,
    tree: Hierarchy,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    root_w: np.ndarray | None = None,
) -> np.ndarray:
    """World positions of every segment's inboard joint, from sensor orientations only.

    Args:
        R_w_s: ``(F, N, 3, 3)`` sensor orientations, sensor to world.
        tree: the hierarchy.
        joint_in_parent: ``(N, 3)`` for each child sensor, its inboard joint in the parent
            sensor's frame, m (the root's row is ignored).
        joint_in_child: ``(N, 3)`` for each child sensor, its inboard joint in its own frame, m.
            For the root, the point that ``root_w`` places (e.g. zeros: the root sensor).
        root_w: ``(F, 3)`` or ``(3,)`` world position of the root's point, m (default origin).

    Returns:
        ``(F, N, 3)``: row ``c`` is the inboard joint of sensor ``c`` (the root's point for the
        root), m. NaN propagates from a missing orientation to everything below it.
    """
    R_w_s = np.asarray(R_w_s, dtype=float)
    f, n = R_w_s.shape[:2]
    lp = np.asarray(joint_in_parent, dtype=float)
    lc = np.asarray(joint_in_child, dtype=float)
    for name, arr in (("joint_in_parent", lp), ("joint_in_child", lc)):
        if arr.shape != (n, 3):
            raise CalibrationInputError(f"Expected {name} to have shape ({n}, 3), got {arr.shape}")
    out = np.empty((f, n, 3))
    out[:, tree.root] = np.zeros(3) if root_w is None else np.broadcast_to(root_w, (f, 3))
    for c in tree.order:
        p = tree.parent[c]
        if p < 0:
            continue
        out[:, c] = out[:, p] + R_w_s[:, p] @ (lp[c] - lc[p])
    return out


def sensor_positions(
    R_w_s: np.ndarray, tree: Hierarchy, joints_w: np.ndarray, joint_in_child: np.ndarray
) -> np.ndarray:
    """Sensor origins ``(F, N, 3)`` from their inboard joints: ``p_c = J_c - R_w_c joint_in_child_c``."""
    return np.asarray(joints_w) - np.einsum("fnij,nj->fni", np.asarray(R_w_s), np.asarray(joint_in_child))
