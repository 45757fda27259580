"""Residual removal: replay the motion through the fitted articulated model (O'Brien 3.4).

The root sensor keeps its measured pose and every sensor keeps its measured rotation; each
child's position is then rebuilt from its parent's through the joint (O'Brien eq. 8 solved for
the child)::

    p_w_c = R_w_p @ joint_in_parent + p_w_p - R_w_c @ joint_in_child

so the joints of the cleaned motion stay together exactly (to rounding).
"""

from __future__ import annotations

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.hierarchy import Hierarchy
from calibration.poses import check_poses


def remove_residual(
    R_w_s: np.ndarray,
    p_w_s: np.ndarray,
    tree: Hierarchy,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> np.ndarray:
    """Positions of every sensor replayed through the articulated model.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` measured rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` measured positions in world, metres.
        tree: the hierarchy.
        joint_in_parent: ``(sensors, 3)`` for each *child* sensor, its inboard joint in the
            parent's frame, metres (the root's row is ignored).
        joint_in_child: ``(sensors, 3)`` for each child sensor, its inboard joint in its own
            frame, metres (the root's row is ignored).

    Returns:
        ``(frames, sensors, 3)`` cleaned positions in world, metres: the root's are the
        measured ones; a sensor whose pose (or an ancestor's) is missing gets NaN.
    """
    R_w_s = np.asarray(R_w_s, dtype=float)
    p_w_s = np.asarray(p_w_s, dtype=float)
    _, n = check_poses(R_w_s, p_w_s)
    lp = np.asarray(joint_in_parent, dtype=float)
    lc = np.asarray(joint_in_child, dtype=float)
    for name, arr in (("joint_in_parent", lp), ("joint_in_child", lc)):
        if arr.shape != (n, 3):
            raise CalibrationInputError(f"Expected {name} to have shape ({n}, 3), got {arr.shape}")
    if tree.parent.shape != (n,):
        raise CalibrationInputError(f"The hierarchy has {tree.parent.shape[0]} sensors, the poses {n}")
    out = np.empty_like(p_w_s)
    out[:, tree.root] = p_w_s[:, tree.root]
    for c in tree.order:
        par = tree.parent[c]
        if par < 0:
            continue
        joint_w = R_w_s[:, par] @ lp[c] + out[:, par]
        out[:, c] = joint_w - R_w_s[:, c] @ lc[c]
    return out
