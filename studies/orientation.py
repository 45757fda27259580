"""Sourceless orientation under the testbed's conditions and on real BROAD trials (issue 5).

    .venv/bin/python studies/orientation.py [--json studies/results/orientation.json]
        [--only VARIANT ...]

``--only`` runs those estimators alone and, with ``--json``, replaces just their rows in the file
(each row is its own estimate of the same sessions: the others' rows stay valid).

1. Simulation (humanoid, 30 s): orientation error of every estimator against the exact actual
   orientations, for the ``mems-industrial`` and ``mems-consumer`` presets (magnetometers
   calibrated from the recording first, as ``simbench orient`` does), at rest (``static``) and in
   motion (``exercise``; ``gait``, a person walking; ``walk``, O'Brien's "chicken walk", every
   joint through 70 % of its range at up to 1.1 Hz while walking: head and hands at 2 g RMS);
   the skeleton method without a skeleton, on the skeleton
   calibrated from the session's own tracker poses (also with the joints' ranges of motion those
   poses show), and on the true skeleton; with and without
   Fontaine's disturbance weighting (and weighted smoothing at 1 Hz); near a ferromagnetic object
   (a 2 A m^2 dipole 40 cm in front of the chest).
2. Posture (Fontaine 3.2): the humanoid's hands and feet placed by forward kinematics from the
   estimated orientations (exact joint offsets, true root position), against the truth.
3. Real data: the two BROAD trials, every estimator, BROAD's error definitions. One setting for
   all data: the reference field comes from each recording's medians, nothing is tuned per trial.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import simbench as sb
from calibration.hierarchy import hierarchy_from_parents
from calibration.orientation import Skeleton
from calibration.posture import joint_positions, sensor_positions
from calibration.rotations import quat_to_matrix
from simbench.io.imu import read_broad
from simbench.orient import calibrate_magnetometers, estimate, skeleton_of
from simbench.score import score_orientation
from simbench.sim.sensor_config import SensorConfig, parse_sensor_config

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
VARIANTS = {
    "skeleton (calibrated skeleton)": dict(method="skeleton", skeleton="calibrated"),
    "skeleton (calibrated skeleton, ranges)": dict(method="skeleton", skeleton="ranges"),
    "skeleton (true skeleton)": dict(method="skeleton", skeleton="truth"),
    "skeleton (no skeleton)": dict(method="skeleton"),
    "triad": dict(method="triad"),
    "wahba": dict(method="wahba"),
    "fontaine (no weighting)": dict(method="fontaine", weighting=False),
    "fontaine (weighting)": dict(method="fontaine"),
    "fontaine (weighting, 1 Hz)": dict(method="fontaine", smooth_hz=1.0),
    "mahony (gyro)": dict(method="mahony"),
}

#: The estimators whose posture (hands and feet placed by forward kinematics) is scored.
POSTURE_VARIANTS = (
    "skeleton (calibrated skeleton)",
    "skeleton (calibrated skeleton, ranges)",
    "triad",
    "fontaine (weighting, 1 Hz)",
    "mahony (gyro)",
)


#: Near a ferromagnetic object: a 2 A m^2 dipole 40 cm in front of the chest, quieter sensors.
MAGNET = {
    "imu": {"accel_noise_density": 0.000588, "mag_noise": 0.05},
    "magnetic": {"disturbance": [{"position": [0.4, 0.0, 1.4], "moment_am2": [0.0, 0.0, 2.0]}]},
}


def score(run, rec) -> dict[str, dict[str, float]]:
    """Per-sensor orientation RMSE (degrees) of one estimator run, over the evaluated samples."""
    return score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate).per_sensor


def mean_scores(scores: dict[str, dict[str, float]]) -> dict[str, float]:
    """RMS over sensors of each sensor's RMSE."""
    keys = ("total_deg", "heading_deg", "inclination_deg")
    return {k: float(np.sqrt(np.mean([s[k] ** 2 for s in scores.values()]))) for k in keys}


def simulated(motion: str, sensors: str | SensorConfig):
    """A 30 s humanoid session and its inertial recording (truth: the on-skin orientations),
    magnetometers calibrated from the recording where it pays."""
    ds = sb.simulate(model="humanoid", motion=motion, duration_s=30.0, seed=11, sensors=sensors)
    rec, _ = calibrate_magnetometers(ds.imu())
    return ds, rec


def skeletons(ds) -> dict[str, Skeleton]:
    """The session's skeleton as calibrated from its tracker poses (and with the joints' ranges
    of motion those poses show), and the true one."""
    tree = hierarchy_from_parents(ds.truth.parent_of, ds.sensors)
    tlp, tlc = ds.truth_joint_arrays()
    calibrated = skeleton_of(sb.calibrate(ds))
    poses = ds.poses()
    return {
        "calibrated": calibrated,
        "ranges": calibrated.with_ranges(poses.R_w_s, poses.valid),
        "truth": Skeleton(np.asarray(tree.parent), tlp, tlc),
    }


