"""Cluster finding and the lower-limb joints on full-body gait and running recordings (issue 42, item 1).

    .venv/bin/python studies/cluster_gait.py FILE.trc|FILE.c3d ...

Not a test: the figures of ``docs/cluster-finding.md``. Each recording is read as
``simbench calibrate`` reads it (``simbench.io.read.read_poses``: clusters found automatically) and
calibrated (``simbench.api.calibrate``, the hierarchy inferred). Its markers are assigned to the
seven lower-body segments by their labels (the public recordings at hand name them: ``ASIS``,
``PSIS``, ``Sacral``, ``S2`` the pelvis; ``TH``/``Thigh`` the thighs; ``SH``/``TB``/``Shank`` the
shanks; ``Heel``/``CAL``/``Toe``/``MT5``/``Midfoot`` the feet; side from an ``R``/``L`` prefix).
A segment *comes out* when a cluster holds three or more of its markers and no other marker;
a joint when the inferred hierarchy joins the two segments' clusters (hips: pelvis-thigh, knees:
thigh-shank, ankles: shank-foot). Results go to ``studies/results/cluster_gait.json``.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

import simbench as sb
from simbench.io.atomic import atomic_write_text
from simbench.io.read import read_poses

OUT = Path(__file__).resolve().parent / "results" / "cluster_gait.json"
SEGMENTS = ("pelvis", "thigh_r", "thigh_l", "shank_r", "shank_l", "foot_r", "foot_l")
JOINTS = {
    "hip_r": ("pelvis", "thigh_r"),
    "hip_l": ("pelvis", "thigh_l"),
    "knee_r": ("thigh_r", "shank_r"),
    "knee_l": ("thigh_l", "shank_l"),
    "ankle_r": ("shank_r", "foot_r"),
    "ankle_l": ("shank_l", "foot_l"),
}
_PATTERNS = (
    ("pelvis", r"ASIS|ASI$|PSIS|PSI$|SACRAL|^S2$"),
    ("thigh", r"THIGH|TH\d|^.THI"),
    ("shank", r"SHANK|SH\d|TB\d"),
    ("foot", r"HEEL|CAL$|TOE|MT5|MIDFOOT"),
)


def segment_of(label: str) -> str | None:
    """The lower-body segment a marker label names, or ``None``."""
    name = label.upper()
    for segment, pattern in _PATTERNS:
        if re.search(pattern, name):
            if segment == "pelvis":
                return segment
            side = name.lstrip(".")[0]
            return f"{segment}_{side.lower()}" if side in "RL" else None
    return None


def measure(path: Path) -> dict[str, Any]:
    """Which segments and joints come out of one recording (module docstring)."""
    rec = read_poses(path)
    rec_notes = list(rec.notes)
    cal = sb.calibrate(rec)
    names = list(rec.names)
    members = {}
    for note in rec_notes:
        m = re.match(r"cluster (\S+) \((.*)\): rigidity residual", note)
        if m:
            members[m.group(1)] = m.group(2).split(", ")
    own = {}
    for seg in SEGMENTS:
        for name in names:
            labels = members.get(name, [])
            segs = {segment_of(x) for x in labels}
            if segs == {seg} and len(labels) >= 3:
                own[seg] = name
    mixed = {
        name: sorted({str(segment_of(x)) for x in labels})
        for name, labels in members.items()
        if len({segment_of(x) for x in labels}) > 1 and any(segment_of(x) for x in labels)
    }
    edges = {frozenset((j.parent, j.child)): j for j in cal.joints}
    joints = {}
    for joint, (a, b) in JOINTS.items():
        e = frozenset((own.get(a), own.get(b)))
        joints[joint] = round(edges[e].fit.rms_residual * 1e3, 1) if None not in e and e in edges else None
    doubt = [n for n in rec_notes if "may be two bodies" in n]
    return {
        "file": path.name,
        "segments": {seg: own.get(seg) for seg in SEGMENTS},
        "segments_out": sum(seg in own for seg in SEGMENTS),
        "joints_rms_mm": joints,
        "joints_out": sum(v is not None for v in joints.values()),
        "mixed_clusters": mixed,
        "doubt_notes": doubt,
        "clusters": members,
    }


def main() -> None:
    rows = [measure(Path(p)) for p in sys.argv[1:]]
    for r in rows:
        print(
            r["file"], r["segments_out"], "of 7 segments,", r["joints_out"], "of 6 joints", r["joints_rms_mm"]
        )
        for name, segs in r["mixed_clusters"].items():
            print("   mixed:", name, segs)
        for seg, name in r["segments"].items():
            if name is None:
                print("   missing:", seg)
        for n in r["doubt_notes"]:
            print("   doubt:", n[:200])
    atomic_write_text(OUT, json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
