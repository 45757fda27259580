"""Sprung soft-tissue mounts: a sensor on its own small body, held to its segment by springs.

Real sensors are strapped on skin; the tissue under them moves. A :class:`Mount` puts the worn
sensor on a small body (sensor plus moving tissue) joined to its segment by three slide joints
with springs (and optionally a ball joint with a rotational spring), so that it lags and rings
under the segment's accelerations by physics. The sensor's bone placement (where it would sit,
rigid) stays on the segment as its own site.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

#: Radius of the sphere whose inertia a mount has, m.
MOUNT_RADIUS_M = 0.02


@dataclass(frozen=True)
class Mount:
    """A soft-tissue mount: the sensor on its own small body, held by springs to its segment.

    Attributes:
        stiffness_n_per_m: translational spring per axis, N/m (> 0).
        rot_stiffness_nm_per_rad: rotational spring, N m/rad (0: no rotation on the mount).
        damping_ratio: of each spring with the mount's mass or inertia.
        mass_kg: sensor and moving tissue, kg; inertia that of a 2 cm-radius sphere.
    """

    stiffness_n_per_m: float
    rot_stiffness_nm_per_rad: float = 0.0
    damping_ratio: float = 0.3
    mass_kg: float = 0.03


def add_mount(spec: mujoco.MjSpec, body: str, pos: np.ndarray, quat: np.ndarray, mount: Mount) -> str:
    """Add a sprung mount body at a sensor's placement; returns the name of its sensor site.

    Args:
        spec: the model being edited (changed in place).
        body: the segment (body name) the sensor is worn on.
        pos: ``(3,)`` the sensor's bone placement in the body frame, m.
        quat: ``(4,)`` its orientation in the body frame, wxyz.
        mount: springs, damping and mass.

    Returns:
        ``sensor_<body>:mount``, the site of the worn sensor on the mount body.
    """
    inertia = 0.4 * mount.mass_kg * MOUNT_RADIUS_M**2
    child = spec.body(body).add_body(name=f"simbench_mount_{body}", pos=pos, quat=quat)
    child.explicitinertial = True
    child.mass = mount.mass_kg
    child.inertia = np.full(3, inertia)
    damping = 2 * mount.damping_ratio * np.sqrt(mount.stiffness_n_per_m * mount.mass_kg)
    for axis, label in zip(np.eye(3), "xyz", strict=True):
        child.add_joint(
            name=f"{body}:mount_{label}",
            type=mujoco.mjtJoint.mjJNT_SLIDE,
            axis=axis,
            stiffness=np.array([mount.stiffness_n_per_m, 0.0, 0.0]),
            damping=np.array([damping, 0.0, 0.0]),
        )
    if mount.rot_stiffness_nm_per_rad > 0:
        rot_damping = 2 * mount.damping_ratio * np.sqrt(mount.rot_stiffness_nm_per_rad * inertia)
        child.add_joint(
            name=f"{body}:mount_rot",
            type=mujoco.mjtJoint.mjJNT_BALL,
            stiffness=np.array([mount.rot_stiffness_nm_per_rad, 0.0, 0.0]),
            damping=np.array([rot_damping, 0.0, 0.0]),
        )
    site = f"sensor_{body}:mount"
    child.add_site(name=site)
    return site
