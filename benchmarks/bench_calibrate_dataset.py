"""``simbench calibrate`` on a large simbench dataset: time and peak memory (issue 19). Not a test.

    .venv/bin/python benchmarks/bench_calibrate_dataset.py [--frames 1000000] [--sensors 32]
        [--dataset FILE.h5] [--repeat N] [--save]

A dataset file (the simbench format: ``/sensors``, ``/time_s``, ``/measured``) of the
benchmarks' synthetic capture (``benchmarks/child.py``, 4 mm of position noise) is written a chunk
at a time; its inertial datasets are declared but never written (HDF5 stores nothing for them).
(``--dataset``: an existing file of that format, e.g. written by an earlier run, is used instead.)
Then the command ``simbench calibrate FILE`` runs in a fresh process, with its defaults (slip
detection on) and with ``--no-slip``, each under ``/usr/bin/time -f "%e %U %S %M"``: wall time,
user and system CPU time, peak resident memory (and the child's own ``VmHWM`` and command time).
The machine is shared, so the time ratio is taken on CPU time (user + system) and the load
average is recorded; with ``--repeat N`` the two commands run N times each, interleaved, and each
keeps its least CPU time (the run least slowed by other work). The targets: memory independent
of the frames, under 300 MiB for a million frames of 32 sensors with the defaults (issues 19 and
45), and the defaults at most 3x the time of ``--no-slip`` (issue 45).
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


def _timed_run(path: Path, extra: list[str]) -> dict:
    """``simbench calibrate`` on ``path`` in a fresh process under ``/usr/bin/time``."""
    done = subprocess.run(
        ["/usr/bin/time", "-f", "%e %U %S %M", sys.executable, "-c", CHILD, str(path), *extra],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    wall, user, system, rss = done.stderr.split()[-4:]
    run = json.loads(done.stdout.splitlines()[-1])
    run.update(
        wall_s=float(wall),
        user_s=float(user),
        sys_s=float(system),
        max_rss_kib=int(rss),
        cpu_s=float(user) + float(system),
    )
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--sensors", type=int, default=32)
    parser.add_argument("--dataset", type=Path, help="an existing dataset file to calibrate (not written)")
    parser.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="runs of each command, interleaved; the least CPU time of each is kept (a shared machine)",
    )
    parser.add_argument(
        "--save", action="store_true", help="write benchmarks/results/calibrate_dataset_FRAMES.json"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = args.dataset or Path(tmp) / "large.h5"
        t_write = None
        if args.dataset is None:
            t0 = time.perf_counter()
            write_dataset_file(path, args.frames, args.sensors)
            t_write = time.perf_counter() - t0
        else:
            with h5py.File(path, "r") as fh:
                args.frames, args.sensors = fh["measured/p_w_s"].shape[:2]
        size = path.stat().st_size
        tries: dict[str, list[dict]] = {"defaults": [], "no_slip": []}
        for _ in range(args.repeat):  # interleaved: both see the same spells of load
            for name, extra in (("defaults", []), ("no_slip", ["--no-slip"])):
                tries[name].append(_timed_run(path, extra))
        runs = {name: min(t, key=lambda run: run["cpu_s"]) for name, t in tries.items()}
    out = {
        "python": platform.python_version(),
        "frames": args.frames,
        "sensors": args.sensors,
        "file_mib": size / 2**20,
        "write_s": t_write,
        "load_average": os.getloadavg(),
        "time_format": "/usr/bin/time -f '%e %U %S %M': wall_s, user_s, sys_s, max_rss_kib",
        "commands": {"defaults": "simbench calibrate FILE", "no_slip": "simbench calibrate FILE --no-slip"},
        **runs,
        "repeat": args.repeat,
        "cpu_s_of_each_try": {name: [run["cpu_s"] for run in t] for name, t in tries.items()},
        "time_ratio_defaults_to_no_slip": runs["defaults"]["seconds"] / runs["no_slip"]["seconds"],
        "cpu_ratio_defaults_to_no_slip": runs["defaults"]["cpu_s"] / runs["no_slip"]["cpu_s"],
        "target_peak_rss_mib": 300.0,
        "target_time_ratio": 3.0,
    }
    print(f"{args.frames:,} frames x {args.sensors} sensors, simbench dataset ({out['file_mib']:.0f} MiB)")
    for name, run in runs.items():
        secs, cpu, peak = run["wall_s"], run["cpu_s"], run["max_rss_kib"] / 1024
        print(f"  simbench calibrate ({name}): {secs:.1f} s wall, {cpu:.1f} s CPU, peak RSS {peak:.1f} MiB")
    ratio, load = out["cpu_ratio_defaults_to_no_slip"], out["load_average"]
    print(f"  defaults / --no-slip CPU time: {ratio:.2f} (load {load})")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / f"calibrate_dataset_{args.frames}.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
