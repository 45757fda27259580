"""Live (streaming) calibration: update cost per frame, memory over a long session, slip-alert
latency and false alarms (issue 17's targets). Not a test.

    .venv/bin/python benchmarks/bench_live.py [--seeds 8] [--minutes 10 60] [--save]

(``bench_streaming.py`` is issue 14's benchmark of streaming CSV *reading*; this one is the
incremental calibrator, :mod:`calibration.streaming`.)

- ``update``: 16 sensors (a seeded random tree, 4 mm of position noise), 60 s at 240 Hz pushed
  frame by frame (a driver callback) and in 0.1 s blocks, slip monitor on; frames per second
  and the time per frame as a fraction of the 240 Hz frame period (target: at most 1/10, i.e.
  at least 2,400 frames/s on one core), against the batch calibration of the same frames in the
  same process; and the cost of one ``state()`` (what a refreshing table asks for).
- ``update_real``: the same on real recordings (marker clusters of C3D files, pushed one frame at
  a time at their own rate, slip monitor on and off; against the batch in the same process), and
  on a 16-sensor real composite (three recordings' clusters side by side, cut to the shortest,
  resampled to 240 Hz by repeating frames) when the files are at hand (``/tmp/realc3d``).
- Every cost is stated with the machine's load (``os.getloadavg()``) when it was measured.
- ``memory``: tracemalloc peak while 10 min and 60 min at 120 Hz of 16 sensors are pushed in
  10 s blocks (one 10 min capture generated once, pushed again and again), and the arrays the
  calibrator holds (``nbytes``); target: independent of the session's length.
- ``slip``: 30 s humanoid exercise sessions (Polhemus Liberty preset, seeds 0..N-1) with a 2 cm
  slip of a random skin sensor at 15-25 s, and the same sessions without it: alert latency
  (raised minus slip time), right sensor, other alerts; false alarms per joint-hour on the clean
  sessions against the rate the threshold is set for.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import tracemalloc
from pathlib import Path

import numpy as np

from calibration import calibrate
from calibration.streaming import StreamingCalibrator
from simbench.experiments.decisions import SKIN_SENSORS
from simbench.io.c3d import c3d_poses, read_cluster_spec
from simbench.sim.live import live_session, with_slip
from simbench.sim.plan import SessionConfig
from simbench.sim.synthetic import random_tree, simulate_motion

RESULTS = Path(__file__).resolve().parent / "results"
HIP_C3D = Path(__file__).resolve().parents[2] / "shared" / "data" / "biobuddy_right_hip.c3d"
HIP_SPEC = Path(__file__).resolve().parents[1] / "studies" / "hip_c3d.toml"
REAL_C3D = [
    HIP_C3D,
    Path("/tmp/realc3d/pyomeca__examples_data_functional_trials_right_knee.c3d"),
    Path("/tmp/realc3d/felixchenier__data_kinematics_racing_full.c3d"),
    Path("/tmp/realc3d/felixchenier__data_kinematics_sprintbasket.c3d"),
    Path("/tmp/realc3d/pyomeca__tests_data_markers_analogs.c3d"),
]


def _capture(n_frames: int, rate_hz: float):
    skeleton = random_tree(16, np.random.default_rng(2))
    cap = simulate_motion(
        skeleton, n_frames=n_frames, rate_hz=rate_hz, rng=np.random.default_rng(3), position_noise_m=0.004
    )
    return skeleton.names, cap.R_w_s, cap.p_w_s


def _frame_by_frame(names, R, p, ok, rate: float, slip: bool) -> tuple[float, float]:
    """Seconds to push every frame one at a time and read the calibration: wall clock, and this
    process's CPU time (what the frames cost whatever else the machine runs)."""
    sc = StreamingCalibrator(names, rate_hz=rate, slip=slip)
    t0, c0 = time.perf_counter(), time.process_time()
    for f in range(R.shape[0]):
        sc.push(R[f], p[f], ok[f])
    sc.calibration()
    return time.perf_counter() - t0, time.process_time() - c0


