"""MuJoCo models made ready for capture sessions: sensors, actuators and a driven root.

Any MJCF model can be used (the built-in ``linkage`` and ``humanoid`` shipped in ``simbench/models/``,
a dm_control suite model as ``dm_control:NAME``, or a path to an ``.xml`` file:
:mod:`simbench.sim.mjcf`). It is edited programmatically with :class:`mujoco.MjSpec`
(:mod:`simbench.sim.instrument`, :mod:`simbench.sim.mounts`):

- **sensors**: one per chosen body, on the body's ``sensor_<body>`` site if the model has one,
  else on a new site near the body's centre of mass, turned against the body frame (real
  sensors are never aligned with the bone). Each gets MuJoCo's ``framepos``, ``framequat``,
  ``accelerometer``, ``gyro`` and ``magnetometer``; each sensor body gets ``framepos`` and
  ``framequat`` of its body frame; one ``clock`` sensor stamps the samples.
- **actuators**: the model's own are removed; every degree of freedom of every joint between
  sensor bodies gets a ``position`` actuator (for a ball joint, three, whose lengths are the
  components of the joint's rotation vector). The gains track at 2 Hz, damping ratio 2:
  ``kp = I (2 pi 2 Hz)^2`` with ``I`` the joint-space inertia at the reference pose (see
  :data:`~simbench.sim.instrument.TRACKING_HZ`).
- **play** (optional): each joint body gets free play, three limited slides
  (:mod:`simbench.sim.play`), so that the ball shifts in its socket under load;
- **root**: if the root sensor body has a free joint it is welded (a stiff soft constraint) to
  a mocap body that the motion program moves -- the linkage carried by hand, a person's pelvis
  moving through the room -- so the root moves by physics, not by a kinematic replay.

Sensor bodies must be joined by single joints: between a sensor body and the nearest sensor
body above it exactly one body may carry joints (1 ball joint or 1-3 hinges through one point),
so that every sensor pair of the hierarchy is a rotary joint with a fixed centre. The one
exception is a model of free bodies only, none joined (a pose trajectory's bodies,
:mod:`simbench.sim.pose_model`, one or more): it has no joints and no hierarchy, and is only
played back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from simbench.errors import InputError
from simbench.sim.instrument import (
    DAMPRATIO,
    ROOT_DRIVER,
    TRACKING_HZ,
    add_actuators,
    add_readings,
    add_root_driver,
    clock_address,
    place_sensor_sites,
    reading_addresses,
    set_tracking_gains,
)
from simbench.sim.mjcf import BUILTIN, MODELS_DIR, compile_spec, read_spec, resolve_model_path
from simbench.sim.mounts import Mount
from simbench.sim.play import add_play

__all__ = [
    "BUILTIN",
    "DAMPRATIO",
    "EARTH_FIELD_UT",
    "MODELS_DIR",
    "TRACKING_HZ",
    "Articulation",
    "CaptureModel",
    "Mount",
    "joint_sensor_indices",
    "load_capture_model",
    "resolve_model_path",
]

#: Earth field used by the magnetometers, world frame ENU (x east, y north, z up), microtesla:
#: 50 uT with 60 degrees inclination (mid-latitude Europe/North America).
EARTH_FIELD_UT = (0.0, 25.0, -43.30127018922193)

_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_BODY = mujoco.mjtObj.mjOBJ_BODY
_JOINT = mujoco.mjtObj.mjOBJ_JOINT


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
        joint_play_m: free play of every joint (:mod:`simbench.sim.play`), m; 0 = none.
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
    joint_play_m: float
    adr: dict[str, np.ndarray]
    clock_adr: int


def joint_sensor_indices(cm: CaptureModel) -> tuple[list[int], list[int]]:
    """``(parent, child)``: ``(J,)`` indices into ``cm.sensors`` of each articulation's sensors."""
    index = {name: k for k, name in enumerate(cm.sensors)}
    parent = [index[cm.parent_of[art.sensor]] for art in cm.articulations]
    child = [index[art.sensor] for art in cm.articulations]
    return parent, child


@dataclass(frozen=True)
class _SensorTree:
    """Sensor bodies (ids in the model as read) and the joints between them.

    Attributes:
        bodies: sensor body ids, parents before children; ``bodies[0]`` is the root.
        parent_of: ``{child body: parent sensor body}``.
        joint_body: ``{child body: the one body between it and its parent that has joints}``.
        joints: ``{body with joints: [joint ids]}`` (free joints left out).
    """

    bodies: tuple[int, ...]
    parent_of: dict[int, int]
    joint_body: dict[int, int]
    joints: dict[int, list[int]]


