"""Automatic clusters of the real hip trial with one marker lost (a robustness scan, not a test).

    .venv/bin/python studies/cluster_marker_loss.py

``../shared/data/biobuddy_right_hip.c3d`` (73 markers), each marker in turn lost for the whole
recording and for its second half: do ``simbench.io.c3d.auto_clusters``' groups stay those of the
whole file (less that marker where it is never seen)? Each case that differs is listed with the
groups it found that the whole file does not have, the joints' rms residuals of the
calibration on those clusters, and whether a note says a cluster may be two bodies
(``calibration.clusters.doubtful_unions``); the cases grouped right that get such a note are
counted (false alarms). Results go to ``studies/results/cluster_marker_loss.json``
(about 2 minutes).
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from calibration import calibrate
from simbench.io.atomic import atomic_write_text
from simbench.io.c3d import auto_clusters, c3d_poses, read_c3d_markers, write_c3d_markers

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
OUT = HERE / "results" / "cluster_marker_loss.json"


def _rms_mm(
    labels: list[str], xyz: np.ndarray, rate_hz: float, clusters: dict[str, list[str]]
) -> dict[str, float]:
    """The joints' rms residuals (mm) of the calibration on ``clusters``, hierarchy inferred."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "lost.c3d"
        write_c3d_markers(path, labels, xyz, rate_hz)
        rec = c3d_poses(path, clusters=clusters)
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    return {f"{j.parent} -> {j.child}": float(j.fit.rms_residual * 1e3) for j in cal.joints}


def main() -> None:
    labels, xyz, rate_hz = read_c3d_markers(C3D)
    whole, _ = auto_clusters(labels, xyz)
    reference = {frozenset(g) for g in whole.values()}
    cases = []
    doubted = []  # every case with a cluster said to be perhaps two bodies, right or not
    t0 = time.perf_counter()
    for mode in ("whole recording", "second half"):
        for dead in labels:
            x = xyz.copy()
            k = labels.index(dead)
            x[(slice(None) if mode == "whole recording" else slice(x.shape[0] // 2, None)), k] = np.nan
            found, notes = auto_clusters(labels, x)
            got = {frozenset(g) for g in found.values()}
            expected = {g - {dead} for g in reference} if mode == "whole recording" else reference
            doubts = [n for n in notes if "may be two bodies" in n]
            if doubts:
                doubted.append({"lost": dead, "for": mode, "right": got == expected, "notes": doubts})
            if got != expected:
                cases.append(
                    {
                        "lost": dead,
                        "for": mode,
                        "clusters": len(found),
                        "new_groups": sorted(sorted(g) for g in got - expected),
                        "missing_groups": sorted(sorted(g) for g in expected - got),
                        "rms_residual_mm": _rms_mm(labels, x, rate_hz, found),
                        "said_doubtful": bool(doubts),
                    }
                )
    doc = {
        "file": C3D.name,
        "markers": len(labels),
        "whole_file_clusters": sorted(sorted(g) for g in reference),
        "whole_file_rms_residual_mm": _rms_mm(labels, xyz, rate_hz, whole),
        "cases": 2 * len(labels),
        "differing": cases,
        "doubtful_notes": doubted,
        "right_cases_said_doubtful": sum(d["right"] for d in doubted),
        "seconds": time.perf_counter() - t0,
    }
    atomic_write_text(OUT, json.dumps(doc, indent=1) + "\n")
    print(f"{len(cases)} of {2 * len(labels)} cases differ from the whole file's clusters; wrote {OUT}")
    for c in cases:
        doubt = "; said to be perhaps two bodies" if c["said_doubtful"] else ""
        print(f"  {c['lost']} lost ({c['for']}): new {c['new_groups']}; rms {c['rms_residual_mm']}{doubt}")
    right = [d for d in doubted if d["right"]]
    print(f"cases grouped as the whole file but with a cluster said to be perhaps two bodies: {len(right)}")


if __name__ == "__main__":
    main()