def update_real() -> dict:
    """Frames per second on real recordings, one frame at a time (module docstring)."""
    out: dict = {}
    recs = []
    for path in REAL_C3D:
        if not path.exists():
            continue
        rec = c3d_poses(path, clusters=read_cluster_spec(HIP_SPEC) if path == HIP_C3D else None)
        recs.append(rec)
        out[path.name] = _real_cost(rec.names, rec.R_w_s, rec.p_w_s, rec.valid, rec.rate_hz)
    # 16 sensors of real data: the first recordings' clusters side by side, 240 Hz
    names: list[str] = []
    parts = []
    for k, rec in enumerate(recs):
        take = min(len(rec.names), 16 - len(names))
        if take <= 0:
            break
        names += [f"{k}:{n}" for n in rec.names[:take]]
        parts.append((rec, take))
    if len(names) == 16:
        seconds = min(rec.n_frames / rec.rate_hz for rec, _ in parts)
        n = int(seconds * 240.0)
        idx = [
            np.minimum((np.arange(n) / 240.0 * rec.rate_hz).astype(int), rec.n_frames - 1) for rec, _ in parts
        ]
        R = np.concatenate([rec.R_w_s[i, :t] for (rec, t), i in zip(parts, idx, strict=True)], axis=1)
        p = np.concatenate([rec.p_w_s[i, :t] for (rec, t), i in zip(parts, idx, strict=True)], axis=1)
        ok = np.concatenate([rec.valid[i, :t] for (rec, t), i in zip(parts, idx, strict=True)], axis=1)
        out["composite_16_sensors_240hz"] = _real_cost(tuple(names), R, p, ok, 240.0)
    return out


def _real_cost(names, R, p, ok, rate: float) -> dict:
    t0, c0 = time.perf_counter(), time.process_time()
    calibrate(R, p, names, valid=ok)
    batch, batch_cpu = time.perf_counter() - t0, time.process_time() - c0
    on, on_cpu = _frame_by_frame(names, R, p, ok, rate, slip=True)
    off, off_cpu = _frame_by_frame(names, R, p, ok, rate, slip=False)
    return {
        "sensors": len(names),
        "frames": int(R.shape[0]),
        "rate_hz": rate,
        "frames_per_s": R.shape[0] / on,
        "frames_per_cpu_s": R.shape[0] / on_cpu,
        "frames_per_s_without_slip": R.shape[0] / off,
        "frames_per_cpu_s_without_slip": R.shape[0] / off_cpu,
        "vs_batch": on / batch,
        "vs_batch_cpu": on_cpu / batch_cpu,
        "load_1min": os.getloadavg()[0],
    }


def update_cost() -> dict:
    rate = 240.0
    names, R, p = _capture(14400, rate)
    out: dict = {"sensors": 16, "frames": int(R.shape[0]), "rate_hz": rate, "load_1min": os.getloadavg()[0]}
    t0 = time.perf_counter()
    batch = calibrate(R, p, names)
    out["batch_s"] = time.perf_counter() - t0
    ok = np.ones(R.shape[:2], dtype=bool)
    wall, cpu = _frame_by_frame(names, R, p, ok, rate, slip=False)
    out["frame_by_frame_without_slip"] = {
        "frames_per_s": R.shape[0] / wall,
        "frames_per_cpu_s": R.shape[0] / cpu,
    }
    wall, cpu = _frame_by_frame(names, R, p, ok, rate, slip=True)
    c0 = time.process_time()
    calibrate(R, p, names)
    batch_cpu = time.process_time() - c0
    out["frame_by_frame_cpu"] = {"frames_per_cpu_s": R.shape[0] / cpu, "vs_batch_cpu": cpu / batch_cpu}
    for label, step in (("frame_by_frame", 1), ("blocks_0.1s", 24)):
        sc = StreamingCalibrator(names, rate_hz=rate)
        t0 = time.perf_counter()
        if step == 1:
            for f in range(R.shape[0]):
                sc.push(R[f], p[f])
        else:
            for lo in range(0, R.shape[0], step):
                sc.push(R[lo : lo + step], p[lo : lo + step])
        sc.calibration()
        seconds = time.perf_counter() - t0
        live = sc.calibration()
        err = max(
            float(np.max(np.abs(a.fit.joint_in_parent - b.fit.joint_in_parent)))
            for a, b in zip(live.joints, batch.joints, strict=True)
        )
        out[label] = {
            "seconds": seconds,
            "frames_per_s": R.shape[0] / seconds,
            "fraction_of_frame_period_240hz": seconds / R.shape[0] * rate,
            "vs_batch": seconds / out["batch_s"],
            "max_centre_difference_vs_batch_m": err,
            "same_tree": live.parent_of == batch.parent_of,
            "alerts": len(sc.alerts),
        }
    t0 = time.perf_counter()
    for _ in range(5):
        sc.state()
    out["state_s"] = (time.perf_counter() - t0) / 5
    return out


