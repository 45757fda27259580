"""The field's joint-centre methods side by side on the same seeded sessions (issue 16, part 4).

    .venv/bin/python studies/methods.py [--seeds 5] [--duration 20] [--json studies/results/methods.json]

Conditions (models, presets, motions) are in ``studies/methods.toml``. For each condition and
seed one session is simulated; every method of :data:`calibration.methods.JOINT_METHODS`
(O'Brien, SCoRE, SARA, the two sphere fits) fits every joint of the TRUE hierarchy from the
measured poses, and Seel's inertial method (:func:`calibration.methods.estimate_inertial`) from
the measured gyroscopes and accelerometers of the same two sensors. Measured per joint and method:

- joint-centre error: ``|estimate - truth|`` in the parent and in the child sensor frame, mm
  (both pooled in the summary); for a fit that returns an axis (SARA always: on a ball joint its
  "axis" is the motion's weakest direction and its point the minimum-norm one, not the centre)
  also the truth's distance from that axis ("off-axis"), which is what SARA recovers;
- limb-length error: every distance between two joint centres of one segment in its sensor frame
  (:func:`calibration.skeleton.segment_lengths`) against the true one, mm;
- run time of the fit, ms (BLAS on one thread);
- for O'Brien (plain, and corrected for the rotations' noise: ``obrien-eiv``): whether the 95 %
  region of :func:`calibration.uncertainty.joint_covariance`
  (batch means and iid) holds the truth (its determined part, for a fit that found a hinge), in
  each frame; the coverage is the share of regions that do.

Positions are multiplied by the tracker's unit scale (known here; ``simbench scale`` measures it)
so that every method works in metres. A fit that raises counts as a failure and its errors are
left out (the count is reported).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shlex
import sys
import tempfile
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import simbench as sb
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hierarchy import hierarchy_from_parents
from calibration.methods import JOINT_METHODS, JointEstimate, estimate_inertial
from calibration.skeleton import joint_name, segment_lengths
from calibration.uncertainty import holds_truth, joint_covariance
from simbench.errors import load_toml
from simbench.experiments.pool import one_blas_thread, worker_pool
from simbench.io.atomic import atomic_write_text
from simbench.io.dataset import Dataset
from simbench.sim.programs import HUMANOID_MOTION
from simbench.sim.sensor_config import PRESETS_DIR, parse_sensor_config
from simbench.versions import software_versions

HERE = Path(__file__).resolve().parent
CONFIG = HERE / "methods.toml"
RATE_HZ = 120.0

#: The methods in table order: the pose-based registry, then Seel's inertial estimator.
METHODS = (*JOINT_METHODS, "inertial")

#: The O'Brien fit's covariance estimators whose 95 % regions are checked.
COVERAGE_METHODS = ("batch-means", "iid")

#: What is recorded of each region: whether each estimator's holds the truth, and whether the
#: batch-means region is bounded at all (its degrees of freedom at least the dimension; with
#: fewer blocks than that the region is all of space and holds the truth trivially).
REGION_KEYS = (*COVERAGE_METHODS, "bounded")

#: The methods whose fit is a :class:`calibration.joint.JointFit`, so that
#: :func:`calibration.uncertainty.joint_covariance` gives their regions: O'Brien's plain least
#: squares and the same corrected for the rotations' noise.
COVERED = ("obrien", "obrien-eiv")


def load_config(path: Path = CONFIG) -> dict:
    """The study file: ``{"condition": [...], "slip": {...}, "small_range": {...}}``."""
    return load_toml(path)


def small_range_program(cfg: dict, duration_s: float, seed: int) -> str:
    """The small-range user program (TOML text): every humanoid joint at once, ``amplitude_scale``
    of the exercise's amplitudes, seeded frequencies and phases (``[small_range]`` of the study file)."""
    rng = np.random.default_rng(seed)
    lines = [
        'name = "small range"',
        f'root = "{cfg["root"]}"',
        "[[phase]]",
        "start_s = 0.0",
        f"end_s = {duration_s}",
    ]
    for joint, (amp, _offset, _primary) in HUMANOID_MOTION.items():
        a = cfg["amplitude_scale"] * np.asarray(amp)
        f = rng.uniform(cfg["frequency_min_hz"], cfg["frequency_max_hz"], 3)
        ph = rng.uniform(0.0, 2 * np.pi, 3)
        lines += [
            f"[phase.joints.{joint}]",
            f"amplitude_rad = [{', '.join(f'{x:.6f}' for x in a)}]",
            f"frequency_hz = [{', '.join(f'{x:.6f}' for x in f)}]",
            f"phase_rad = [{', '.join(f'{x:.6f}' for x in ph)}]",
        ]
    return "\n".join(lines) + "\n"


