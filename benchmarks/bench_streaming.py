"""Streaming pose-CSV reading and calibration: peak memory and time against just reading the file
(issue 14's benchmark). Not a test.

    .venv/bin/python benchmarks/bench_streaming.py [--frames 1000000] [--sensors 2 32] [--save]

For each size a pose CSV of a seeded random tree in smooth motion (4 mm position noise, 120 Hz)
is written to a temporary directory, then each stage runs in a fresh process that reports its
own time and peak resident memory (VmHWM):

- ``bytes``: the file read in 1 MiB blocks and dropped (the floor of I/O);
- ``parse``: pyarrow's streaming CSV parse of every column, dropped (the floor of parsing);
- ``read``: :func:`simbench.io.poses.read_pose_csv` (two passes, poses to arrays or to the
  unlinked temporary HDF5 file);
- ``read+calibrate``: that, then the chunked calibration (``keep_frame_residuals=False``:
  hierarchy, joints, skeleton; nothing per frame kept);
- ``simbench calibrate --no-slip``: the command without slip detection (it keeps every joint's
  per-frame residual: frames x joints floats);
- ``simbench calibrate``: the command as a user runs it (slip detection on every joint holds
  the joint's whole series, several arrays of frames x 3).

Target (issue 14): ``read+calibrate`` below 300 MiB peak at 1,000,000 frames x 32 sensors.
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
import pyarrow as pa
import pyarrow.csv as pacsv
from child import PEAK_RSS, capture_chunks  # benchmarks/child.py: the script's own folder is on the path

from calibration.rotations import matrix_to_quat

RESULTS = Path(__file__).resolve().parent / "results"

COLUMNS = ("time", "sensor", "x", "y", "z", "qw", "qx", "qy", "qz")


def write_csv(path: Path, n_frames: int, n_sensors: int, chunk: int = 20_000) -> dict[str, str]:
    """A pose CSV, frame by frame; returns the true ``{child: parent}``."""
    skeleton, chunks = capture_chunks(n_frames, n_sensors, chunk)
    names = np.array(skeleton.names)
    schema = pa.schema(
        [("time", pa.float64()), ("sensor", pa.string())] + [(c, pa.float64()) for c in COLUMNS[2:]]
    )
    with pacsv.CSVWriter(path, schema) as writer:
        for start, stop, cap in chunks:
            m = (stop - start) * n_sensors
            q = matrix_to_quat(cap.R_w_s).reshape(m, 4)
            p = cap.p_w_s.reshape(m, 3)
            cols = [
                pa.array(np.repeat(np.arange(start, stop) / 120.0, n_sensors)),
                pa.array(np.tile(names, stop - start)),
            ]
            cols += [pa.array(p[:, i]) for i in range(3)] + [pa.array(q[:, i]) for i in range(4)]
            writer.write_table(pa.table(cols, schema=schema))
    return dict(skeleton.parent_of)


PRELUDE = (
    PEAK_RSS
    + """
import json, sys, time
path, truth = sys.argv[1], json.loads(sys.argv[2])
out = {}
"""
)

STAGES = {
    "bytes": """
t0 = time.perf_counter()
with open(path, "rb") as fh:
    while fh.read(1 << 20):
        pass
""",
    "parse": """
import pyarrow.csv as pacsv
t0 = time.perf_counter()
for batch in pacsv.open_csv(path, read_options=pacsv.ReadOptions(block_size=1 << 20)):
    pass
""",
    "read": """
from simbench.io.poses import read_pose_csv
t0 = time.perf_counter()
rec = read_pose_csv(path)
out["store"] = type(rec.R_w_s).__module__
""",
    "read+calibrate": """
from calibration import calibrate
from simbench.io.poses import read_pose_csv
t0 = time.perf_counter()
rec = read_pose_csv(path)
cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, keep_frame_residuals=False)
out["tree_correct"] = {frozenset(e) for e in cal.parent_of.items()} == {frozenset(e) for e in truth.items()}
""",
    "simbench calibrate --no-slip": """
import contextlib, io
from simbench.cli import main
t0 = time.perf_counter()
with contextlib.redirect_stdout(io.StringIO()) as text:
    status = main(["calibrate", path, "--no-slip"])
out["exit"] = status
""",
    "simbench calibrate": """
import contextlib, io
from simbench.cli import main
t0 = time.perf_counter()
with contextlib.redirect_stdout(io.StringIO()) as text:
    status = main(["calibrate", path])
out["exit"] = status
""",
}

EPILOGUE = """
out["seconds"] = time.perf_counter() - t0
out["peak_rss_mib"] = peak_rss_mib()
print(json.dumps(out))
"""


def run_stage(stage: str, path: Path, truth: dict[str, str]) -> dict:
    code = PRELUDE + STAGES[stage] + EPILOGUE
    done = subprocess.run(
        [sys.executable, "-c", code, str(path), json.dumps(truth)],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode:
        return {
            "error": done.stderr.strip().splitlines()[-1]
            if done.stderr.strip()
            else f"exit {done.returncode}"
        }
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1_000_000)
    parser.add_argument("--sensors", type=int, nargs="+", default=[2, 32])
    parser.add_argument("--stages", nargs="+", default=list(STAGES), choices=list(STAGES))
    parser.add_argument(
        "--dir", type=Path, help="keep the CSVs here and reuse them (default: a temporary directory)"
    )
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/streaming.json")
    args = parser.parse_args()
    out: dict = {"python": platform.python_version(), "pyarrow": pa.__version__, "cases": []}
    for n in args.sensors:
        with tempfile.TemporaryDirectory() as tmp:
            path = (args.dir or Path(tmp)) / f"poses-{args.frames}x{n}.csv"
            t0 = time.perf_counter()
            if path.exists() and path.with_suffix(".json").exists():
                truth = json.loads(path.with_suffix(".json").read_text())
            else:
                truth = write_csv(path, args.frames, n)
                path.with_suffix(".json").write_text(json.dumps(truth))
            case = {"frames": args.frames, "sensors": n, "file_mib": path.stat().st_size / 2**20}
            case["write_s"] = time.perf_counter() - t0
            print(f"{args.frames:,} frames x {n} sensors: {case['file_mib']:.0f} MiB CSV", flush=True)
            for stage in args.stages:
                case[stage] = result = run_stage(stage, path, truth)
                if "error" in result:
                    print(f"  {stage:20s} failed: {result['error']}", flush=True)
                    continue
                extra = {k: v for k, v in result.items() if k not in ("seconds", "peak_rss_mib")}
                took, peak = result["seconds"], result["peak_rss_mib"]
                print(f"  {stage:20s} {took:8.1f} s  {peak:7.0f} MiB  {extra or ''}", flush=True)
            for stage in ("read", "read+calibrate", "simbench calibrate --no-slip", "simbench calibrate"):
                if "seconds" in case.get(stage, {}) and "seconds" in case.get("parse", {}):
                    case[f"{stage} / parse"] = case[stage]["seconds"] / case["parse"]["seconds"]
            out["cases"].append(case)
    if args.save:  # cases of other sizes already saved are kept (run the sizes separately)
        RESULTS.mkdir(exist_ok=True)
        saved = RESULTS / "streaming.json"
        if saved.exists():
            sizes = {(c["frames"], c["sensors"]) for c in out["cases"]}
            kept = [
                c for c in json.loads(saved.read_text())["cases"] if (c["frames"], c["sensors"]) not in sizes
            ]
            out["cases"] = sorted(kept + out["cases"], key=lambda c: (c["frames"], c["sensors"]))
        saved.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
