"""Calibration speed and memory (issue 2's benchmark). Not a test: it measures and reports.

    .venv/bin/python benchmarks/bench_calibration.py            # the paper's case, ~10 s
    .venv/bin/python benchmarks/bench_calibration.py --large    # also 1,000,000 x 32 from HDF5

**The paper's case**: 16 sensors x 5,400 frames (45 s at 120 Hz), hierarchy unknown. In the
same process it times the whole calibration (all-pairs normal equations, spanning tree, joint
solutions, exact residual pass, lengths), a plain loop of one ``numpy.linalg.lstsq`` per sensor
pair (O'Brien's method as written) and one ``numpy.sum`` over the pose array (the memory-bound
floor), and reports the ratios. Targets: at least 50x faster than the loop, within 5x of the sum.

**Bounded memory** (``--large``): 1,000,000 frames x 32 sensors (3 GB of poses) are written to
an HDF5 file chunk by chunk, then calibrated from the file in a fresh process that reads it in
chunks; that process's peak resident memory is reported.
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from child import PEAK_RSS, capture_chunks  # benchmarks/child.py: the script's own folder is on the path

from calibration import calibrate
from simbench.sim.synthetic import random_tree, simulate_motion

RESULTS = Path(__file__).resolve().parent / "results"


def best_of(fn, repeats: int) -> float:
    """Smallest wall time of ``repeats`` calls, seconds (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def lstsq_loop(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """O'Brien's method as written: build and solve eq. 13 with lstsq for every pair."""
    n_frames, n = p.shape[:2]
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            A = np.concatenate([R[:, i], -R[:, j]], axis=2).reshape(3 * n_frames, 6)
            b = (p[:, j] - p[:, i]).reshape(3 * n_frames)
            _, res, *_ = np.linalg.lstsq(A, b, rcond=None)
            out[i, j] = out[j, i] = np.sqrt(res[0] / n_frames) if res.size else 0.0
    return out


def paper_case(repeats: int) -> dict:
    skeleton = random_tree(16, np.random.default_rng(0))
    cap = simulate_motion(
        skeleton, n_frames=5400, rate_hz=120.0, rng=np.random.default_rng(1), position_noise_m=0.004
    )
    R, p, names = cap.R_w_s, cap.p_w_s, cap.names
    cal = calibrate(R, p, names, root="b0")
    assert cal.parent_of == skeleton.parent_of, "benchmark data: wrong hierarchy"
    t_cal = best_of(lambda: calibrate(R, p, names), repeats)
    t_cal_given = best_of(lambda: calibrate(R, p, names, parent_of=skeleton.parent_of), repeats)
    t_cal_rms = best_of(lambda: calibrate(R, p, names, keep_frame_residuals=False), repeats)
    t_loop = best_of(lambda: lstsq_loop(R, p), max(1, repeats // 3))
    t_sum = best_of(lambda: (np.sum(R), np.sum(p)), repeats * 4)
    stages = calibrate(R, p, names).seconds
    return {
        "sensors": 16,
        "frames": 5400,
        "calibrate_s": t_cal,
        "calibrate_hierarchy_given_s": t_cal_given,
        "calibrate_no_frame_residuals_s": t_cal_rms,
        "speedup_vs_lstsq_loop_no_frame_residuals": t_loop / t_cal_rms,
        "calibrate_stages_s": stages,
        "lstsq_loop_s": t_loop,
        "sum_s": t_sum,
        "speedup_vs_lstsq_loop": t_loop / t_cal,
        "ratio_to_sum": t_cal / t_sum,
        "target_speedup": 50.0,
        "target_ratio_to_sum": 5.0,
    }


def write_large(path: Path, n_frames: int, n_sensors: int, chunk: int) -> list[str]:
    import h5py

    skeleton, chunks = capture_chunks(n_frames, n_sensors, chunk)
    with h5py.File(path, "w") as fh:
        R_ds = fh.create_dataset(
            "R_w_s", (n_frames, n_sensors, 3, 3), dtype="f8", chunks=(4096, n_sensors, 3, 3)
        )
        p_ds = fh.create_dataset("p_w_s", (n_frames, n_sensors, 3), dtype="f8", chunks=(4096, n_sensors, 3))
        for start, stop, cap in chunks:
            R_ds[start:stop] = cap.R_w_s
            p_ds[start:stop] = cap.p_w_s
        fh.attrs["parent_of"] = json.dumps(skeleton.parent_of)
    return list(skeleton.names)


CHILD = (
    PEAK_RSS
    + """
import json, sys, time
import h5py
from calibration import calibrate
path, names = sys.argv[1], json.loads(sys.argv[2])
with h5py.File(path, "r") as fh:
    t0 = time.perf_counter()
    cal = calibrate(fh["R_w_s"], fh["p_w_s"], names, chunk_frames=8192, keep_frame_residuals=False)
    seconds = time.perf_counter() - t0
    truth = json.loads(fh.attrs["parent_of"])
print(json.dumps({
    "seconds": seconds,
    "peak_rss_mib": peak_rss_mib(),
    "tree_correct": {frozenset(e) for e in cal.parent_of.items()} == {frozenset(e) for e in truth.items()},
    "root": cal.root,
}))
"""
)


def large_case(n_frames: int, n_sensors: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "large.h5"
        t0 = time.perf_counter()
        names = write_large(path, n_frames, n_sensors, chunk=50_000)
        t_write = time.perf_counter() - t0
        size = path.stat().st_size
        done = subprocess.run(
            [sys.executable, "-c", CHILD, str(path), json.dumps(names)],
            capture_output=True,
            text=True,
            check=True,
        )
        child = json.loads(done.stdout)
    return {
        "frames": n_frames,
        "sensors": n_sensors,
        "file_mib": size / 2**20,
        "write_s": t_write,
        "calibrate_s": child["seconds"],
        "peak_rss_mib": child["peak_rss_mib"],
        "root": child["root"],
        "tree_correct": child["tree_correct"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--large", action="store_true", help="also run 1,000,000 frames x 32 sensors")
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/calibration.json")
    args = parser.parse_args()
    out = {"python": platform.python_version(), "numpy": np.__version__, "machine": platform.machine()}
    small = paper_case(args.repeats)
    out["paper_case"] = small
    print("16 sensors x 5,400 frames, hierarchy unknown")
    print(f"  calibrate (whole)         {small['calibrate_s'] * 1e3:9.2f} ms")
    print(f"  calibrate (hier. given)   {small['calibrate_hierarchy_given_s'] * 1e3:9.2f} ms")
    print(f"  calibrate (rms only)      {small['calibrate_no_frame_residuals_s'] * 1e3:9.2f} ms")
    print("  stages: " + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in small["calibrate_stages_s"].items()))
    print(f"  lstsq loop, 120 pairs     {small['lstsq_loop_s'] * 1e3:9.2f} ms")
    print(f"  numpy.sum over poses      {small['sum_s'] * 1e3:9.3f} ms")
    print(f"  speed-up vs lstsq loop    {small['speedup_vs_lstsq_loop']:9.1f} x   (target >= 50)")
    print(f"  ratio to numpy.sum        {small['ratio_to_sum']:9.1f} x   (target <= 5)")
    if args.large:
        big = large_case(1_000_000, 32)
        out["large_case"] = big
        print(f"1,000,000 frames x 32 sensors from HDF5 ({big['file_mib']:.0f} MiB)")
        print(
            f"  calibrate {big['calibrate_s']:.1f} s, peak RSS {big['peak_rss_mib']:.0f} MiB, "
            f"tree correct: {big['tree_correct']}"
        )
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "calibration.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
