"""Calibrate the simulator against O'Brien et al. (2000): the Flock of Birds and the linkage.

    .venv/bin/python studies/paper_tracker.py [--sets 6] [--duration 45] [--json OUT]

1. Two sensors rigidly 56.5 cm apart are moved through the capture volume (a smooth random
   path and tumbling, 60 s at 120 Hz, within about 0.3-1.4 m of the transmitter) and seen by
   the ``ascension-flock`` preset; the unit scale factor and the scaled standard deviation of
   their distance are estimated as the paper did (section 4: 0.94 and 0.7 cm).
2. The linkage goes through ``--sets`` exercise sessions (seeds 1..N) with the same preset;
   each is calibrated with the hierarchy unknown, lengths are converted with the scale factor
   from step 1 (as the paper converted its units), and the joint-to-joint distances are
   compared with the truth (the paper: max error 1.1 cm over six sets, hierarchy right in all).

Nothing here is tuned to the paper's numbers: the preset's parameters come from the vendor's
and the paper's published figures, and this script only reports.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from calibration import calibrate, unit_scale
from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.sensor_config import load_sensor_config
from simbench.sensor_models import apply_tracker
from simbench.simulate import SessionConfig, load_session_model, run_session

PAPER = {"scale": 0.94, "scaled_std_cm": 0.7, "linkage_max_error_cm": 1.1}


def rigid_pair(seed: int, duration_s: float = 60.0, rate_hz: float = 120.0):
    """Two sensor poses 56.5 cm apart on a bar moved smoothly through the volume."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    f = rng.uniform(0.05, 0.3, (3, 6))
    ph = rng.uniform(0, 2 * np.pi, (3, 6))
    centre = (
        np.array([0.0, 0.0, 1.2])
        + np.sum(
            np.array([0.25, 0.25, 0.15])[None, :, None]
            * np.sin(2 * np.pi * f[None, :, :3] * t[:, None, None] + ph[:, :3]),
            axis=2,
        )
        / 3**0.5
    )
    rotvec = np.sum(1.5 * np.sin(2 * np.pi * f[None, :, 3:] * t[:, None, None] + ph[:, 3:]), axis=2) / 3**0.5
    R = rotvec_to_matrix(rotvec)
    half = np.array([0.565 / 2, 0.0, 0.0])
    p = np.stack([centre - R @ half, centre + R @ half], axis=1)
    q = matrix_to_quat(np.stack([R, R], axis=1))
    return t, p, q


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=6)
    parser.add_argument("--duration", type=float, default=45.0)
    parser.add_argument("--json", metavar="OUT")
    args = parser.parse_args()
    flock = load_sensor_config("ascension-flock")
    t, p, q = rigid_pair(seed=7)
    rep, _, _ = apply_tracker(t, p, q, flock.tracker, np.random.default_rng(8))
    est = unit_scale(rep[:, 0], rep[:, 1], 0.565)
    dist_tx = np.linalg.norm(p - np.asarray(flock.tracker.transmitter_pos), axis=2)
    print("Two sensors rigidly 56.5 cm apart, ascension-flock preset")
    print(
        f"  distance to transmitter: {dist_tx.min():.2f}-{dist_tx.max():.2f} m "
        f"(median {np.median(dist_tx):.2f})"
    )
    print(f"  {'':24}{'paper':>10}{'simbench':>10}")
    print(f"  {'scale factor':24}{PAPER['scale']:>10.3f}{est.scale:>10.3f}")
    print(f"  {'scaled std (cm)':24}{PAPER['scaled_std_cm']:>10.2f}{est.scaled_std * 100:>10.2f}")

    config0 = SessionConfig(
        model="linkage", motion="exercise", duration_s=args.duration, sensors="ascension-flock"
    )
    cm = load_session_model(config0)
    rows = []
    for s in range(1, args.sets + 1):
        config = SessionConfig(
            model="linkage", motion="exercise", duration_s=args.duration, seed=s, sensors="ascension-flock"
        )
        ds = run_session(config, cm)
        rec = ds.poses()
        cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
        index = {n: k for k, n in enumerate(ds.sensors)}
        from calibration.skeleton import segment_lengths

        joints = [(index[a], index[b]) for a, b in zip(ds.truth.parent, ds.truth.child, strict=True)]
        truth = {
            (x.segment, x.joint_a, x.joint_b): x.length
            for x in segment_lengths(ds.sensors, joints, ds.truth.joint_in_parent, ds.truth.joint_in_child)
        }
        errors = {}
        for x in cal.lengths:
            key = (x.segment, x.joint_a, x.joint_b)
            if key in truth:
                errors[key] = (truth[key] - x.length * est.scale) * 100  # paper's sign: meas - computed
        rows.append(
            {
                "set": s,
                "hierarchy_correct": {frozenset(e) for e in cal.parent_of.items()}
                == {frozenset(e) for e in ds.truth.parent_of.items()},
                "errors_cm": {"/".join(k[1:]): v for k, v in errors.items()},
                "max_abs_error_cm": max((abs(v) for v in errors.values()), default=float("nan")),
                "rms_residual_mm": [round(j.fit.rms_residual * est.scale * 1e3, 2) for j in cal.joints],
            }
        )
    print(
        f"\nLinkage, {args.sets} exercise sets of {args.duration:g} s, ascension-flock, "
        f"lengths x {est.scale:.3f}"
    )
    for r in rows:
        errs = " ".join(f"{v:+.2f}" for v in r["errors_cm"].values())
        print(
            f"  set {r['set']}: hierarchy {'right' if r['hierarchy_correct'] else 'WRONG'}, "
            f"errors (cm) {errs}"
        )
    worst = max(r["max_abs_error_cm"] for r in rows)
    right = sum(r["hierarchy_correct"] for r in rows)
    print(f"  {'':24}{'paper':>10}{'simbench':>10}")
    print(f"  {'max error (cm)':24}{PAPER['linkage_max_error_cm']:>10.2f}{worst:>10.2f}")
    print(f"  {'hierarchy right':24}{'6 of 6':>10}{f'{right} of {len(rows)}':>10}")
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {"scale": est.scale, "scaled_std_m": est.scaled_std, "linkage_sets": rows, "paper": PAPER},
                indent=2,
                default=str,
            )
            + "\n"
        )


if __name__ == "__main__":
    main()
