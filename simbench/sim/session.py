"""Capture sessions moved by MuJoCo physics, with exact ground truth and modelled sensors.

The motion program gives actuator set-points and the root driver's pose at every physics
step; ``mujoco.rollout`` runs the dynamics natively in chunks of steps (gravity, position
actuators tracking the program, the root welded to its driver) and MuJoCo's own sensors give,
at every sample, each sensor's pose, specific force, angular velocity and magnetic field and each
segment's pose. Samples are taken every ``k`` physics steps: the physics timestep is the model's,
or slightly finer so that the capture period is a whole number ``k`` of steps.

Truth constants (joint centres in both sensor frames, hinge axes, sensor placement) are read off
the model at its reference pose; the joints of a MuJoCo model are exact, so they hold at every
frame to rounding (unless joint laxity is switched on).

Then the sensor configuration (:mod:`simbench.sim.sensor_config`) turns truth into measurements:
joint laxity moves joint centres (and everything below them), soft-tissue artefact and slip
events move the worn sensors off their bone placement (on top of the physics of a sprung
soft-tissue mount, if any), the magnetic field is the Earth's plus dipole disturbances at each
sensor's place, and the tracker and IMU models add their imperfections. Every random draw comes
from a stream spawned from the session seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from calibration.rotations import matrix_to_quat, quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError
from simbench.io.dataset import Dataset, SensorData, Truth
from simbench.sim.models import CaptureModel, Mount, load_capture_model
from simbench.sim.programs import (
    BUILTIN_PROGRAMS,
    Program,
    builtin_program,
    joint_targets,
    load_program,
    root_pose,
)
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.sim.sensor_models import apply_imu, apply_tracker, dipole_field, earth_field
from simbench.sim.skin import (
    laxity_offsets,
    per_sensor,
    relative_rotvecs,
    second_derivative,
    slip_offsets,
    soft_tissue_offsets,
    subtree_masks,
)
from simbench.versions import software_versions

#: Physics steps per rollout call (bounds memory: states and sensor rows of one chunk).
CHUNK_STEPS = 12_000

#: Seconds of physics before the recording starts, holding the first set-points, so that the
#: body hangs at rest under gravity (not in free fall) when the capture begins.
SETTLE_S = 1.0


@dataclass(frozen=True)
class SessionConfig:
    """What a capture session is asked to be.

    Attributes:
        model: model name (``linkage``, ``humanoid``, ``dm_control:NAME``, an MJCF path).
        motion: built-in program name or a program TOML path.
        duration_s: session length, s (> 0).
        rate_hz: capture rate, Hz (> 0, at most the model's physics rate).
        seed: seed of the session's ``numpy.random.Generator``.
        sensor_bodies: bodies carrying a sensor, or ``None`` for the model's default.
        sensors: sensor preset name, configuration TOML path, or a :class:`SensorConfig`
            (:mod:`simbench.sim.sensor_config`).
        placement: ``((sensor, (dx, dy, dz)), ...)`` sensor shifts in their body frames, m.
    """

    model: str = "linkage"
    motion: str = "exercise"
    duration_s: float = 20.0
    rate_hz: float = 120.0
    seed: int = 0
    sensor_bodies: tuple[str, ...] | None = None
    sensors: str | SensorConfig = "ideal"
    placement: tuple[tuple[str, tuple[float, float, float]], ...] = ()

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise InputError(f"duration must be > 0 s, got {self.duration_s}")
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise InputError(f"rate must be > 0 Hz, got {self.rate_hz}")

    def as_dict(self) -> dict:
        """JSON-ready copy."""
        return {
            "model": self.model,
            "motion": self.motion,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "seed": self.seed,
            "sensor_bodies": None if self.sensor_bodies is None else list(self.sensor_bodies),
            "sensors": self.sensors if isinstance(self.sensors, str) else self.sensors.as_dict(),
            "placement": {k: list(v) for k, v in self.placement},
        }


def steps_per_sample(model_timestep: float, rate_hz: float) -> tuple[int, float]:
    """``(k, dt)``: physics steps per sample and the timestep, ``dt <= model_timestep``.

    Raises:
        InputError: when the capture rate is above the model's physics rate.
    """
    period = 1.0 / rate_hz
    if period < model_timestep * (1 - 1e-9):
        raise InputError(
            f"capture rate {rate_hz:g} Hz is above the model's physics rate {1 / model_timestep:g} Hz"
        )
    k = max(1, math.ceil(period / model_timestep - 1e-9))
    return k, period / k


def _program(config: SessionConfig, cm: CaptureModel, rng: np.random.Generator) -> Program:
    if config.motion in BUILTIN_PROGRAMS:
        return builtin_program(config.motion, cm, config.duration_s, rng)
    if config.motion.endswith(".toml"):
        return load_program(config.motion, cm)
    raise InputError(
        f"unknown motion {config.motion!r}: expected one of {', '.join(BUILTIN_PROGRAMS)} or a .toml file"
    )


def _initial_state(cm: CaptureModel, targets0: np.ndarray) -> mujoco.MjData:
    """Model data at the reference pose with the joints at the program's first set-points."""
    m = cm.model
    d = mujoco.MjData(m)
    for art in cm.articulations:
        col = 0
        for joint, kind in zip(art.joints, art.kinds, strict=True):
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
            adr = m.jnt_qposadr[j]
            if kind == "ball":
                rv = targets0[list(art.actuators[col : col + 3])]
                d.qpos[adr : adr + 4] = matrix_to_quat(rotvec_to_matrix(rv))
                col += 3
            else:
                d.qpos[adr] = targets0[art.actuators[col]]
                col += 1
    d.ctrl[:] = targets0
    mujoco.mj_forward(m, d)
    return d


def truth_constants(cm: CaptureModel) -> dict[str, np.ndarray]:
    """Joint centres and axes in the sensor frames, sensor placement: exact, from the model."""
    m = cm.model
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    index = {name: k for k, name in enumerate(cm.sensors)}
    n_j = len(cm.articulations)
    out = {
        "joint_in_parent": np.zeros((n_j, 3)),
        "joint_in_child": np.zeros((n_j, 3)),
        "single_axis": np.zeros(n_j, dtype=bool),
        "axis_in_parent": np.full((n_j, 3), np.nan),
        "axis_in_child": np.full((n_j, 3), np.nan),
    }
    R_s = d.site_xmat[cm.site_ids].reshape(-1, 3, 3)
    p_s = d.site_xpos[cm.site_ids]
    for k, art in enumerate(cm.articulations):
        c = index[art.sensor]
        p = index[cm.parent_of[art.sensor]]
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, art.joints[0])
        anchor = d.xanchor[j]
        out["joint_in_parent"][k] = R_s[p].T @ (anchor - p_s[p])
        out["joint_in_child"][k] = R_s[c].T @ (anchor - p_s[c])
        if art.kinds == ("hinge",):
            out["single_axis"][k] = True
            out["axis_in_parent"][k] = R_s[p].T @ d.xaxis[j]
            out["axis_in_child"][k] = R_s[c].T @ d.xaxis[j]
    R_b = d.xmat[cm.body_ids].reshape(-1, 3, 3)
    p_b = d.xpos[cm.body_ids]
    out["p_b_s"] = np.einsum("nji,nj->ni", R_b, p_s - p_b)
    out["q_b_s"] = matrix_to_quat(np.einsum("nji,njk->nik", R_b, R_s))
    return out


