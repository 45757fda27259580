"""Capture sessions moved by MuJoCo physics, with exact ground truth.

The motion program gives actuator set-points and the root driver's pose at every physics
step; ``mujoco.rollout`` runs the dynamics natively in chunks of steps (gravity, position
actuators tracking the program, the root welded to its driver) and MuJoCo's own sensors give,
at every sample, each sensor's pose, specific force, angular velocity and magnetic field and each
segment's pose. Samples are taken every ``k`` physics steps: the physics timestep is the model's,
or slightly finer so that the capture period is a whole number ``k`` of steps.

Truth constants (joint centres in both sensor frames, hinge axes, sensor placement) are read off
the model at its reference pose; the joints of a MuJoCo model are exact, so they hold at every
frame to rounding.
"""

from __future__ import annotations

import math
import platform
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

import simbench
from calibration.rotations import matrix_to_quat, quat_to_matrix, rotvec_to_matrix
from simbench.dataset import Dataset, SensorData, Truth
from simbench.errors import InputError
from simbench.models import CaptureModel, load_capture_model
from simbench.programs import (
    BUILTIN_PROGRAMS,
    Program,
    builtin_program,
    joint_targets,
    load_program,
    root_pose,
)

#: Physics steps per rollout call (bounds memory: states and sensor rows of one chunk).
CHUNK_STEPS = 12_000


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
    """

    model: str = "linkage"
    motion: str = "exercise"
    duration_s: float = 20.0
    rate_hz: float = 120.0
    seed: int = 0
    sensor_bodies: tuple[str, ...] | None = None

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


def run_session(config: SessionConfig, cm: CaptureModel | None = None) -> Dataset:
    """Simulate one capture session and return its dataset (measured = ideal = truth).

    Args:
        config: the session.
        cm: an already loaded model for ``config.model`` (loaded when ``None``).

    Raises:
        InputError: bad model, body or program names, rates, durations.
    """
    if cm is None:
        cm = load_capture_model(config.model, sensor_bodies=config.sensor_bodies)
    m = cm.model
    model_dt = float(m.opt.timestep)
    k, dt = steps_per_sample(model_dt, config.rate_hz)
    m.opt.timestep = dt
    rng = np.random.default_rng(config.seed)
    program = _program(config, cm, rng)
    root_phases = rng.uniform(0, 2 * np.pi, 12)
    n_samples = math.floor(config.duration_s * config.rate_hz + 1e-9)
    if n_samples < 2:
        raise InputError(f"duration {config.duration_s} s at {config.rate_hz} Hz gives fewer than 2 samples")
    n_steps = n_samples * k
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
    rows = []
    chunk = max(k, (CHUNK_STEPS // k) * k)
    for start in range(0, n_steps, chunk):
        n = min(chunk, n_steps - start)
        t = (start + np.arange(n)) * dt
        control = [joint_targets(program, cm, t)]
        if mocap >= 0:
            pos, quat = root_pose(program, p0, q0, t, root_phases)
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
    m.opt.timestep = model_dt
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(d.warning) if w.number > 0}
    sd = np.concatenate(rows, axis=0)[:n_samples]
    a = cm.adr

    def take(kind: str, width: int) -> np.ndarray:
        cols = a[kind][:, None] + np.arange(width)[None, :]
        return sd[:, cols]

    const = truth_constants(cm)
    n_sensors = len(cm.sensors)
    valid = np.ones((n_samples, n_sensors), dtype=bool)
    ideal = SensorData(
        p_w_s=take("site_pos", 3),
        q_w_s=take("site_quat", 4),
        valid=valid,
        acc=take("acc", 3),
        gyro=take("gyro", 3),
        mag=take("mag", 3),
    )
    index = {name: i for i, name in enumerate(cm.sensors)}
    child_idx = [index[art.sensor] for art in cm.articulations]
    R_c = quat_to_matrix(ideal.q_w_s[:, child_idx])
    joint_w = np.einsum("fjab,jb->fja", R_c, const["joint_in_child"]) + ideal.p_w_s[:, child_idx]
    truth = Truth(
        sensors=ideal,
        p_w_b=take("body_pos", 3),
        q_w_b=take("body_quat", 4),
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
        "program": program.name,
        "seed": config.seed,
        "rate_hz": config.rate_hz,
        "duration_s": config.duration_s,
        "n_samples": n_samples,
        "physics_timestep_s": dt,
        "model_timestep_s": model_dt,
        "steps_per_sample": k,
        "sensor_model": "ideal",
        "mujoco_warnings": warnings,
        "config": config.as_dict(),
        "versions": {
            "simbench": simbench.__version__,
            "mujoco": mujoco.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
    }
    return Dataset(time_s=sd[:, cm.clock_adr], sensors=cm.sensors, measured=ideal, truth=truth, meta=meta)
