"""Equipping an MJCF model for capture: sensor sites, MuJoCo sensors, a root driver, actuators.

Every function here edits a :class:`mujoco.MjSpec` in place (see :mod:`simbench.sim.models` for
what a capture model is); :func:`set_tracking_gains` reads the compiled model to size the gains.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.sim.mounts import Mount, add_mount

#: Natural frequency of the position actuators' tracking, Hz, and their damping ratio. A PD on
#: a ball joint's rotation-vector components with damping on its angular velocity is not
#: symmetric at large angles and can flutter; 2 Hz, twice critically damped, kept every model
#: stable with human-like accelerations (99th percentile 25-50 m/s^2 on the humanoid; 4 Hz
#: critically damped shook its legs at 200 g, and 4 Hz at damping ratio 2 diverged on the CMU
#: humanoid).
TRACKING_HZ = 2.0
DAMPRATIO = 2.0

#: Name of the mocap body that drives a free root, and of the weld that holds the root to it.
ROOT_DRIVER = "simbench_root_driver"
ROOT_WELD = "simbench_root_weld"

#: Name of the clock sensor that stamps the samples.
CLOCK = "clock"

_SENSOR = mujoco.mjtSensor
_SITE = mujoco.mjtObj.mjOBJ_SITE

#: The MuJoCo sensors each capture sensor gets, in sensordata order: ``(kind, sensor type,
#: object)``, named ``<body>:<kind>``. ``worn`` is the site where the sensor actually is (its
#: mount's, if any), ``bone`` its bone placement, ``body`` the segment (body) frame.
READINGS = (
    ("site_pos", _SENSOR.mjSENS_FRAMEPOS, "worn"),
    ("site_quat", _SENSOR.mjSENS_FRAMEQUAT, "worn"),
    ("bone_pos", _SENSOR.mjSENS_FRAMEPOS, "bone"),
    ("bone_quat", _SENSOR.mjSENS_FRAMEQUAT, "bone"),
    ("bone_acc", _SENSOR.mjSENS_ACCELEROMETER, "bone"),
    ("bone_gyro", _SENSOR.mjSENS_GYRO, "bone"),
    ("acc", _SENSOR.mjSENS_ACCELEROMETER, "worn"),
    ("gyro", _SENSOR.mjSENS_GYRO, "worn"),
    ("mag", _SENSOR.mjSENS_MAGNETOMETER, "worn"),
    ("body_pos", _SENSOR.mjSENS_FRAMEPOS, "body"),
    ("body_quat", _SENSOR.mjSENS_FRAMEQUAT, "body"),
)


def default_site_frame(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A fixed, arbitrary-looking sensor offset ``(3,)`` m and orientation ``(4,)`` wxyz.

    For bodies without a ``sensor_<body>`` site: real sensors are never aligned with the bone.
    """
    rng = np.random.default_rng(seed)
    offset = rng.uniform(-0.02, 0.02, size=3)
    rotvec = rng.uniform(-0.6, 0.6, size=3)
    return offset, matrix_to_quat(rotvec_to_matrix(rotvec))


def place_sensor_sites(
    spec: mujoco.MjSpec,
    base: mujoco.MjModel,
    bodies: Sequence[int],
    placement: Mapping[str, Sequence[float]],
    mount: Mount | None,
) -> tuple[list[str], list[str]]:
    """Put each sensor on its body: its ``sensor_<body>`` site (shifted), or a new one.

    Args:
        spec: the model being edited.
        base: the model as read (compiled, unedited), for body and site frames.
        bodies: ``(N,)`` sensor body ids in ``base``, parents before children.
        placement: ``{body name: (dx, dy, dz)}`` shifts in the body frame, m.
        mount: a sprung soft-tissue mount for every sensor, or ``None``.

    Returns:
        ``(bone sites, worn sites)``: site names of each sensor's bone placement and of where it
        is worn (the same site, or its mount's).
    """
    bone_sites, worn_sites = [], []
    for k, body_id in enumerate(bodies):
        name = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, body_id)
        site = f"sensor_{name}"
        site_id = mujoco.mj_name2id(base, _SITE, site)
        shift = np.asarray(placement.get(name, (0.0, 0.0, 0.0)), dtype=float)
        if site_id < 0:
            pos, quat = default_site_frame(k)
            pos = base.body_ipos[body_id] + pos + shift
            spec.body(name).add_site(name=site, pos=pos, quat=quat)
        else:
            pos, quat = base.site_pos[site_id].copy() + shift, base.site_quat[site_id].copy()
            if np.any(shift):
                spec.site(site).pos = pos
        bone_sites.append(site)
        worn_sites.append(site if mount is None else add_mount(spec, name, pos, quat, mount))
    return bone_sites, worn_sites


def add_readings(
    spec: mujoco.MjSpec, bodies: Sequence[str], bone_sites: Sequence[str], worn_sites: Sequence[str]
) -> None:
    """Add the :data:`READINGS` of every sensor, then the :data:`CLOCK`, to the spec.

    Args:
        spec: the model being edited.
        bodies: ``(N,)`` sensor body names.
        bone_sites, worn_sites: ``(N,)`` site names from :func:`place_sensor_sites`.
    """
    for body, bone, worn in zip(bodies, bone_sites, worn_sites, strict=True):
        objects = {
            "worn": (_SITE, worn),
            "bone": (_SITE, bone),
            "body": (mujoco.mjtObj.mjOBJ_XBODY, body),
        }
        for kind, sensor_type, on in READINGS:
            objtype, objname = objects[on]
            spec.add_sensor(name=f"{body}:{kind}", type=sensor_type, objtype=objtype, objname=objname)
    spec.add_sensor(name=CLOCK, type=_SENSOR.mjSENS_CLOCK)