@dataclass(frozen=True)
class SessionPlan:
    """What a session will do, fixed before any physics runs.

    Attributes:
        program: the motion program.
        root_phases: ``(12,)`` phases of the root's motion, rad.
        steps_per_sample: physics steps per capture sample ``k``.
        timestep: physics timestep, s.
        n_samples: samples to record.
        sensors: the sensor configuration.
        streams: independent random generators for the ``skin``, ``tracker`` and ``imu`` models
            (so that switching one imperfection on does not change another's draws).
    """

    program: Program
    root_phases: np.ndarray
    steps_per_sample: int
    timestep: float
    n_samples: int
    sensors: SensorConfig
    streams: dict[str, np.random.Generator]


def _mount_of(sensors: SensorConfig) -> Mount | None:
    skin = sensors.skin
    if not skin.has_mount:
        return None
    return Mount(
        stiffness_n_per_m=skin.mount_stiffness_n_per_m,
        rot_stiffness_nm_per_rad=skin.mount_rot_stiffness_nm_per_rad,
        damping_ratio=skin.mount_damping_ratio,
        mass_kg=skin.mount_mass_kg,
    )


def _sensors(config: SessionConfig) -> SensorConfig:
    return config.sensors if isinstance(config.sensors, SensorConfig) else load_sensor_config(config.sensors)


