"""The validation run: the paper's experiments reproduced in simulation, scored against truth.

:func:`run_validation` simulates and calibrates, and returns every figure as plain data (the
report module turns it into tables, plots and pictures):

- **linkage** (O'Brien Table 1): six exercise sets with the ``ascension-flock`` preset; the
  joint-to-joint distances computed (converted to metres with the tracker's unit scale factor,
  measured by the rigid-pair experiment as the paper did) against the truth, the largest error,
  the hierarchy per set;
- **unit scale** (section 4): two sensors rigidly 56.5 cm apart moved through the volume;
- **humanoid** (Tables 2-4): four ``exercise`` and three ``walk`` trials with ``skin-paper-human``
  (centimetre soft-tissue artefact, knee laxity, sprung mounts): the paper's eight limb lengths
  per trial against the truth, the hierarchy per trial (exact tree and thigh parents);
- **slip**: a linkage set with a 3 cm slip of the left forearm's sensor at mid-session, the joint
  residual over time and the intervals the detector finds;
- **orientation**: a humanoid exercise with the ``mems-industrial`` preset, the orientation error
  over time of the sourceless estimators and the gyro-aided reference;
- **decisions** (:mod:`simbench.experiments.decisions`): slip alarms per hour on the sessions
  above (none has a slip), detection of 1-3 cm slips, hinge verdicts, cluster grouping, each
  against its target.

``quick=True`` shortens everything (CI); the full run takes a few minutes on 2 cores. Seeds are
fixed: the same version gives the same figures.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration import calibrate, detect_slip, unit_scale
from calibration.rotations import matrix_to_quat, rotvec_to_matrix
from simbench.experiments.decisions import clean_alarms, run_decisions
from simbench.experiments.paper_tables import TABLE_1
from simbench.orient import estimate
from simbench.score import compare_trees, estimated_lengths, length_of, score_orientation, truth_lengths
from simbench.sim.sensor_config import load_sensor_config, parse_sensor_config
from simbench.sim.sensor_models import apply_tracker
from simbench.sim.session import SessionConfig, load_session_model, run_session

#: The paper's published figures (DESIGN.md).
PAPER = {
    "linkage_max_error_cm": 1.1,
    "linkage_hierarchy": "correct in 6 of 6 sets",
    "male_max_error_cm": 4.1,
    "walk_hierarchy": "wrong in 3 of 5 walk trials (one thigh a child of the other)",
    "exercise_hierarchy": "correct in every exercise trial",
    "unit_scale": 0.94,
    "scaled_std_cm": 0.7,
    "linkage_cm": dict(TABLE_1.measured_cm),
}

#: Table 1's rows as (segment, joint a, joint b) of the linkage model.
LINKAGE_ROWS = {
    "Neck - Left Shoulder": ("chest", "chest-head", "chest-upper_arm_l"),
    "Neck - Right Shoulder": ("chest", "chest-head", "chest-upper_arm_r"),
    "Between Shoulders": ("chest", "chest-upper_arm_l", "chest-upper_arm_r"),
    "Right Upper Arm": ("upper_arm_r", "chest-upper_arm_r", "upper_arm_r-forearm_r"),
    "Left Upper Arm": ("upper_arm_l", "chest-upper_arm_l", "upper_arm_l-forearm_l"),
}

#: Tables 2-4's rows as (segment, inboard joint, outboard joint) of the humanoid.
HUMANOID_ROWS = {
    "Right Lower Leg": ("shank_r", "thigh_r-shank_r", "shank_r-foot_r"),
    "Left Lower Leg": ("shank_l", "thigh_l-shank_l", "shank_l-foot_l"),
    "Right Upper Leg": ("thigh_r", "pelvis-thigh_r", "thigh_r-shank_r"),
    "Left Upper Leg": ("thigh_l", "pelvis-thigh_l", "thigh_l-shank_l"),
    "Right Lower Arm": ("forearm_r", "upper_arm_r-forearm_r", "forearm_r-hand_r"),
    "Left Lower Arm": ("forearm_l", "upper_arm_l-forearm_l", "forearm_l-hand_l"),
    "Right Upper Arm": ("upper_arm_r", "chest-upper_arm_r", "upper_arm_r-forearm_r"),
    "Left Upper Arm": ("upper_arm_l", "chest-upper_arm_l", "upper_arm_l-forearm_l"),
}


#: The steps :func:`run_validation` announces through ``progress``, in order.
STEPS = (
    "unit scale: two rigid sensors",
    "linkage sets",
    "humanoid trials",
    "slip detection",
    "sourceless orientation",
    "decisions: slip alarms and detection, hinge verdicts, cluster grouping",
)


@dataclass(frozen=True)
class Plan:
    """Sizes of the validation run."""

    linkage_sets: int
    linkage_s: float
    exercise_trials: int
    walk_trials: int
    humanoid_s: float
    orientation_s: float

    @classmethod
    def of(cls, quick: bool) -> Plan:
        if quick:
            return cls(
                linkage_sets=2,
                linkage_s=12.0,
                exercise_trials=1,
                walk_trials=1,
                humanoid_s=20.0,
                orientation_s=8.0,
            )
        return cls(
            linkage_sets=6,
            linkage_s=45.0,
            exercise_trials=4,
            walk_trials=3,
            humanoid_s=45.0,
            orientation_s=30.0,
        )


def _length_rows(
    labels: dict[str, tuple[str, str, str]], truth: dict, got: dict, scale: float
) -> dict[str, dict[str, float]]:
    """True, computed (scaled to metres) and true - computed lengths in cm for labelled rows."""
    rows = {}
    for label, key in labels.items():
        true_cm = length_of(truth, key) * 100
        computed_cm = length_of(got, key) * scale * 100
        rows[label] = {"true_cm": true_cm, "computed_cm": computed_cm, "difference_cm": true_cm - computed_cm}
    return rows


def rigid_pair_scale(seed: int = 7, duration_s: float = 60.0) -> dict[str, float]:
    """O'Brien section 4 with the ascension-flock tracker: the scale factor and the spread."""
    rng = np.random.default_rng(seed)
    rate = 120.0
    t = np.arange(int(duration_s * rate)) / rate
    f = rng.uniform(0.05, 0.3, (3, 6))
    ph = rng.uniform(0, 2 * np.pi, (3, 6))
    amp = np.array([0.25, 0.25, 0.15])
    centre = (
        np.array([0.0, 0.0, 1.2])
        + np.sum(
            amp[None, :, None] * np.sin(2 * np.pi * f[None, :, :3] * t[:, None, None] + ph[:, :3]), axis=2
        )
        / 3**0.5
    )
    R = rotvec_to_matrix(
        np.sum(1.5 * np.sin(2 * np.pi * f[None, :, 3:] * t[:, None, None] + ph[:, 3:]), axis=2) / 3**0.5
    )
    half = np.array([0.565 / 2, 0.0, 0.0])
    p = np.stack([centre - R @ half, centre + R @ half], axis=1)
    q = matrix_to_quat(np.stack([R, R], axis=1))
    flock = load_sensor_config("ascension-flock").tracker
    rep, _, _ = apply_tracker(t, p, q, flock, np.random.default_rng(seed + 1))
    est = unit_scale(rep[:, 0], rep[:, 1], 0.565)
    return {"scale": est.scale, "scaled_std_cm": est.scaled_std * 100, "frames": est.n_frames}


