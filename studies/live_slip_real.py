"""The live slip monitor on real recordings and on skin-artefact sessions, 2 cm slips injected
(issue 42, item 5).

    .venv/bin/python studies/live_slip_real.py [--real PATH ...] [--sim-seeds 4] [--out FILE]

Each recording is turned into segment poses from its marker clusters (the biobuddy hip trial with
``studies/hip_c3d.toml``, every other C3D with :func:`simbench.io.c3d.auto_clusters`) and pushed
through :class:`calibration.streaming.StreamingCalibrator` one frame at a time, with the defaults
(nothing set per recording):

- **clean**: the recording as it is. Every alert is a false alarm; per joint, the time its noise
  model armed (its first finite threshold), seconds after the first frame; false alarms per
  joint-minute (joints of the final tree times the recording's minutes).
- **slips**: for each moving cluster in turn (not a ``still`` group), a 2 cm shift in a random
  direction of its frame from a random time between :data:`FIRST_SLIP_S` and 1 s before the end
  (seeded by recording and cluster): ``p += R @ offset`` from that frame on, as a cluster that
  moved on the skin (:func:`simbench.sim.live.recording_with_slip`). A hit is an alert naming that
  cluster raised within :data:`TOLERANCE_S` after the slip; latency is the raise time minus the
  slip time; an alert before the slip is a false alarm.
- **frames/s**: the pushes' wall time on the clean recording, with the machine's load.

Simulated sessions made as messy as real ones (``--sim-seeds``): the humanoid's exercise with the
skin-artefact presets ``skin-markers`` (fitted to the biobuddy hip trial) and ``skin-paper-human``,
30 s, a slip of a random skin sensor between 10 and 25 s, the same injection.

Real files outside the repository (``/tmp/realc3d``) are used when present and listed in the
results; the default list is :data:`REAL`. Results: ``studies/results/live_slip_real.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from calibration.errors import CalibrationError
from calibration.streaming import LIVE_SLIP_WINDOW_S, SLIP_WARMUP_S, StreamingCalibrator
from simbench.experiments.decisions import SKIN_SENSORS
from simbench.io.c3d import c3d_poses, read_cluster_spec
from simbench.io.poses import PoseRecording
from simbench.sim.live import recording_with_slip
from simbench.sim.plan import SessionConfig, load_session_model
from simbench.sim.session import run_session

HERE = Path(__file__).resolve().parent
SHARED = HERE.parents[1] / "shared" / "data"
OUT = HERE / "results" / "live_slip_real.json"
REAL = [
    SHARED / "biobuddy_right_hip.c3d",
    Path("/tmp/realc3d/pyomeca__examples_data_functional_trials_right_knee.c3d"),
    Path("/tmp/realc3d/pyomeca__examples_data_functional_trials_right_hip.c3d"),
    Path("/tmp/realc3d/felixchenier__data_kinematics_racing_full.c3d"),
    Path("/tmp/realc3d/felixchenier__data_kinematics_sample_propulsion.c3d"),
    Path("/tmp/realc3d/felixchenier__data_kinematics_sprintbasket.c3d"),
    Path("/tmp/realc3d/pyomeca__tests_data_markers_analogs.c3d"),
]
SPECS = {"biobuddy_right_hip.c3d": HERE / "hip_c3d.toml"}
SLIP_M = 0.02
FIRST_SLIP_S = 3.5
TOLERANCE_S = 0.5
PRESETS = ("skin-markers", "skin-paper-human")
#: A joint arms once its window differences hold SLIP_WARMUP_S, the first 2 w after its pair's first frame.
ARMING_S = 2 * LIVE_SLIP_WINDOW_S + SLIP_WARMUP_S


def real_recording(path: Path) -> PoseRecording:
    """Segment poses of a C3D file (the named clusters where :data:`SPECS` has them)."""
    spec = SPECS.get(path.name)
    return c3d_poses(path, clusters=None if spec is None else read_cluster_spec(spec))


def run_live(rec: PoseRecording) -> dict[str, Any]:
    """Push every frame one at a time; the alerts, each joint's armed time, the cost."""
    sc = StreamingCalibrator(rec.names, rate_hz=rec.rate_hz)
    R, p, ok = rec.R_w_s, rec.p_w_s, rec.valid
    t0 = time.perf_counter()
    for f in range(R.shape[0]):
        sc.push(R[f], p[f], ok[f])
    seconds = time.perf_counter() - t0
    try:
        joints = [j.name for j in sc.calibration().joints]
    except CalibrationError:
        joints = []
    armed = sc.slip_armed_s()
    return {
        "alerts": [
            {
                "sensor": a.sensor,
                "joint": a.joint,
                "time_s": a.time_s,
                "raised_s": a.raised_frame / rec.rate_hz,
                "size_cm": a.size_m * 100,
                "z_over_threshold": a.z / a.threshold,
            }
            for a in sc.alerts
        ],
        "joints": joints,
        "armed_s": armed,
        "frames_per_s": R.shape[0] / seconds,
        "load": os.getloadavg()[0],
    }