def load_session_model(config: SessionConfig) -> CaptureModel:
    """The capture model a session needs (with the soft-tissue mount its sensors ask for)."""
    sensors = _sensors(config)
    return load_capture_model(
        config.model,
        sensor_bodies=config.sensor_bodies,
        mount=_mount_of(sensors),
        placement=dict(config.placement),
    )


def plan_session(config: SessionConfig, cm: CaptureModel) -> SessionPlan:
    """Draw everything random about a session from its seed, and check it against the model."""
    sensors = _sensors(config)
    if _mount_of(sensors) != cm.mount:
        raise InputError(
            f"sensors {config.sensors!r} need mount {_mount_of(sensors)}; the model was loaded with "
            f"{cm.mount} (load it with load_session_model)"
        )
    k, dt = steps_per_sample(float(cm.model.opt.timestep), config.rate_hz)
    n_samples = math.floor(config.duration_s * config.rate_hz + 1e-9)
    if n_samples < 2:
        raise InputError(f"duration {config.duration_s} s at {config.rate_hz} Hz gives fewer than 2 samples")
    seeds = np.random.SeedSequence(config.seed).spawn(5)
    motion_rng = np.random.default_rng(seeds[0])
    program = _program(config, cm, motion_rng)
    root_phases = np.random.default_rng(seeds[1]).uniform(0, 2 * np.pi, 12)
    streams = {
        name: np.random.default_rng(s) for name, s in zip(("skin", "tracker", "imu"), seeds[2:], strict=True)
    }
    return SessionPlan(program, root_phases, k, dt, n_samples, sensors, streams)


