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
method's; and each one's accuracy against the truth. ``--levels`` also prints, for one more
skeleton run, each level's solves (frames, iterations, CPU time) and the banded factorisations.

**Where the time goes** (issue 43, measured on this machine, 2 cores shared, 60 s): 15 solves,
181 iterations, 253 factorisations (72 of them a try again after a rejected step, mostly on the
coarse levels); by level 20 Hz 3.3 s (29 iterations over the three starts and the mix), 10 Hz
1.5 s (27), 5 Hz 1.5 s (45), the coarser ones 0.8 s (80). One iteration at 20 Hz (1,200 frames,
16 sensors) about 107 ms: residuals 7.5, Jacobian blocks 5.2, normal equations 45 (the 3 x 3
products 27, the band written from their sums 9 of which its zeroing 2, the sparse sum 4-6),
``pbsv`` 52 (``pbtrf`` 47: the band is dense after fill-in, 12 G multiply-adds/s, half the rate
of a large ``dgemm`` on the same core; a blocked solve in Python could not gain on it). Tried and
not kept (issue 43): a sparse matrix writing the band directly (twice as slow), chunked or
transposed scatters, other forms of the 3 x 3 products (``einsum`` is the fastest); the damping
divided by 10 where the gain ratio exceeds 0.75 (181 -> 179 iterations: the tail is the
problem's curvature, not the damping); each start's last level cut at 1 or 2 iterations before
the mix (0.75 and 0.78 x the time; the mix then picks unconverged windows: exercise 1.40 -> 3.07
degrees, chicken walk 9.9 -> 18.0); a stop when a step lowers the cost by less than 1 (it moved
no quantity by more than its standard deviation; 0.92 x; gait on the calibrated skeleton 2.37
-> 4.75); chord steps reusing the factor (Fan's modified Levenberg-Marquardt) on every level
(0.73 x; gait 2.94 -> 6.12) or on the last level only (0.91-0.97 x; the walk 9.9 -> 21.2, BROAD
and RepoIMU medians unchanged). The figures of 30 s sessions move by chance under any such
change (inputs times ``1 + 1e-12 e``: the walk 9.9 -> 11.6): ``studies/orientation_seeds.py``
judges a change over many sessions.
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

import calibration.orientation.skeleton as sk
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
    parser.add_argument("--levels", action="store_true", help="each level's solves and factorisations")
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
    if args.levels:
        levels(runs["skeleton"])
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


def levels(run) -> None:
    """One more run, each Levenberg-Marquardt solve timed (frames, iterations, CPU time) and the
    banded factorisations counted, by wrapping the solver's functions for the run."""
    solves: list[tuple[int, int, float]] = []
    factorisations = [0]
    lm, pbsv = sk._levenberg_marquardt, sk.dpbsv

    def timed(problem, *args, **kwargs):
        t0 = time.process_time()
        out = lm(problem, *args, **kwargs)
        solves.append((problem.use.shape[0], out[2], time.process_time() - t0))
        return out

    def counted(*args, **kwargs):
        factorisations[0] += 1
        return pbsv(*args, **kwargs)

    sk._levenberg_marquardt, sk.dpbsv = timed, counted
    try:
        with threadpool_limits(limits=1):
            t0 = time.process_time()
            run()
            total = time.process_time() - t0
    finally:
        sk._levenberg_marquardt, sk.dpbsv = lm, pbsv
    print(f"  one skeleton run {total:.2f} s: {len(solves)} solves, {factorisations[0]} factorisations")
    print(f"  {'frames':>8}{'solves':>8}{'iterations':>12}{'CPU s':>8}")
    for frames in sorted({s[0] for s in solves}, reverse=True):
        rows = [s for s in solves if s[0] == frames]
        print(f"  {frames:>8}{len(rows):>8}{sum(s[1] for s in rows):>12}{sum(s[2] for s in rows):>8.2f}")


if __name__ == "__main__":
    main()