def moving_sensors(rec: PoseRecording) -> list[int]:
    """The clusters a slip is injected on: not a still group."""
    return [k for k, name in enumerate(rec.names) if not name.startswith("still")]


def slip_draw(label: str, rec: PoseRecording, k: int, first_s: float) -> tuple[float, int, np.ndarray]:
    """The slip injected on sensor ``k``: its drawn time (s after the first frame), its first frame,
    and the offset ``(3,)`` in the sensor's frame, metres (seeded by ``label`` and the sensor)."""
    duration = rec.n_frames / rec.rate_hz
    rng = np.random.default_rng([42, zlib.crc32(f"{label}/{rec.names[k]}".encode())])
    t_slip = float(rng.uniform(first_s, duration - 1.0))
    d = rng.normal(size=3)
    return t_slip, int(np.ceil(t_slip * rec.rate_hz)), SLIP_M * d / np.linalg.norm(d)


def slip_runs(label: str, rec: PoseRecording, sensors: list[int], first_s: float) -> list[dict[str, Any]]:
    runs = []
    for k in sensors:
        t_slip, frame, offset = slip_draw(label, rec, k, first_s)
        if not rec.valid[frame : frame + round(TOLERANCE_S * rec.rate_hz), k].any():
            runs.append({"sensor": rec.names[k], "slip_s": t_slip, "skipped": "no pose after the slip"})
            continue
        t_slip = frame / rec.rate_hz  # seconds after the first frame, as the alerts' raise times
        live = run_live(recording_with_slip(rec, rec.names[k], float(rec.time_s[frame]), offset))
        hits = [
            a
            for a in live["alerts"]
            if 0.0 <= a["raised_s"] - t_slip <= TOLERANCE_S and a["sensor"] == rec.names[k]
        ]
        near = [a for a in live["alerts"] if 0.0 <= a["raised_s"] - t_slip <= TOLERANCE_S]
        joints_of = [j for j in live["joints"] if rec.names[k] in j.split("-")]
        armed = [live["armed_s"].get(j) for j in joints_of]
        runs.append(
            {
                "sensor": rec.names[k],
                "slip_s": t_slip,
                "armed_s": armed,
                "armed_before_slip": any(a is not None and a <= t_slip for a in armed),
                "detected": bool(near),
                "right_sensor": bool(hits),
                "latency_s": hits[0]["raised_s"] - t_slip if hits else None,
                "alerts_before_slip": sum(a["raised_s"] < t_slip for a in live["alerts"]),
                "alerts": live["alerts"],
            }
        )
    return runs


def seen_s(rec: PoseRecording, joint: str) -> float | None:
    """Seconds after the first frame by which both sensors of ``"parent-child"`` had been valid
    together for :data:`ARMING_S` (the history a joint needs to arm); ``None`` if never."""
    a, b = (rec.names.index(x) for x in _ends(rec.names, joint))
    both = np.flatnonzero(rec.valid[:, a] & rec.valid[:, b])
    need = round(ARMING_S * rec.rate_hz)
    return float(both[need - 1] / rec.rate_hz) if both.size >= need else None


def _ends(names: tuple[str, ...], joint: str) -> tuple[str, str]:
    """The two sensor names of ``"parent-child"`` (names may hold ``-``)."""
    for name in names:
        if joint.startswith(name + "-") and joint[len(name) + 1 :] in names:
            return name, joint[len(name) + 1 :]
    raise ValueError(f"{joint!r} is not a pair of {names}")


def clean_summary(rec: PoseRecording, live: dict[str, Any]) -> dict[str, Any]:
    minutes = rec.n_frames / rec.rate_hz / 60.0
    armed = [live["armed_s"].get(j) for j in live["joints"]]
    seen = [seen_s(rec, j) for j in live["joints"]]
    after_seen = [a - s for a, s in zip(armed, seen, strict=True) if a is not None and s is not None]
    return {
        "sensors": list(rec.names),
        "frames": rec.n_frames,
        "rate_hz": rec.rate_hz,
        "duration_s": rec.n_frames / rec.rate_hz,
        "joints": live["joints"],
        "armed_s": dict(zip(live["joints"], armed, strict=True)),
        "armed_s_max": max((round(a, 3) for a in armed if a is not None), default=None),
        "seen_s": dict(zip(live["joints"], seen, strict=True)),
        "armed_after_seen_s_max": max((round(a, 3) for a in after_seen), default=None),
        "never_armed": [j for j, a in zip(live["joints"], armed, strict=True) if a is None],
        "false_alarms": live["alerts"],
        "joint_minutes": len(live["joints"]) * minutes,
        "false_alarms_per_joint_minute": len(live["alerts"]) / (len(live["joints"]) * minutes)
        if live["joints"]
        else None,
        "frames_per_s": live["frames_per_s"],
        "load_1min": live["load"],
    }


