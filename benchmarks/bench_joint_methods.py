"""The field's joint-centre methods against the whole calibration, on the same arrays (issue 16). Not a test.

    .venv/bin/python benchmarks/bench_joint_methods.py [--seconds 45] [--repeats 5] [--save]

A simulated humanoid session (16 sensors, ``polhemus-liberty``, exercise, 120 Hz: 5,400 frames in
45 s). Each pose-based method of :data:`calibration.methods.JOINT_METHODS` fits the 15 joints of
the true hierarchy, one pair of sensors after another; :func:`calibration.calibrate` (O'Brien's
all-pairs calibration, hierarchy unknown: every pair's statistics, the spanning tree, the joints,
the skeleton) runs on the same ``(frames, 16, ...)`` arrays. Seel's inertial method fits the same
15 joints from the session's gyroscopes and accelerometers (other arrays; for reference). Runs are
interleaved, on one core (BLAS limited to one thread); reported: each one's median time over the
repeats and its ratio to the calibration's.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import simbench as sb
from calibration import calibrate
from calibration.hierarchy import hierarchy_from_parents
from calibration.methods import JOINT_METHODS, estimate_inertial

RESULTS = Path(__file__).resolve().parent / "results"
BASELINE = "calibrate (all pairs, hierarchy unknown)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=45.0)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    ds = sb.simulate(
        model="humanoid",
        motion="exercise",
        sensors="polhemus-liberty",
        duration_s=args.seconds,
        rate_hz=120.0,
        seed=11,
    )
    poses, imu = ds.poses(), ds.imu()
    R, p, valid, names = poses.R_w_s, poses.p_w_s * ds.position_unit_scale, poses.valid, poses.names
    joints = hierarchy_from_parents(ds.truth.parent_of, names).joints

    def pose_method(method):
        def run():
            return [
                method(R[:, a], p[:, a], R[:, b], p[:, b], valid=valid[:, a] & valid[:, b]) for a, b in joints
            ]

        return run

    def inertial():
        ok = imu.valid
        return [
            estimate_inertial(
                imu.gyro[:, a],
                imu.gyro[:, b],
                imu.acc[:, a],
                imu.acc[:, b],
                rate_hz=imu.rate_hz,
                valid=ok[:, a] & ok[:, b],
            )
            for a, b in joints
        ]

    runs = {BASELINE: lambda: calibrate(R, p, names, valid=valid)}
    runs.update({name: pose_method(method) for name, method in JOINT_METHODS.items()})
    runs["inertial (gyro + accelerometer)"] = inertial
    times: dict[str, list[float]] = {k: [] for k in runs}
    with threadpool_limits(limits=1):
        for _ in range(args.repeats):
            for name, fn in runs.items():
                t0 = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - t0)
    base = float(np.median(times[BASELINE]))
    rows = {
        name: {
            "median_s": float(np.median(t)),
            "times_s": t,
            "ratio_to_calibrate": float(np.median(t)) / base,
        }
        for name, t in times.items()
    }
    print(
        f"{len(names)} sensors x {R.shape[0]} frames, {len(joints)} joints, one core, "
        f"median of {args.repeats}"
    )
    print(f"  {'method':<42}{'median s':>10}{'/ calibrate':>13}")
    for name, r in rows.items():
        print(f"  {name:<42}{r['median_s']:>10.3f}{r['ratio_to_calibrate']:>13.2f}")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        doc = {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "sensors": len(names),
            "frames": int(R.shape[0]),
            "joints": len(joints),
            "rate_hz": imu.rate_hz,
            "preset": "polhemus-liberty",
            "repeats": args.repeats,
            "baseline": BASELINE,
            "rows": rows,
        }
        (RESULTS / "joint_methods.json").write_text(json.dumps(doc, indent=2) + "\n")


if __name__ == "__main__":
    main()
