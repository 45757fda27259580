"""The main job's time and its floor (issue 19's benchmark). Not a test: it measures and reports.

    .venv/bin/python benchmarks/bench_validate.py [--quick] [--workers 2] [--save]

Runs ``simbench validate`` (``--quick`` for the short variant) as the command does: the
experiments on a process pool of ``--workers``, then the report written to a temporary folder.
Every physics run (``mujoco.rollout``, in this process or a worker) is timed, so the report can
say what bounds the run: the physics that must be computed (each distinct session once, the
physics cache sharing the rest) divided over the workers is a floor no scheduling goes under.
Reported: wall time of the experiments and of the report, the sessions simulated and the physics
runs computed, the physics seconds and that floor, and the wall time's ratio to the floor.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from simbench.experiments.validate import run_validation
from simbench.report.validation import write_report
from simbench.sim import physics, session

RESULTS = Path(__file__).resolve().parent / "results"

#: Each process appends ``seconds`` of every physics run (0 when the cache had it) here.
LOG_ENV = "SIMBENCH_BENCH_PHYSICS_LOG"


def _timed_physics(cm, plan):
    t0 = time.perf_counter()
    out = _real(cm, plan)
    with open(os.environ[LOG_ENV], "a", encoding="utf-8") as fh:
        fh.write(f"{time.perf_counter() - t0}\n")
    return out


_real = physics.run_physics


def measure(quick: bool, workers: int) -> dict:
    session.run_physics = _timed_physics  # inherited by the pool's (forked) workers
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "physics.log"
        log.touch()
        os.environ[LOG_ENV] = str(log)
        t0 = time.perf_counter()
        results, keep = run_validation(quick=quick, workers=workers)
        t_run = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_report(results, keep, Path(tmp) / "report")
        t_report = time.perf_counter() - t0
        runs = [float(x) for x in log.read_text().split()]
    computed = [t for t in runs if t > 0.05]  # a cache hit reads a file in milliseconds
    physics_s = sum(runs)
    return {
        "quick": quick,
        "workers": workers,
        "experiments_s": t_run,
        "report_s": t_report,
        "sessions": len(runs),
        "physics_runs_computed": len(computed),
        "physics_s": physics_s,
        "physics_floor_s": physics_s / workers,
        "ratio_to_floor": t_run / (physics_s / workers),
        "target_s": 10.0 if quick else 40.0,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the short variant")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/validate[_quick].json")
    args = parser.parse_args()
    out = {"python": platform.python_version(), "cpus": os.cpu_count(), **measure(args.quick, args.workers)}
    print(f"simbench validate{' --quick' if args.quick else ''}, {args.workers} workers")
    print(
        f"  experiments {out['experiments_s']:.1f} s, report {out['report_s']:.1f} s "
        f"(target {out['target_s']:.0f} s)"
    )
    print(
        f"  {out['sessions']} sessions, {out['physics_runs_computed']} physics runs computed: "
        f"{out['physics_s']:.1f} s of physics, floor {out['physics_floor_s']:.1f} s on {args.workers} "
        "workers; "
        f"experiments / floor = {out['ratio_to_floor']:.2f}"
    )
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        name = "validate_quick.json" if args.quick else "validate.json"
        (RESULTS / name).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