def linkage_experiment(plan: Plan, scale: float, keep: dict[str, Any] | None = None) -> dict[str, Any]:
    """O'Brien Table 1: the linkage's exercise sets with the ``ascension-flock`` preset.

    Args:
        plan: sizes (number of sets, seconds each).
        scale: the tracker's unit scale factor (:func:`rigid_pair_scale`): computed lengths are
            multiplied by it.
        keep: if given, receives the first set's dataset and calibration (``linkage_ds``,
            ``linkage_cal``) for the report's pictures.

    Returns:
        JSON-ready figures: per set the true, computed and difference lengths (cm) of Table 1's
        rows, the largest error, whether the hierarchy is right, each joint's rms residual (mm).
    """
    config0 = SessionConfig(
        model="linkage", motion="exercise", duration_s=plan.linkage_s, sensors="ascension-flock"
    )
    cm = load_session_model(config0)
    sets = []
    for s in range(1, plan.linkage_sets + 1):
        config = SessionConfig(
            model="linkage", motion="exercise", duration_s=plan.linkage_s, seed=s, sensors="ascension-flock"
        )
        ds = run_session(config, cm)
        rec = ds.poses()
        cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
        truth = truth_lengths(ds)
        got = estimated_lengths(cal)
        rows = _length_rows(LINKAGE_ROWS, truth, got, scale)
        sets.append(
            {
                "set": s,
                "seed": s,
                "rows": rows,
                "max_abs_error_cm": max(abs(r["difference_cm"]) for r in rows.values()),
                "hierarchy_correct": compare_trees(cal.parent_of, ds.truth.parent_of).correct,
                "rms_residual_mm": {j.name: j.fit.rms_residual * scale * 1e3 for j in cal.joints},
                "slip_alarms": clean_alarms(rec, cal),
            }
        )
        if s == 1 and keep is not None:
            keep["linkage_ds"], keep["linkage_cal"] = ds, cal
    return {"preset": "ascension-flock", "duration_s": plan.linkage_s, "sets": sets}