def simulate(condition: dict, cfg: dict, duration_s: float, seed: int, workdir: Path) -> Dataset:
    """One session of a condition of the study file."""
    sensors = condition["sensors"]
    if sensors == "slip":
        doc = load_toml(PRESETS_DIR / f"{cfg['slip']['slip_base']}.toml")
        doc.setdefault("skin", {})["slip"] = [
            {"sensor": e["sensor"], "time_s": e["time_fraction"] * duration_s, "offset_m": e["offset_m"]}
            for e in cfg["slip"]["event"]
        ]
        sensors = parse_sensor_config(doc, f"{cfg['slip']['slip_base']} with slips")
    motion = condition["motion"]
    if motion == "small-range":
        path = workdir / f"small_range_{seed}.toml"
        path.write_text(small_range_program(cfg["small_range"], duration_s, seed))
        motion = str(path)
    return sb.simulate(
        model=condition["model"],
        motion=motion,
        duration_s=duration_s,
        rate_hz=RATE_HZ,
        seed=seed,
        sensors=sensors,
    )


def _timed(fn, *args, **kwargs) -> tuple[JointEstimate | None, float, str | None]:
    """Run one fit: its estimate (``None`` if it raised), time in ms, the error message."""
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est = fn(*args, **kwargs)
        return est, 1e3 * (time.perf_counter() - t0), None
    except (CalibrationError, CalibrationInputError) as err:
        return None, 1e3 * (time.perf_counter() - t0), f"{type(err).__name__}: {err}"


def _coverage(Rp, pp, Rc, pc, valid, est: JointEstimate, tp: np.ndarray, tc: np.ndarray) -> dict:
    """Whether each covariance estimator's 95 % region holds the truth, per frame, and whether the
    batch-means region is bounded (``"bounded"``)."""
    out = {}
    for method in COVERAGE_METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            unc = joint_covariance(Rp, pp, Rc, pc, est.fit, valid=valid, method=method)
        parent, child = holds_truth(unc, tp, tc)
        out[method] = {"parent": parent, "child": child}
        if method == "batch-means":
            out["bounded"] = {
                part: bool(np.isfinite(unc.region(part).threshold)) for part in ("parent", "child")
            }
    return out


def _line_distance(point: np.ndarray, on_line: np.ndarray, direction: np.ndarray) -> float:
    """Distance from ``point`` to the line through ``on_line`` along ``direction``, metres."""
    d = point - on_line
    u = direction / np.linalg.norm(direction)
    return float(np.linalg.norm(d - (d @ u) * u))


