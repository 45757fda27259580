"""Start-up: ``import simbench`` and ``simbench --help``, each in fresh processes. Not a test.

    .venv/bin/python benchmarks/bench_startup.py [--runs 5] [--save]

Each is run ``--runs`` times in a fresh interpreter; the median wall time and the peak resident
memory (``VmHWM``) are reported beside ``python -c pass`` run the same way, the floor any command
pays, so that the ratio holds on a loaded machine; the load average (1 min) is recorded before and
after. Targets (issue 44): ``import simbench`` at most 0.3 s and ``simbench --help`` at most 0.5 s
on a quiet machine; ``simbench calibrate --help`` is a command's help (its options, whose defaults
and choices come from the registries).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
PEAK = (
    "import atexit, sys\n"
    "def _peak():\n"
    "    for line in open('/proc/self/status'):\n"
    "        if line.startswith('VmHWM'):\n"
    "            sys.stderr.write('PEAK ' + line.split()[1] + '\\n')\n"
    "atexit.register(_peak)\n"
)

CASES = {
    "python -c pass": [sys.executable, "-c", PEAK + "pass"],
    "import simbench": [sys.executable, "-c", PEAK + "import simbench"],
}
for _argv in (["--help"], ["calibrate", "--help"]):
    CASES[" ".join(["simbench", *_argv])] = [
        sys.executable,
        "-c",
        PEAK
        + f"import sys; sys.argv = {['simbench', *_argv]!r}\n"
        + "import runpy; runpy.run_module('simbench', run_name='__main__')",
    ]


def run(argv: list[str]) -> tuple[float, float]:
    """``(seconds, peak MiB)`` of one fresh run."""
    t0 = time.perf_counter()
    done = subprocess.run(argv, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    peak = [line for line in done.stderr.splitlines() if line.startswith("PEAK ")]
    if not peak:
        raise SystemExit(f"{argv[-1][:40]}: no peak reported (exit {done.returncode}): {done.stderr[-500:]}")
    return seconds, int(peak[-1].split()[1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/startup.json")
    args = parser.parse_args()
    out: dict = {"python": platform.python_version(), "runs": args.runs, "load_average": os.getloadavg()}
    out["cpus"] = os.cpu_count()
    for name, argv in CASES.items():
        samples = [run(argv) for _ in range(args.runs)]
        out[name] = {
            "median_s": statistics.median(s for s, _ in samples),
            "peak_rss_mib": max(m for _, m in samples),
        }
    floor = out["python -c pass"]["median_s"]
    for name in CASES:
        out[name]["over_python_s"] = out[name]["median_s"] - floor
        print(
            f"{name:26s} {out[name]['median_s']:.3f} s ({out[name]['over_python_s']:+.3f} s over python), "
            f"{out[name]['peak_rss_mib']:.0f} MiB"
        )
    out["load_average_after"] = os.getloadavg()
    print(f"load average {out['load_average'][0]:.1f} before, {out['load_average_after'][0]:.1f} after")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "startup.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
