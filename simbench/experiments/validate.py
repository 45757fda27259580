"""The validation run: the paper's experiments reproduced in simulation, scored against truth.

:func:`run_validation` simulates and calibrates, and returns every figure as plain data (the
report module turns it into tables, plots and pictures):

- **linkage** (O'Brien Table 1), **unit scale** (section 4), **humanoid** (Tables 2-4, the male
  and the female subject) and the **paper tables** side by side with the effects that explain
  them switched off in turn: :mod:`simbench.experiments.obrien`;
- **slip**: a linkage set with a 3 cm slip of the left forearm's sensor at mid-session, the joint
  residual over time and the intervals the detector finds;
- **orientation**: a humanoid exercise with the ``mems-industrial`` preset, the orientation error
  over time of the sourceless estimators (the default, ``skeleton``, on the skeleton calibrated
  from the same session's tracker poses, with the joints' ranges of motion those poses show) and
  the gyro-aided reference; and each on the BROAD
  trials at hand (no skeleton: one IMU);
- **decisions** (:mod:`simbench.experiments.decisions`): slip alarms per hour on the sessions
  above (none has a slip), detection of 1-3 cm slips, hinge verdicts, cluster grouping, each
  against its target;
- **realism** (:mod:`simbench.experiments.realism`): the statistics an estimator sees on each
  real recording in ``../shared/data`` beside a simulated counterpart's, and each BROAD trial's
  digital twin (:mod:`simbench.twin`);
- **joint-centre methods**: every method of :mod:`calibration.methods` on the same seeded
  sessions, and the coverage of O'Brien's 95 % regions (batch means against i.i.d.).

``quick=True`` shortens everything (CI); the full run takes a few minutes on 2 cores (the human
trials run on a process pool). Seeds are fixed: the same version gives the same figures.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from calibration import calibrate, detect_slip, fit_joint
from calibration.errors import CalibrationError
from calibration.methods import estimate_obrien_eiv
from calibration.slip import SLIP_WINDOW_S
from calibration.uncertainty import holds_truth, joint_covariance
from simbench.estimators import DEFAULT_ORIENTATION as DEFAULT_METHOD
from simbench.estimators import names, resolve
from simbench.experiments.decisions import run_decisions, slip_trials
from simbench.experiments.metrics import joint_method_metrics, true_joints
from simbench.experiments.obrien import (
    HUMAN_PRESET,
    PAIR_S,
    PAPER,
    human_causes,
    human_trial,
    human_trials,
    linkage_causes,
    linkage_experiment,
    paper_tables,
    rigid_pair_scale,
)
from simbench.experiments.pool import one_blas_thread, worker_pool
from simbench.experiments.realism import DEFAULT_DATA_DIR, run_realism, run_twins
from simbench.experiments.walk_hierarchy import walk_trial
from simbench.experiments.work import Job, Work
from simbench.io.imu import read_broad
from simbench.orient import estimate, skeleton_of
from simbench.score import score_orientation
from simbench.sim.physics_cache import physics_cache
from simbench.sim.sensor_config import parse_sensor_config
from simbench.sim.session import SessionConfig, load_session_model, run_session
from simbench.twin import BASELINE as TWIN_BASELINE
from simbench.twin import METHODS as TWIN_METHODS
from simbench.twin import REFERENCE as TWIN_REFERENCE

__all__ = ["PAPER", "STEPS", "Plan", "expected_cost", "expected_jobs", "run_validation"]

#: The steps :func:`run_validation` announces through ``progress``, in order.
STEPS = (
    "unit scale: two rigid sensors",
    "linkage sets",
    "humanoid trials",
    "slip detection",
    "sourceless orientation",
    "decisions: slip alarms and detection, hinge verdicts, cluster grouping",
    "paper tables: each effect switched off in turn",
    "walk hierarchies: the paper's failure (transmitter on the stand) and both methods",
    "realism: real recordings beside simulated ones",
    "joint-centre methods side by side, and O'Brien's 95 % regions",
)

#: The expected cost of each step, CPU seconds (on all processes) of a reference run, and its number
#: of jobs, full and ``quick``; and of writing the report (``"report"``): the units of the progress
#: bar (:class:`simbench.experiments.work.Work`) and the order the pool takes the jobs in (the
#: longest first). Measured by ``benchmarks/bench_validate.py [--quick]`` (its ``steps``: the jobs'
#: CPU seconds; 0.1 for a step that took less; the full run's in one process, each job's own CPU
#: without the jobs it waited on), rounded; only the shares matter (the bar's rate is the
#: machine's).
COST_S: dict[bool, dict[str, tuple[float, int]]] = {
    False: dict(
        zip(
            (*STEPS, "report"),
            (
                (0.1, 1),
                (9.4, 6),
                (52.9, 10),
                (1.0, 1),
                (16.1, 2),
                (17.4, 14),
                (25.1, 44),
                (23.4, 6),
                (22.6, 4),
                (38.1, 13),
                (2.2, 1),
            ),
            strict=True,
        )
    ),
    True: dict(
        zip(
            (*STEPS, "report"),
            (
                (0.1, 1),
                (1.1, 2),
                (5.7, 4),
                (0.3, 1),
                (7.3, 2),
                (2.8, 5),
                (3.3, 16),
                (1.1, 2),
                (5.8, 3),
                (4.1, 4),
                (2.8, 1),
            ),
            strict=True,
        )
    ),
}


def expected_cost(quick: bool) -> dict[str, float]:
    """``{step: expected CPU seconds}`` of a run, the report's (``"report"``) last."""
    return {step: cpu_s for step, (cpu_s, _) in COST_S[quick].items()}