def evaluate_session(ds: Dataset) -> dict:
    """Every method on every joint of one session's true hierarchy, against the truth.

    Returns:
        ``{"joints": [J names], "length_pairs": [L x [segment, joint_a, joint_b]], "methods":
        {method: {...}}}``, per method ``(J,)`` lists ``"error_parent_mm"``, ``"error_child_mm"``,
        ``"axis_distance_parent_mm"``, ``"axis_distance_child_mm"`` (the truth's distance from the
        fitted axis; NaN for a fit without one), ``"time_ms"``, an ``(L,)`` list
        ``"length_error_mm"`` (NaN where a joint failed), ``"failures"`` ``{joint: message}``
        (errors NaN there) and, for the methods of :data:`COVERED`, ``"coverage"``
        ``{estimator: {"parent": (J,) bool, "child": (J,) bool}}`` (``None`` where the fit failed).
    """
    names = ds.sensors
    joints = hierarchy_from_parents(ds.truth.parent_of, names).joints
    n = len(joints)
    true_p, true_c = ds.truth_joint_arrays()  # (N, 3) by child sensor
    poses = ds.poses()
    R = poses.R_w_s
    p = poses.p_w_s * ds.position_unit_scale  # metres
    imu = ds.imu()
    keys = (
        "error_parent_mm",
        "error_child_mm",
        "axis_distance_parent_mm",
        "axis_distance_child_mm",
        "time_ms",
    )
    cols = {m: {k: np.full(n, np.nan) for k in keys} for m in METHODS}
    est_p = {m: np.full((n, 3), np.nan) for m in METHODS}
    est_c = {m: np.full((n, 3), np.nan) for m in METHODS}
    failures: dict[str, dict[str, str]] = {m: {} for m in METHODS}
    coverage: dict[str, dict[str, dict[str, list]]] = {
        m: {c: {"parent": [], "child": []} for c in REGION_KEYS} for m in COVERED
    }
    joint_names = [joint_name(names[a], names[b]) for a, b in joints]
    for k, (a, b) in enumerate(joints):
        valid = poses.valid[:, a] & poses.valid[:, b]
        args = (R[:, a], p[:, a], R[:, b], p[:, b])
        tp, tc = true_p[b], true_c[b]
        for method in METHODS:
            if method == "inertial":
                ok = imu.valid[:, a] & imu.valid[:, b]
                w_f = (imu.gyro[:, a], imu.gyro[:, b], imu.acc[:, a], imu.acc[:, b])
                est, ms, failure = _timed(estimate_inertial, *w_f, rate_hz=imu.rate_hz, valid=ok)
            else:
                est, ms, failure = _timed(JOINT_METHODS[method], *args, valid=valid)
            col = cols[method]
            col["time_ms"][k] = ms
            if est is None:
                failures[method][joint_names[k]] = str(failure)
                if method in COVERED:
                    for c in REGION_KEYS:
                        coverage[method][c]["parent"].append(None)
                        coverage[method][c]["child"].append(None)
                continue
            est_p[method][k], est_c[method][k] = est.joint_in_parent, est.joint_in_child
            col["error_parent_mm"][k] = 1e3 * np.linalg.norm(est.joint_in_parent - tp)
            col["error_child_mm"][k] = 1e3 * np.linalg.norm(est.joint_in_child - tc)
            if est.axis_in_parent is not None and est.axis_in_child is not None:
                col["axis_distance_parent_mm"][k] = 1e3 * _line_distance(
                    tp, est.joint_in_parent, est.axis_in_parent
                )
                col["axis_distance_child_mm"][k] = 1e3 * _line_distance(
                    tc, est.joint_in_child, est.axis_in_child
                )
            if method in COVERED:
                for c, by_frame in _coverage(*args, valid, est, tp, tc).items():
                    coverage[method][c]["parent"].append(by_frame["parent"])
                    coverage[method][c]["child"].append(by_frame["child"])
    children = [b for _, b in joints]
    truth_lengths = segment_lengths(names, joints, true_p[children], true_c[children])
    out: dict = {
        "joints": joint_names,
        "length_pairs": [[s.segment, s.joint_a, s.joint_b] for s in truth_lengths],
        "methods": {},
    }
    for method in METHODS:
        lengths = segment_lengths(names, joints, est_p[method], est_c[method])
        row: dict = {k: [float(x) for x in v] for k, v in cols[method].items()}
        row["length_error_mm"] = [
            1e3 * abs(s.length - t.length) for s, t in zip(lengths, truth_lengths, strict=True)
        ]
        row["failures"] = failures[method]
        if method in COVERED:
            row["coverage"] = coverage[method]
        out["methods"][method] = row
    return out


