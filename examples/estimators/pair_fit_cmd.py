#!/usr/bin/env python3
"""A user's joint-centre estimator as an external command (any language would do; this is Python).

    simbench calibrate poses.csv --hierarchy tree.json \
        --method "cmd:python3 examples/estimators/pair_fit_cmd.py {poses} {hierarchy} {out}"

It reads the pose CSV (time,sensor,x,y,z,qw,qx,qy,qz; metres) and the hierarchy JSON
({child: parent}), solves each joint's constraint R_p j_p + p_p = R_c j_c + p_c over the frames
by least squares (O'Brien et al. 2000, eq. 8), and writes the calibration JSON simbench reads.
"""

import csv
import json
import sys

import numpy as np


def rotation(qw, qx, qy, qz):
    return np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
            [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
            [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )


def main(poses_csv, hierarchy_json, out_json):
    frames = {}  # time -> {sensor: (R, p)}
    with open(poses_csv, newline="") as fh:
        for row in csv.DictReader(fh):
            q = [float(row[k]) for k in ("qw", "qx", "qy", "qz")]
            p = np.array([float(row[k]) for k in ("x", "y", "z")])
            frames.setdefault(row["time"], {})[row["sensor"]] = (rotation(*q), p)
    with open(hierarchy_json) as fh:
        hierarchy = json.load(fh)
    joints = []
    for child, parent in hierarchy.items():
        both = [f for f in frames.values() if parent in f and child in f]
        A = np.vstack([np.hstack([f[parent][0], -f[child][0]]) for f in both])
        b = np.concatenate([f[child][1] - f[parent][1] for f in both])
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        joints.append(
            {
                "parent": parent,
                "child": child,
                "joint_in_parent": x[:3].tolist(),
                "joint_in_child": x[3:].tolist(),
            }
        )
    with open(out_json, "w") as fh:
        json.dump({"units": "m", "joints": joints}, fh, indent=2)


if __name__ == "__main__":
    main(*sys.argv[1:4])
