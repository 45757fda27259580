"""Capture sessions moved by MuJoCo physics, with exact ground truth and modelled sensors.

A session runs in five stages, one module each:

1. **plan** (:mod:`simbench.sim.plan`): the motion program, the root's phases, the physics
   timestep and the random streams, all from the session seed;
2. **physics** (:mod:`simbench.sim.physics`): ``mujoco.rollout`` runs the dynamics natively in
   chunks of steps (gravity, position actuators tracking the program, the root welded to its
   driver); samples are taken every ``k`` physics steps, the physics timestep being the model's
   or slightly finer so that the capture period is a whole number ``k`` of steps;
3. **readings** (:mod:`simbench.sim.readings`): MuJoCo's own sensors give, at every sample, each
   sensor's pose, specific force and angular velocity and each segment's pose;
4. **skin and sensor models**: joint laxity moves joint centres (and everything below them),
   soft-tissue artefact and slip events move the worn sensors off their bone placement (on top
   of the physics of a sprung soft-tissue mount, if any), the magnetic field is the Earth's plus
   dipole disturbances at each sensor's place (:mod:`simbench.sim.readings`), and the tracker and
   IMU models add their imperfections (:mod:`simbench.sim.sensor_models`);
5. **the Dataset** (here): truth, measurements and metadata.

Truth constants (joint centres in both sensor frames, hinge axes, sensor placement) are read off
the model at its reference pose; the joints of a MuJoCo model are exact, so they hold at every
frame to rounding (unless joint laxity is switched on). Every random draw comes from a stream
spawned from the session seed.
"""

from __future__ import annotations

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.errors import InputError
from simbench.io.dataset import Dataset, SensorData, Truth
from simbench.sim.models import CaptureModel, joint_sensor_indices
from simbench.sim.physics import CHUNK_STEPS, SETTLE_S, run_physics
from simbench.sim.plan import (
    SessionConfig,
    SessionPlan,
    load_session_model,
    plan_session,
    sensors_source,
    steps_per_sample,
)
from simbench.sim.readings import Readings, readings_at_samples, true_sensor_data, wear
from simbench.sim.sensor_models import apply_imu, apply_tracker
from simbench.versions import software_versions

__all__ = [
    "CHUNK_STEPS",
    "SETTLE_S",
    "SessionConfig",
    "SessionPlan",
    "load_session_model",
    "plan_session",
    "run_session",
    "steps_per_sample",
    "truth_constants",
]


def truth_constants(cm: CaptureModel) -> dict[str, np.ndarray]:
    """Joint centres and axes in the sensor frames, sensor placement: exact, from the model.

    Read at the model's reference pose. With ``J`` articulations and ``N`` sensors:
    ``joint_in_parent``, ``joint_in_child`` ``(J, 3)`` m; ``single_axis`` ``(J,)`` bool;
    ``axis_in_parent``, ``axis_in_child`` ``(J, 3)`` unit vectors (NaN unless a single hinge);
    ``p_b_s`` ``(N, 3)`` m and ``q_b_s`` ``(N, 4)`` wxyz: each sensor's bone placement in its
    segment (body) frame.
    """
    m = cm.model
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    parent, child = joint_sensor_indices(cm)
    n_j = len(cm.articulations)
    out = {
        "joint_in_parent": np.zeros((n_j, 3)),
        "joint_in_child": np.zeros((n_j, 3)),
        "single_axis": np.zeros(n_j, dtype=bool),
        "axis_in_parent": np.full((n_j, 3), np.nan),
        "axis_in_child": np.full((n_j, 3), np.nan),
    }
    R_w_s = d.site_xmat[cm.site_ids].reshape(-1, 3, 3)
    p_w_s = d.site_xpos[cm.site_ids]
    for k, art in enumerate(cm.articulations):
        i_p, i_c = parent[k], child[k]
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, art.joints[0])
        anchor_w = d.xanchor[j]
        out["joint_in_parent"][k] = R_w_s[i_p].T @ (anchor_w - p_w_s[i_p])
        out["joint_in_child"][k] = R_w_s[i_c].T @ (anchor_w - p_w_s[i_c])
        if art.kinds == ("hinge",):
            out["single_axis"][k] = True
            out["axis_in_parent"][k] = R_w_s[i_p].T @ d.xaxis[j]
            out["axis_in_child"][k] = R_w_s[i_c].T @ d.xaxis[j]
    R_w_b = d.xmat[cm.body_ids].reshape(-1, 3, 3)
    p_w_b = d.xpos[cm.body_ids]
    out["p_b_s"] = np.einsum("nji,nj->ni", R_w_b, p_w_s - p_w_b)
    out["q_b_s"] = matrix_to_quat(np.einsum("nji,njk->nik", R_w_b, R_w_s))
    return out


