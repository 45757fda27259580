"""The statistical single-axis (hinge) verdict on messy simulated joints and a real trial (issue 12, item 3).

    .venv/bin/python studies/hinge_verdict.py

Two sensors across one joint (``simbench.sim.synthetic.messy_joint``), 60 s at 100 Hz, 20 seeds
per case, with 2 mm play, 5 mm soft-tissue-like slow sensor offsets (half of the child's
following the joint angle), 2 mm and 0.6 degree white tracker noise:

- ``hinge``: about 2 degrees rms of wobble about the two other axes (s_min/s_max 0.017-0.020,
  as on the real magnetic-tracker hinge rig); target: single-axis in 20 of 20 seeds;
- ``ball_2_axes`` (flexion and abduction, 2 degrees of twist) and ``ball_3_axes``: target:
  never single-axis (20 of 20);
- ``hinge_sensors_one_side``: both sensors 4 cm to the same side along the hinge axis, so that
  the minimum-norm point is 4 cm off the true centre along the axis and the wobble can reveal it
  to a significance test given enough clean frames; target (issue 42): single-axis in 20 of 20,
  as the bias bound along the axis (effect size, :mod:`calibration.hinge`) is most of the
  sensors' distance;
- ``hinge_sensors_one_side_long_clean``: the same rig recorded 4 times as long with a quarter of
  the tracker noise (s_min/s_max in the same 0.014-0.020): the same verdict is the target.

Each seed also checks that the all-pairs path (``solve_pairs``) gives the same verdict as
``fit_joint`` and that the verdict is the same in mm and in inches. The old fixed rule
(s_min/s_max < 0.01) is counted for comparison. The real trial
``../shared/data/biobuddy_right_hip.c3d`` (hip and knee, clusters of studies/hip_c3d.toml) is
reported as measured. Results: ``studies/results/hinge_verdict.json``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from calibration import calibrate, fit_joint
from calibration.pairs import pair_statistics, solve_pairs
from simbench.io.c3d import c3d_poses, read_cluster_spec
from simbench.sim.synthetic import messy_joint

HERE = Path(__file__).resolve().parent
C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
#: Measured when at hand (never committed, studies only): the knee trial of the same subject.
KNEE_C3D = Path("/tmp/realc3d/pyomeca__examples_data_functional_trials_right_knee.c3d")
SEEDS = 20
OLD_RATIO = 0.01
CASES = {
    "hinge": {"amp": (0.04, 0.04, 0.8), "target_flagged": SEEDS},
    "ball_2_axes": {"amp": (0.04, 0.8, 0.8), "target_flagged": 0},
    "ball_3_axes": {"amp": (0.8, 0.8, 0.8), "target_flagged": 0},
    "hinge_sensors_one_side": {
        "amp": (0.04, 0.04, 0.8),
        "offsets": ((0.28, 0.05, 0.04), (0.20, 0.04, 0.04)),
        "target_flagged": SEEDS,
    },
    "hinge_sensors_one_side_long_clean": {
        "amp": (0.04, 0.04, 0.8),
        "offsets": ((0.28, 0.05, 0.04), (0.20, 0.04, 0.04)),
        "frames": 24000,
        "noise_m": 0.0005,
        "target_flagged": SEEDS,
    },
}


def one_seed(case: dict, seed: int) -> dict:
    """The verdicts and figures of one simulated session."""
    kwargs = {"sensor_offsets": case["offsets"]} if "offsets" in case else {}
    if "noise_m" in case:
        kwargs["position_noise_m"] = case["noise_m"]
    n_frames = case.get("frames", 6000)
    cap = messy_joint(
        case["amp"], n_frames=n_frames, rate_hz=100.0, rng=np.random.default_rng(seed), **kwargs
    )
    R, p = cap.R_w_s, cap.p_w_s
    fit = fit_joint(R[:, 0], p[:, 0], R[:, 1], p[:, 1])
    sol = solve_pairs(pair_statistics(R, p), [0], [1])
    in_mm = fit_joint(R[:, 0], 1e3 * p[:, 0], R[:, 1], 1e3 * p[:, 1])
    in_inch = fit_joint(R[:, 0], p[:, 0] / 0.0254, R[:, 1], p[:, 1] / 0.0254)
    return {
        "seed": seed,
        "single_axis": bool(fit.single_axis),
        "rank": fit.rank,
        "pairs_rank": int(sol.keep[0].sum()),
        "same_in_mm_and_inches": bool(in_mm.rank == in_inch.rank == fit.rank),
        "weak_ratio": fit.weak_ratio,
        "old_rule_single_axis": bool(fit.weak_ratio < OLD_RATIO),
        "t_weakest": float(sol.t_statistic[0, 5]),
        "rms_residual_mm": fit.rms_residual * 1e3,
        "frames": n_frames,
    }


def real_trial(path: Path = C3D) -> list[dict]:
    """Verdicts on a hip/knee trial of the clusters of studies/hip_c3d.toml (hierarchy given)."""
    rec = c3d_poses(path, clusters=read_cluster_spec(HERE / "hip_c3d.toml"))
    cal = calibrate(
        rec.R_w_s,
        rec.p_w_s,
        rec.names,
        valid=rec.valid,
        parent_of={"thigh_r": "pelvis", "shank_r": "thigh_r"},
    )
    return [
        {
            "joint": j.name,
            "single_axis": bool(j.fit.single_axis),
            "rank": j.fit.rank,
            "weak_ratio": j.fit.weak_ratio,
            "old_rule_single_axis": bool(j.fit.weak_ratio < OLD_RATIO),
            "rms_residual_mm": j.fit.rms_residual * 1e3,
            "reported_undetermined": any(
                w.startswith(f"joint {j.name}:") and "hardly determines" in w for w in cal.warnings
            ),
        }
        for j in cal.joints
    ]


def main() -> None:
    t0 = time.perf_counter()
    out: dict = {"seeds": SEEDS, "frames": 6000, "rate_hz": 100.0, "cases": {}}
    for name, case in CASES.items():
        runs = [one_seed(case, seed) for seed in range(SEEDS)]
        flagged = sum(r["single_axis"] for r in runs)
        ratios = [r["weak_ratio"] for r in runs]
        summary = {
            "joint_amplitude_rad": case["amp"],
            "flagged_single_axis": flagged,
            "target_flagged": case["target_flagged"],
            "target_met": None if case["target_flagged"] is None else flagged == case["target_flagged"],
            "old_rule_flagged": sum(r["old_rule_single_axis"] for r in runs),
            "pairs_path_agrees": sum(r["pairs_rank"] == r["rank"] for r in runs),
            "same_verdict_in_mm_and_inches": sum(r["same_in_mm_and_inches"] for r in runs),
            "weak_ratio_range": [min(ratios), max(ratios)],
            "runs": runs,
        }
        out["cases"][name] = summary
        print(
            f"{name:24s} single-axis {flagged:2d}/{SEEDS} (target {case['target_flagged']}), "
            f"old rule {summary['old_rule_flagged']:2d}/{SEEDS}, "
            f"pairs agree {summary['pairs_path_agrees']}/{SEEDS}, "
            f"s_min/s_max {min(ratios):.3f}-{max(ratios):.3f}"
        )
    out["real_biobuddy_right_hip"] = real_trial()
    if KNEE_C3D.exists():
        out["real_pyomeca_right_knee"] = real_trial(KNEE_C3D)
    for key in ("real_biobuddy_right_hip", "real_pyomeca_right_knee"):
        for j in out.get(key, []):
            verdict = f"single-axis {j['single_axis']} rank {j['rank']}"
            print(f"{key} {j['joint']:16s} {verdict} s_min/s_max {j['weak_ratio']:.3f}")
    out["seconds"] = time.perf_counter() - t0
    path = HERE / "results" / "hinge_verdict.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path} in {out['seconds']:.0f} s")


if __name__ == "__main__":
    main()
