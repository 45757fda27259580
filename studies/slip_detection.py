"""False alarms and detection rate of the slip detector (issue 12), on simulated and real data.

    .venv/bin/python studies/slip_detection.py [--seeds 20] [--slip-seeds 10] [--workers 2]

- False alarms on clean simulated sessions (no slip, 30 s): ``ascension-flock`` and
  ``polhemus-liberty`` on the linkage, ``skin-paper-human`` on the humanoid; motions walk and
  exercise; alarms per hour of joint time (target: at most 6, one per 10 minutes).
- False alarms on the real biobuddy hip trial (``../shared/data/biobuddy_right_hip.c3d``,
  clusters of ``studies/hip_c3d.toml``).
- Detection of 1, 2 and 3 cm slips injected (``[[skin.slip]]``) on a skin-mounted sensor of the
  humanoid with ``skin-paper-human``: a hit is an event on a joint of that sensor within 0.5 s
  of the slip, in that sensor's frame; the time error of hits (targets 95 / 99 / 99 %).

Every case uses the detector's defaults (1 false alarm per hour, the window below); nothing is
tuned per case. Results: ``studies/results/slip_detection.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from calibration import calibrate
from calibration.slip import FALSE_ALARMS_PER_HOUR, SLIP_WINDOW_S
from simbench.experiments.decisions import DETECTION_TOLERANCE_S, joint_slips, slip_trial
from simbench.io.read import read_poses
from simbench.sim.session import SessionConfig, load_session_model, run_session

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
OUT = HERE / "results" / "slip_detection.json"
DURATION_S = 30.0
WINDOW_S = SLIP_WINDOW_S
CLEAN = [
    ("linkage", "walk", "ascension-flock"),
    ("linkage", "exercise", "ascension-flock"),
    ("linkage", "walk", "polhemus-liberty"),
    ("linkage", "exercise", "polhemus-liberty"),
    ("humanoid", "walk", "skin-paper-human"),
    ("humanoid", "exercise", "skin-paper-human"),
]
SLIP_CM = (1, 2, 3)
TOLERANCE_S = DETECTION_TOLERANCE_S


def _session(model: str, motion: str, sensors: Any, seed: int):
    config = SessionConfig(model=model, motion=motion, duration_s=DURATION_S, seed=seed, sensors=sensors)
    ds = run_session(config, load_session_model(config))
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    return ds, rec, joint_slips(rec, cal)


def clean_case(args: tuple[str, str, str, int]) -> dict[str, Any]:
    """Alarms of every joint of one clean session."""
    model, motion, preset, seed = args
    ds, rec, found = _session(model, motion, preset, seed)
    return {
        "model": model,
        "motion": motion,
        "preset": preset,
        "seed": seed,
        "joint_hours": len(found) * rec.n_frames / rec.rate_hz / 3600.0,
        "alarms": [
            {"joint": j.name, "time_s": float(ds.time_s[ev.frame]), "jump_mm": ev.jump * 1e3, "z": ev.z}
            for j, rep in found
            for ev in rep.events
        ],
        "min_jump_mm": [rep.min_jump * 1e3 for _, rep in found],
    }


def slip_case(args: tuple[str, int, int]) -> dict[str, Any]:
    """One injected slip (:func:`simbench.experiments.decisions.slip_trial`)."""
    motion, cm, seed = args
    return slip_trial(motion, cm, seed, DURATION_S)


def hip_case() -> dict[str, Any]:
    """Alarms on the real hip trial."""
    rec = read_poses(C3D, clusters=HERE / "hip_c3d.toml")
    parent_of = {"thigh_r": "pelvis", "shank_r": "thigh_r"}
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, parent_of=parent_of)
    found = joint_slips(rec, cal)
    return {
        "joint_hours": len(found) * rec.n_frames / rec.rate_hz / 3600.0,
        "alarms": [
            {"joint": j.name, "frame": ev.frame, "jump_mm": ev.jump * 1e3}
            for j, rep in found
            for ev in rep.events
        ],
        "min_jump_mm": {j.name: rep.min_jump * 1e3 for j, rep in found},
    }


def summarise(clean: list[dict], slips: list[dict], hip: dict) -> dict[str, Any]:
    """Alarm rates per hour by case and detection rates by motion and size."""
    out: dict[str, Any] = {"false_alarms": {}, "detection": {}}
    for model, motion, preset in CLEAN:
        runs = [c for c in clean if (c["model"], c["motion"], c["preset"]) == (model, motion, preset)]
        hours = sum(c["joint_hours"] for c in runs)
        alarms = sum(len(c["alarms"]) for c in runs)
        out["false_alarms"][f"{model}/{motion}/{preset}"] = {
            "sessions": len(runs),
            "joint_hours": hours,
            "alarms": alarms,
            "per_hour": alarms / hours if hours else None,
            "median_min_jump_mm": float(np.median([m for c in runs for m in c["min_jump_mm"]])),
        }
    out["false_alarms"]["biobuddy_right_hip.c3d"] = {
        "joint_hours": hip["joint_hours"],
        "alarms": len(hip["alarms"]),
        "per_hour": len(hip["alarms"]) / hip["joint_hours"],
    }
    for motion in ("exercise", "walk"):
        for cm in SLIP_CM:
            runs = [s for s in slips if s["motion"] == motion and s["slip_cm"] == cm]
            errors = [h["error_s"] for s in runs for h in s["hits"] if h["right_frame"]]
            out["detection"][f"{motion}/{cm}cm"] = {
                "sessions": len(runs),
                "rate_within_0.5s": float(np.mean([s["detected"] for s in runs])),
                "rate_right_frame": float(np.mean([s["detected_right_frame"] for s in runs])),
                "median_abs_time_error_s": float(np.median(np.abs(errors))) if errors else None,
                "max_abs_time_error_s": float(np.max(np.abs(errors))) if errors else None,
                "other_alarms": sum(s["other_alarms"] for s in runs),
            }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="clean sessions per case")
    parser.add_argument("--slip-seeds", type=int, default=10, help="slip sessions per motion and size")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    clean_jobs = [(m, mo, p, s) for m, mo, p in CLEAN for s in range(args.seeds)]
    slip_jobs = [(mo, cm, s) for mo in ("exercise", "walk") for cm in SLIP_CM for s in range(args.slip_seeds)]
    with ProcessPoolExecutor(args.workers) as pool:
        clean = list(pool.map(clean_case, clean_jobs))
        slips = list(pool.map(slip_case, slip_jobs))
    hip = hip_case()
    summary = summarise(clean, slips, hip)
    doc = {
        "settings": {
            "duration_s": DURATION_S,
            "window_s": WINDOW_S,
            "false_alarms_per_hour": FALSE_ALARMS_PER_HOUR,
            "seeds": args.seeds,
            "slip_seeds": args.slip_seeds,
            "tolerance_s": TOLERANCE_S,
            "seconds": time.perf_counter() - start,
        },
        "summary": summary,
        "hip": hip,
        "clean": clean,
        "slips": slips,
    }
    OUT.write_text(json.dumps(doc, indent=1))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
