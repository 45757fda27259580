"""MuJoCo models made ready for capture sessions: sensors, actuators and a driven root.

Any MJCF model can be used (the built-in ``linkage`` and ``humanoid`` in ``models/``, a
dm_control suite model as ``dm_control:NAME``, or a path to an ``.xml`` file). It is edited
programmatically with :class:`mujoco.MjSpec`:

- **sensors**: one per chosen body, on the body's ``sensor_<body>`` site if the model has one,
  else on a new site near the body's centre of mass, turned against the body frame (real
  sensors are never aligned with the bone). Each gets MuJoCo's ``framepos``, ``framequat``,
  ``accelerometer``, ``gyro`` and ``magnetometer``; each sensor body gets ``framepos`` and
  ``framequat`` of its body frame; one ``clock`` sensor stamps the samples.
- **actuators**: the model's own are removed; every degree of freedom of every joint between
  sensor bodies gets a ``position`` actuator (for a ball joint, three, whose lengths are the
  components of the joint's rotation vector). The gains track at 2 Hz, damping ratio 2:
  ``kp = I (2 pi 2 Hz)^2`` with ``I`` the joint-space inertia at the reference pose (see
  :data:`TRACKING_HZ`).
- **root**: if the root sensor body has a free joint it is welded (a stiff soft constraint) to
  a mocap body that the motion program moves -- the linkage carried by hand, a person's pelvis
  moving through the room -- so the root moves by physics, not by a kinematic replay.

Sensor bodies must be joined by single joints: between a sensor body and the nearest sensor
body above it exactly one body may carry joints (1 ball joint or 1-3 hinges through one point),
so that every sensor pair of the hierarchy is a rotary joint with a fixed centre.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.errors import InputError

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
BUILTIN = ("linkage", "humanoid")

#: Natural frequency of the position actuators' tracking, Hz, and their damping ratio. A PD on
#: a ball joint's rotation-vector components with damping on its angular velocity is not
#: symmetric at large angles and can flutter; 2 Hz, twice critically damped, kept every model
#: stable with human-like accelerations (99th percentile 25-50 m/s^2 on the humanoid; 4 Hz
#: critically damped shook its legs at 200 g, and 4 Hz at damping ratio 2 diverged on the CMU
#: humanoid).
TRACKING_HZ = 2.0
DAMPRATIO = 2.0

#: Earth field used by the magnetometers, world frame ENU (x east, y north, z up), microtesla:
#: 50 uT with 60 degrees inclination (mid-latitude Europe/North America).
EARTH_FIELD_UT = (0.0, 25.0, -43.30127018922193)

_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)


@dataclass(frozen=True)
class Articulation:
    """The joint(s) between a sensor body and its parent sensor body.

    Attributes:
        body: name of the body that carries the joints.
        sensor: name of the child sensor (body) the joint belongs to.
        joints: MJCF joint names (one ball joint, or one to three hinges).
        kinds: ``"ball"`` or ``"hinge"`` per joint.
        actuators: actuator ids driving it, in degree-of-freedom order (3 per ball, 1 per hinge).
        cone: for a ball joint its range (max rotation angle, rad), 0 when unlimited.
        hinge_range: ``(n_hinges, 2)`` hinge ranges, rad (``-inf, inf`` when unlimited).
    """

    body: str
    sensor: str
    joints: tuple[str, ...]
    kinds: tuple[str, ...]
    actuators: tuple[int, ...]
    cone: float
    hinge_range: np.ndarray

    @property
    def n_dof(self) -> int:
        """Rotational degrees of freedom."""
        return len(self.actuators)


@dataclass(frozen=True)
class CaptureModel:
    """A compiled model ready for a capture session, and where its sensors' data lie.

    Attributes:
        source: how the model was named (``linkage``, ``dm_control:humanoid_CMU``, a path).
        model: the compiled model (sensors, actuators, mocap added).
        sensors: sensor names (= the names of the bodies they sit on), parents before children.
        parent_of: ``{child sensor: parent sensor}``; the first sensor is the root.
        articulations: the joint(s) of each non-root sensor, in ``sensors[1:]`` order.
        site_ids: ``(N,)`` site id of each sensor's bone placement.
        body_ids: ``(N,)`` body id of each sensor body.
        mocap_id: mocap index driving the root, or -1 when the root is fixed or not free.
        mount: the soft-tissue mount the sensors sit on, or ``None`` (rigid on the bone).
        adr: sensordata address of each of our sensor kinds: ``{"site_pos": (N,), ...}``;
            ``site_*``, ``acc``, ``gyro``, ``mag`` are the worn sensor (on its mount, if any),
            ``bone_*`` its bone placement, ``body_*`` the segment frame.
        clock_adr: sensordata address of the clock.
    """

    source: str
    model: mujoco.MjModel
    sensors: tuple[str, ...]
    parent_of: dict[str, str]
    articulations: tuple[Articulation, ...]
    site_ids: np.ndarray
    body_ids: np.ndarray
    mocap_id: int
    mount: Mount | None
    adr: dict[str, np.ndarray]
    clock_adr: int


def resolve_model_path(source: str) -> Path:
    """The MJCF file of a model name (built-in, ``dm_control:NAME``, or a path).

    Raises:
        InputError: naming what was expected.
    """
    if source in BUILTIN:
        path = MODELS_DIR / source / "scene.xml"
        if not path.is_file():
            raise InputError(f"built-in model {source!r} not found at {path} (is the repository complete?)")
        return path
    if source.startswith("dm_control:"):
        name = source.split(":", 1)[1]
        try:
            import dm_control
        except ImportError:
            raise InputError(f"{source}: dm_control is not installed (pip install dm-control)") from None
        suite = Path(dm_control.__file__).parent / "suite"
        path = suite / f"{name}.xml"
        if not path.is_file():
            names = sorted(p.stem for p in suite.glob("*.xml"))
            raise InputError(f"{source}: no such dm_control suite model; available: {', '.join(names)}")
        return path
    path = Path(source)
    if path.suffix.lower() == ".xml":
        if not path.is_file():
            raise InputError(f"model file {path} does not exist")
        return path
    raise InputError(
        f"unknown model {source!r}: expected one of {', '.join(BUILTIN)}, dm_control:NAME, "
        "or a path to an MJCF .xml file"
    )


def _compile(spec: mujoco.MjSpec, source: str) -> mujoco.MjModel:
    try:
        return spec.compile()
    except Exception as exc:  # mujoco raises ValueError with the compiler's message
        raise InputError(f"model {source}: MuJoCo could not compile it: {exc}") from None


def _joint_bodies(model: mujoco.MjModel) -> dict[int, list[int]]:
    """``{body id: [joint ids]}`` for bodies with joints other than free joints."""
    out: dict[int, list[int]] = {}
    for j in range(model.njnt):
        if model.jnt_type[j] != _FREE:
            out.setdefault(int(model.jnt_bodyid[j]), []).append(j)
    return out


def _default_sensor_bodies(model: mujoco.MjModel) -> list[str]:
    """Bodies with a ``sensor_<body>`` site; else every body with joints plus the root."""
    named = []
    for b in range(1, model.nbody):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
        if name and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"sensor_{name}") >= 0:
            named.append(name)
    if named:
        return named
    jb = _joint_bodies(model)
    free_roots = {int(model.jnt_bodyid[j]) for j in range(model.njnt) if model.jnt_type[j] == _FREE}
    out = []
    for b in range(1, model.nbody):
        if b in jb or b in free_roots:
            out.append(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b))
    return out


def _site_frame(rng_seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A fixed, arbitrary-looking sensor offset (m) and orientation for bodies without a site."""
    rng = np.random.default_rng(rng_seed)
    offset = rng.uniform(-0.02, 0.02, size=3)
    rotvec = rng.uniform(-0.6, 0.6, size=3)
    return offset, matrix_to_quat(rotvec_to_matrix(rotvec))


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