def _body_name(model: mujoco.MjModel, body_id: int) -> str:
    return mujoco.mj_id2name(model, _BODY, body_id)


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
    for body_id in range(1, model.nbody):
        name = _body_name(model, body_id)
        if name and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"sensor_{name}") >= 0:
            named.append(name)
    if named:
        return named
    with_joints = _joint_bodies(model)
    free_roots = {int(model.jnt_bodyid[j]) for j in range(model.njnt) if model.jnt_type[j] == _FREE}
    return [
        _body_name(model, body_id)
        for body_id in range(1, model.nbody)
        if body_id in with_joints or body_id in free_roots
    ]


def _sensor_body_ids(
    base: mujoco.MjModel, names: Sequence[str], source: str, forest: bool = False
) -> tuple[int, ...]:
    """Body ids of the sensor bodies, sorted (MuJoCo numbers parents before children)."""
    ids = []
    for name in names:
        body_id = mujoco.mj_name2id(base, _BODY, name)
        if body_id <= 0:
            bodies = [_body_name(base, k) for k in range(1, base.nbody)]
            raise InputError(f"model {source} has no body {name!r}; bodies: {', '.join(map(str, bodies))}")
        ids.append(body_id)
    if len(set(ids)) != len(ids):
        raise InputError(f"model {source}: sensor bodies named twice: {names}")
    if len(ids) < 2 and not (forest and ids and _free_root(base, ids[0])):
        raise InputError(f"model {source}: a capture needs at least 2 sensor bodies, got {names}")
    return tuple(sorted(ids))


def _sensor_tree(
    base: mujoco.MjModel, bodies: tuple[int, ...], source: str, forest: bool = False
) -> _SensorTree:
    """The tree of the sensor bodies; checks that one body with joints joins each pair (or, with
    ``forest``, that they are free bodies none of which joins another)."""
    is_sensor = set(bodies)
    joints = _joint_bodies(base)
    parent_of: dict[int, int] = {}
    joint_body: dict[int, int] = {}
    for body_id in bodies:
        between = [body_id]  # the child and the bodies up to (not including) its parent sensor
        parent_id = int(base.body_parentid[body_id])
        while parent_id != 0 and parent_id not in is_sensor:
            between.append(parent_id)
            parent_id = int(base.body_parentid[parent_id])
        if parent_id == 0:
            continue  # a root sensor (hangs from the world)
        parent_of[body_id] = parent_id
        with_joints = [x for x in between if x in joints]
        if len(with_joints) != 1:
            found = [_body_name(base, x) for x in with_joints]
            raise InputError(
                f"model {source}: sensor bodies {_body_name(base, parent_id)!r} and "
                f"{_body_name(base, body_id)!r} must be joined by the joints of exactly one body, found "
                f"joints on {found}; put a sensor on each body with joints"
            )
        joint_body[body_id] = with_joints[0]
    roots = [body_id for body_id in bodies if body_id not in parent_of]
    if forest and len(roots) > 1 and not parent_of and all(_free_root(base, r) for r in roots):
        return _SensorTree(bodies, parent_of, joint_body, joints)  # free bodies: a pose trajectory's
    if len(roots) != 1:
        raise InputError(
            f"model {source}: the sensor bodies must form one tree, found several roots: "
            f"{[_body_name(base, b) for b in roots]}"
        )
    return _SensorTree(bodies, parent_of, joint_body, joints)


def _check_joints(base: mujoco.MjModel, tree: _SensorTree, source: str) -> None:
    """Each joint body has one ball joint or 1-3 hinges, all through one point."""
    for body_id in tree.joint_body.values():
        joint_ids = tree.joints[body_id]
        kinds = {int(base.jnt_type[j]) for j in joint_ids}
        names = [mujoco.mj_id2name(base, _JOINT, j) for j in joint_ids]
        if not kinds <= {_BALL, _HINGE} or (_BALL in kinds and len(joint_ids) > 1) or len(joint_ids) > 3:
            raise InputError(f"model {source}: body joints {names} must be one ball joint or 1-3 hinges")
        anchors = base.jnt_pos[joint_ids]
        if np.max(np.abs(anchors - anchors[0])) > 1e-9:
            raise InputError(f"model {source}: joints {names} do not pass through one point")