def run(ds, rec, kw, skels):
    kw = dict(kw)
    if "skeleton" in kw:
        kw["skeleton"] = skels[kw["skeleton"]]
    return estimate(rec, **kw)


def posture_error(ds, rec, method_kwargs, skels) -> dict[str, float]:
    est = run(ds, rec, method_kwargs, skels)
    tree = hierarchy_from_parents(ds.truth.parent_of, ds.sensors)
    lp, lc = ds.truth_joint_arrays()
    R = quat_to_matrix(np.where(np.isfinite(est.q_enu), est.q_enu, np.nan))
    root = ds.truth.actual.p_w_s[:, 0]
    J = joint_positions(R, tree, lp, lc, root_w=root)
    P = sensor_positions(R, tree, J, lc)
    out = {}
    for name in ("hand_l", "hand_r", "foot_l", "foot_r"):
        k = ds.sensors.index(name)
        d = np.linalg.norm(P[:, k] - ds.truth.rigid.p_w_s[:, k], axis=1)
        out[name] = float(np.sqrt(np.nanmean(d**2)) * 100)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="OUT")
    parser.add_argument(
        "--only", nargs="+", choices=list(VARIANTS), metavar="VARIANT", help="these rows only"
    )
    args = parser.parse_args()
    variants = {v: kw for v, kw in VARIANTS.items() if not args.only or v in args.only}
    posture = [v for v in POSTURE_VARIANTS if v in variants]
    results: dict = {"simulation": {}, "disturbance": {}, "posture_cm": {}, "broad": {}}
    for preset in ("mems-industrial", "mems-consumer"):
        for motion in ("static", "exercise", "gait", "walk"):
            ds, rec = simulated(motion, preset)
            skels = skeletons(ds)
            row = {v: mean_scores(score(run(ds, rec, kw, skels), rec)) for v, kw in variants.items()}
            results["simulation"][f"{preset} / {motion}"] = row
            print(f"{preset} / {motion}: done", flush=True)
            if preset == "mems-industrial" and motion in ("exercise", "gait", "walk") and posture:
                results["posture_cm"][motion] = {
                    v: posture_error(ds, rec, VARIANTS[v], skels) for v in posture
                }
    ds, rec = simulated("exercise", parse_sensor_config(MAGNET, "the magnet case"))
    skels = skeletons(ds)
    results["disturbance"] = {
        v: mean_scores(score(run(ds, rec, kw, skels), rec)) for v, kw in variants.items()
    }
    for trial in ("broad_02_undisturbed_slow_rotation_B", "broad_30_disturbed_stationary_magnet_C"):
        path = DATA / f"{trial}.hdf5"
        if path.is_file():
            rec = read_broad(path)
            results["broad"][trial] = {
                v: score(estimate(rec, **kw), rec)["imu"]
                for v, kw in variants.items()
                if "skeleton" not in kw
            }
            if "skeleton (no skeleton)" in variants:
                results["broad"][trial]["skeleton (no skeleton)"] = score(estimate(rec, "skeleton"), rec)[
                    "imu"
                ]

    def table(title: str, rows: dict[str, dict[str, float]]) -> None:
        print(f"\n{title}")
        print(f"  {'estimator':<40}{'total':>8}{'heading':>9}{'inclin.':>9}  (RMSE, degrees)")
        for v, s in rows.items():
            print(f"  {v:<40}{s['total_deg']:>8.2f}{s['heading_deg']:>9.2f}{s['inclination_deg']:>9.2f}")

    for cond, rows in results["simulation"].items():
        table(f"humanoid, {cond}", rows)
    table("humanoid, exercise, a 2 A m^2 dipole 40 cm in front of the chest", results["disturbance"])
    for motion, rows in results["posture_cm"].items():
        print("\nposture: hand and foot sensors placed from estimated orientations")
        print(f"(mems-industrial, {motion}), RMS error in cm")
        for v, s in rows.items():
            print(f"  {v:<40}" + "".join(f"{k} {x:6.2f}  " for k, x in s.items()))
    for trial, rows in results["broad"].items():
        table(f"BROAD {trial}", rows)
    if args.json:
        out = Path(args.json)
        if args.only and out.is_file():  # these rows into the earlier run's, in its order
            earlier = json.loads(out.read_text())
            for part, rows in results.items():
                for key, row in rows.items():
                    earlier.setdefault(part, {}).setdefault(key, {}).update(row)
            results = earlier
        tmp = out.with_suffix(out.suffix + ".tmp")
        tmp.write_text(json.dumps(results, indent=2) + "\n")
        tmp.replace(out)


if __name__ == "__main__":
    main()