def summarise(trials: Sequence[dict]) -> dict:
    """Pool the trials of one condition: per method median and 90th percentile of the joint-centre
    error (both frames), of the truth's distance from the fitted axis (fits with an axis) and of the
    length error, median time, coverage, failures."""
    out = {}
    for method in METHODS:
        rows = [trial["methods"][method] for trial in trials]

        def pooled(*keys: str, rows: list[dict] = rows) -> np.ndarray:
            x = np.concatenate([np.asarray(r[k], dtype=float) for r in rows for k in keys])
            return x[np.isfinite(x)]

        times = pooled("time_ms")
        summary: dict = {
            "joint_error_mm": _quantiles(pooled("error_parent_mm", "error_child_mm")),
            "axis_distance_mm": _quantiles(pooled("axis_distance_parent_mm", "axis_distance_child_mm")),
            "length_error_mm": _quantiles(pooled("length_error_mm")),
            "time_ms": float(np.median(times)) if times.size else math.nan,
            "coverage95": None,
            "n_fits": int(times.size),
            "failures": sum(len(r["failures"]) for r in rows),
        }
        if method in COVERED:
            hits = {
                c: [h for r in rows for part in ("parent", "child") for h in r["coverage"][c][part]]
                for c in REGION_KEYS
            }
            summary["coverage95"] = {c: _share(h) for c, h in hits.items()}
            summary["coverage95"]["regions"] = sum(h is not None for h in hits[COVERAGE_METHODS[0]])
        out[method] = summary
    return out


def _share(hits: list) -> float:
    """The share of True among the regions that exist (``None``: the fit failed)."""
    known = [h for h in hits if h is not None]
    return float(np.mean(known)) if known else math.nan


def _quantiles(x: np.ndarray) -> dict[str, float]:
    if x.size == 0:
        return {"median": math.nan, "p90": math.nan, "n": 0}
    return {"median": float(np.median(x)), "p90": float(np.quantile(x, 0.9)), "n": int(x.size)}


def run_study(
    seeds: Sequence[int],
    duration_s: float,
    *,
    conditions: Sequence[str] | None = None,
    config: dict | None = None,
    workers: int = 1,
    keep_trials: bool = True,
) -> dict:
    """Every condition (all, or those named) for every seed: the JSON document of the study.

    Returns:
        ``{"study", "versions", "config": {"seeds", "duration_s", "rate_hz", "methods",
        "conditions", "slip", "small_range"}, "summary": {condition: {method: ...}},
        "trials": {condition: [{"seed", "frames", "joints", "length_pairs", "methods"}]}}``
        (a trial as :func:`evaluate_session` gives it; ``{}`` without ``keep_trials``). The
        sessions are independent: ``workers > 1`` runs them on a process pool, with the same
        output.
    """
    cfg = load_config() if config is None else config
    chosen = [c for c in cfg["condition"] if conditions is None or c["name"] in conditions]
    if conditions is not None and len(chosen) != len(conditions):
        known = [c["name"] for c in cfg["condition"]]
        raise ValueError(f"unknown conditions {sorted(set(conditions) - set(known))}; known: {known}")
    doc: dict = {
        "study": "methods",
        "versions": software_versions(),
        "config": {
            "seeds": [int(s) for s in seeds],
            "duration_s": float(duration_s),
            "rate_hz": RATE_HZ,
            "methods": list(METHODS),
            "coverage_methods": list(COVERAGE_METHODS),
            "conditions": chosen,
            "slip": cfg.get("slip"),
            "small_range": cfg.get("small_range"),
        },
        "summary": {},
        "trials": {},
    }
    jobs = [(condition, cfg, float(duration_s), int(seed)) for condition in chosen for seed in seeds]
    if workers > 1:
        with worker_pool(workers) as pool:
            done = list(pool.map(_trial, jobs, chunksize=4))
    else:
        done = list(map(_trial, jobs))
    for i, condition in enumerate(chosen):
        trials = done[i * len(seeds) : (i + 1) * len(seeds)]
        if keep_trials:
            doc["trials"][condition["name"]] = trials
        doc["summary"][condition["name"]] = summarise(trials)
    return doc


