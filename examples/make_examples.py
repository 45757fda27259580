"""Regenerate the bundled example pose files (deterministic: fixed seeds).

    python examples/make_examples.py

``linkage_exercise.csv``: O'Brien's wooden linkage (docs/conventions.md dimensions) moved through
smooth motion exercising every joint, 20 s at 60 Hz, with 2 mm position noise and 0.5 degree
rotation noise per sensor, like a magnetic tracker near its transmitter.
``linkage_exercise_truth.json`` holds the exact joint locations and lengths it was made with.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from simbench.io.atomic import atomic_write_text
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.sim.synthetic import linkage, simulate_motion

HERE = Path(__file__).resolve().parent


def main() -> None:
    skeleton = linkage()
    cap = simulate_motion(
        skeleton,
        n_frames=1200,
        rate_hz=60.0,
        rng=np.random.default_rng(2000),
        position_noise_m=0.002,
        rotation_noise_rad=np.deg2rad(0.5),
    )
    rec = PoseRecording(
        names=cap.names,
        time_s=np.round(cap.time_s, 6),
        R_w_s=cap.R_w_s,
        p_w_s=cap.p_w_s,
        valid=np.ones(cap.p_w_s.shape[:2], dtype=bool),
        source="examples/make_examples.py (seed 2000)",
    )
    write_pose_csv(HERE / "linkage_exercise.csv", rec, digits=8)
    joints = skeleton.joint_in_sensor_frames()
    truth = {
        "units": "m",
        "root": "chest",
        "joints": [
            {
                "parent": parent,
                "child": child,
                "joint_in_parent": joints[child][0].tolist(),
                "joint_in_child": joints[child][1].tolist(),
                "rms_residual": 0.0,
                "single_axis": False,
                "axis_in_parent": None,
                "axis_in_child": None,
            }
            for child, parent in skeleton.parent_of.items()
        ],
        "limb_lengths": [
            {"segment": seg, "joint_a": a, "joint_b": b, "length": length}
            for (seg, a, b), length in skeleton.segment_lengths().items()
        ],
    }
    atomic_write_text(HERE / "linkage_exercise_truth.json", json.dumps(truth, indent=2) + "\n")


if __name__ == "__main__":
    main()
