"""A lab's estimators, registered with simbench by the entry point in pyproject.toml."""

import numpy as np


def sphere_fit(poses, *, hierarchy):
    """Least-squares sphere fit of each child sensor's origin in its parent's frame."""
    joints = []
    for child, parent in hierarchy.items():
        p, c = poses.names.index(parent), poses.names.index(child)
        use = poses.valid[:, p] & poses.valid[:, c]
        d = poses.p_w_s[use, c] - poses.p_w_s[use, p]
        x = np.einsum("fji,fj->fi", poses.R_w_s[use, p], d)  # child origin in the parent frame
        centre = np.linalg.lstsq(np.column_stack([2 * x, np.ones(len(x))]), (x**2).sum(axis=1), rcond=None)[
            0
        ][:3]
        world = np.einsum("fij,j->fi", poses.R_w_s[use, p], centre) - d  # from the child's origin
        in_child = np.einsum("fji,fj->fi", poses.R_w_s[use, c], world).mean(axis=0)
        joints.append(
            {
                "parent": parent,
                "child": child,
                "joint_in_parent": centre.tolist(),
                "joint_in_child": in_child.tolist(),
            }
        )
    return {"units": poses.unit, "joints": joints}
