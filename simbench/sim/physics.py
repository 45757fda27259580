"""The physics of a capture session: settle, then roll the program out natively in chunks.

The motion program gives actuator set-points and the root driver's pose at every physics step;
``mujoco.rollout`` runs the dynamics (gravity, position actuators tracking the program, the root
welded to its driver) in chunks of :data:`CHUNK_STEPS` steps, and MuJoCo's own sensors are kept
at every ``k``-th step, the capture samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.errors import InputError
from simbench.sim.models import CaptureModel
from simbench.sim.physics_cache import cache_folder, load_run, physics_key, store_run
from simbench.sim.plan import SessionPlan
from simbench.sim.playback import run_playback
from simbench.sim.programs import joint_targets, root_pose

#: Physics steps per rollout call (bounds memory: states and sensor rows of one chunk).
CHUNK_STEPS = 12_000

#: Seconds of physics before the recording starts, holding the first set-points, so that the
#: body hangs at rest under gravity (not in free fall) when the capture begins.
SETTLE_S = 1.0


def initial_state(cm: CaptureModel, targets0: np.ndarray) -> mujoco.MjData:
    """Model data at the reference pose with the joints at the program's first set-points.

    Args:
        cm: the capture model.
        targets0: ``(nu,)`` actuator set-points (rad; a ball joint's three are its rotation vector).
    """
    m = cm.model
    d = mujoco.MjData(m)
    for art in cm.articulations:
        col = 0
        for joint, kind in zip(art.joints, art.kinds, strict=True):
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
            adr = m.jnt_qposadr[j]
            if kind == "ball":
                rotvec = targets0[list(art.actuators[col : col + 3])]
                d.qpos[adr : adr + 4] = matrix_to_quat(rotvec_to_matrix(rotvec))
                col += 3
            else:
                d.qpos[adr] = targets0[art.actuators[col]]
                col += 1
    d.ctrl[:] = targets0
    mujoco.mj_forward(m, d)
    return d


@dataclass(frozen=True)
class _Driver:
    """The mocap bodies at the initial state.

    Attributes:
        p_w_root, q_w_root: ``(3,)`` m, ``(4,)`` wxyz: the root driver's reference pose (the origin
            of the program's root motion); zero and identity when the root is not driven.
        mocap_pos, mocap_quat: ``(nmocap, 3)``, ``(nmocap, 4)``: every mocap body (the model's
            others stay put).
    """

    p_w_root: np.ndarray
    q_w_root: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray


def _driver(cm: CaptureModel, d: mujoco.MjData) -> _Driver:
    mocap = cm.mocap_id
    return _Driver(
        p_w_root=d.mocap_pos[mocap].copy() if mocap >= 0 else np.zeros(3),
        q_w_root=d.mocap_quat[mocap].copy() if mocap >= 0 else np.array([1.0, 0.0, 0.0, 0.0]),
        mocap_pos=d.mocap_pos.copy(),
        mocap_quat=d.mocap_quat.copy(),
    )


def _control_spec(cm: CaptureModel) -> int:
    """``mujoco.rollout``'s control spec: actuator set-points, and the mocap poses when driven."""
    spec = int(mujoco.mjtState.mjSTATE_CTRL)
    if cm.mocap_id >= 0:
        spec |= int(mujoco.mjtState.mjSTATE_MOCAP_POS) | int(mujoco.mjtState.mjSTATE_MOCAP_QUAT)
    return spec


def _controls(cm: CaptureModel, plan: SessionPlan, driver: _Driver, t: np.ndarray) -> np.ndarray:
    """``(n, ncontrol)`` rollout controls at physics times ``t`` ``(n,)`` s."""
    n = t.size
    control = [joint_targets(plan.program, cm, t)]
    if cm.mocap_id >= 0:
        pos, quat = root_pose(plan.program, driver.p_w_root, driver.q_w_root, t, plan.root_phases)
        all_pos = np.tile(driver.mocap_pos, (n, 1, 1))  # the model's other mocap bodies stay put
        all_quat = np.tile(driver.mocap_quat, (n, 1, 1))
        all_pos[:, cm.mocap_id] = pos
        all_quat[:, cm.mocap_id] = quat
        control += [all_pos.reshape(n, -1), all_quat.reshape(n, -1)]
    return np.concatenate(control, axis=1)


def _settle(
    cm: CaptureModel, plan: SessionPlan, d: mujoco.MjData, driver: _Driver, state: np.ndarray
) -> np.ndarray:
    """The full physics state after :data:`SETTLE_S` holding the first set-points, clock at 0.

    So that the recording does not start in free fall: the body hangs at rest under gravity.
    """
    n_settle = round(SETTLE_S / plan.timestep)
    if n_settle <= 0:
        return state
    hold = [joint_targets(plan.program, cm, np.zeros(1))]
    if cm.mocap_id >= 0:
        hold += [driver.mocap_pos.reshape(1, -1), driver.mocap_quat.reshape(1, -1)]
    states, _ = rollout.rollout(
        cm.model,
        d,
        state[None],
        np.tile(np.concatenate(hold, axis=1), (n_settle, 1))[None],
        control_spec=_control_spec(cm),
    )
    settled = states[0, -1].copy()
    settled[0] = 0.0  # mjSTATE_TIME comes first in the full physics state
    return settled


def _record(
    cm: CaptureModel, plan: SessionPlan, d: mujoco.MjData, driver: _Driver, state: np.ndarray
) -> np.ndarray:
    """``(n_samples, nsensordata)``: the program rolled out in chunks, sensordata every k steps."""
    k, dt = plan.steps_per_sample, plan.timestep
    n_steps = plan.n_samples * k
    rows = []
    chunk = max(k, (CHUNK_STEPS // k) * k)
    for start in range(0, n_steps, chunk):
        n = min(chunk, n_steps - start)
        t = (start + np.arange(n)) * dt
        states, sensordata = rollout.rollout(
            cm.model, d, state[None], _controls(cm, plan, driver, t)[None], control_spec=_control_spec(cm)
        )
        rows.append(sensordata[0, ::k].copy())
        state = states[0, -1].copy()
    return np.concatenate(rows, axis=0)[: plan.n_samples]


def run_physics(cm: CaptureModel, plan: SessionPlan) -> tuple[np.ndarray, dict[str, int]]:
    """Run the dynamics of a session.

    The model's timestep is set to ``plan.timestep`` for the run and restored afterwards.

    Inside :func:`simbench.sim.physics_cache.physics_cache` a run already made (the same model,
    program and steps, whatever the sensors) is read back instead of computed again.

    A session whose motion is a recording (``plan.playback``) is played back, not simulated
    (:func:`simbench.sim.playback.run_playback`: the same rows).

    Returns:
        ``(sensordata, warnings)``: ``(n_samples, nsensordata)`` MuJoCo's sensor data at the
        samples (addresses in ``cm.adr``, ``cm.clock_adr``), and ``{warning name: count}`` of
        MuJoCo's warnings.
    """
    if plan.playback is not None:
        return run_playback(cm, plan.playback)
    folder = cache_folder()
    key = physics_key(cm, plan, plan.timestep, (SETTLE_S, CHUNK_STEPS)) if folder is not None else ""
    shape = (plan.n_samples, cm.model.nsensordata)
    if folder is not None and (kept := load_run(folder, key, shape)) is not None:
        return kept
    m = cm.model
    model_dt = float(m.opt.timestep)
    m.opt.timestep = plan.timestep
    try:
        d = initial_state(cm, joint_targets(plan.program, cm, np.zeros(1))[0])
        driver = _driver(cm, d)
        spec_state = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        state = np.zeros(mujoco.mj_stateSize(m, spec_state))
        mujoco.mj_getState(m, d, state, spec_state)
        state = _settle(cm, plan, d, driver, state)
        sensordata = _record(cm, plan, d, driver, state)
    finally:
        m.opt.timestep = model_dt
    warnings = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(d.warning) if w.number > 0}
    check_diverged(cm, plan, d, sensordata, warnings)
    if folder is not None:
        store_run(folder, key, sensordata, warnings)
    return sensordata, warnings


#: MuJoCo's warnings that mean the state blew up (MuJoCo then resets the state: time restarts).
DIVERGENCE_WARNINGS = ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS")


def check_diverged(
    cm: CaptureModel, plan: SessionPlan, d: mujoco.MjData, sensordata: np.ndarray, warnings: dict[str, int]
) -> None:
    """Refuse a session whose physics diverged: a divergence warning, a clock that restarts, or
    sensor data that is not finite.

    Raises:
        InputError: naming the model, the time and (where MuJoCo says) the joint; no dataset is
            written from such a run.
    """
    clock = sensordata[:, cm.clock_adr]
    restarts = np.flatnonzero(np.diff(clock) <= 0)
    not_finite = np.flatnonzero(~np.isfinite(sensordata).all(axis=1))
    bad = {name: n for name, n in warnings.items() if name in DIVERGENCE_WARNINGS}
    if not (bad or restarts.size or not_finite.size):
        return
    first = min([*restarts + 1, *not_finite, len(clock)])
    when = (
        f"at t = {first * plan.timestep * plan.steps_per_sample:.3f} s"
        if first < len(clock)
        else "during the run"
    )
    joint = ""
    for name in bad:
        dof = int(d.warning[int(getattr(mujoco.mjtWarning, name))].lastinfo)
        if 0 <= dof < cm.model.nv:
            name_of = mujoco.mj_id2name(cm.model, mujoco.mjtObj.mjOBJ_JOINT, int(cm.model.dof_jntid[dof]))
            joint = f", joint {name_of!r}"
            break
    raise InputError(
        f"model {cm.source}: the simulation diverged {when}{joint} (MuJoCo: {bad or 'state reset'}); no "
        "dataset is written. A body left without a sensor may be unactuated (choose --sensors-on to "
        "include it), or the motion too violent for the timestep"
    )