def _add_mount(spec: mujoco.MjSpec, body: str, pos: np.ndarray, quat: np.ndarray, mount: Mount) -> str:
    """Add a sprung mount body at a sensor's placement; returns the name of its sensor site."""
    inertia = 0.4 * mount.mass_kg * 0.02**2
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


def load_capture_model(
    source: str,
    *,
    sensor_bodies: Sequence[str] | None = None,
    mount: Mount | None = None,
    placement: Mapping[str, Sequence[float]] | None = None,
) -> CaptureModel:
    """Load a model and equip it for capture sessions (see the module docstring).

    Args:
        source: ``linkage``, ``humanoid``, ``dm_control:NAME`` or a path to an MJCF file.
        sensor_bodies: bodies that carry a sensor; default: bodies with a ``sensor_<body>``
            site, else every body with joints and the free root.
        mount: put every sensor on a sprung soft-tissue mount (``None``: rigid on the bone).
            The bone placement is still recorded (``bone_pos``/``bone_quat``).
        placement: ``{sensor body: (dx, dy, dz)}`` shifts of sensors from their default place,
            in the body frame, m (placement studies).

    Raises:
        InputError: unknown model or body names, bodies not joined by single joints.
    """
    path = resolve_model_path(source)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:
        raise InputError(f"model {source}: MuJoCo could not read {path}: {exc}") from None
    base = _compile(spec, source)
    names = list(sensor_bodies) if sensor_bodies is not None else _default_sensor_bodies(base)
    unknown = sorted(set(placement or {}) - set(names))
    if unknown:
        raise InputError(f"placement names {unknown}, which carry no sensor; sensors: {names}")
    ids = []
    for name in names:
        b = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_BODY, name)
        if b <= 0:
            bodies = [mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, k) for k in range(1, base.nbody)]
            raise InputError(f"model {source} has no body {name!r}; bodies: {', '.join(map(str, bodies))}")
        ids.append(b)
    if len(set(ids)) != len(ids):
        raise InputError(f"sensor bodies named twice: {names}")
    if len(ids) < 2:
        raise InputError(f"a capture needs at least 2 sensor bodies, got {names}")
    order = sorted(ids)  # MuJoCo numbers parents before children
    is_sensor = set(order)
    jb = _joint_bodies(base)
    parent_of: dict[int, int] = {}
    joint_body: dict[int, int] = {}
    for b in order:
        path_bodies = []
        a = int(base.body_parentid[b]) if b != 0 else 0
        path_bodies.append(b)
        while a != 0 and a not in is_sensor:
            path_bodies.append(a)
            a = int(base.body_parentid[a])
        if a == 0:
            continue  # a root sensor (hangs from the world)
        parent_of[b] = a
        with_joints = [x for x in path_bodies if x in jb]
        bname = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, b)
        pname = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, a)
        if len(with_joints) != 1:
            between = [mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, x) for x in with_joints]
            raise InputError(
                f"model {source}: sensor bodies {pname!r} and {bname!r} must be joined by the joints of "
                f"exactly one body, found joints on {between}; put a sensor on each body with joints"
            )
        joint_body[b] = with_joints[0]
    roots = [b for b in order if b not in parent_of]
    if len(roots) != 1:
        rnames = [mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, b) for b in roots]
        raise InputError(
            f"model {source}: the sensor bodies must form one tree, found several roots: {rnames}"
        )
    root = roots[0]
    for jbody in joint_body.values():
        kinds = {int(base.jnt_type[j]) for j in jb[jbody]}
        jn = [mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, j) for j in jb[jbody]]
        if not kinds <= {_BALL, _HINGE} or (_BALL in kinds and len(jb[jbody]) > 1) or len(jb[jbody]) > 3:
            raise InputError(f"model {source}: body joints {jn} must be one ball joint or 1-3 hinges")
        anchors = base.jnt_pos[jb[jbody]]
        if np.max(np.abs(anchors - anchors[0])) > 1e-9:
            raise InputError(f"model {source}: joints {jn} do not pass through one point")

    def bname(b: int) -> str:
        return mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_BODY, b)

    # -- edit the spec: sites, sensors, actuators, mocap root
    for a in list(spec.actuators):
        spec.delete(a)
    for s in list(spec.sensors):
        spec.delete(s)
    site_names = []  # the bone placement of each sensor
    worn_names = []  # where the sensor actually is: the same site, or its mount's
    for k, b in enumerate(order):
        name = bname(b)
        site = f"sensor_{name}"
        sid_base = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SITE, site)
        shift = np.asarray((placement or {}).get(name, (0.0, 0.0, 0.0)), dtype=float)
        if sid_base < 0:
            pos, quat = _site_frame(k)
            pos = base.body_ipos[b] + pos + shift
            spec.body(name).add_site(name=site, pos=pos, quat=quat)
        else:
            pos, quat = base.site_pos[sid_base].copy() + shift, base.site_quat[sid_base].copy()
            if np.any(shift):
                spec.site(site).pos = pos
        site_names.append(site)
        worn_names.append(site if mount is None else _add_mount(spec, name, pos, quat, mount))
    st = mujoco.mjtSensor
    obj = mujoco.mjtObj
    for name, bone, site in zip(map(bname, order), site_names, worn_names, strict=True):
        spec.add_sensor(
            name=f"{name}:site_pos", type=st.mjSENS_FRAMEPOS, objtype=obj.mjOBJ_SITE, objname=site
        )
        spec.add_sensor(
            name=f"{name}:site_quat", type=st.mjSENS_FRAMEQUAT, objtype=obj.mjOBJ_SITE, objname=site
        )
        spec.add_sensor(
            name=f"{name}:bone_pos", type=st.mjSENS_FRAMEPOS, objtype=obj.mjOBJ_SITE, objname=bone
        )
        spec.add_sensor(
            name=f"{name}:bone_quat", type=st.mjSENS_FRAMEQUAT, objtype=obj.mjOBJ_SITE, objname=bone
        )
        spec.add_sensor(
            name=f"{name}:bone_acc", type=st.mjSENS_ACCELEROMETER, objtype=obj.mjOBJ_SITE, objname=bone
        )
        spec.add_sensor(name=f"{name}:bone_gyro", type=st.mjSENS_GYRO, objtype=obj.mjOBJ_SITE, objname=bone)
        spec.add_sensor(
            name=f"{name}:acc", type=st.mjSENS_ACCELEROMETER, objtype=obj.mjOBJ_SITE, objname=site
        )
        spec.add_sensor(name=f"{name}:gyro", type=st.mjSENS_GYRO, objtype=obj.mjOBJ_SITE, objname=site)
        spec.add_sensor(name=f"{name}:mag", type=st.mjSENS_MAGNETOMETER, objtype=obj.mjOBJ_SITE, objname=site)
        spec.add_sensor(
            name=f"{name}:body_pos", type=st.mjSENS_FRAMEPOS, objtype=obj.mjOBJ_XBODY, objname=name
        )
        spec.add_sensor(
            name=f"{name}:body_quat", type=st.mjSENS_FRAMEQUAT, objtype=obj.mjOBJ_XBODY, objname=name
        )
    spec.add_sensor(name="clock", type=st.mjSENS_CLOCK)
    free_root = any(base.jnt_type[j] == _FREE for j in range(base.njnt) if base.jnt_bodyid[j] == root)
    if free_root:
        data0 = mujoco.MjData(base)
        mujoco.mj_kinematics(base, data0)
        mocap = spec.worldbody.add_body(name="simbench_root_driver", mocap=True)
        mocap.pos = data0.xpos[root].copy()
        mocap.quat = data0.xquat[root].copy()
        weld = spec.add_equality(
            name="simbench_root_weld", type=mujoco.mjtEq.mjEQ_WELD, objtype=obj.mjOBJ_BODY
        )
        weld.name1 = "simbench_root_driver"
        weld.name2 = bname(root)
        # anchor at the driver's origin, relative pose taken from the reference pose, torque
        # scale 1 (MjSpec's default data belong to other constraint types)
        weld.data = np.array([0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1.0] + [0.0] * (len(weld.data) - 11))
        weld.solref = np.array([0.005, 1.0])
    for b in order[1:]:
        jbody = joint_body[b]
        for j in jb[jbody]:
            jname = mujoco.mj_id2name(base, mujoco.mjtObj.mjOBJ_JOINT, j)
            gears = np.eye(3) if base.jnt_type[j] == _BALL else np.eye(1, 3)
            for g in gears:
                act = spec.add_actuator(name=f"{jname}:{'xyz'[int(np.argmax(g))]}", target=jname)
                act.trntype = mujoco.mjtTrn.mjTRN_JOINT
                act.gear = np.concatenate([g, np.zeros(3)])
                act.set_to_position(kp=1.0, dampratio=1.0)
    model = _compile(spec, source)
    # gains from the joint-space inertia at the reference pose
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    kp = np.zeros(model.nu)
    for a in range(model.nu):
        j = int(model.actuator_trnid[a, 0])
        dof = int(model.jnt_dofadr[j]) + (
            int(np.argmax(model.actuator_gear[a, :3])) if model.jnt_type[j] == _BALL else 0
        )
        kp[a] = M[dof, dof] * (2 * np.pi * TRACKING_HZ) ** 2
    for a, act in enumerate(spec.actuators):
        act.set_to_position(kp=float(kp[a]), dampratio=DAMPRATIO)
    model = _compile(spec, source)
    model.opt.magnetic[:] = EARTH_FIELD_UT

    def sid(kind: str, name: str) -> int:
        return int(model.sensor_adr[mujoco.mj_name2id(model, obj.mjOBJ_SENSOR, f"{name}:{kind}")])

    sensor_names = tuple(bname(b) for b in order)
    adr = {
        kind: np.array([sid(kind, n) for n in sensor_names])
        for kind in (
            "site_pos",
            "site_quat",
            "bone_pos",
            "bone_quat",
            "bone_acc",
            "bone_gyro",
            "acc",
            "gyro",
            "mag",
            "body_pos",
            "body_quat",
        )
    }
    articulations = []
    for b in order[1:]:
        jbody = joint_body[b]
        jnames = tuple(mujoco.mj_id2name(base, obj.mjOBJ_JOINT, j) for j in jb[jbody])
        kinds = tuple("ball" if base.jnt_type[j] == _BALL else "hinge" for j in jb[jbody])
        acts = []
        for jn in jnames:
            for axis in "xyz":
                a = mujoco.mj_name2id(model, obj.mjOBJ_ACTUATOR, f"{jn}:{axis}")
                if a >= 0:
                    acts.append(a)
        cone = 0.0
        hr = []
        for j in jb[jbody]:
            limited = bool(base.jnt_limited[j])
            if base.jnt_type[j] == _BALL:
                cone = float(base.jnt_range[j, 1]) if limited else 0.0
            else:
                hr.append(base.jnt_range[j] if limited else (-np.inf, np.inf))
        articulations.append(
            Articulation(
                body=bname(jbody),
                sensor=bname(b),
                joints=jnames,
                kinds=kinds,
                actuators=tuple(acts),
                cone=cone,
                hinge_range=np.array(hr, dtype=float).reshape(-1, 2),
            )
        )
    mocap_id = (
        int(model.body_mocapid[mujoco.mj_name2id(model, obj.mjOBJ_BODY, "simbench_root_driver")])
        if free_root
        else -1
    )
    return CaptureModel(
        source=source,
        model=model,
        sensors=sensor_names,
        parent_of={bname(c): bname(p) for c, p in parent_of.items()},
        articulations=tuple(articulations),
        site_ids=np.array([mujoco.mj_name2id(model, obj.mjOBJ_SITE, s) for s in site_names]),
        body_ids=np.array([mujoco.mj_name2id(model, obj.mjOBJ_BODY, bname(b)) for b in order]),
        mocap_id=mocap_id,
        mount=mount,
        adr=adr,
        clock_adr=int(model.sensor_adr[mujoco.mj_name2id(model, obj.mjOBJ_SENSOR, "clock")]),
    )
