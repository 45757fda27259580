"""Orientation estimation throughput and accuracy (issue 5's benchmark). Not a test.

    .venv/bin/pip install ahrs   # a benchmark-only dependency (the `bench` extra)
    .venv/bin/python benchmarks/bench_orientation.py [--save]

16 sensors x 100,000 frames of accelerometer and magnetometer readings (random smooth attitudes,
MTi-class noise: 0.0064 m/s^2 and 0.05 uT per axis) go through each of our estimators; in the same
process the ``ahrs`` package's FQA and TRIAD process a slice of the same arrays (they loop over
samples in Python: the whole set would take minutes), and throughputs are compared in samples per
second. Accuracy: RMS total error against the true attitudes on the same slice, for all. Frames
were matched empirically on noise-free readings: ahrs TRIAD with NED reference vectors returns
the world-to-sensor quaternion in NED (conjugated and converted here); ahrs FQA returns
sensor-to-world in NED. Targets: closed forms >= 100x faster than ahrs, the iterative Fontaine
estimator >= 10x, with equal or better accuracy.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from calibration.orientation import (
    Weighting,
    change_frame,
    fontaine,
    orientation_errors,
    reference,
    triad,
    wahba,
)
from calibration.rotations import matrix_to_quat, rotvec_to_matrix

RESULTS = Path(__file__).resolve().parent / "results"


def data(frames: int, sensors: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    ref = reference()
    t = np.arange(frames) / 100.0
    f = rng.uniform(0.05, 0.5, (sensors, 3))
    ph = rng.uniform(0, 2 * np.pi, (sensors, 3))
    rotvec = 2.0 * np.sin(2 * np.pi * f[None] * t[:, None, None] + ph[None])
    R = rotvec_to_matrix(rotvec)
    acc = np.einsum("fsji,j->fsi", R, ref.up_w * ref.gravity) + rng.normal(0, 0.0064, (frames, sensors, 3))
    mag = np.einsum("fsji,j->fsi", R, ref.field_w) + rng.normal(0, 0.05, (frames, sensors, 3))
    return ref, acc, mag, matrix_to_quat(R)


def timed(fn, repeats: int = 3) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--sensors", type=int, default=16)
    parser.add_argument("--ahrs-samples", type=int, default=20_000)
    parser.add_argument("--save", action="store_true")
    args = parser.parse_args()
    ref, acc, mag, truth = data(args.frames, args.sensors)
    n = args.frames * args.sensors
    ours = {
        "triad": lambda a, m: triad(a, m, ref).q_w_s,
        "wahba (closed form)": lambda a, m: wahba(a, m, ref).q_w_s,
        "wahba (svd)": lambda a, m: wahba(a, m, ref, method="svd").q_w_s,
        "fontaine": lambda a, m: fontaine(a, m, ref).q_w_s,
        "fontaine (weighting)": lambda a, m: fontaine(a, m, ref, weighting=Weighting()).q_w_s,
    }
    k = args.ahrs_samples
    a1, m1, t1 = acc[:k, 0], mag[:k, 0], truth[:k, 0]
    rms = lambda q, t: float(np.rad2deg(np.sqrt(np.nanmean(orientation_errors(q, t)[..., 0] ** 2))))  # noqa: E731
    rows = {}
    for name, fn in ours.items():
        seconds, q = timed(lambda fn=fn: fn(acc, mag))
        rows[name] = {
            "samples_per_s": n / seconds,
            "rms_error_deg": rms(fn(a1, m1), t1),
            "full_rms_error_deg": rms(q, truth),
        }
    try:
        from ahrs.filters import FQA, TRIAD
    except ImportError:
        print("ahrs is not installed (pip install ahrs): only our estimators are timed")
        FQA = TRIAD = None
    if FQA is not None:
        ned = reference("ned")
        seconds, f = timed(lambda: FQA(acc=a1, mag=m1), repeats=1)
        rows["ahrs FQA"] = {
            "samples_per_s": k / seconds,
            "rms_error_deg": rms(change_frame(f.Q, "ned", "enu"), t1),
        }
        seconds, tr = timed(
            lambda: TRIAD(w1=a1, w2=m1, v1=ned.up_w, v2=ned.field_w, representation="quaternion"), repeats=1
        )
        q = change_frame(np.asarray(tr.A) * np.array([1.0, -1.0, -1.0, -1.0]), "ned", "enu")
        rows["ahrs TRIAD"] = {"samples_per_s": k / seconds, "rms_error_deg": rms(q, t1)}
    print(f"{args.sensors} sensors x {args.frames} frames ({n} samples); ahrs on {k} samples")
    print(f"  {'method':<24}{'samples/s':>14}{'RMS error (deg)':>18}")
    for name, r in rows.items():
        print(f"  {name:<24}{r['samples_per_s']:>14.3g}{r['rms_error_deg']:>18.4f}")
    if "ahrs FQA" in rows:
        base = max(rows["ahrs FQA"]["samples_per_s"], rows["ahrs TRIAD"]["samples_per_s"])
        print("  speed-up over the faster ahrs estimator:")
        for name in ours:
            print(f"    {name:<22}{rows[name]['samples_per_s'] / base:>8.0f}x")
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        out = {"python": platform.python_version(), "numpy": np.__version__, "samples": n, "rows": rows}
        (RESULTS / "orientation.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
