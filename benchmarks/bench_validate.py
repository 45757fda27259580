"""The main job's time and its floor (issue 19's benchmark). Not a test: it measures and reports.

    .venv/bin/python benchmarks/bench_validate.py [--quick] [--workers 2] [--save]

Runs ``simbench validate`` (``--quick`` for the short variant) as the command does: the
experiments on a process pool of ``--workers``, then the report written to a temporary folder.
Every physics run (``mujoco.rollout``, in this process or a worker) is timed, so the report can
say what bounds the run: the physics that must be computed (each distinct session once, the
physics cache sharing the rest) divided over the workers is a floor no scheduling goes under.
Reported: wall time of the experiments and of the report, the sessions simulated and the physics
runs computed, the physics seconds and that floor, and the wall time's ratio to the floor; the CPU
seconds of this process and its children (``getrusage``) and the load average before and after,
as the machine is shared; and where the time goes: per step of the run, its jobs' CPU seconds and
the wall span from its first job's start to its last one's end, per process its busy seconds (a
pool's imbalance), and the start-up before the first job and the tail after the last.
``--save`` writes the per-step CPU seconds beside the totals: the progress bar's units
(:data:`simbench.experiments.validate.COST_S`).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from simbench.experiments.validate import STEPS, run_validation
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


def _cpu_s() -> float:
    """CPU seconds (user + system) of this process and its reaped children."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def breakdown(jobs: list, t_start: float, t_end: float) -> dict:
    """Where the run's wall time went, from its jobs' records (:class:`simbench.experiments.work.Job`)."""
    steps: dict = defaultdict(lambda: {"jobs": 0, "cpu_s": 0.0, "first_start_s": None, "last_end_s": 0.0})
    for job in jobs:
        row = steps[job.step]
        row["jobs"] += 1
        row["cpu_s"] += job.cpu_s
        start, end = job.start - t_start, job.end - t_start
        row["first_start_s"] = start if row["first_start_s"] is None else min(row["first_start_s"], start)
        row["last_end_s"] = max(row["last_end_s"], end)
    main_pid = os.getpid()
    busy: dict = defaultdict(float)
    for job in jobs:
        if job.pid != main_pid:  # a worker's busy time; this process's jobs overlap its threads'
            busy[str(job.pid)] += job.end - job.start
    ends = [j.end for j in jobs if j.pid != main_pid]
    starts = [j.start for j in jobs if j.pid != main_pid]
    return {
        "steps": {s: steps[s] for s in STEPS if s in steps},
        "worker_busy_s": dict(busy),
        "first_worker_job_s": min(starts) - t_start if starts else None,
        "after_last_worker_job_s": t_end - max(ends) if ends else None,
    }


def measure(quick: bool, workers: int) -> dict:
    session.run_physics = _timed_physics  # inherited by the pool's (forked) workers
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "physics.log"
        log.touch()
        os.environ[LOG_ENV] = str(log)
        jobs: list = []
        cpu0, t0 = _cpu_s(), time.time()
        results, keep = run_validation(quick=quick, workers=workers, jobs=jobs)
        t_run = time.time() - t0
        cpu_run = _cpu_s() - cpu0
        t1 = time.time()
        write_report(results, keep, Path(tmp) / "report")
        t_report = time.time() - t1
        cpu_report = _cpu_s() - cpu0 - cpu_run
        runs = [float(x) for x in log.read_text().split()]
    computed = [t for t in runs if t > 0.05]  # a cache hit reads a file in milliseconds
    physics_s = sum(runs)
    return {
        "quick": quick,
        "workers": workers,
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "experiments_s": t_run,
        "experiments_cpu_s": cpu_run,
        "report_s": t_report,
        "report_cpu_s": cpu_report,
        "sessions": len(runs),
        "physics_runs_computed": len(computed),
        "physics_s": physics_s,
        "physics_floor_s": physics_s / workers,
        "ratio_to_floor": t_run / (physics_s / workers),
        "cpu_floor_s": cpu_run / workers,
        "ratio_to_cpu_floor": t_run / (cpu_run / workers),
        "target_s": 10.0 if quick else 40.0,
        **breakdown(jobs, t0, t0 + t_run),
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
    print(
        f"  CPU: experiments {out['experiments_cpu_s']:.1f} s, report {out['report_cpu_s']:.1f} s; "
        f"wall / (CPU / workers) = {out['ratio_to_cpu_floor']:.2f}; load "
        f"{out['load_average_before'][0]:.1f} before, {out['load_average_after'][0]:.1f} after"
    )
    if out["first_worker_job_s"] is not None:  # with --workers 1 every job runs in this process
        print(
            f"  first worker job at {out['first_worker_job_s']:.1f} s, last one ended "
            f"{out['after_last_worker_job_s']:.1f} s before the end; workers busy "
            + ", ".join(f"{b:.1f} s" for b in out["worker_busy_s"].values())
        )
    for step, row in out["steps"].items():
        print(
            f"  {row['cpu_s']:7.1f} cpu-s {row['jobs']:3d} jobs  {row['first_start_s']:6.1f} .. "
            f"{row['last_end_s']:6.1f} s  {step[:60]}"
        )
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        name = "validate_quick.json" if args.quick else "validate.json"
        (RESULTS / name).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
