"""The live slip monitor on slips late in the longer recordings (issue 42, item 5, fifth round).

    .venv/bin/python studies/live_slip_late.py [--sim-seeds 2] [--out FILE]

``studies/live_slip_real.py`` draws one slip per cluster uniformly from :data:`FIRST_SLIP_S` to 1 s
before the end; in its 10 s recordings (racing, propulsion: 18 of its 34 slips) most fall within
seconds of arming. Here every real recording longer than :data:`MIN_LENGTH_S` (the biobuddy and
pyomeca hip trials, sprintbasket) and ``--sim-seeds`` sessions of the ``skin-paper-human`` preset
get :data:`DRAWS` slips per moving cluster, each at a uniform time from :data:`FIRST_SLIP_S` to 1 s
before the end (2 cm, a random direction of the cluster's frame; seeded by recording, cluster and
draw, not the draws of live_slip_real). A hit is as there: an alert naming the cluster raised within
:data:`live_slip_real.TOLERANCE_S` of the slip. Results: ``studies/results/live_slip_late.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from simbench.io.poses import PoseRecording
from simbench.sim.live import recording_with_slip
from simbench.sim.plan import SessionConfig, load_session_model
from simbench.sim.session import run_session

sys.path.insert(0, str(Path(__file__).resolve().parent))
from live_slip_real import REAL, SLIP_M, TOLERANCE_S, moving_sensors, real_recording, run_live

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "live_slip_late.json"
FIRST_SLIP_S = 8.0
MIN_LENGTH_S = 15.0
DRAWS = 2


def late_draw(label: str, rec: PoseRecording, k: int, draw: int) -> tuple[float, int, np.ndarray]:
    """Slip ``draw`` of sensor ``k``: its time (s after the first frame, before rounding to a
    frame), its first frame, and the offset ``(3,)`` in the sensor's frame, metres."""
    rng = np.random.default_rng([7, draw, zlib.crc32(f"{label}/{rec.names[k]}".encode())])
    t = float(rng.uniform(FIRST_SLIP_S, rec.n_frames / rec.rate_hz - 1.0))
    offset = rng.normal(size=3)
    return t, int(np.ceil(t * rec.rate_hz)), SLIP_M * offset / np.linalg.norm(offset)


def late_recordings(sim_seeds: int) -> list[tuple[str, PoseRecording]]:
    """The real recordings longer than :data:`MIN_LENGTH_S` and ``sim_seeds`` skin sessions."""
    out = []
    for path in [p for p in REAL if p.exists()]:
        rec = real_recording(path)
        if rec.n_frames / rec.rate_hz > MIN_LENGTH_S:
            out.append((path.name, rec))
    for seed in range(sim_seeds):
        config = SessionConfig(
            model="humanoid", motion="exercise", duration_s=30.0, seed=seed, sensors="skin-paper-human"
        )
        out.append((f"skin-paper-human/{seed}", run_session(config, load_session_model(config)).poses()))
    return out


def late_runs(label: str, rec: PoseRecording) -> list[dict[str, Any]]:
    rows = []
    tol = round(TOLERANCE_S * rec.rate_hz)
    for k in moving_sensors(rec):
        for draw in range(DRAWS):
            _t, frame, offset = late_draw(label, rec, k, draw)
            if not rec.valid[frame : frame + tol, k].any():
                continue
            live = run_live(recording_with_slip(rec, rec.names[k], float(rec.time_s[frame]), offset))
            t = frame / rec.rate_hz
            near = [a for a in live["alerts"] if 0.0 <= a["raised_s"] - t <= TOLERANCE_S]
            hit = any(a["sensor"] == rec.names[k] for a in near)
            rows.append(
                {
                    "recording": label,
                    "sensor": rec.names[k],
                    "slip_s": t,
                    "right_sensor": hit,
                    "alerts_before_slip": sum(a["raised_s"] < t for a in live["alerts"]),
                }
            )
            print(f"{label[:45]:45s} {rec.names[k][:30]:30s} {t:6.2f} s {hit}", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-seeds", type=int, default=2)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    rows = []
    for label, rec in late_recordings(args.sim_seeds):
        rows += late_runs(label, rec)
    real = [r for r in rows if not r["recording"].startswith("skin")]
    sim = [r for r in rows if r["recording"].startswith("skin")]
    summary = {
        "real": {"slips": len(real), "right_sensor": sum(r["right_sensor"] for r in real)},
        "simulated": {"slips": len(sim), "right_sensor": sum(r["right_sensor"] for r in sim)},
    }
    doc = {
        "settings": {"first_slip_s": FIRST_SLIP_S, "min_length_s": MIN_LENGTH_S, "draws": DRAWS},
        "summary": summary,
        "runs": rows,
    }
    args.out.parent.mkdir(exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