def _measure(config: SessionConfig, plan: SessionPlan, time_s: np.ndarray, actual: SensorData) -> SensorData:
    """What the configured tracker and IMU report of the actual sensors."""
    sensor_config = plan.sensor_config
    p_w_s, q_w_s, valid = apply_tracker(
        time_s, actual.p_w_s, actual.q_w_s, sensor_config.tracker, plan.streams["tracker"]
    )
    acc, gyro, mag = apply_imu(
        config.rate_hz, actual.acc, actual.gyro, actual.mag, sensor_config.imu, plan.streams["imu"]
    )
    return SensorData(p_w_s=p_w_s, q_w_s=q_w_s, valid=valid, acc=acc, gyro=gyro, mag=mag)


def _truth(cm: CaptureModel, readings: Readings, bone: SensorData, actual: SensorData) -> Truth:
    """The ground truth: sensors on the bone and as worn, segments, joint centres and constants."""
    const = truth_constants(cm)
    _, child = joint_sensor_indices(cm)
    R_w_c = quat_to_matrix(bone.q_w_s[:, child])
    joint_w = np.einsum("fjab,jb->fja", R_w_c, const["joint_in_child"]) + bone.p_w_s[:, child]
    return Truth(
        rigid=bone,
        actual=actual,
        p_w_b=readings.p_w_b,
        q_w_b=readings.q_w_b,
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


def _meta(
    config: SessionConfig, cm: CaptureModel, plan: SessionPlan, n_samples: int, warnings: dict[str, int]
) -> dict:
    """The Dataset's metadata: what was asked, what ran, MuJoCo's warnings, software versions."""
    sensor_config = plan.sensor_config
    return {
        "model": config.model,
        "program": plan.program.name,
        "seed": config.seed,
        "rate_hz": config.rate_hz,
        "duration_s": config.duration_s,
        "n_samples": n_samples,
        "physics_timestep_s": plan.timestep,
        "model_timestep_s": float(cm.model.opt.timestep),
        "steps_per_sample": plan.steps_per_sample,
        "sensor_model": sensor_config.name,
        "sensor_config": sensor_config.as_dict(),
        "mujoco_warnings": warnings,
        **({"sensor_notes": list(plan.notes)} if plan.notes else {}),
        **({} if plan.playback is None else {"playback": plan.playback.as_dict()}),
        "config": config.as_dict(),
        "versions": software_versions(),
    }


def run_session(config: SessionConfig, cm: CaptureModel | None = None) -> Dataset:
    """Simulate one capture session and return its dataset.

    Truth keeps both the bone-rigid sensor data (``truth.rigid``) and the actual ones where the
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
    sensordata, warnings = run_physics(cm, plan)
    readings = wear(readings_at_samples(cm, sensordata), cm, plan.sensor_config.skin, plan.streams["skin"])
    time_s = readings.time_s
    valid = np.ones((time_s.size, len(cm.sensors)), dtype=bool)
    magnetic = plan.sensor_config.magnetic
    bone = true_sensor_data(readings.bone, valid, magnetic, time_s, cm.sensors)
    actual = true_sensor_data(readings.worn, valid, magnetic, time_s, cm.sensors)
    measured = _measure(config, plan, time_s, actual)
    if not measured.valid.any():
        raise InputError(
            f"{sensors_source(config)}: the tracker gives no valid sample in {time_s.size} samples "
            "(its latency, dropouts or sample rate); no dataset is written"
        )
    return Dataset(
        time_s=time_s,
        sensors=cm.sensors,
        measured=measured,
        truth=_truth(cm, readings, bone, actual),
        meta=_meta(config, cm, plan, time_s.size, warnings),
        position_unit_scale=plan.sensor_config.tracker.unit_scale,
    )
