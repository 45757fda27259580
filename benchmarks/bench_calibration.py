"""Calibration speed and memory (issues 2 and 19). Not a test: it measures and reports.

    .venv/bin/python benchmarks/bench_calibration.py            # the in-memory cases, ~1 min
    .venv/bin/python benchmarks/bench_calibration.py --large    # also 1,000,000 x 32 from HDF5
    .venv/bin/python benchmarks/bench_calibration.py --save     # write benchmarks/results/calibration.json
    .venv/bin/python benchmarks/bench_calibration.py --blas-threads 1  # one BLAS thread (a busy machine)

**In memory** (issue 19's table): 16 sensors x 5,400 frames (45 s at 120 Hz), 32 x 5,400 and
4 x 50,000, hierarchy unknown. Each case times the default :func:`calibration.calibrate` against
the plain reference (one ``numpy.linalg.lstsq`` of O'Brien's ``3F x 6`` system per sensor pair),
interleaved in one process -- calibrate, loop, calibrate, loop, ... -- and reports the medians and
their ratio, so that a load that comes and goes hits both alike. Floors that explain what is left
are timed the same way: the Gram matrix of all poses (``[X | P]^T [X | P]``, the one product
every pair's normal equations come from), one ``numpy.sum`` over the poses (the memory-bound
floor), and the calibration's own stage times (``Calibration.seconds``, medians).

**Bounded memory** (``--large``): 1,000,000 frames x 32 sensors (3 GB of poses) are written to
an HDF5 file chunk by chunk; then, each in a fresh process, the default ``calibrate`` on the
file's datasets (no chunk size or option given: what the API does with them), reading the file
alone, chunk by chunk, and the floor of the pair statistics (reading as calibrate reads, laying
out ``[X | P]`` and one Gram product); each process's wall time and peak resident memory are
reported.
"""

from __future__ import annotations

import argparse
import json
import os
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

#: (label, sensors, frames, target speed-up over the lstsq loop): issue 19's table.
CASES = (
    ("16 sensors x 5,400 frames, hierarchy unknown", 16, 5400, 50.0),
    ("32 sensors x 5,400 frames, hierarchy unknown", 32, 5400, 50.0),
    ("4 sensors x 50,000 frames, hierarchy unknown", 4, 50_000, 20.0),
)


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