def _humanoid(plan: Plan, scale: float) -> dict[str, Any]:
    trials = []
    configs = [("exercise", k + 1) for k in range(plan.exercise_trials)] + [
        ("walk", k + 1) for k in range(plan.walk_trials)
    ]
    config0 = SessionConfig(model="humanoid", duration_s=plan.humanoid_s, sensors="skin-paper-human")
    cm = load_session_model(config0)
    for motion, k in configs:
        config = SessionConfig(
            model="humanoid",
            motion=motion,
            duration_s=plan.humanoid_s,
            seed=100 + k,
            sensors="skin-paper-human",
        )
        ds = run_session(config, cm)
        rec = ds.poses()
        cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, root="pelvis")
        truth = truth_lengths(ds)
        got = estimated_lengths(cal)
        given = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, parent_of=ds.truth.parent_of)
        got_given = estimated_lengths(given)  # limb lengths for the right hierarchy, as the paper reports
        rows = _length_rows(HUMANOID_ROWS, truth, got_given, scale)
        trials.append(
            {
                "trial": f"{motion.capitalize()} {k}",
                "motion": motion,
                "seed": config.seed,
                "rows": rows,
                "max_abs_error_cm": max(abs(r["difference_cm"]) for r in rows.values()),
                "hierarchy_correct": compare_trees(cal.parent_of, ds.truth.parent_of).correct,
                "thigh_parents": {t: cal.parent_of.get(t) for t in ("thigh_l", "thigh_r")},
                "wrong_joints": list(compare_trees(cal.parent_of, ds.truth.parent_of).wrong_edges),
                "slip_alarms": clean_alarms(rec, given),
                "inferred_lengths_cm": {
                    label: length_of(got, key) * scale * 100 for label, key in HUMANOID_ROWS.items()
                },
            }
        )
    return {"preset": "skin-paper-human", "duration_s": plan.humanoid_s, "trials": trials}