def _trial(job: tuple[dict, dict, float, int]) -> dict:
    """One condition's session for one seed, every method on it (BLAS on one thread)."""
    condition, cfg, duration_s, seed = job
    with tempfile.TemporaryDirectory() as tmp, one_blas_thread():
        ds = simulate(condition, cfg, duration_s, seed, Path(tmp))
        return {"seed": seed, "frames": int(ds.time_s.size), **evaluate_session(ds)}


def table(doc: dict) -> str:
    """The summary as a Markdown table (condition x method)."""
    head = (
        "| condition | method | centre median mm | centre p90 mm | off-axis median mm | length median mm "
        "| length p90 mm | time ms | coverage 95 % (batch means / iid; bounded) | failures |"
    )
    rows = [head, "|" + "---|" * 10]
    for cond, by_method in doc["summary"].items():
        for method, s in by_method.items():
            cov = s["coverage95"]
            cov_text = (
                ""
                if cov is None
                else f"{_pct(cov['batch-means'])} / {_pct(cov['iid'])}; {_pct(cov.get('bounded', math.nan))}"
            )
            rows.append(
                f"| {cond} | {method} "
                f"| {_num(s['joint_error_mm']['median'])} | {_num(s['joint_error_mm']['p90'])} "
                f"| {_num(s['axis_distance_mm']['median'])} "
                f"| {_num(s['length_error_mm']['median'])} | {_num(s['length_error_mm']['p90'])} "
                f"| {s['time_ms']:.2f} | {cov_text} | {s['failures']}/{s['n_fits']} |"
            )
    return "\n".join(rows)


def _num(x: float) -> str:
    if not math.isfinite(x):
        return "-"
    return f"{x:.3g}" if x < 0.01 else f"{x:.2f}"


def _pct(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.0f} %"


def _json_safe(x, digits: int = 4):
    """``x`` with every float rounded to ``digits`` significant digits and NaN as ``None``."""
    if isinstance(x, float):
        return float(f"{x:.{digits}g}") if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _json_safe(v, digits) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v, digits) for v in x]
    return x


def json_text(doc: dict) -> str:
    """The study's JSON: strict (NaN as ``null``), 4 significant digits, lists of numbers or names
    on one line."""
    text = json.dumps(_json_safe(doc), indent=1, allow_nan=False)
    return (
        re.sub(
            r"\[[^\[\]{}]*\]",
            lambda m: re.sub(r"\s*\n\s*", " ", m.group()).replace("[ ", "[").replace(" ]", "]"),
            text,
        )
        + "\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds 1..N per condition")
    parser.add_argument("--duration", type=float, default=20.0, help="session length, s")
    parser.add_argument("--condition", action="append", help="run only this condition (repeatable)")
    parser.add_argument("--json", metavar="OUT")
    parser.add_argument("--workers", type=int, default=1, help="processes (the sessions are independent)")
    parser.add_argument(
        "--summary-only", action="store_true", help="leave the per-trial detail out of the JSON"
    )
    args = parser.parse_args()
    t0 = time.perf_counter()
    doc = run_study(
        range(1, args.seeds + 1),
        args.duration,
        conditions=args.condition,
        workers=args.workers,
        keep_trials=not args.summary_only,
    )
    doc["seconds"] = time.perf_counter() - t0
    doc["command"] = shlex.join(["studies/methods.py", *sys.argv[1:]])
    print(table(doc))
    print(f"\n{args.seeds} seeds x {args.duration:g} s per condition; {doc['seconds']:.0f} s in all")
    if args.json:
        atomic_write_text(args.json, json_text(doc))


if __name__ == "__main__":
    main()