def add_root_driver(spec: mujoco.MjSpec, base: mujoco.MjModel, root: int) -> None:
    """Weld the free root body ``root`` (a body id in ``base``) to a new mocap body.

    The mocap body starts at the root's reference pose; the weld is a stiff soft constraint, so
    the root follows the driver by physics.
    """
    data0 = mujoco.MjData(base)
    mujoco.mj_kinematics(base, data0)
    mocap = spec.worldbody.add_body(name=ROOT_DRIVER, mocap=True)
    mocap.pos = data0.xpos[root].copy()
    mocap.quat = data0.xquat[root].copy()
    weld = spec.add_equality(name=ROOT_WELD, type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY)
    weld.name1 = ROOT_DRIVER
    weld.name2 = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, root)
    # anchor at the driver's origin, relative pose taken from the reference pose, torque
    # scale 1 (MjSpec's default data belong to other constraint types)
    weld.data = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1.0] + [0.0] * (len(weld.data) - 11))
    weld.solref = np.array([0.005, 1.0])


def add_actuators(spec: mujoco.MjSpec, base: mujoco.MjModel, joints: Sequence[int]) -> None:
    """A ``position`` actuator per degree of freedom of each joint (ids in ``base``).

    A ball joint gets three, named ``<joint>:x``, ``:y``, ``:z`` (gears on its rotation vector's
    components), a hinge one, ``<joint>:x``. Gains are placeholders until
    :func:`set_tracking_gains`.
    """
    for joint_id in joints:
        joint = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, joint_id)
        gears = np.eye(3) if base.jnt_type[joint_id] == mujoco.mjtJoint.mjJNT_BALL else np.eye(1, 3)
        for gear in gears:
            act = spec.add_actuator(name=f"{joint}:{'xyz'[int(np.argmax(gear))]}", target=joint)
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.gear = np.concatenate([gear, np.zeros(3)])
            act.set_to_position(kp=1.0, dampratio=1.0)


def set_tracking_gains(spec: mujoco.MjSpec, model: mujoco.MjModel) -> None:
    """Size each actuator's gain to track at :data:`TRACKING_HZ` with damping ratio :data:`DAMPRATIO`.

    ``kp = I (2 pi f)^2`` with ``I`` the actuated degree of freedom's diagonal of the joint-space
    inertia at the reference pose of ``model`` (the spec compiled with :func:`add_actuators`).
    A light segment whose joint's own damping ``b`` already exceeds the damping that asks for
    (``b > 2 DAMPRATIO I 2 pi f``: the humanoid's hands and feet, ``b`` 1 N m s/rad against
    0.014-0.019 kg m^2) would follow its set-points at a third of their amplitude at 0.6 Hz (damping
    ratio 4-4.7), its wrist turning 15 degrees where the exercise asks 49: its stiffness is raised
    until the joint's damping alone gives :data:`DAMPRATIO` (``w = b / (2 DAMPRATIO I)``, 2.8 Hz for
    the wrists) and the actuator adds no damping of its own.
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    kp = np.zeros(model.nu)
    passive = np.zeros(model.nu, dtype=bool)
    for a in range(model.nu):
        j = int(model.actuator_trnid[a, 0])
        ball = model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL
        dof = int(model.jnt_dofadr[j]) + (int(np.argmax(model.actuator_gear[a, :3])) if ball else 0)
        w = 2 * np.pi * TRACKING_HZ
        damping = float(model.dof_damping[dof])
        passive[a] = damping > 2 * DAMPRATIO * M[dof, dof] * w
        if passive[a]:
            w = damping / (2 * DAMPRATIO * M[dof, dof])
        kp[a] = M[dof, dof] * w**2
    for a, act in enumerate(spec.actuators):
        if passive[a]:
            act.set_to_position(kp=float(kp[a]), kv=0.0)
        else:
            act.set_to_position(kp=float(kp[a]), dampratio=DAMPRATIO)


def tracking_response(model: mujoco.MjModel, f_hz: float) -> np.ndarray:
    """Each actuator's joint response to a sine set-point at ``f_hz``: ``(nu,)`` complex, the
    amplitude ratio and phase lag of the joint's angle to its set-point.

    Each degree of freedom is taken alone, a second-order system: its actuator's ``kp`` and
    ``kv``, the joint's damping and armature, and its diagonal of the joint-space inertia at the
    reference pose (as :func:`set_tracking_gains` sizes the gains). The humanoid's gait, its
    set-points divided by this, moves its knees, hips and elbows within 4 % of the gait's first
    harmonic and the knees within 8 % of the second (``tests/test_gait.py``).
    """
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    w = 2 * np.pi * f_hz
    out = np.zeros(model.nu, dtype=complex)
    for a in range(model.nu):
        j = int(model.actuator_trnid[a, 0])
        ball = model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL
        dof = int(model.jnt_dofadr[j]) + (int(np.argmax(model.actuator_gear[a, :3])) if ball else 0)
        kp = float(model.actuator_gainprm[a, 0])
        kv = -float(model.actuator_biasprm[a, 2]) + float(model.dof_damping[dof])
        out[a] = kp / complex(kp - M[dof, dof] * w * w, w * kv)
    return out


def reading_addresses(model: mujoco.MjModel, bodies: Sequence[str]) -> dict[str, np.ndarray]:
    """``{kind: (N,) sensordata address}`` of each of the :data:`READINGS` of each sensor body."""

    def address(kind: str, body: str) -> int:
        return int(model.sensor_adr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{body}:{kind}")])

    return {kind: np.array([address(kind, body) for body in bodies]) for kind, _, _ in READINGS}


def clock_address(model: mujoco.MjModel) -> int:
    """Sensordata address of the :data:`CLOCK`."""
    return int(model.sensor_adr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, CLOCK)])