def _slip(plan: Plan) -> dict[str, Any]:
    t_slip = plan.linkage_s / 2
    sensors = parse_sensor_config(
        {
            "name": "slip",
            "tracker": {"position_noise_m": 0.002, "transmitter_pos": [0.0, -0.8, 1.0]},
            "skin": {"slip": [{"sensor": "forearm_l", "time_s": t_slip, "offset_m": [0.0, 0.03, 0.0]}]},
        },
        "the validation's slip case",
    )
    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=plan.linkage_s, seed=21, sensors=sensors
    )
    ds = run_session(config, load_session_model(config))
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    j = next(j for j in cal.joints if j.child == "forearm_l")
    window = min(round(2.0 * rec.rate_hz), rec.n_frames // 4)  # 2 s, the CLI's default
    rep = detect_slip(
        *rec.pair(j.parent, j.child),
        j.fit.joint_in_parent,
        j.fit.joint_in_child,
        window=window,
        rate_hz=rec.rate_hz,
    )
    return {
        "joint": j.name,
        "true_slip_s": t_slip,
        "events_s": [float(ds.time_s[e.frame]) for e in rep.events],
        "jumps_mm": [e.jump * 1e3 for e in rep.events],
        "false_alarms_per_hour": rep.false_alarms_per_hour,
        "min_jump_mm": rep.min_jump * 1e3,
        "intervals_s": [[float(ds.time_s[a]), float(ds.time_s[b - 1])] for a, b in rep.intervals],
        "time_s": np.asarray(ds.time_s).tolist(),
        "residual_mm": (np.asarray(j.fit.frame_residual) * 1e3).tolist(),
        "jump_statistic_mm": np.nan_to_num(rep.jump * 1e3).tolist(),
    }


def _orientation(plan: Plan) -> dict[str, Any]:
    config = SessionConfig(
        model="humanoid", motion="exercise", duration_s=plan.orientation_s, seed=31, sensors="mems-industrial"
    )
    ds = run_session(config, load_session_model(config))
    rec = ds.imu()
    out: dict[str, Any] = {
        "preset": "mems-industrial",
        "time_s": np.asarray(rec.time_s).tolist(),
        "methods": {},
    }
    for label, kw in {
        "triad": {"method": "triad"},
        "fontaine": {"method": "fontaine"},
        "fontaine (1 Hz weighted smoothing)": {"method": "fontaine", "smooth_hz": 1.0},
        "mahony (gyro-aided)": {"method": "mahony"},
    }.items():
        run = estimate(rec, **kw)
        scored = score_orientation(run.q_enu, rec.q_true, rec.names)
        out["methods"][label] = {
            "total_rmse_deg": scored.total_rmse_deg,
            "heading_rmse_deg": scored.heading_rmse_deg,
            "inclination_rmse_deg": scored.inclination_rmse_deg,
            "per_frame_deg": np.nan_to_num(scored.per_frame_deg).tolist(),
        }
    return out


def _clean_sessions(linkage: dict[str, Any], humanoid: dict[str, Any]) -> dict[str, list[dict[str, Any]]]:
    """The slip alarms of the sessions without slip, by case."""
    out = {f"linkage exercise, {linkage['preset']}": [s["slip_alarms"] for s in linkage["sets"]]}
    for motion in ("exercise", "walk"):
        runs = [t["slip_alarms"] for t in humanoid["trials"] if t["motion"] == motion]
        if runs:
            out[f"humanoid {motion}, {humanoid['preset']}"] = runs
    return out


def run_validation(
    *, quick: bool = False, progress: Callable[[str], None] | None = None
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run every experiment; returns ``(results, keep)``: JSON-ready figures, and the objects
    the report draws from (datasets, calibrations).

    Args:
        quick: the short variant (CI).
        progress: called with the name of each step as it starts.
    """
    plan = Plan.of(quick)
    say = progress or (lambda _: None)
    keep: dict[str, Any] = {}
    t0 = time.perf_counter()
    say(STEPS[0])
    scale = rigid_pair_scale(duration_s=20.0 if quick else 60.0)
    say(STEPS[1])
    linkage = linkage_experiment(plan, scale["scale"], keep)
    say(STEPS[2])
    humanoid = _humanoid(plan, scale["scale"])
    say(STEPS[3])
    slip = _slip(plan)
    say(STEPS[4])
    orientation = _orientation(plan)
    say(STEPS[5])
    decisions = run_decisions(quick, _clean_sessions(linkage, humanoid))
    results = {
        "quick": quick,
        "plan": plan.__dict__,
        "paper": PAPER,
        "unit_scale": scale,
        "linkage": linkage,
        "humanoid": humanoid,
        "slip": slip,
        "orientation": orientation,
        "decisions": decisions,
        "summary": {
            "linkage_max_error_cm": max(s["max_abs_error_cm"] for s in linkage["sets"]),
            "linkage_hierarchy_correct": sum(s["hierarchy_correct"] for s in linkage["sets"]),
            "linkage_sets": len(linkage["sets"]),
            "humanoid_max_error_cm": max(t["max_abs_error_cm"] for t in humanoid["trials"]),
            "exercise_hierarchy_correct": sum(
                t["hierarchy_correct"] for t in humanoid["trials"] if t["motion"] == "exercise"
            ),
            "exercise_trials": sum(t["motion"] == "exercise" for t in humanoid["trials"]),
            "walk_hierarchy_correct": sum(
                t["hierarchy_correct"] for t in humanoid["trials"] if t["motion"] == "walk"
            ),
            "walk_trials": sum(t["motion"] == "walk" for t in humanoid["trials"]),
            "slip_found": len(slip["events_s"]) == 1
            and abs(slip["events_s"][0] - slip["true_slip_s"]) < 0.25,
            "orientation_total_rmse_deg": {k: v["total_rmse_deg"] for k, v in orientation["methods"].items()},
        },
        "run_time_s": time.perf_counter() - t0,
    }
    return results, keep
