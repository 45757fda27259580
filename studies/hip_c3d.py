"""The functional hip centre of the biobuddy trial (../shared/data/biobuddy_right_hip.c3d).

    .venv/bin/python studies/hip_c3d.py

Pelvis, right thigh and right shank clusters (studies/hip_c3d.toml), the known hierarchy; prints
the hip joint centre in the pelvis cluster's frame, its residual, and its distance to the
anterior superior iliac spine markers. No per-file tuning: the defaults of the calibration.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calibration import calibrate
from simbench.io.c3d import c3d_poses, read_c3d_markers, read_cluster_spec

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"


def main() -> None:
    rec = c3d_poses(C3D, clusters=read_cluster_spec(HERE / "hip_c3d.toml"))
    for note in rec.notes:
        print(note)
    cal = calibrate(
        rec.R_w_s,
        rec.p_w_s,
        rec.names,
        valid=rec.valid,
        parent_of={"thigh_r": "pelvis", "shank_r": "thigh_r"},
    )
    hip = next(j for j in cal.joints if j.child == "thigh_r")
    labels, xyz, _ = read_c3d_markers(C3D)
    centre = np.einsum("fij,j->fi", rec.R_w_s[:, 0], hip.fit.joint_in_parent) + rec.p_w_s[:, 0]
    print(f"hip centre in the pelvis cluster frame: {np.round(hip.fit.joint_in_parent * 100, 2)} cm")
    print(f"residual: rms {hip.fit.rms_residual * 1e3:.1f} mm, condition {hip.fit.condition:.1f}")
    for m in ("RASIS", "LASIS", "RGT"):
        d = np.nanmedian(np.linalg.norm(centre - xyz[:, labels.index(m)], axis=1))
        print(f"distance to {m}: {d * 100:.1f} cm")


if __name__ == "__main__":
    main()
