"""Why the live slip monitor misses the slips it misses (issue 42, item 5).

    .venv/bin/python studies/live_slip_misses.py [--real PATH ...] [--late] [--out FILE]

The slips of ``studies/live_slip_real.py`` (the same draws) pushed again, with the monitor's test
recorded at every frame from the slip to :data:`live_slip_real.TOLERANCE_S` after it, for the joints
of the slipped sensor. Each slip not alerted on the right sensor in time gets one cause, the first
that applies:

- ``not armed``: none of the sensor's joints had a threshold yet;
- ``wrong sensor``: an alert within the tolerance named another sensor;
- ``step test``: the window statistic crossed, and :meth:`_SlipMonitor._steady` (the step against
  the joint's fit error and against the white noise) rejected it every time;
- ``neighbours' motion``: it would have crossed divided by the joint's own motion factor alone;
- ``own motion``: it would have crossed undivided;
- ``below threshold``: not even undivided (the window difference's noise scale, skin motion
  included, and the threshold: ``z / threshold`` and the scale in mm are listed).

With ``--late``, the slips of ``studies/live_slip_late.py`` in the real recordings instead (results
``studies/results/live_slip_late_misses.json``).

The monitor is observed by wrapping two of its methods (nothing in it changes). Results:
``studies/results/live_slip_misses.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from calibration import streaming
from simbench.io.poses import PoseRecording
from simbench.sim.live import recording_with_slip

sys.path.insert(0, str(Path(__file__).resolve().parent))
from live_slip_late import DRAWS, late_draw, late_recordings
from live_slip_real import (
    FIRST_SLIP_S,
    REAL,
    TOLERANCE_S,
    moving_sensors,
    real_recording,
    run_live,
    slip_draw,
)

HERE = Path(__file__).resolve().parent
OUT = HERE / "results" / "live_slip_misses.json"
LATE_OUT = HERE / "results" / "live_slip_late_misses.json"

_TESTS: list[dict[str, Any]] = []  # per _examine call: the test of every joint at its frames
_STEPS: list[tuple[tuple[int, int], int, bool]] = []  # per _steady call: joint, frame, verdict
_examine = streaming._SlipMonitor._examine
_steady = streaming._SlipMonitor._steady


def _recording_examine(self, d, factor, delta, frames, q, e0):  # type: ignore[no-untyped-def]
    turn = np.nan_to_num(np.linalg.norm(delta[..., :9], axis=2))
    own = self._motion_factor(turn / self.motion0)  # (c, J)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.linalg.norm(d / np.where(self.scale > 0, self.scale, np.inf), axis=3) / self.threshold
    z = np.nan_to_num(z, nan=0.0, posinf=0.0).max(axis=2)  # (c, J): the test, over its threshold
    _TESTS.append(
        {
            "frames": frames.copy(),
            "keys": list(self.keys),
            "z": z,
            "z_own": z * factor / own,
            "z_raw": z * factor,
            "armed": np.isfinite(self.threshold).all(axis=1),
            "threshold": self.threshold.max(axis=1),
            "scale_mm": self.scale * 1e3,
        }
    )
    return _examine(self, d, factor, delta, frames, q, e0)


def _recording_steady(self, j, frame, e, ok, M, e0, factor):  # type: ignore[no-untyped-def]
    verdict = _steady(self, j, frame, e, ok, M, e0, factor)
    _STEPS.append((self.keys[j], frame, verdict))
    return verdict


def diagnose(label: str, rec: PoseRecording, k: int, draw: int | None = None) -> dict[str, Any] | None:
    """The slip of sensor ``k`` (as live_slip_real draws it, or live_slip_late's ``draw``), or
    ``None`` if skipped there."""
    if draw is None:
        _t, frame, offset = slip_draw(label, rec, k, FIRST_SLIP_S)
    else:
        _t, frame, offset = late_draw(label, rec, k, draw)
    tol = round(TOLERANCE_S * rec.rate_hz)
    if not rec.valid[frame : frame + tol, k].any():
        return None
    t_slip = frame / rec.rate_hz
    _TESTS.clear()
    _STEPS.clear()
    live = run_live(recording_with_slip(rec, rec.names[k], float(rec.time_s[frame]), offset))
    window = [a for a in live["alerts"] if 0.0 <= a["raised_s"] - t_slip <= TOLERANCE_S]
    hit = any(a["sensor"] == rec.names[k] for a in window)
    joints: dict[str, dict[str, Any]] = {}
    for test in _TESTS:
        sel = (test["frames"] >= frame) & (test["frames"] <= frame + tol)
        if not sel.any():
            continue
        for j, key in enumerate(test["keys"]):
            if k not in key:
                continue
            name = f"{rec.names[key[0]]}-{rec.names[key[1]]}"
            row = joints.setdefault(name, {"armed": False, "z": 0.0, "z_own": 0.0, "z_raw": 0.0})
            row["armed"] |= bool(test["armed"][j])
            for field in ("z", "z_own", "z_raw"):
                row[field] = max(row[field], float(test[field][sel, j].max()))
            if test["armed"][j]:
                row["threshold"] = float(test["threshold"][j])
                row["scale_mm"] = np.round(test["scale_mm"][j], 1).tolist()
    steps = [v for key, f, v in _STEPS if k in key and frame <= f <= frame + tol]
    armed = [r for r in joints.values() if r["armed"]]
    if hit:
        cause = None
    elif not armed:
        cause = "not armed"
    elif window:
        cause = "wrong sensor"
    elif steps and not any(steps):
        cause = "step test"
    elif max(r["z_own"] for r in armed) >= 1.0:
        cause = "neighbours' motion"
    elif max(r["z_raw"] for r in armed) >= 1.0:
        cause = "own motion"
    else:
        cause = "below threshold"
    return {
        "recording": label,
        "sensor": rec.names[k],
        "slip_s": t_slip,
        "hit": hit,
        "cause": cause,
        "alerts": [
            {
                "sensor": a["sensor"],
                "after_slip_s": a["raised_s"] - t_slip,
                "z_over_threshold": a["z_over_threshold"],
            }
            for a in live["alerts"]
        ],
        "joints": joints,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, nargs="*", default=None, help="C3D files (default: REAL)")
    parser.add_argument(
        "--late", action="store_true", help="live_slip_late's draws (results live_slip_late_misses.json)"
    )
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or (LATE_OUT if args.late else OUT)
    streaming._SlipMonitor._examine = _recording_examine  # type: ignore[method-assign]
    streaming._SlipMonitor._steady = _recording_steady  # type: ignore[method-assign]
    if args.late:
        cases = [(label, rec, draw) for label, rec in late_recordings(0) for draw in range(DRAWS)]
    else:
        paths = [p for p in (REAL if args.real is None else args.real) if p.exists()]
        cases = [(path.name, real_recording(path), None) for path in paths]
    rows = []
    for label, rec, draw in cases:
        for k in moving_sensors(rec):
            row = diagnose(label, rec, k, draw)
            if row is None:
                continue
            rows.append(row)
            if not row["hit"]:
                worst = max(row["joints"].values(), key=lambda r: r["z_raw"], default={})
                print(
                    f"{label[:45]:45s} {row['sensor'][:28]:28s} {row['slip_s']:6.2f} s "
                    f"{row['cause']:18s}"
                    f" z/thr {worst.get('z', 0):.2f} (own motion only {worst.get('z_own', 0):.2f},"
                    f" undivided {worst.get('z_raw', 0):.2f}), scale mm {worst.get('scale_mm')}",
                    flush=True,
                )
    causes: dict[str, int] = {}
    for row in rows:
        if row["cause"]:
            causes[row["cause"]] = causes.get(row["cause"], 0) + 1
    doc = {"slips": len(rows), "hits": sum(r["hit"] for r in rows), "causes": causes, "rows": rows}
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps({k: doc[k] for k in ("slips", "hits", "causes")}))


if __name__ == "__main__":
    main()