def memory(minutes: list[float]) -> dict:
    rate = 120.0
    block = int(10 * rate)
    names, R, p = _capture(int(10 * 60 * rate), rate)
    out: dict = {"sensors": 16, "rate_hz": rate}
    for m in minutes:
        n = int(m * 60 * rate)
        tracemalloc.start()
        t0 = time.perf_counter()
        sc = StreamingCalibrator(names, rate_hz=rate)
        for lo in range(0, n, block):
            k = lo % R.shape[0]
            sc.push(R[k : k + block], p[k : k + block])
        sc.state()
        seconds = time.perf_counter() - t0
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        out[f"{m:g}_min"] = {
            "frames": n,
            "tracemalloc_peak_mib": peak / 2**20,
            "held_arrays_mib": sc.nbytes / 2**20,
            "seconds_traced": seconds,
        }
    return out


def slip_sessions(seeds: int) -> dict:
    runs = []
    joint_hours = 0.0
    clean_alarms = 0
    for seed in range(seeds):
        rng = np.random.default_rng([17, seed])
        sensor = SKIN_SENSORS[int(rng.integers(len(SKIN_SENSORS)))]
        t_slip = float(rng.uniform(15.0, 25.0))
        d = rng.normal(size=3)
        offset = 0.02 * d / np.linalg.norm(d)
        for slip in (True, False):
            sensors = with_slip("polhemus-liberty", sensor, t_slip, offset) if slip else "polhemus-liberty"
            config = SessionConfig(
                model="humanoid", motion="exercise", duration_s=30.0, seed=seed, sensors=sensors
            )
            rec, blocks = live_session(config, block_frames=12, speed=None)
            t0 = float(rec.time_s[0])
            sc = StreamingCalibrator(rec.names, rate_hz=rec.rate_hz, start_time_s=t0)
            for b in blocks:
                sc.push(b.R_w_s, b.p_w_s, b.valid)
            alerts = [
                {
                    "sensor": a.sensor,
                    "joint": a.joint,
                    "time_s": a.time_s - t0,
                    "raised_s": a.raised_frame / rec.rate_hz,
                    "size_cm": a.size_m * 100,
                }
                for a in sc.alerts
            ]
            if not slip:
                joint_hours += len(sc.calibration().joints) * rec.time_s.size / rec.rate_hz / 3600.0
                clean_alarms += len(alerts)
                runs[-1]["clean_alerts"] = alerts
                continue
            near = [a for a in alerts if 0.0 <= a["raised_s"] - t_slip <= 0.5]
            runs.append(
                {
                    "seed": seed,
                    "sensor": sensor,
                    "slip_s": t_slip,
                    "alerts": alerts,
                    "detected_within_0.5s": bool(near),
                    "right_sensor": any(a["sensor"] == sensor for a in near),
                    "latency_s": near[0]["raised_s"] - t_slip if near else None,
                    "other_alerts": len(alerts) - (1 if near else 0),
                }
            )
    lat = [r["latency_s"] for r in runs if r["latency_s"] is not None]
    return {
        "preset": "polhemus-liberty",
        "model": "humanoid",
        "motion": "exercise",
        "duration_s": 30.0,
        "slip_cm": 2.0,
        "sessions": seeds,
        "detected_within_0.5s": sum(r["detected_within_0.5s"] for r in runs),
        "right_sensor": sum(r["right_sensor"] for r in runs),
        "other_alerts_in_slip_sessions": sum(r["other_alerts"] for r in runs),
        "latency_s_median": float(np.median(lat)) if lat else None,
        "latency_s_max": float(np.max(lat)) if lat else None,
        "clean_joint_hours": joint_hours,
        "clean_false_alarms": clean_alarms,
        "clean_false_alarms_per_joint_hour": clean_alarms / joint_hours if joint_hours else None,
        "threshold_false_alarms_per_joint_hour": 1.0,
        "runs": runs,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0])
    parser.add_argument("--save", action="store_true", help="write benchmarks/results/live.json")
    parser.add_argument("--update-only", action="store_true", help="only the update costs (no memory, slips)")
    args = parser.parse_args()
    out = {"python": platform.python_version(), "numpy": np.__version__, "machine": platform.machine()}
    out["update"] = update_cost()
    u = out["update"]
    for label in ("frame_by_frame", "blocks_0.1s"):
        x = u[label]
        print(
            f"update {label:15s} {x['frames_per_s']:8.0f} frames/s  "
            f"{x['fraction_of_frame_period_240hz']:.3f} of the 240 Hz period  "
            f"{x['vs_batch']:.2f} x batch ({u['batch_s']:.2f} s)  centre diff "
            f"{x['max_centre_difference_vs_batch_m']:.1e} m"
        )
    print(
        f"update frame_by_frame CPU time: {u['frame_by_frame_cpu']['frames_per_cpu_s']:.0f} frames per "
        "CPU-second, "
        f"{u['frame_by_frame_cpu']['vs_batch_cpu']:.2f} x batch (CPU); without the slip monitor "
        f"{u['frame_by_frame_without_slip']['frames_per_cpu_s']:.0f}"
    )
    print(
        f"state() {u['state_s'] * 1e3:.1f} ms; without the slip monitor "
        f"{u['frame_by_frame_without_slip']['frames_per_s']:.0f} frames/s; load {u['load_1min']:.2f}"
    )
    out["update_real"] = update_real()
    for k, v in out["update_real"].items():
        print(
            f"real {k:55s} {v['sensors']:2d} sensors {v['rate_hz']:5.0f} Hz: "
            f"{v['frames_per_s']:7.0f} frames/s ({v['frames_per_cpu_s']:.0f} per CPU-second) "
            f"({v['frames_per_s_without_slip']:.0f} without the slip monitor), {v['vs_batch']:.1f} x batch, "
            f"load {v['load_1min']:.2f}"
        )
    if args.update_only:
        args.minutes, args.seeds = [], 0
    out["memory"] = memory(args.minutes)
    for k, v in out["memory"].items():
        if isinstance(v, dict):
            print(
                f"memory {k:8s} peak {v['tracemalloc_peak_mib']:.2f} MiB, held {v['held_arrays_mib']:.2f} MiB"
            )
    if args.seeds:
        s = out["slip"] = slip_sessions(args.seeds)
        print(
            f"slip: {s['detected_within_0.5s']}/{s['sessions']} within 0.5 s, "
            f"{s['right_sensor']} right sensor, "
            f"latency median {s['latency_s_median']} s max {s['latency_s_max']} s, other alerts "
            f"{s['other_alerts_in_slip_sessions']}; clean: {s['clean_false_alarms']} alarms in "
            f"{s['clean_joint_hours']:.2f} joint-hours"
        )
    if args.save:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "live.json").write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