def slip_summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    done = [r for r in runs if "skipped" not in r]
    lat = [r["latency_s"] for r in done if r["latency_s"] is not None]
    return {
        "slips": len(done),
        "armed_before_slip": sum(r["armed_before_slip"] for r in done),
        "right_sensor_of_armed": sum(r["right_sensor"] and r["armed_before_slip"] for r in done),
        "detected_within_0.5s": sum(r["detected"] for r in done),
        "right_sensor": sum(r["right_sensor"] for r in done),
        "latency_s_median": float(np.median(lat)) if lat else None,
        "latency_s_max": float(np.max(lat)) if lat else None,
        "alerts_before_slip": sum(r["alerts_before_slip"] for r in done),
    }


def real_case(path: Path) -> dict[str, Any]:
    rec = real_recording(path)
    clean = clean_summary(rec, run_live(rec))
    runs = slip_runs(path.name, rec, moving_sensors(rec), FIRST_SLIP_S)
    return {"file": str(path), "clean": clean, "slip": slip_summary(runs), "runs": runs}


def sim_case(preset: str, seed: int) -> dict[str, Any]:
    config = SessionConfig(model="humanoid", motion="exercise", duration_s=30.0, seed=seed, sensors=preset)
    rec = run_session(config, load_session_model(config)).poses()
    clean = clean_summary(rec, run_live(rec))
    rng = np.random.default_rng([42, seed, zlib.crc32(preset.encode())])
    sensor = rec.names.index(SKIN_SENSORS[int(rng.integers(len(SKIN_SENSORS)))])
    runs = slip_runs(f"{preset}/{seed}", rec, [sensor], 10.0)
    return {"preset": preset, "seed": seed, "clean": clean, "slip": slip_summary(runs), "runs": runs}


def _line(label: str, case: dict[str, Any]) -> str:
    c, s = case["clean"], case["slip"]
    return (
        f"{label:58s} armed by {c['armed_s_max']} s ({c['armed_after_seen_s_max']} s after seen)"
        f" (never: {len(c['never_armed'])}), false alarms {len(c['false_alarms'])} in "
        f"{c['joint_minutes']:.1f} joint-min; slips {s['right_sensor']}/{s['slips']} right sensor "
        f"({s['detected_within_0.5s']} any), latency max {s['latency_s_max']}, "
        f"{c['frames_per_s']:.0f} frames/s (load {c['load_1min']:.2f})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, nargs="*", default=None, help="C3D files (default: REAL)")
    parser.add_argument("--sim-seeds", type=int, default=4, help="sessions per skin-artefact preset")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    paths = [p for p in (REAL if args.real is None else args.real) if p.exists()]
    start = time.perf_counter()
    real = []
    for path in paths:
        case = real_case(path)
        real.append(case)
        print(_line(path.name, case), flush=True)
    sims = []
    for preset in PRESETS:
        for seed in range(args.sim_seeds):
            case = sim_case(preset, seed)
            sims.append(case)
            print(_line(f"{preset} seed {seed}", case), flush=True)

    def total(cases: list[dict[str, Any]]) -> dict[str, Any]:
        runs = [r for c in cases for r in c["runs"]]
        minutes = sum(c["clean"]["joint_minutes"] for c in cases)
        alarms = sum(len(c["clean"]["false_alarms"]) for c in cases)
        armed = [c["clean"]["armed_s_max"] for c in cases]
        after_seen = [c["clean"]["armed_after_seen_s_max"] for c in cases]
        return {
            **slip_summary(runs),
            "armed_s_max": max((a for a in armed if a is not None), default=None),
            "armed_after_seen_s_max": max((a for a in after_seen if a is not None), default=None),
            "recordings_never_armed": sum(bool(c["clean"]["never_armed"]) for c in cases),
            "clean_false_alarms": alarms,
            "clean_joint_minutes": minutes,
            "false_alarms_per_10_joint_minutes": 10.0 * alarms / minutes if minutes else None,
        }

    doc = {
        "settings": {
            "slip_m": SLIP_M,
            "tolerance_s": TOLERANCE_S,
            "first_slip_s": FIRST_SLIP_S,
            "live_window_s": LIVE_SLIP_WINDOW_S,
            "warmup_s": SLIP_WARMUP_S,
            "seconds": time.perf_counter() - start,
        },
        "summary": {"real": total(real), "simulated": total(sims)},
        "real": real,
        "simulated": sims,
    }
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps(doc["summary"], indent=1))


if __name__ == "__main__":
    main()