def expected_jobs(quick: bool) -> dict[str, int]:
    """``{step: expected number of jobs}`` of a run (:data:`COST_S`)."""
    return {step: jobs for step, (_, jobs) in COST_S[quick].items() if step in STEPS}


@dataclass(frozen=True)
class Plan:
    """Sizes of the validation run."""

    linkage_sets: int
    linkage_s: float
    exercise_trials: int
    walk_trials: int
    female_walk_trials: int
    humanoid_s: float
    orientation_s: float
    cause_tables: tuple[str, ...]
    failure_walks: int
    methods_seeds: int
    methods_s: float

    @classmethod
    def of(cls, quick: bool) -> Plan:
        if quick:
            return cls(
                linkage_sets=2,
                linkage_s=12.0,
                exercise_trials=1,
                walk_trials=1,
                female_walk_trials=1,
                humanoid_s=10.0,
                orientation_s=8.0,
                cause_tables=("table_1", "table_2"),
                failure_walks=1,
                methods_seeds=1,
                methods_s=8.0,
            )
        return cls(
            linkage_sets=6,
            linkage_s=45.0,
            exercise_trials=4,
            walk_trials=3,
            female_walk_trials=2,
            humanoid_s=45.0,
            orientation_s=30.0,
            cause_tables=("table_1", "table_2", "table_3", "table_4"),
            failure_walks=5,
            methods_seeds=4,
            methods_s=20.0,
        )


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
    window = min(round(SLIP_WINDOW_S * rec.rate_hz), rec.n_frames // 4)  # the detector's default
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
    poses = ds.poses()
    # the skeleton and the joints' ranges of motion as `simbench calibrate --json` gives them
    cal = calibrate(poses.R_w_s, poses.p_w_s, poses.names, valid=poses.valid)
    skeleton = skeleton_of(cal).with_ranges(poses.R_w_s, poses.valid)
    for label, kw in ORIENTATION_METHODS.items():
        run = estimate(rec, **kw, **({"skeleton": skeleton} if kw["method"] == "skeleton" else {}))
        scored = score_orientation(run.q_enu, rec.q_true, rec.names)
        out["methods"][label] = {
            "total_rmse_deg": scored.total_rmse_deg,
            "heading_rmse_deg": scored.heading_rmse_deg,
            "inclination_rmse_deg": scored.inclination_rmse_deg,
            "per_frame_deg": np.nan_to_num(scored.per_frame_deg).tolist(),
        }
    out["default"] = DEFAULT_METHOD
    out["target_deg"] = SIMULATION_TARGET_DEG
    out["target_met"] = bool(out["methods"][DEFAULT_METHOD]["total_rmse_deg"] <= SIMULATION_TARGET_DEG)
    return out


#: Issue 15's target for the default gyro-free estimator on the humanoid exercise with
#: ``mems-industrial`` sensors: total RMSE, degrees.
SIMULATION_TARGET_DEG = 8.0


#: The label of Fontaine's estimator with 1 Hz weighted smoothing, a variant of the same estimator.
SMOOTHED_FONTAINE = "fontaine (1 Hz weighted smoothing)"


#: The orientation estimators the report compares: gyro-free, then the gyro-aided reference.
def _orientation_methods() -> dict[str, dict[str, Any]]:
    """Every gyro-free built-in (the registry's order), Fontaine's also with 1 Hz weighted
    smoothing, then VQF as the gyro-aided reference."""
    out: dict[str, dict[str, Any]] = {}
    for name in names("orientation", plugins=False):
        if "gyro" not in resolve(name).needs:
            out[name] = {"method": name}
        if name == "fontaine":
            out[SMOOTHED_FONTAINE] = {"method": name, "smooth_hz": 1.0}
    out["vqf (gyro-aided reference)"] = {"method": "vqf"}
    return out


ORIENTATION_METHODS = _orientation_methods()

#: Issue 15's targets for the default gyro-free estimator, as a fraction of TRIAD's total RMSE:
#: by the kind of BROAD trial its file name says (the first that matches).
BROAD_TARGETS = (("magnet", 0.6), ("undisturbed", 0.8), ("", 1.0))


def _broad_orientation(quick: bool = False) -> dict[str, Any]:
    """Every estimator on each BROAD trial at hand (``broad_*.hdf5`` in ``../shared/data``),
    scored with BROAD's definitions, with its ratio to TRIAD and the default estimator's target;
    ``{}`` without the recordings. ``quick``: without Fontaine's smoothed variant (a fifth of the
    step; the simulated session runs it)."""
    out: dict[str, Any] = {}
    methods = {k: v for k, v in ORIENTATION_METHODS.items() if not (quick and k == SMOOTHED_FONTAINE)}
    for path in sorted(DEFAULT_DATA_DIR.glob("broad_*.hdf5")):
        rec = read_broad(path)
        scores = {}
        for label, kw in methods.items():
            run = estimate(rec, **kw)
            s = score_orientation(run.q_enu, rec.q_true, rec.names, rec.evaluate).per_sensor
            scores[label] = {
                k: float(np.mean([v[k] for v in s.values()]))
                for k in ("total_deg", "heading_deg", "inclination_deg")
            }
        triad_total = scores["triad"]["total_deg"]
        target = next(t for word, t in BROAD_TARGETS if word in path.stem)
        ratio = scores[DEFAULT_METHOD]["total_deg"] / triad_total
        out[path.stem] = {
            "methods": {k: {**v, "ratio_to_triad": v["total_deg"] / triad_total} for k, v in scores.items()},
            "default": DEFAULT_METHOD,
            "target_ratio": target,
            "target_met": bool(ratio <= target),
        }
    return out


def _twin_methods(quick: bool) -> tuple[str, ...]:
    """The orientation methods of the twins: all of :data:`simbench.twin.METHODS`; the quick
    variant leaves out the default gyro-free estimator (half of a twin's 9 s; its error on the
    real trials is in the orientation section)."""
    return (TWIN_BASELINE, TWIN_REFERENCE) if quick else TWIN_METHODS


#: The BROAD trials the twins are made of: all at hand; the quick variant's, the undisturbed ones
#: (issue 41's R^2 targets are theirs; a twin is 2.5 CPU-s of the quick run's 30).
TWIN_TRIALS = {False: "broad_*.hdf5", True: "broad_*undisturbed*.hdf5"}


def _clean_sessions(linkage: dict[str, Any], humanoid: dict[str, Any]) -> dict[str, list[dict[str, Any]]]:
    """The slip alarms of the sessions without slip, by case."""
    out = {f"linkage exercise, {linkage['preset']}": [s["slip_alarms"] for s in linkage["sets"]]}
    for motion in ("exercise", "walk"):
        runs = [t["slip_alarms"] for t in humanoid["trials"] if t["motion"] == motion]
        if runs:
            out[f"humanoid {motion}, {humanoid['preset']}"] = runs
    return out


def _human_causes(
    plan: Plan, trials: list[dict[str, Any]], run: Callable, pair_s: float
) -> dict[str, dict[str, dict[str, Any]]]:
    """The causes of Tables 2-4, each over the table's first trial (``trials``: those run with
    every effect on)."""
    firsts = {
        "table_2": ("male", "exercise", 1),
        "table_3": ("male", "walk", 1),
        "table_4": ("female", "exercise", 1),
    }
    out = {}
    for key, (subject, motion, k) in firsts.items():
        if key not in plan.cause_tables:
            continue
        done = [t["rows"] for t in trials if t["trial"] == f"{subject} {motion.capitalize()} {k}"]
        out[key] = human_causes([(subject, motion, k)], plan.humanoid_s, run=run, done=done, pair_s=pair_s)
    return out


def _walk_failures(plan: Plan, run: Callable) -> dict[str, Any]:
    """The paper's walk failure reproduced (:mod:`simbench.experiments.walk_hierarchy`): walks
    with the hips turning nearly about one lateral axis, the transmitter on the stand in front
    (noisier at the far end of the walk), the pelvis sensor on its pack; both hierarchy methods.
    As many walks as the paper's (five), seeds 101..."""
    seeds = [101 + k for k in range(plan.failure_walks)]
    trials = list(
        run(
            walk_trial,
            seeds,
            [plan.humanoid_s] * len(seeds),
            [True] * len(seeds),
            ["sagittal"] * len(seeds),
            ["stand"] * len(seeds),
        )
    )
    summary = {
        method: {
            "correct": sum(t["methods"][method]["correct"] for t in trials),
            "thigh_child_of_thigh": sum(t["methods"][method]["thigh_child_of_thigh"] for t in trials),
        }
        for method in ("mst", "misfit")
    }
    return {"seeds": seeds, "trials": trials, "summary": summary}


def run_validation(
    *,
    quick: bool = False,
    progress: Callable[[float], None] | None = None,
    workers: int = 2,
    physics_folder: Path | None = None,
    jobs: list[Job] | None = None,
) -> tuple[dict[str, Any], dict[str, Any]]:
    """Run every experiment; returns ``(results, keep)``: JSON-ready figures, and the objects
    the report draws from (datasets, calibrations).

    Args:
        quick: the short variant (CI).
        progress: called with the work done, in the units of :func:`expected_cost` (the steps'
            costs credited as their jobs end: :class:`simbench.experiments.work.Work`), each
            time it grows; it reaches the total of the steps' costs (the report's is the caller's).
        workers: processes for the human trials (1: run them here); the figures do not depend
            on it.
        physics_folder: keep the physics runs there (:mod:`simbench.sim.physics_cache`) and read
            back those it holds from an earlier run: the same figures, without the physics (a
            full run's are about 830 MiB); ``None``: a temporary folder (or the one the
            environment names).
        jobs: if given, receives every job's step, process, start, end and CPU seconds.
    """
    plan = Plan.of(quick)
    keep: dict[str, Any] = {}
    t0 = time.perf_counter()
    # the cache shares the physics of sessions that differ only in their sensors (each effect
    # switched off in turn), in this process and the workers
    # BLAS on one thread here too: this process works beside the pool's workers
    # ``helper``: threads of this process that gather the jobs they hand to the pool (and run the
    # decisions' small checks) while this thread waits on its own; entered before the pool, so
    # that an interrupt stops the pool first and the threads waiting on it end
    with (
        physics_cache(physics_folder),
        one_blas_thread(),
        ThreadPoolExecutor(HELPER_THREADS) if workers > 1 else _Here() as helper,
        worker_pool(workers) if workers > 1 else _Here() as pool,
    ):
        # every job is handed out as soon as what it needs is there, and the pool takes them in
        # the order of :class:`Work`: first the jobs this process waits on to go on (the humanoid
        # trials, which Tables 2-4's causes and the decisions need; the linkage sets and the slip
        # trials, which the decisions need; the tables' sessions), then the costliest steps' jobs:
        # the rest of the work fills the cores while this process works on what came back
        if workers > 1:
            # the workers are forked now, while this thread is the only one at work: forked later
            # (on the first job the dispatcher hands out) beside threads running MuJoCo or BLAS, a
            # worker can inherit a lock held mid-call and die (BrokenProcessPool under xdist)
            pool.submit(int).result()
        cost = expected_cost(quick)
        work = Work(
            pool,
            {s: cost[s] for s in STEPS},
            progress,
            slots=workers if workers > 1 else None,
            first=(STEPS[1], STEPS[2], STEPS[5], STEPS[6]),
            jobs=expected_jobs(quick),
        )
        pair_s = 20.0 if quick else PAIR_S
        scale = work.call(STEPS[0], rigid_pair_scale, duration_s=pair_s)
        work.close(STEPS[0])
        trials = human_trials(plan.exercise_trials, plan.walk_trials, plan.female_walk_trials)
        human_runs = helper.submit(
            list,
            work.map(STEPS[2])(
                human_trial,
                *zip(*trials, strict=True),
                *[[x] * len(trials) for x in (plan.humanoid_s, scale["scale"])],
            ),
        )
        linkage_run = helper.submit(
            work.bound(STEPS[1], linkage_experiment),
            plan.linkage_sets,
            plan.linkage_s,
            scale["scale"],
            keep,
            run=work.map(STEPS[1]),
        )
        # the slips ride the male subject's trials' motions (decisions.SLIP_FIRST_SEED): handed out
        # once those trials are done, their physics is in the cache rather than computed twice
        slips_run = helper.submit(
            _after, human_runs, work.bound(STEPS[5], slip_trials), quick, work.map(STEPS[5])
        )
        # each BROAD trial's digital twin (the realism section's), a job each
        twins_run = helper.submit(
            work.bound(STEPS[8], run_twins),
            DEFAULT_DATA_DIR,
            run=work.map(STEPS[8]),
            methods=_twin_methods(quick),
            pattern=TWIN_TRIALS[quick],
        )
        slip_run = work.submit(STEPS[3], _slip, plan)
        orientation_run = work.submit(STEPS[4], _orientation, plan)
        broad_run = work.submit(
            STEPS[4], _broad_orientation, quick
        )  # the real recordings: a job of their own
        realism_run = work.submit(STEPS[8], run_realism, quick=quick)
        methods_run = helper.submit(work.bound(STEPS[9], _joint_methods), plan, work.map(STEPS[9]))
        walks_run = helper.submit(work.bound(STEPS[7], _walk_failures), plan, work.map(STEPS[7]))
        table_1_run = helper.submit(
            work.bound(STEPS[6], linkage_causes),
            plan.linkage_sets,
            plan.linkage_s,
            run=work.map(STEPS[6]),
            pair_s=pair_s,
        )
        humanoid = {"preset": HUMAN_PRESET, "duration_s": plan.humanoid_s, "trials": human_runs.result()}
        tables_2_4 = _human_causes(plan, humanoid["trials"], work.map(STEPS[6]), pair_s)
        linkage = linkage_run.result()
        decisions_run = helper.submit(
            work.bound(
                STEPS[5], lambda: run_decisions(quick, _clean_sessions(linkage, humanoid), slips_run.result())
            )
        )
        causes = {"table_1": table_1_run.result(), **tables_2_4}
        tables = work.call(STEPS[6], paper_tables, linkage, humanoid, causes)
        walks = walks_run.result()
        slip, orientation = slip_run.result(), {**orientation_run.result(), "broad": broad_run.result()}
        decisions, realism = decisions_run.result(), {**realism_run.result(), "twins": twins_run.result()}
        methods = methods_run.result()
        for step in STEPS:
            work.close(step)
        if jobs is not None:
            jobs.extend(work.jobs)
    results = {
        "quick": quick,
        "plan": plan.__dict__,
        "paper": PAPER,
        "unit_scale": scale,
        "linkage": linkage,
        "humanoid": humanoid,
        "paper_tables": tables,
        "walk_failures": walks,
        "slip": slip,
        "orientation": orientation,
        "decisions": decisions,
        "realism": realism,
        "joint_methods": methods,
        "summary": _summary(linkage, humanoid, slip, orientation),
        "run_time_s": time.perf_counter() - t0,
    }
    return results, keep


#: The sessions of the methods comparison: (label, model, preset); seeds 41..
METHODS_CONDITIONS = (
    ("linkage, Polhemus Liberty", "linkage", "polhemus-liberty"),
    ("humanoid, Polhemus Liberty", "humanoid", "polhemus-liberty"),
    ("humanoid, skin (paper-like)", "humanoid", "skin-paper-human"),
)


#: The joint-centre methods study at 200 seeds per condition (``studies/methods.py``), as a
#: checkout ships it; the report quotes its coverage when the file is there.
COVERAGE_STUDY = Path(__file__).resolve().parents[2] / "studies" / "results" / "methods_coverage_200.json"


def coverage_study(path: Path = COVERAGE_STUDY) -> dict[str, Any] | None:
    """The coverage of the study's 95 % regions per noisy condition, or ``None`` without the file.

    Returns:
        ``{"seeds", "duration_s", "command", "file", "conditions": {name: {"shares": [O'Brien
        batch means, O'Brien iid, corrected batch means, corrected iid], "bounded": the share of
        the corrected fit's batch-means regions that are bounded (``None`` if not recorded),
        "regions"}}}``.
    """
    if not path.is_file():
        return None
    doc = json.loads(path.read_text())
    conditions = {}
    for name, by_method in doc["summary"].items():
        if name.endswith("/ ideal"):  # exact data: every region is a point that holds the truth
            continue
        cover = [by_method["obrien"]["coverage95"], by_method["obrien-eiv"]["coverage95"]]
        conditions[name] = {
            "shares": [c[k] for c in cover for k in ("batch-means", "iid")],
            "bounded": cover[1].get("bounded"),
            "regions": int(cover[0]["regions"]),
        }
    return {
        "seeds": len(doc["config"]["seeds"]),
        "duration_s": doc["config"]["duration_s"],
        "command": doc.get("command", "studies/methods.py"),
        "file": f"studies/results/{path.name}",
        "conditions": conditions,
    }


#: The joint-centre methods the report compares on the same sessions: every built-in that
#: estimates from poses (the registry's; :mod:`simbench.estimators.builtin`).
POSE_JOINT_METHODS = tuple(n for n in names("joints", plugins=False) if resolve(n).data == "poses")


def _methods_session(model: str, preset: str, seed: int, duration_s: float) -> dict[str, Any]:
    """One session of the methods comparison: every method's metrics and the regions' hits."""
    config = SessionConfig(model=model, motion="exercise", duration_s=duration_s, seed=seed, sensors=preset)
    ds = run_session(config, load_session_model(config))
    hits = {"batch-means": [0, 0], "iid": [0, 0], "eiv": [0, 0]}
    _coverage(ds, hits)
    return {"rows": {m: joint_method_metrics(ds, m) for m in POSE_JOINT_METHODS}, "hits": hits}


def _joint_methods(plan: Plan, run: Callable = map) -> dict[str, Any]:
    """Every joint-centre method of :mod:`calibration.methods` on the same seeded sessions (the
    true hierarchy), and how often O'Brien's 95 % regions hold the true centre: batch means
    (:mod:`calibration.uncertainty`, the default) against i.i.d. (``studies/methods.py`` runs
    more seeds and conditions). ``run``: ``map`` or an executor's ``map`` (one session a job)."""
    out: dict[str, Any] = {"seeds": plan.methods_seeds, "duration_s": plan.methods_s, "conditions": {}}
    seeds = range(41, 41 + plan.methods_seeds)
    jobs = [(m, preset, seed, plan.methods_s) for _, m, preset in METHODS_CONDITIONS for seed in seeds]
    sessions = iter(run(_methods_session, *zip(*jobs, strict=True)))
    for label, _, preset in METHODS_CONDITIONS:
        done = [next(sessions) for _ in seeds]
        rows = {m: [d["rows"][m] for d in done] for m in POSE_JOINT_METHODS}
        hits = {k: [sum(d["hits"][k][i] for d in done) for i in (0, 1)] for k in done[0]["hits"]}
        out["conditions"][label] = {
            "preset": preset,
            "methods": {
                m: {
                    "centre_error_mm": 1000 * float(np.nanmean([r["joint_centre_error_m"] for r in v])),
                    "length_error_mm": 1000 * float(np.nanmean([r["limb_length_error_m"] for r in v])),
                    "failed_joints": int(sum(r["failed_joints"] for r in v)),
                }
                for m, v in rows.items()
            },
            "coverage": {k: {"covered": h[0], "regions": h[1]} for k, h in hits.items()},
        }
    out["study"] = coverage_study()
    return out


def _coverage(ds: Any, hits: dict[str, list[int]]) -> None:
    """Add the session's O'Brien regions (both frames of every joint of the true hierarchy) that
    hold the true centre to ``hits`` (``[covered, regions]``): for the plain fit by each
    covariance method (``"batch-means"``, ``"iid"``), and for the fit corrected for the rotations'
    noise (:mod:`calibration.eiv`) by batch means (``"eiv"``)."""
    rec = ds.poses()
    p = rec.p_w_s * ds.position_unit_scale  # metres
    true_p, true_c = ds.truth_joint_arrays()
    for k, child in true_joints(ds):
        args = (rec.R_w_s[:, k], p[:, k], rec.R_w_s[:, child], p[:, child])
        valid = rec.valid[:, k] & rec.valid[:, child]
        fits = {"batch-means": fit_joint(*args, valid=valid)}
        fits["iid"] = fits["batch-means"]
        try:
            fits["eiv"] = estimate_obrien_eiv(*args, valid=valid).fit
        except CalibrationError:
            fits["eiv"] = None
        for key in hits:
            fit = fits[key]
            if fit is None:
                continue
            method = "iid" if key == "iid" else "batch-means"
            unc = joint_covariance(*args, fit, valid=valid, method=method)
            for held in holds_truth(unc, true_p[child], true_c[child]):
                hits[key][0] += int(held)
                hits[key][1] += 1


#: Threads of :func:`run_validation`'s ``helper``: more than the tasks it holds at once (eight), as
#: one may wait on another's result.
HELPER_THREADS = 12


def _after(first: Future, fn: Callable[..., Any], /, *args: Any) -> Any:
    """``fn(*args)`` once ``first`` is done (its result waited for, its exception raised)."""
    first.result()
    return fn(*args)


class _Here:
    """An executor stand-in that maps, and runs what is submitted, in this process."""

    map = staticmethod(map)

    @staticmethod
    def submit(fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        done: Future = Future()
        done.set_result(fn(*args, **kwargs))
        return done

    def __enter__(self) -> _Here:
        return self

    def __exit__(self, *exc: object) -> None:
        return None


def _summary(
    linkage: dict[str, Any], humanoid: dict[str, Any], slip: dict[str, Any], orientation: dict[str, Any]
) -> dict[str, Any]:
    """The figures the report compares with the paper's."""
    trials = humanoid["trials"]
    return {
        "linkage_max_error_cm": max(s["max_abs_error_cm"] for s in linkage["sets"]),
        "linkage_hierarchy_correct": sum(s["hierarchy_correct"] for s in linkage["sets"]),
        "linkage_sets": len(linkage["sets"]),
        "humanoid_max_error_cm": max(t["max_abs_error_cm"] for t in trials if t["subject"] == "male"),
        "exercise_hierarchy_correct": sum(
            t["hierarchy_correct"] for t in trials if t["motion"] == "exercise"
        ),
        "exercise_trials": sum(t["motion"] == "exercise" for t in trials),
        "walk_hierarchy_correct": sum(t["hierarchy_correct"] for t in trials if t["motion"] == "walk"),
        "walk_hierarchy_correct_mst": sum(
            t["hierarchy_correct_mst"] for t in trials if t["motion"] == "walk"
        ),
        "walk_trials": sum(t["motion"] == "walk" for t in trials),
        "slip_found": len(slip["events_s"]) == 1 and abs(slip["events_s"][0] - slip["true_slip_s"]) < 0.25,
        "orientation_total_rmse_deg": {k: v["total_rmse_deg"] for k, v in orientation["methods"].items()},
    }