def _physics(cm: CaptureModel, plan: SessionPlan) -> tuple[np.ndarray, dict[str, int]]:
    """Run the dynamics; returns the sensordata rows at the samples and MuJoCo's warnings."""
    m = cm.model
    model_dt = float(m.opt.timestep)
    k, dt = plan.steps_per_sample, plan.timestep
    program = plan.program
    m.opt.timestep = dt
    try:
        n_steps = plan.n_samples * k
        d = _initial_state(cm, joint_targets(program, cm, np.zeros(1))[0])
        mocap = cm.mocap_id
        p0 = d.mocap_pos[mocap].copy() if mocap >= 0 else np.zeros(3)
        q0 = d.mocap_quat[mocap].copy() if mocap >= 0 else np.array([1.0, 0.0, 0.0, 0.0])
        mocap_pos0, mocap_quat0 = d.mocap_pos.copy(), d.mocap_quat.copy()
        spec_state = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        spec_ctrl = int(mujoco.mjtState.mjSTATE_CTRL)
        if mocap >= 0:
            spec_ctrl |= int(mujoco.mjtState.mjSTATE_MOCAP_POS) | int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)
        state = np.zeros(mujoco.mj_stateSize(m, spec_state))
        mujoco.mj_getState(m, d, state, spec_state)
        # settle: hold the program's first set-points until the body hangs at rest under
        # gravity, so that the recording does not start in free fall; then restart the clock
        n_settle = round(SETTLE_S / dt)
        if n_settle > 0:
            hold = [joint_targets(program, cm, np.zeros(1))]
            if mocap >= 0:
                hold += [mocap_pos0.reshape(1, -1), mocap_quat0.reshape(1, -1)]
            states, _ = rollout.rollout(
                m,
                d,
                state[None],
                np.tile(np.concatenate(hold, axis=1), (n_settle, 1))[None],
                control_spec=spec_ctrl,
            )
            state = states[0, -1].copy()
            state[0] = 0.0  # mjSTATE_TIME comes first in the full physics state
        rows = []
        chunk = max(k, (CHUNK_STEPS // k) * k)
        for start in range(0, n_steps, chunk):
            n = min(chunk, n_steps - start)
            t = (start + np.arange(n)) * dt
            control = [joint_targets(program, cm, t)]
            if mocap >= 0:
                pos, quat = root_pose(program, p0, q0, t, plan.root_phases)
                all_pos = np.tile(mocap_pos0, (n, 1, 1))  # the model's other mocap bodies stay put
                all_quat = np.tile(mocap_quat0, (n, 1, 1))
                all_pos[:, mocap] = pos
                all_quat[:, mocap] = quat
                control += [all_pos.reshape(n, -1), all_quat.reshape(n, -1)]
            states, sensordata = rollout.rollout(
                m, d, state[None], np.concatenate(control, axis=1)[None], control_spec=spec_ctrl
            )
            rows.append(sensordata[0, ::k].copy())
            state = states[0, -1].copy()
    finally:
        m.opt.timestep = model_dt
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(d.warning) if w.number > 0}
    return np.concatenate(rows, axis=0)[: plan.n_samples], warnings


def _field(sensors: SensorConfig, p_w: np.ndarray, R_w_s: np.ndarray) -> np.ndarray:
    """Magnetic field in the sensor frames at ``p_w`` ``(F, N, 3)``, uT."""
    b_w = np.broadcast_to(
        earth_field(sensors.magnetic.strength_ut, sensors.magnetic.inclination_deg), p_w.shape
    )
    for dist in sensors.magnetic.disturbance:
        b_w = b_w + dipole_field(p_w, np.asarray(dist.position), np.asarray(dist.moment_am2))
    return np.einsum("fsji,fsj->fsi", R_w_s, b_w)


def run_session(config: SessionConfig, cm: CaptureModel | None = None) -> Dataset:
    """Simulate one capture session and return its dataset.

    Truth keeps both the bone-rigid sensor data (``truth.sensors``) and the actual ones where the
    sensor sits on the skin (``truth.actual``: soft-tissue mount, artefact, slip events);
    ``measured`` is what the configured instruments report of the actual ones.

    Args:
        config: the session.
        cm: an already loaded model (:func:`load_session_model`; loaded when ``None``).

    Raises:
        InputError: bad model, body, program or sensor-configuration names, rates, durations.
    """
    if cm is None:
        cm = load_session_model(config)
    plan = plan_session(config, cm)
    sd, warnings = _physics(cm, plan)
    sensors = plan.sensors
    a = cm.adr

    def take(kind: str, width: int) -> np.ndarray:
        cols = a[kind][:, None] + np.arange(width)[None, :]
        return sd[:, cols]

    time_s = sd[:, cm.clock_adr]
    const = truth_constants(cm)
    index = {name: i for i, name in enumerate(cm.sensors)}
    parent_idx = [index[cm.parent_of[art.sensor]] for art in cm.articulations]
    child_idx = [index[art.sensor] for art in cm.articulations]
    n_samples, n_sensors = time_s.size, len(cm.sensors)
    bone_p, bone_q = take("bone_pos", 3), take("bone_quat", 4)
    bone_acc, bone_gyro = take("bone_acc", 3), take("bone_gyro", 3)
    worn_p, worn_q = take("site_pos", 3), take("site_quat", 4)
    worn_acc, worn_gyro = take("acc", 3), take("gyro", 3)
    body_p, body_q = take("body_pos", 3), take("body_quat", 4)
    R_b = quat_to_matrix(body_q)
    skin = sensors.skin
    rng = plan.streams["skin"]
    phi = relative_rotvecs(body_q, parent_idx, child_idx)
    # joint laxity: a joint centre moves in its parent's frame; the child's subtree moves with it
    laxity = per_sensor(skin.laxity_by_joint, cm.sensors, 0.0, "skin.laxity_by_joint")[child_idx]
    lax = laxity_offsets(phi, laxity, rng)
    lax_w = np.einsum("fjab,fjb->fja", R_b[:, parent_idx], lax)
    shift_w = np.einsum("fja,js->fsa", lax_w, subtree_masks(n_sensors, parent_idx, child_idx).astype(float))
    # skin: soft-tissue artefact and slip events, in each segment's frame
    sta = per_sensor(skin.sta_by_sensor, cm.sensors, skin.sta_amplitude_m, "skin.sta_by_sensor")
    offsets = soft_tissue_offsets(phi, parent_idx, child_idx, sta, rng)
    offsets += slip_offsets(time_s, cm.sensors, skin.slip)
    skin_w = np.einsum("fsab,fsb->fsa", R_b, offsets)
    if np.any(shift_w) or np.any(skin_w):
        body_p = body_p + shift_w
        bone_p = bone_p + shift_w
        bone_acc = bone_acc + np.einsum(
            "fsji,fsj->fsi", quat_to_matrix(bone_q), second_derivative(shift_w, time_s)
        )
        worn_p = worn_p + shift_w + skin_w
        worn_acc = worn_acc + np.einsum(
            "fsji,fsj->fsi", quat_to_matrix(worn_q), second_derivative(shift_w + skin_w, time_s)
        )
    valid = np.ones((n_samples, n_sensors), dtype=bool)
    bone = SensorData(
        p_w_s=bone_p,
        q_w_s=bone_q,
        valid=valid,
        acc=bone_acc,
        gyro=bone_gyro,
        mag=_field(sensors, bone_p, quat_to_matrix(bone_q)),
    )
    actual = SensorData(
        p_w_s=worn_p,
        q_w_s=worn_q,
        valid=valid,
        acc=worn_acc,
        gyro=worn_gyro,
        mag=_field(sensors, worn_p, quat_to_matrix(worn_q)),
    )
    p_meas, q_meas, valid_meas = apply_tracker(
        time_s, actual.p_w_s, actual.q_w_s, sensors.tracker, plan.streams["tracker"]
    )
    acc_meas, gyro_meas, mag_meas = apply_imu(
        config.rate_hz, actual.acc, actual.gyro, actual.mag, sensors.imu, plan.streams["imu"]
    )
    measured = SensorData(
        p_w_s=p_meas, q_w_s=q_meas, valid=valid_meas, acc=acc_meas, gyro=gyro_meas, mag=mag_meas
    )
    R_c = quat_to_matrix(bone.q_w_s[:, child_idx])
    joint_w = np.einsum("fjab,jb->fja", R_c, const["joint_in_child"]) + bone.p_w_s[:, child_idx]
    truth = Truth(
        sensors=bone,
        actual=actual,
        p_w_b=body_p,
        q_w_b=body_q,
        joint_w=joint_w,
        parent=tuple(cm.parent_of[art.sensor] for art in cm.articulations),
        child=tuple(art.sensor for art in cm.articulations),
        joint_in_parent=const["joint_in_parent"],
        joint_in_child=const["joint_in_child"],
        single_axis=const["single_axis"],
        axis_in_parent=const["axis_in_parent"],
        axis_in_child=const["axis_in_child"],
        p_b_s=const["p_b_s"],
        q_b_s=const["q_b_s"],
    )
    meta = {
        "model": config.model,
        "program": plan.program.name,
        "seed": config.seed,
        "rate_hz": config.rate_hz,
        "duration_s": config.duration_s,
        "n_samples": n_samples,
        "physics_timestep_s": plan.timestep,
        "model_timestep_s": float(cm.model.opt.timestep),
        "steps_per_sample": plan.steps_per_sample,
        "sensor_model": sensors.name,
        "sensor_config": sensors.as_dict(),
        "mujoco_warnings": warnings,
        "config": config.as_dict(),
        "versions": software_versions(),
    }
    return Dataset(
        time_s=time_s,
        sensors=cm.sensors,
        measured=measured,
        truth=truth,
        meta=meta,
        position_unit_scale=sensors.tracker.unit_scale,
    )
