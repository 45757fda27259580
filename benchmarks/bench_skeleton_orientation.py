"""Throughput of the skeleton-aware sourceless estimator (issue 15). Not a test.

    .venv/bin/python benchmarks/bench_skeleton_orientation.py [--seconds 60] [--save]

A simulated humanoid session (16 sensors, ``mems-industrial``, exercise, 100 Hz) is estimated by
the skeleton method on the true skeleton (by default from three starts, mixed; and from one
start, ``starts=((),)``), without a skeleton (every sensor on its own, each solved alone), and
by the per-sample Fontaine estimator (with its disturbance
weighting) on the same arrays, interleaved, on one core (BLAS limited to one thread).
Times are the process's CPU time (``time.process_time``): the machine is shared, and wall time
counts the other users' work; the load average before and after is recorded beside them (a
loaded machine still slows a process's CPU time through shared caches and memory).
Reported: each one's median time over the repeats, the skeleton method's real-time factor
(session length / CPU time; issue 43's target >= 10x) and its time as a ratio to the per-sample
method's; and each one's accuracy against the truth.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import simbench as sb
from calibration.hierarchy import hierarchy_from_parents
from calibration.orientation import Skeleton, Weighting, fontaine, orientation_errors, skeleton_orientation
from calibration.orientation.world import reference_from_data

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    ds = sb.simulate(
        model="humanoid",
        motion="exercise",
        sensors="mems-industrial",
        duration_s=args.seconds,
        rate_hz=100.0,
        seed=11,
    )
    rec = ds.imu()
    tree = hierarchy_from_parents(ds.truth.parent_of, ds.sensors)
    lp, lc = ds.truth_joint_arrays()
    skeleton = Skeleton(np.asarray(tree.parent), lp, lc)
    ref = reference_from_data(rec.acc, rec.mag, valid=rec.valid)
    runs = {
        "skeleton": lambda: skeleton_orientation(rec.acc, rec.mag, rec.rate_hz, skeleton, valid=rec.valid),
        "skeleton (one start)": lambda: skeleton_orientation(
            rec.acc, rec.mag, rec.rate_hz, skeleton, valid=rec.valid, starts=((),)
        ),
        "no skeleton": lambda: skeleton_orientation(rec.acc, rec.mag, rec.rate_hz, valid=rec.valid),
        "fontaine (per sample)": lambda: fontaine(
            rec.acc, rec.mag, ref, weighting=Weighting(), valid=rec.valid
        ),
    }
    times: dict[str, list[float]] = {k: [] for k in runs}
    out = {}
    load_before = os.getloadavg()
    with threadpool_limits(limits=1):
        for _ in range(args.repeats):
            for name, fn in runs.items():
                t0 = time.process_time()
                out[name] = fn()
                times[name].append(time.process_time() - t0)
    load_after = os.getloadavg()
    seconds = rec.time_s[-1] - rec.time_s[0] + 1 / rec.rate_hz
    rows = {}
    for name, est in out.items():
        e = np.rad2deg(orientation_errors(est.q_w_s, rec.q_true)[..., 0])
        t = float(np.median(times[name]))
        rows[name] = {
            "median_s": t,
            "times_s": times[name],
            "real_time_factor": seconds / t,
            "total_rmse_deg": float(np.sqrt(np.nanmean(e**2))),
        }
    ratio = rows["skeleton"]["median_s"] / rows["fontaine (per sample)"]["median_s"]
    print(
        f"16 sensors x {rec.time_s.size} frames at {rec.rate_hz:g} Hz ({seconds:.0f} s), one core, CPU time"
    )
    print(f"  load average (1, 5, 15 min) before {load_before}, after {load_after}")
    print(f"  {'method':<26}{'median s':>10}{'x real time':>13}{'RMSE (deg)':>12}")
    for name, r in rows.items():
        print(f"  {name:<26}{r['median_s']:>10.3f}{r['real_time_factor']:>13.1f}{r['total_rmse_deg']:>12.2f}")
    print(f"  skeleton / per-sample time: {ratio:.1f}; target: skeleton >= 10 x real time")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        doc = {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "session_s": seconds,
            "rate_hz": rec.rate_hz,
            "sensors": len(rec.names),
            "repeats": args.repeats,
            "clock": "process_time (CPU seconds of this process)",
            "cpus": os.cpu_count(),
            "load_average_before": list(load_before),
            "load_average_after": list(load_after),
            "rows": rows,
            "skeleton_over_per_sample": ratio,
            "target_real_time_factor": 10.0,
        }
        (RESULTS / "skeleton_orientation.json").write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
