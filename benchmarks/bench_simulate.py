"""Simulation speed (issue 3's benchmark). Not a test: it measures and reports.

    .venv/bin/python benchmarks/bench_simulate.py [--save]

Generates the humanoid's 45 s at 120 Hz (``exercise``, physics at the model's 1/1200 s
timestep: 54,000 steps) with :func:`simbench.sim.session.run_session`, and in the same process
runs a bare native ``mujoco.rollout`` of the same compiled model for the same number of physics
steps, fed the same control array computed beforehand (so the physics is identical and only
simbench's own work differs). Target: the session within 1.5x of the bare rollout.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from simbench.sim.models import load_capture_model
from simbench.sim.physics import initial_state
from simbench.sim.programs import joint_targets, root_pose
from simbench.sim.session import SessionConfig, plan_session, run_session

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/simulate.json")
    args = parser.parse_args()
    config = SessionConfig(model="humanoid", motion="exercise", duration_s=45.0, rate_hz=120.0, seed=1)
    t0 = time.perf_counter()
    cm = load_capture_model(config.model)
    t_load = time.perf_counter() - t0
    m = cm.model
    n_steps = round(config.duration_s / m.opt.timestep)
    # the same controls, computed outside the timed bare rollout
    plan = plan_session(config, cm)
    program, phases = plan.program, plan.root_phases
    t = np.arange(n_steps) * m.opt.timestep
    d = initial_state(cm, joint_targets(program, cm, np.zeros(1))[0])
    pos, quat = root_pose(program, d.mocap_pos[0].copy(), d.mocap_quat[0].copy(), t, phases)
    control = np.concatenate([joint_targets(program, cm, t), pos, quat], axis=1)[None]
    spec_state = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    spec_ctrl = int(
        mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_MOCAP_POS | mujoco.mjtState.mjSTATE_MOCAP_QUAT
    )
    state0 = np.zeros(mujoco.mj_stateSize(m, spec_state))
    mujoco.mj_getState(m, d, state0, spec_state)

    def bare() -> None:
        rollout.rollout(m, mujoco.MjData(m), state0[None], control, control_spec=spec_ctrl)

    def session() -> None:
        run_session(config, cm)

    times = {"bare": [], "session": []}
    for _ in range(args.repeats):  # interleaved, so that machine noise hits both alike
        for name, fn in (("bare", bare), ("session", session)):
            t1 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t1)
    t_bare, t_session = min(times["bare"]), min(times["session"])
    out = {
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "model": config.model,
        "duration_s": config.duration_s,
        "rate_hz": config.rate_hz,
        "physics_steps": n_steps,
        "load_model_s": t_load,
        "session_s": t_session,
        "bare_rollout_s": t_bare,
        "ratio": t_session / t_bare,
        "target_ratio": 1.5,
    }
    print(f"humanoid, 45 s at 120 Hz, {n_steps} physics steps of {m.opt.timestep * 1e3:.4f} ms")
    print(f"  load and equip the model   {t_load * 1e3:8.1f} ms")
    print(f"  run_session                {t_session:8.3f} s")
    print(f"  bare mujoco.rollout        {t_bare:8.3f} s")
    print(f"  ratio                      {t_session / t_bare:8.3f} x   (target <= 1.5)")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "simulate.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