def _articulation(
    base: mujoco.MjModel, model: mujoco.MjModel, tree: _SensorTree, body_id: int
) -> Articulation:
    """The joints of sensor body ``body_id`` (an id in ``base``), their actuators in ``model``."""
    joint_body = tree.joint_body[body_id]
    joint_ids = tree.joints[joint_body]
    names = tuple(mujoco.mj_id2name(base, _JOINT, j) for j in joint_ids)
    actuators = []
    for name in names:
        for axis in "xyz":
            actuator = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"{name}:{axis}")
            if actuator >= 0:
                actuators.append(actuator)
    cone = 0.0
    hinge_range = []
    for j in joint_ids:
        limited = bool(base.jnt_limited[j])
        if base.jnt_type[j] == _BALL:
            cone = float(base.jnt_range[j, 1]) if limited else 0.0
        else:
            hinge_range.append(base.jnt_range[j] if limited else (-np.inf, np.inf))
    return Articulation(
        body=_body_name(base, joint_body),
        sensor=_body_name(base, body_id),
        joints=names,
        kinds=tuple("ball" if base.jnt_type[j] == _BALL else "hinge" for j in joint_ids),
        actuators=tuple(actuators),
        cone=cone,
        hinge_range=np.array(hinge_range, dtype=float).reshape(-1, 2),
    )


def _free_root(base: mujoco.MjModel, root: int) -> bool:
    """The root sensor body has a free joint."""
    return any(base.jnt_type[j] == _FREE for j in range(base.njnt) if base.jnt_bodyid[j] == root)


def load_capture_model(
    source: str,
    *,
    sensor_bodies: Sequence[str] | None = None,
    mount: Mount | None = None,
    placement: Mapping[str, Sequence[float]] | None = None,
    joint_play_m: float = 0.0,
    spec: mujoco.MjSpec | None = None,
    played_back: bool = False,
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
        joint_play_m: free play of every joint between sensor bodies, m (half the clearance
            per axis; 0 = none): :mod:`simbench.sim.play`.
        spec: the model already as a spec (a BVH clip's skeleton, :mod:`simbench.sim.bvh_model`),
            named ``source``; ``None``: read ``source``.
        played_back: the model will only be played back (a recorded motion), not moved by physics:
            free bodies none of which joins another (one or more) are a capture model too.

    Raises:
        InputError: unknown model or body names, bodies not joined by single joints.
    """
    if not (np.isfinite(joint_play_m) and joint_play_m >= 0):
        raise InputError(f"joint play must be a finite number >= 0 m, got {joint_play_m!r}")
    spec = read_spec(source) if spec is None else spec
    base = compile_spec(spec, source)
    names = list(sensor_bodies) if sensor_bodies is not None else _default_sensor_bodies(base)
    unknown = sorted(set(placement or {}) - set(names))
    if unknown:
        raise InputError(f"placement names {unknown}, which carry no sensor; sensors: {names}")
    tree = _sensor_tree(base, _sensor_body_ids(base, names, source, played_back), source, played_back)
    _check_joints(base, tree, source)
    sensors = tuple(_body_name(base, body_id) for body_id in tree.bodies)
    root = tree.bodies[0]
    children = [b for b in tree.bodies if b in tree.parent_of]  # bodies[1:] but in a forest of free bodies
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    for sensor in list(spec.sensors):
        spec.delete(sensor)
    bone_sites, worn_sites = place_sensor_sites(spec, base, tree.bodies, placement or {}, mount)
    add_readings(spec, sensors, bone_sites, worn_sites)
    free_root = _free_root(base, root)
    if free_root:
        add_root_driver(spec, base, root)
    if joint_play_m > 0:
        add_play(spec, [_body_name(base, tree.joint_body[b]) for b in children], joint_play_m)
    add_actuators(spec, base, [j for b in children for j in tree.joints[tree.joint_body[b]]])
    set_tracking_gains(spec, compile_spec(spec, source))
    model = compile_spec(spec, source)
    model.opt.magnetic[:] = EARTH_FIELD_UT
    driver = mujoco.mj_name2id(model, _BODY, ROOT_DRIVER)
    return CaptureModel(
        source=source,
        model=model,
        sensors=sensors,
        parent_of={_body_name(base, c): _body_name(base, p) for c, p in tree.parent_of.items()},
        articulations=tuple(_articulation(base, model, tree, body_id) for body_id in children),
        site_ids=np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, s) for s in bone_sites]),
        body_ids=np.array([mujoco.mj_name2id(model, _BODY, name) for name in sensors]),
        mocap_id=int(model.body_mocapid[driver]) if free_root else -1,
        mount=mount,
        joint_play_m=float(joint_play_m),
        adr=reading_addresses(model, sensors),
        clock_adr=clock_address(model),
    )
