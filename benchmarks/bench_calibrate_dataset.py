"""``simbench calibrate`` on a large simbench dataset: time and peak memory (issue 19). Not a test.

    .venv/bin/python benchmarks/bench_calibrate_dataset.py [--frames 1000000] [--sensors 32] [--save]

A dataset file (the simbench format: ``/sensors``, ``/time_s``, ``/measured``) of the
benchmarks' synthetic capture (``benchmarks/child.py``, 4 mm of position noise) is written a chunk
at a time; its inertial datasets are declared but never written (HDF5 stores nothing for them).
Then the command ``simbench calibrate FILE`` runs in a fresh process, with its defaults (slip
detection on) and with ``--no-slip``, each reporting its wall time and peak resident memory
(``VmHWM``); the targets: memory independent of the frames, under 300 MiB for a million frames of
32 sensors with the defaults (issues 19 and 45), and the defaults at most 3x the time of
``--no-slip`` (issue 45).
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

import h5py
import numpy as np
from child import PEAK_RSS, capture_chunks  # benchmarks/child.py

from calibration.rotations import matrix_to_quat
from simbench.io.dataset import FORMAT, FORMAT_VERSION

RESULTS = Path(__file__).resolve().parent / "results"

CHILD = (
    PEAK_RSS
    + """
import contextlib, io, json, sys, time
from simbench.cli import main
t0 = time.perf_counter()
with contextlib.redirect_stdout(io.StringIO()) as out:
    status = main(["calibrate", sys.argv[1], *sys.argv[2:]])
seconds = time.perf_counter() - t0
print(json.dumps({"status": status, "seconds": seconds, "peak_rss_mib": peak_rss_mib(),
                  "table_head": out.getvalue().splitlines()[:3]}))
"""
)


def write_dataset_file(path: Path, n_frames: int, n_sensors: int, chunk: int = 50_000) -> None:
    skeleton, chunks = capture_chunks(n_frames, n_sensors, chunk)
    with h5py.File(path, "w") as fh:
        fh.attrs["format"] = FORMAT
        fh.attrs["format_version"] = FORMAT_VERSION
        fh.attrs["meta"] = json.dumps({"source": "bench_calibrate_dataset"})
        fh.attrs["position_unit_scale"] = 1.0
        fh.create_dataset("sensors", data=np.array(skeleton.names, dtype=h5py.string_dtype()))
        fh.create_dataset("time_s", data=np.arange(n_frames) / 120.0)
        g = fh.create_group("measured")
        q = g.create_dataset("q_w_s", (n_frames, n_sensors, 4), dtype="f8", chunks=(4096, n_sensors, 4))
        p = g.create_dataset("p_w_s", (n_frames, n_sensors, 3), dtype="f8", chunks=(4096, n_sensors, 3))
        v = g.create_dataset("valid", (n_frames, n_sensors), dtype=bool, chunks=(4096, n_sensors))
        for name in ("acc", "gyro", "mag"):
            g.create_dataset(name, (n_frames, n_sensors, 3), dtype="f8", chunks=(4096, n_sensors, 3))
        for start, stop, cap in chunks:
            q[start:stop] = matrix_to_quat(cap.R_w_s)
            p[start:stop] = cap.p_w_s
            v[start:stop] = True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--sensors", type=int, default=32)
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/calibrate_dataset.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "large.h5"
        t0 = time.perf_counter()
        write_dataset_file(path, args.frames, args.sensors)
        t_write = time.perf_counter() - t0
        size = path.stat().st_size
        runs = {}
        for name, extra in (("defaults", []), ("no_slip", ["--no-slip"])):
            done = subprocess.run(
                [sys.executable, "-c", CHILD, str(path), *extra], capture_output=True, text=True
            )
            if done.returncode != 0:
                raise SystemExit(done.stderr)
            runs[name] = json.loads(done.stdout.splitlines()[-1])
    out = {
        "python": platform.python_version(),
        "frames": args.frames,
        "sensors": args.sensors,
        "file_mib": size / 2**20,
        "write_s": t_write,
        "load_average": os.getloadavg(),
        "commands": {"defaults": "simbench calibrate FILE", "no_slip": "simbench calibrate FILE --no-slip"},
        **runs,
        "time_ratio_defaults_to_no_slip": runs["defaults"]["seconds"] / runs["no_slip"]["seconds"],
        "target_peak_rss_mib": 300.0,
        "target_time_ratio": 3.0,
    }
    print(f"{args.frames:,} frames x {args.sensors} sensors, simbench dataset ({out['file_mib']:.0f} MiB)")
    for name, run in runs.items():
        secs, peak = run["seconds"], run["peak_rss_mib"]
        print(f"  simbench calibrate ({name}): {secs:.1f} s, peak RSS {peak:.0f} MiB")
    print(f"  defaults / --no-slip time: {out['time_ratio_defaults_to_no_slip']:.2f}")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "calibrate_dataset.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
