"""Study throughput and scaling (issue 7's benchmark). Not a test.

    .venv/bin/python benchmarks/bench_sweep.py [--trials 1000] [--save]

A linkage noise study (10 s sessions, ascension-flock, noise 0-16 mm) is run four ways in the
same process: the trials called directly one after another (the reference), through a local
process pool of 1 and of 2 workers, and on a Dask ``LocalCluster`` of 2 worker processes over
loopback TCP. Reported: trials per second, the speed-up from 1 to 2 workers (target >= 1.7x),
and the per-trial overhead of the executor relative to a trial (target < 5 %).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from simbench.experiments import study as st
from simbench.experiments import sweep as sw

RESULTS = Path(__file__).resolve().parent / "results"

STUDY = """
name = "bench-noise"
seed = 9
seeds_per_cell = {seeds}
estimators = ["calibration"]
metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]
[base]
model = "linkage"
motion = "exercise"
sensors = "ascension-flock"
duration_s = 10.0
[sampling]
kind = "grid"
[[parameter]]
name = "sensors.tracker.position_noise_m"
unit = "mm"
values = [0.0, 1.0, 2.0, 4.0, 8.0, 12.0, 16.0, 20.0, 24.0, 32.0]
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000, help="multiple of 10")
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_s:
        tmp = Path(tmp_s)
        path = tmp / "study.toml"
        path.write_text(STUDY.format(seeds=max(1, args.trials // 10)))
        study = st.load_study(path)
        todo = st.trials(study)
        n = len(todo)
        t0 = time.perf_counter()
        for t in todo:
            sw.run_trial(study, t)
        direct = time.perf_counter() - t0
        times = {"direct": direct}
        for label, workers in (("pool-1", 1), ("pool-2", 2)):
            t0 = time.perf_counter()
            with ProcessPoolExecutor(workers) as ex:
                sw.run_study(study, tmp / label, executor=ex)
            times[label] = time.perf_counter() - t0
        if importlib.util.find_spec("distributed") is not None:  # the studies extra has it
            with sw.local_dask_executor(2) as executor:
                t0 = time.perf_counter()
                sw.run_study(study, tmp / "dask-2", executor=executor)
                times["dask-2"] = time.perf_counter() - t0
    out = {
        "trials": n,
        "seconds": times,
        "trials_per_s": {k: n / v for k, v in times.items()},
        "speedup_pool_1_to_2": times["pool-1"] / times["pool-2"],
        "speedup_1_to_dask_2": times["pool-1"] / times["dask-2"] if "dask-2" in times else None,
        "executor_overhead_per_trial": (times["pool-1"] - direct) / direct,
        "python": platform.python_version(),
    }
    print(f"{n} linkage trials (10 s sessions each)")
    for k, v in times.items():
        print(f"  {k:<8}{v:8.1f} s  {n / v:6.2f} trials/s")
    print(f"  speed-up 1 -> 2 workers (pool): {out['speedup_pool_1_to_2']:.2f}x   (target >= 1.7)")
    if out["speedup_1_to_dask_2"]:
        print(f"  speed-up 1 worker -> Dask 2:    {out['speedup_1_to_dask_2']:.2f}x")
    print(
        f"  executor overhead per trial:    {100 * out['executor_overhead_per_trial']:.1f} %   (target < 5 %)"
    )
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "sweep.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