def gram_of_poses(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The floor of the pair statistics: ``[X | P]`` (world-axis rows of every rotation, positions;
    ``3F x 4N``) laid out and multiplied by itself, one product over all frames."""
    n_frames, n = p.shape[:2]
    XP = np.empty((n_frames, 3, 4 * n))
    XP[:, :, : 3 * n] = R.transpose(0, 2, 1, 3).reshape(n_frames, 3, 3 * n)
    XP[:, :, 3 * n :] = p.transpose(0, 2, 1)
    flat = XP.reshape(3 * n_frames, 4 * n)
    return flat.T @ flat


def interleaved(fns: dict, repeats: int) -> dict[str, list[float]]:
    """Wall times, seconds, of ``repeats`` rounds in which each function runs once in turn
    (after one warm-up round)."""
    times: dict[str, list[float]] = {k: [] for k in fns}
    for r in range(repeats + 1):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            if r:
                times[k].append(time.perf_counter() - t0)
    return times


def in_memory_case(label: str, n_sensors: int, n_frames: int, target: float, repeats: int) -> dict:
    skeleton = random_tree(n_sensors, np.random.default_rng(0))
    cap = simulate_motion(
        skeleton, n_frames=n_frames, rate_hz=120.0, rng=np.random.default_rng(1), position_noise_m=0.004
    )
    R, p, names = cap.R_w_s, cap.p_w_s, cap.names
    cal = calibrate(R, p, names)
    tree_correct = {frozenset(e) for e in cal.parent_of.items()} == {
        frozenset(e) for e in skeleton.parent_of.items()
    }
    stages: dict[str, list[float]] = {}

    def run_calibrate() -> None:
        for k, v in calibrate(R, p, names).seconds.items():
            stages.setdefault(k, []).append(v)

    times = interleaved({"calibrate": run_calibrate, "lstsq_loop": lambda: lstsq_loop(R, p)}, repeats)
    floors = interleaved(
        {
            "calibrate_no_frame_residuals": lambda: calibrate(R, p, names, keep_frame_residuals=False),
            "calibrate_hierarchy_given": lambda: calibrate(R, p, names, parent_of=skeleton.parent_of),
            "gram_of_poses": lambda: gram_of_poses(R, p),
            "sum": lambda: (np.sum(R), np.sum(p)),
        },
        repeats,
    )
    med = {k: float(np.median(v)) for k, v in {**times, **floors}.items()}
    return {
        "label": label,
        "sensors": n_sensors,
        "frames": n_frames,
        "repeats": repeats,
        "tree_correct": tree_correct,
        "median_s": med,
        "times_s": times,
        "calibrate_stages_median_s": {k: float(np.median(v[1:])) for k, v in stages.items()},
        "speedup_vs_lstsq_loop": med["lstsq_loop"] / med["calibrate"],
        "speedup_per_round_median": float(
            np.median(np.array(times["lstsq_loop"]) / np.array(times["calibrate"]))
        ),
        "target_speedup": target,
        "ceiling_speedup_at_gram": med["lstsq_loop"] / med["gram_of_poses"],
        "calibrate_over_gram": med["calibrate"] / med["gram_of_poses"],
        "calibrate_over_sum": med["calibrate"] / med["sum"],
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


CHILD_CALIBRATE = (
    PEAK_RSS
    + """
import json, sys, time
import h5py
from calibration import calibrate
path, names = sys.argv[1], json.loads(sys.argv[2])
with h5py.File(path, "r") as fh:
    t0 = time.perf_counter()
    cal = calibrate(fh["R_w_s"], fh["p_w_s"], names)  # the default path, as the API takes a file
    seconds = time.perf_counter() - t0
    truth = json.loads(fh.attrs["parent_of"])
print(json.dumps({
    "seconds": seconds,
    "peak_rss_mib": peak_rss_mib(),
    "tree_correct": {frozenset(e) for e in cal.parent_of.items()} == {frozenset(e) for e in truth.items()},
    "root": cal.root,
    "stages_s": cal.seconds,
    "frame_residuals_kept": cal.joints[0].fit.frame_residual is not None,
}))
"""
)

CHILD_READ = (
    PEAK_RSS
    + """
import json, sys, time
import h5py
import numpy as np
path = sys.argv[1]
with h5py.File(path, "r") as fh:
    R_ds, p_ds = fh["R_w_s"], fh["p_w_s"]
    step = R_ds.chunks[0] if R_ds.chunks else 4096  # the file's own chunks: the fastest plain read
    t0 = time.perf_counter()
    for start in range(0, R_ds.shape[0], step):
        R, p = np.asarray(R_ds[start:start + step]), np.asarray(p_ds[start:start + step])
    seconds = time.perf_counter() - t0
print(json.dumps({"seconds": seconds, "peak_rss_mib": peak_rss_mib(), "chunk_frames": step}))
"""
)


CHILD_GRAM = (
    PEAK_RSS
    + """
import json, sys, time
import h5py
import numpy as np
from calibration.pair_sums import lay_out
from calibration.poses import CHUNK_FRAMES, iter_chunks
path = sys.argv[1]
with h5py.File(path, "r") as fh:
    R_ds, p_ds = fh["R_w_s"], fh["p_w_s"]
    n = R_ds.shape[1]
    XP, gram = np.empty((CHUNK_FRAMES, 3, 4 * n)), np.zeros((4 * n, 4 * n))
    t0 = time.perf_counter()
    for _, R, p, _ in iter_chunks(R_ds, p_ds):  # read as calibrate reads, lay out, one Gram
        flat = lay_out(R, p, XP[: R.shape[0]]).reshape(-1, 4 * n)
        gram += flat.T @ flat
    seconds = time.perf_counter() - t0
print(json.dumps({"seconds": seconds, "peak_rss_mib": peak_rss_mib()}))
"""
)


def _child(code: str, *args: str) -> dict:
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=True)
    return json.loads(done.stdout)


def large_case(n_frames: int, n_sensors: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "large.h5"
        t0 = time.perf_counter()
        names = write_large(path, n_frames, n_sensors, chunk=50_000)
        t_write = time.perf_counter() - t0
        size = path.stat().st_size
        read = _child(CHILD_READ, str(path))  # read first, then calibrate, then read again:
        cal = _child(CHILD_CALIBRATE, str(path), json.dumps(names))  # the page cache is warm for both
        read2 = _child(CHILD_READ, str(path))
        gram = _child(CHILD_GRAM, str(path))  # the floor of the pair statistics: one Gram of the file
    read_s = float(np.median([read["seconds"], read2["seconds"]]))
    return {
        "frames": n_frames,
        "sensors": n_sensors,
        "file_mib": size / 2**20,
        "write_s": t_write,
        "calibrate_s": cal["seconds"],
        "calibrate_peak_rss_mib": cal["peak_rss_mib"],
        "calibrate_stages_s": cal["stages_s"],
        "frame_residuals_kept": cal["frame_residuals_kept"],
        "read_s": read_s,
        "read_runs_s": [read["seconds"], read2["seconds"]],
        "read_peak_rss_mib": max(read["peak_rss_mib"], read2["peak_rss_mib"]),
        "calibrate_over_read": cal["seconds"] / read_s,
        "floor_read_and_one_gram_s": gram["seconds"],
        "calibrate_over_one_gram": cal["seconds"] / gram["seconds"],
        "target_calibrate_over_read": 2.0,
        "target_peak_rss_mib": 300.0,
        "root": cal["root"],
        "tree_correct": cal["tree_correct"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--large", action="store_true", help="also run 1,000,000 frames x 32 sensors")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved rounds per case (at least 5)")
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/calibration.json")
    parser.add_argument("--only", type=int, nargs="*", help="indices of the in-memory cases to run (0-2)")
    parser.add_argument(
        "--blas-threads",
        type=int,
        help="limit BLAS to this many threads (threadpoolctl; the children of --large too); results "
        "are saved to calibration_blas<N>.json",
    )
    args = parser.parse_args()
    repeats = max(args.repeats, 5)
    if args.blas_threads is not None:
        from threadpoolctl import threadpool_limits

        threadpool_limits(args.blas_threads)
        os.environ["OPENBLAS_NUM_THREADS"] = os.environ["OMP_NUM_THREADS"] = str(args.blas_threads)
    out = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
        "blas_threads": args.blas_threads or "default",
        "timing": f"median of {repeats} interleaved rounds (calibrate, loop, ...) in one process",
        "cases": [],
    }
    for k, (label, n_sensors, n_frames, target) in enumerate(CASES):
        if args.only is not None and k not in args.only:
            continue
        case = in_memory_case(label, n_sensors, n_frames, target, repeats)
        out["cases"].append(case)
        med = case["median_s"]
        print(label, f"(median of {repeats} interleaved rounds; tree correct: {case['tree_correct']})")
        print(f"  calibrate (default)       {med['calibrate'] * 1e3:9.2f} ms")
        print(f"  lstsq loop (reference)    {med['lstsq_loop'] * 1e3:9.2f} ms")
        print(
            f"  speed-up                  {case['speedup_vs_lstsq_loop']:9.1f} x   "
            f"(target >= {target:g}; per-round median {case['speedup_per_round_median']:.1f} x)"
        )
        print(f"  calibrate, no frame res.  {med['calibrate_no_frame_residuals'] * 1e3:9.2f} ms")
        print(f"  calibrate, tree given     {med['calibrate_hierarchy_given'] * 1e3:9.2f} ms")
        print(
            "  stages: "
            + ", ".join(f"{k} {v * 1e3:.2f} ms" for k, v in case["calibrate_stages_median_s"].items())
        )
        print(
            f"  floor: Gram of all poses  {med['gram_of_poses'] * 1e3:9.2f} ms   "
            f"(loop / Gram {case['ceiling_speedup_at_gram']:.0f} x; calibrate / Gram "
            f"{case['calibrate_over_gram']:.1f} x)"
        )
        print(f"  floor: numpy.sum of poses {med['sum'] * 1e3:9.3f} ms")
    if args.large:
        big = large_case(1_000_000, 32)
        out["large_case"] = big
        print(f"1,000,000 frames x 32 sensors from HDF5 ({big['file_mib']:.0f} MiB), default calibrate")
        print(
            f"  calibrate {big['calibrate_s']:.1f} s, peak RSS {big['calibrate_peak_rss_mib']:.0f} MiB, "
            f"tree correct: {big['tree_correct']}, per-frame residuals kept: {big['frame_residuals_kept']}"
        )
        print(f"  read alone {big['read_s']:.1f} s, peak RSS {big['read_peak_rss_mib']:.0f} MiB")
        print(
            f"  floor: read + one Gram of [X | P] {big['floor_read_and_one_gram_s']:.1f} s "
            f"(calibrate / that {big['calibrate_over_one_gram']:.1f} x)"
        )
        print(
            f"  calibrate / read {big['calibrate_over_read']:.1f} x (target <= 2), "
            "stages: " + ", ".join(f"{k} {v:.2f} s" for k, v in big["calibrate_stages_s"].items())
        )
    out["load_average_at_end"] = os.getloadavg()
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        suffix = "" if args.blas_threads is None else f"_blas{args.blas_threads}"
        name = f"calibration{suffix}.json"
        (RESULTS / name).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
