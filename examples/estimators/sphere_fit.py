"""A user's joint-centre estimator in Python: a least-squares sphere fit, one joint at a time.

Run it through simbench without touching simbench's source:

    simbench calibrate poses.csv --method examples/estimators/sphere_fit.py:estimate --hierarchy tree.json

The child sensor's origin, seen from the parent sensor, moves on a sphere about the joint centre;
the centre solves ``2 x . c + (r^2 - |c|^2) = |x|^2`` over the frames (linear least squares).
"""

import numpy as np


def estimate(poses, *, hierarchy):
    """Joint centres of a given hierarchy ({child: parent}) from 6-DoF poses, metres."""
    joints = []
    for child, parent in hierarchy.items():
        p, c = poses.names.index(parent), poses.names.index(child)
        use = poses.valid[:, p] & poses.valid[:, c]
        R_p, R_c = poses.R_w_s[use, p], poses.R_w_s[use, c]
        d = poses.p_w_s[use, c] - poses.p_w_s[use, p]
        x = np.einsum("fji,fj->fi", R_p, d)  # the child's origin in the parent's frame
        A = np.column_stack([2 * x, np.ones(len(x))])
        sol = np.linalg.lstsq(A, np.sum(x**2, axis=1), rcond=None)[0]
        in_parent = sol[:3]
        # the same point in the child's frame, averaged over the frames
        in_child = np.mean(np.einsum("fji,fj->fi", R_c, np.einsum("fij,j->fi", R_p, in_parent) - d), axis=0)
        joints.append(
            {
                "parent": parent,
                "child": child,
                "joint_in_parent": in_parent.tolist(),
                "joint_in_child": in_child.tolist(),
            }
        )
    return {"units": poses.unit, "joints": joints}
