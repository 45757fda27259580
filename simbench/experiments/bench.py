"""``simbench bench``: every estimator on the benchmark suite, summed up in a scorecard.

**Runs.** Each (scenario, seed) of the suite (:mod:`simbench.experiments.suite`) is simulated once
and every estimator of the scenario's kind runs on that dataset: one job per scenario-seed, on a
local process pool or any ``concurrent.futures.Executor`` (a Dask cluster). Estimators travel to the
workers as spec strings and are resolved there. An estimator that raises on a dataset (any
``Exception``: :class:`simbench.estimators.EstimatorError`, ``InputError``, ``CalibrationError``, a
user's own) is a *failure* of that (estimator, scenario, seed), its message kept; the run goes on.

**Metrics** (lower is better, SI units in their names): joints scenarios
``joint_centre_error_m`` and ``limb_length_error_m`` (:func:`metrics.joint_method_metrics`, the true
hierarchy given to estimators that take one), orientation scenarios ``orientation_rmse_deg``
(the true skeleton given to estimators that take one, on simulated scenarios)
(:func:`metrics.orientation_metrics`' ``total_rmse_deg``). A metric that is not finite (every
joint left out) counts as a failure for that metric.

**Summary.** Per (estimator, scenario, metric): the median over seeds and its 95 % interval by a
percentile bootstrap over seeds (:data:`BOOTSTRAP` resamples, ``numpy.random.default_rng`` seeded
with :data:`BOOTSTRAP_SEED`; ``[median, median]`` with fewer than two seeds). With five seeds the
bootstrap's interval is narrower than the median's true 95 % interval (the resampled medians are
among the five values); it is a description, not a test: the tests are the comparisons.

**Comparisons.** Per scenario and metric, paired over the seeds both estimators completed: each
user estimator against each built-in, and each built-in against the scenario's best (lowest
median). The test (:data:`TEST`) is a two-sided paired t-test on the log of the errors (their
ratio), at level :data:`ALPHA`, not corrected for the number of comparisons: the exact Wilcoxon
signed-rank test cannot reach 0.05 two-sided with five seeds (its smallest p is 0.0625). Log-ratios
smaller than :data:`TIE` are ties (zero), so an estimator that repeats another's figures to the last
bit, or nearly, is never "significantly" different from it.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, as_completed
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simbench.errors import InputError, read_text
from simbench.estimators import TIME_LIMIT_S, names, resolve
from simbench.estimators.command import PREFIX
from simbench.experiments import suite
from simbench.experiments.metrics import joint_method_metrics, orientation_metrics, true_skeleton
from simbench.experiments.pool import one_blas_thread, worker_pool
from simbench.io.atomic import atomic_write_text
from simbench.report.markdown import markdown_table, markdown_to_html
from simbench.versions import __version__, software_versions

#: The metrics of each kind of scenario, the first ranking the estimators (all lower is better).
METRICS: dict[str, tuple[str, ...]] = {
    "joints": ("joint_centre_error_m", "limb_length_error_m"),
    "orientation": ("orientation_rmse_deg",),
}

#: What each metric is.
METRIC_HELP = {
    "joint_centre_error_m": "mean distance of estimated from true joint centres (parent frame), m",
    "limb_length_error_m": "mean absolute limb-length error, m",
    "orientation_rmse_deg": "orientation RMSE over every sensor and sample, degrees",
}

#: The kinds ``--kind`` takes.
KIND_CHOICES = ("joints", "orientation", "all")

#: The fewest paired seeds a comparison is tested on (a p of NaN below: two seeds' t-test has
#: one degree of freedom and calls two nearly equal ratios significant).
MIN_PAIRS = 3
#: Significance level of the comparisons.
ALPHA = 0.05
#: The comparisons' test, as the scorecard and report state it.
TEST = (
    "paired t-test on the log of the errors (log a - log b per seed), two-sided, level 0.05, over "
    f"the seeds both estimators completed (at least {MIN_PAIRS}); not corrected for multiple comparisons"
)
#: Log-ratios below this are ties (numerically the same figure).
TIE = 1e-9
#: Errors are floored here before their log (an exact zero error), in the metric's unit.
LOG_FLOOR = 1e-12

#: Bootstrap resamples of the median's interval, and the generator's seed.
BOOTSTRAP = 2000
BOOTSTRAP_SEED = 20240601
#: The interval's method, as the scorecard states it.
CI_METHOD = (
    f"percentile bootstrap over seeds, {BOOTSTRAP} resamples, numpy default_rng({BOOTSTRAP_SEED}); "
    "[median, median] with fewer than 2 seeds"
)

#: How many distinct failure messages a row keeps, and how long each may be (characters).
ERRORS_KEPT = 3
ERROR_CHARS = 500

#: The seed a real recording's one run is filed under (it has no seeds: n is 1, and no comparison
#: is tested on it).
REAL_SEED = 0

#: The scorecard's file name in the output folder.
SCORECARD = "scorecard.json"


@dataclass(frozen=True)
class BenchEstimator:
    """One estimator of a bench run.

    Attributes:
        name: how rows name it: a built-in's name, or the user's spec as given.
        kind: ``joints`` or ``orientation``.
        spec: what a worker resolves (a file's path made absolute: workers may run elsewhere).
        builtin: one of simbench's own (a user's gets the run's time limit).
    """

    name: str
    kind: str
    spec: str
    builtin: bool


def _worker_spec(spec: str) -> str:
    """``spec`` with a ``path/file.py:function``'s path made absolute."""
    if spec.startswith(PREFIX) or ":" not in spec:
        return spec
    where, attr = spec.rsplit(":", 1)
    if where.endswith(".py") or "/" in where or "\\" in where:
        return f"{Path(where).expanduser().resolve()}:{attr}"
    return spec


def plan_estimators(
    specs: Sequence[str], kinds: Sequence[str], builtins: Sequence[str] | None = None
) -> tuple[BenchEstimator, ...]:
    """The built-ins of ``kinds`` (all, or those named in ``builtins``), then the user's specs,
    each resolved once here so that a bad one stops the run before any work.

    Raises:
        InputError: a spec that cannot be resolved (named), or one of a kind the run has no
            scenario of.
    """
    out: list[BenchEstimator] = []
    for kind in kinds:
        for name in names(kind, plugins=False):
            if builtins is None or name in builtins:
                out.append(BenchEstimator(name, kind, name, True))
    seen = {e.name for e in out}
    for spec in specs:
        spec = spec.strip() if isinstance(spec, str) else spec
        if spec in seen:
            continue
        est = resolve(spec)
        if est.kind not in kinds:
            raise InputError(
                f"estimator {spec!r} estimates {est.kind}; this run has only {', '.join(kinds)} scenarios "
                "(--kind)"
            )
        out.append(BenchEstimator(spec, est.kind, _worker_spec(spec), est.origin == "builtin"))
        seen.add(spec)
    return tuple(out)


@dataclass(frozen=True)
class Job:
    """One scenario-seed and the estimators to run on its dataset (picklable: names and specs)."""

    scenario: str
    seed: int
    estimators: tuple[BenchEstimator, ...]
    time_limit_s: float


def _message(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if not text.startswith("estimator "):
        text = f"{type(exc).__name__}: {text}"
    return text[:ERROR_CHARS]


def run_job(job: Job) -> dict[str, Any]:
    """Simulate one seed of a scenario and run every estimator on it.

    Returns:
        ``{"scenario", "seed", "simulate_s", "results"}``, ``results`` one dict per estimator:
        ``estimator``, ``metrics`` (``{metric: value}`` in the metric's unit; empty on failure),
        ``error`` (the message, or ``None``), ``joints_left_out`` (joints a joints estimator did
        not return, left out of its means) and ``run_time_s``.
    """
    with one_blas_thread():
        t0 = time.perf_counter()
        sc = suite.scenario(job.scenario)
        ds = suite.scenario_dataset(sc, job.seed)
        simulate_s = time.perf_counter() - t0
        # an orientation estimator that takes a skeleton is given the true one where the truth
        # scores it, as a joints estimator is given the true tree (a real recording has none)
        skeleton = true_skeleton(ds) if sc.kind == "orientation" and not sc.real else None
        results = []
        for est in job.estimators:
            t1 = time.perf_counter()
            limit = None if est.builtin else float(job.time_limit_s)
            row: dict[str, Any] = {"estimator": est.name, "metrics": {}, "error": None, "joints_left_out": 0}
            try:
                if sc.kind == "joints":
                    got = joint_method_metrics(ds, resolve(est.spec, "joints"), time_limit_s=limit)
                    row["metrics"] = {m: float(got[m]) for m in METRICS["joints"]}
                    row["joints_left_out"] = int(got["failed_joints"])
                else:
                    got = orientation_metrics(
                        ds, resolve(est.spec, "orientation"), time_limit_s=limit, skeleton=skeleton
                    )
                    row["metrics"] = {"orientation_rmse_deg": float(got["total_rmse_deg"])}
            except Exception as exc:  # any failure of an estimator on this dataset: kept, the run goes on
                row["metrics"] = {}
                row["error"] = _message(exc)
            row["run_time_s"] = time.perf_counter() - t1
            results.append(row)
    return {"scenario": job.scenario, "seed": job.seed, "simulate_s": simulate_s, "results": results}


def _kinds(kind: str) -> tuple[str, ...]:
    if kind not in KIND_CHOICES:
        raise InputError(f"kind must be one of {list(KIND_CHOICES)}, got {kind!r}")
    return ("joints", "orientation") if kind == "all" else (kind,)


def select_scenarios(
    kind: str = "all", quick: bool = False, scenarios: Sequence[str] | None = None
) -> tuple[suite.SuiteScenario, ...]:
    """The suite's scenarios of ``kind`` (``all``: both), only the quick ones with ``quick``, only
    those named in ``scenarios`` if given (in the suite's order).

    Raises:
        InputError: an unknown kind or scenario name.
    """
    kinds = _kinds(kind)
    for name in scenarios or ():
        suite.scenario(name)
    return tuple(
        sc
        for sc in suite.SCENARIOS
        if sc.kind in kinds and (sc.quick or not quick) and (scenarios is None or sc.name in scenarios)
    )


def run_bench(
    specs: Sequence[str] = (),
    *,
    kind: str = "all",
    quick: bool = False,
    executor: Executor | None = None,
    workers: int = 1,
    time_limit_s: float = TIME_LIMIT_S,
    progress: Callable[[int, int], None] | None = None,
    scenarios: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    builtins: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Run the suite and return its scorecard (:func:`summarise`).

    Args:
        specs: the user's estimators (any spec :func:`simbench.estimators.resolve` takes); each runs
            on the scenarios of its own kind, beside every built-in of that kind.
        kind: ``joints``, ``orientation`` or ``all``.
        quick: the quick scenarios over the first :data:`suite.QUICK_SEEDS` seeds.
        executor: where the jobs run; default a local process pool of ``workers``.
        workers: size of the default pool.
        time_limit_s: a command estimator's time limit per dataset, s.
        progress: called with ``(done, total)`` jobs as they finish.
        scenarios, seeds, builtins: a subset of the suite's scenarios, seeds and built-ins (tests).

    Raises:
        InputError: a bad spec, kind, scenario or time limit, before any work.
    """
    if not (isinstance(time_limit_s, int | float) and math.isfinite(time_limit_s) and time_limit_s > 0):
        raise InputError(f"time limit: expected a number of seconds > 0, got {time_limit_s!r}")
    chosen = select_scenarios(kind, quick, scenarios)
    kinds = tuple(k for k in _kinds(kind) if any(sc.kind == k for sc in chosen)) or _kinds(kind)
    estimators = plan_estimators(specs, _kinds(kind), builtins)
    if seeds is None:
        seeds = suite.SEEDS[: suite.QUICK_SEEDS] if quick else suite.SEEDS
    seeds = tuple(int(s) for s in seeds)
    jobs = [
        Job(sc.name, seed, tuple(e for e in estimators if e.kind == sc.kind), float(time_limit_s))
        for sc in chosen
        for seed in ((REAL_SEED,) if sc.real else seeds)  # a real recording is one, whatever the seed
    ]
    t0 = time.perf_counter()
    done: list[dict[str, Any]] = []
    with worker_pool(workers) if executor is None else nullcontext(executor) as pool:
        futures = []
        try:
            futures = [pool.submit(run_job, job) for job in jobs]
            for fut in as_completed(futures):
                done.append(fut.result())
                if progress:
                    progress(len(done), len(jobs))
        except BaseException:  # Ctrl-C, SIGTERM, an internal error: run no more
            if pool is executor:
                for fut in futures:
                    fut.cancel()
            raise
    order = {(j.scenario, j.seed): k for k, j in enumerate(jobs)}
    done.sort(key=lambda r: order[(r["scenario"], r["seed"])])
    card = summarise(done, chosen, estimators, seeds)
    card["quick"] = bool(quick)
    card["kinds"] = list(kinds)
    card["time_limit_s"] = float(time_limit_s)
    card["run_time_s"] = round(time.perf_counter() - t0, 3)
    return card


def median_ci(values: Sequence[float]) -> tuple[float, float, float]:
    """The median of ``values`` and its 95 % interval (:data:`CI_METHOD`); NaNs without values.

    Returns:
        ``(median, low, high)`` in the values' unit.
    """
    x = np.asarray(values, dtype=float)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    med = float(np.median(x))
    if x.size < 2:
        return med, med, med
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    meds = np.median(x[rng.integers(0, x.size, size=(BOOTSTRAP, x.size))], axis=1)
    low, high = np.quantile(meds, [0.025, 0.975])
    return med, float(min(low, med)), float(max(high, med))


def paired_test(a: Sequence[float], b: Sequence[float]) -> tuple[float, float]:
    """The paired comparison of two estimators' errors over the same seeds (:data:`TEST`).

    Args:
        a, b: ``(n,)`` errors, one per seed, in the same unit, paired by position.

    Returns:
        ``(median_difference, p_value)``: the median of ``a - b`` (the unit of the errors) and the
        two-sided p of the paired t-test on ``log a - log b`` (NaN with fewer than
        :data:`MIN_PAIRS` pairs; 1 when every pair ties, 0 when every pair differs by the same
        nonzero ratio).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.size == 0:
        return math.nan, math.nan
    diff = float(np.median(a - b))
    d = np.log(np.maximum(a, LOG_FLOOR)) - np.log(np.maximum(b, LOG_FLOOR))
    d[np.abs(d) < TIE] = 0.0
    if d.size < MIN_PAIRS:
        return diff, math.nan
    if np.ptp(d) == 0:
        return diff, 1.0 if d[0] == 0 else 0.0
    from scipy.stats import ttest_1samp

    return diff, float(ttest_1samp(d, 0.0).pvalue)


def _values(
    results: Sequence[Mapping[str, Any]], scenario: str, estimator: str, metric: str
) -> tuple[dict[int, float], list[str], int]:
    """``({seed: value}, failure messages, joints left out)`` of one estimator on one scenario."""
    values: dict[int, float] = {}
    errors: list[str] = []
    left_out = 0
    for job in results:
        if job["scenario"] != scenario:
            continue
        for r in job["results"]:
            if r["estimator"] != estimator:
                continue
            left_out += int(r.get("joints_left_out", 0))
            if r["error"] is not None:
                errors.append(r["error"])
                continue
            v = r["metrics"].get(metric, math.nan)
            if v is None or not math.isfinite(v):
                errors.append(f"estimator {estimator!r} gave no finite {metric} (every joint left out?)")
                continue
            values[int(job["seed"])] = float(v)
    return values, errors, left_out


def _num(x: float) -> float | None:
    """A number for JSON: NaN as ``None``."""
    return None if x is None or not math.isfinite(x) else float(x)


def summarise(
    results: Sequence[Mapping[str, Any]],
    scenarios: Sequence[suite.SuiteScenario],
    estimators: Sequence[BenchEstimator],
    seeds: Sequence[int],
) -> dict[str, Any]:
    """The scorecard of a run's results (:func:`run_job`'s dicts): rows, rankings, comparisons.

    Returns:
        A JSON-ready dict: ``suite_version``, ``simbench_version``, ``software``, ``seeds``,
        ``scenarios`` (name, kind, about, fingerprint), ``estimators`` (name, kind, builtin),
        ``metrics``, ``ci_method``, ``test`` and ``alpha``; ``rows`` one per (estimator, scenario,
        metric): ``estimator``, ``scenario``, ``metric``, ``median``, ``ci95`` ``[low, high]``
        (the metric's unit; ``None`` when every seed failed), ``n`` (seeds scored), ``failures``,
        ``errors`` (the first :data:`ERRORS_KEPT` distinct messages), ``joints_left_out``;
        ``rankings`` ``{scenario: [estimator, ...]}`` best first by the scenario's first metric
        (those without a median last); ``comparisons`` (:func:`compare`); ``results`` the raw
        figures per scenario, seed and estimator.
    """
    rows: list[dict[str, Any]] = []
    rankings: dict[str, list[str]] = {}
    comparisons: list[dict[str, Any]] = []
    for sc in scenarios:
        ests = [e for e in estimators if e.kind == sc.kind]
        per_metric: dict[str, dict[str, dict[int, float]]] = {}
        medians: dict[str, dict[str, float]] = {}
        for metric in METRICS[sc.kind]:
            per_metric[metric] = {}
            medians[metric] = {}
            for est in ests:
                values, errors, left_out = _values(results, sc.name, est.name, metric)
                med, low, high = median_ci([values[s] for s in sorted(values)])
                per_metric[metric][est.name] = values
                medians[metric][est.name] = med
                row = {
                    "estimator": est.name,
                    "scenario": sc.name,
                    "metric": metric,
                    "median": _num(med),
                    "ci95": [_num(low), _num(high)] if math.isfinite(med) else [None, None],
                    "n": len(values),
                    "failures": len(errors),
                    "errors": list(dict.fromkeys(errors))[:ERRORS_KEPT],
                }
                if sc.kind == "joints":
                    row["joints_left_out"] = left_out
                rows.append(row)
            comparisons += compare(sc.name, metric, ests, per_metric[metric], medians[metric])
        first = medians[METRICS[sc.kind][0]]
        rankings[sc.name] = sorted(
            (e.name for e in ests),
            key=lambda n: (not math.isfinite(first[n]), first[n] if math.isfinite(first[n]) else 0.0),
        )
    versions = software_versions()
    return {
        "suite_version": suite.SUITE_VERSION,
        "simbench_version": __version__,
        "software": versions,
        "seeds": [int(s) for s in seeds],
        "scenarios": [
            {
                "name": sc.name,
                "kind": sc.kind,
                "about": sc.about,
                "fingerprint": suite.scenario_fingerprint(sc),
            }
            for sc in scenarios
        ],
        "estimators": [{"name": e.name, "kind": e.kind, "builtin": e.builtin} for e in estimators],
        "metrics": {m: METRIC_HELP[m] for sc in scenarios for m in METRICS[sc.kind]},
        "ci_method": CI_METHOD,
        "test": TEST,
        "alpha": ALPHA,
        "rows": rows,
        "rankings": rankings,
        "comparisons": comparisons,
        "results": [
            {
                "scenario": job["scenario"],
                "seed": int(job["seed"]),
                "simulate_s": round(float(job["simulate_s"]), 3),
                "results": [
                    {
                        **r,
                        "metrics": {k: _num(v) for k, v in r["metrics"].items()},
                        "run_time_s": round(float(r["run_time_s"]), 3),
                    }
                    for r in job["results"]
                ],
            }
            for job in results
        ],
    }


def compare(
    scenario: str,
    metric: str,
    estimators: Sequence[BenchEstimator],
    values: Mapping[str, Mapping[int, float]],
    medians: Mapping[str, float],
) -> list[dict[str, Any]]:
    """The paired comparisons of one scenario and metric (:data:`TEST`): each user estimator
    against each built-in, then each built-in against the best (lowest median; a pair already
    compared is not repeated).

    Args:
        values: ``{estimator: {seed: value}}`` of the seeds each completed.
        medians: ``{estimator: median}`` (NaN when it completed none).

    Returns:
        Dicts of ``scenario``, ``metric``, ``a``, ``b``, ``n`` (paired seeds), ``median_difference``
        (median of a - b, the metric's unit), ``a_lower`` (seeds where a's error is lower),
        ``p_value`` and ``significant`` (p < :data:`ALPHA`).
    """
    builtin = [e.name for e in estimators if e.builtin]
    users = [e.name for e in estimators if not e.builtin]
    pairs = [(u, b) for u in users for b in builtin]
    scored = [e.name for e in estimators if math.isfinite(medians.get(e.name, math.nan))]
    if scored:
        best = min(scored, key=lambda n: medians[n])  # ties: the first listed
        done = {frozenset(p) for p in pairs}
        pairs += [(b, best) for b in builtin if b != best and frozenset((b, best)) not in done]
    out = []
    for a, b in pairs:
        seeds = sorted(set(values.get(a, {})) & set(values.get(b, {})))
        xa = [values[a][s] for s in seeds]
        xb = [values[b][s] for s in seeds]
        diff, p = paired_test(xa, xb)
        out.append(
            {
                "scenario": scenario,
                "metric": metric,
                "a": a,
                "b": b,
                "n": len(seeds),
                "median_difference": _num(diff),
                "a_lower": int(sum(x < y for x, y in zip(xa, xb, strict=True))),
                "p_value": _num(p),
                "significant": bool(math.isfinite(p) and p < ALPHA),
            }
        )
    return out


def comparable(a: Mapping[str, Any], b: Mapping[str, Any]) -> list[str]:
    """Why two scorecards cannot be compared figure by figure (empty: they can): another suite
    version, other seeds, or a scenario whose data differs (its fingerprint: session, seeds,
    simbench version) or that only one of them ran."""
    reasons = []
    if a.get("suite_version") != b.get("suite_version"):
        reasons.append(f"suite version {a.get('suite_version')} vs {b.get('suite_version')}")
    if list(a.get("seeds", [])) != list(b.get("seeds", [])):
        reasons.append(f"seeds {a.get('seeds')} vs {b.get('seeds')}")
    fa = {s["name"]: s["fingerprint"] for s in a.get("scenarios", [])}
    fb = {s["name"]: s["fingerprint"] for s in b.get("scenarios", [])}
    for name in fa.keys() | fb.keys():
        if name not in fb:
            reasons.append(f"scenario {name!r} only in the first")
        elif name not in fa:
            reasons.append(f"scenario {name!r} only in the second")
        elif fa[name] != fb[name]:
            reasons.append(f"scenario {name!r}: fingerprint {fa[name]} vs {fb[name]}")
    return sorted(reasons)


def load_scorecard(path: str | Path) -> dict[str, Any]:
    """A scorecard written by :func:`write_bench` (its file or its folder).

    Raises:
        InputError: not found, or not a scorecard.
    """
    path = Path(path)
    if path.is_dir():
        path = path / SCORECARD
    if not path.is_file():
        raise InputError(f"{path}: no such scorecard")
    text = read_text(path)  # unreadable or not UTF-8: named
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise InputError(f"{path}: not JSON: {exc}") from None
    if not isinstance(doc, dict) or "rows" not in doc or "suite_version" not in doc:
        raise InputError(f"{path}: not a simbench bench scorecard")
    return doc


def _shown(metric: str, x: float | None) -> str:
    """A figure in the report's unit: millimetres for metres, degrees as they are."""
    if x is None:
        return "-"
    return f"{x * 1000:.2f}" if metric.endswith("_m") else f"{x:.2f}"


def _unit(metric: str) -> str:
    return "mm" if metric.endswith("_m") else "deg"


def scorecard_markdown(card: Mapping[str, Any]) -> str:
    """The scorecard as a Markdown report: the medians with their intervals (scenario x
    estimator), each scenario's ranking, the significant differences, the failures, the suite's
    version and fingerprints."""
    rows = card["rows"]
    scenarios = [s["name"] for s in card["scenarios"]]
    by = {(r["scenario"], r["estimator"], r["metric"]): r for r in rows}
    lines = [
        "# simbench bench: scorecard",
        "",
        f"Suite version {card['suite_version']}, simbench {card['simbench_version']}; seeds "
        f"{', '.join(map(str, card['seeds']))}{' (quick)' if card.get('quick') else ''}; "
        f"run time {card.get('run_time_s', math.nan):.1f} s. Lower is better throughout.",
        "",
        f"Each cell is the median over seeds and its 95 % interval ({card['ci_method']}); "
        "`(k failed)` counts seeds on which the estimator failed.",
        "",
        "## Scenarios",
        "",
        markdown_table(
            ["scenario", "kind", "fingerprint", "about"],
            [[s["name"], s["kind"], f"`{s['fingerprint']}`", s["about"]] for s in card["scenarios"]],
        ),
    ]
    for kind in ("joints", "orientation"):
        scs = [s["name"] for s in card["scenarios"] if s["kind"] == kind]
        ests = [e["name"] for e in card["estimators"] if e["kind"] == kind]
        if not scs or not ests:
            continue
        for metric in METRICS[kind]:
            table = []
            for est in ests:
                cells: list[Any] = [f"`{est}`"]
                for sc in scs:
                    r = by.get((sc, est, metric))
                    if r is None:
                        cells.append("")
                        continue
                    if r["median"] is None:
                        cells.append(f"failed ({r['failures']}/{r['failures'] + r['n']})")
                        continue
                    low, high = r["ci95"]
                    text = f"{_shown(metric, r['median'])} [{_shown(metric, low)}, {_shown(metric, high)}]"
                    if r["failures"]:
                        text += f" ({r['failures']} failed)"
                    cells.append(text)
                table.append(cells)
            lines += [
                "",
                f"## {metric} ({_unit(metric)})",
                "",
                METRIC_HELP[metric] + ".",
                "",
                markdown_table(["estimator", *scs], table),
            ]
    lines += ["", "## Ranking", "", "By the median of each scenario's first metric, best first.", ""]
    for sc in card["scenarios"]:
        metric = METRICS[sc["kind"]][0]
        ranked = []
        for est in card["rankings"].get(sc["name"], []):
            med = by[(sc["name"], est, metric)]["median"]
            ranked.append(f"`{est}` {_shown(metric, med)}" if med is not None else f"`{est}` (failed)")
        lines.append(f"- **{sc['name']}** ({metric}, {_unit(metric)}): " + ", ".join(ranked))
    significant = [c for c in card["comparisons"] if c["significant"]]
    lines += [
        "",
        "## Significant differences",
        "",
        f"Test: {card['test']}. Compared: each user estimator with each built-in, each built-in "
        f"with the scenario's best. {len(significant)} of {len(card['comparisons'])} comparisons "
        f"are significant at {card['alpha']:g} (all are in `{SCORECARD}`).",
        "",
    ]
    if len(card["seeds"]) < MIN_PAIRS:
        lines += [
            f"With {len(card['seeds'])} seed(s) nothing is tested (at least {MIN_PAIRS} are needed).",
            "",
        ]
    if significant:
        lines.append(
            markdown_table(
                ["scenario", "metric", "a", "b", "median a - b", "a lower in", "p"],
                [
                    [
                        c["scenario"],
                        c["metric"],
                        f"`{c['a']}`",
                        f"`{c['b']}`",
                        f"{_shown(c['metric'], c['median_difference'])} {_unit(c['metric'])}",
                        f"{c['a_lower']} of {c['n']}",
                        f"{c['p_value']:.2g}",
                    ]
                    for c in significant
                ],
            )
        )
    else:
        lines.append("None.")
    failed = [r for r in rows if r["failures"] and r["metric"] == METRICS[_kind_of(card, r["scenario"])][0]]
    lines += ["", "## Failures", ""]
    if failed:
        for r in failed:
            first = r["errors"][0] if r["errors"] else ""
            lines.append(
                f"- `{r['estimator']}` on {r['scenario']}: {r['failures']} of {r['failures'] + r['n']} "
                f"seed(s) failed: {first}"
            )
    else:
        lines.append("None.")
    left = [r for r in rows if r.get("joints_left_out") and r["metric"] == METRICS["joints"][0]]
    if left:
        lines += ["", "Joints left out (not fitted; the means are over the rest):", ""]
        lines += [f"- `{r['estimator']}` on {r['scenario']}: {r['joints_left_out']}" for r in left]
    lines += ["", "## Run time", "", "Median seconds per dataset (the simulation not included).", ""]
    lines.append(markdown_table(["estimator", *scenarios], _run_times(card, scenarios)))
    return "\n".join(lines) + "\n"


def _run_times(card: Mapping[str, Any], scenarios: Sequence[str]) -> list[list[Any]]:
    """Rows of each estimator's median run time (s) per scenario; empty where it did not run."""
    times: dict[tuple[str, str], list[float]] = {}
    for job in card.get("results", []):
        for r in job["results"]:
            times.setdefault((r["estimator"], job["scenario"]), []).append(float(r["run_time_s"]))
    table = []
    for est in card["estimators"]:
        cells = [
            f"{float(np.median(times[(est['name'], sc)])):.2f}" if (est["name"], sc) in times else ""
            for sc in scenarios
        ]
        table.append([f"`{est['name']}`", *cells])
    return table


def _kind_of(card: Mapping[str, Any], scenario: str) -> str:
    return next(s["kind"] for s in card["scenarios"] if s["name"] == scenario)


def write_bench(card: Mapping[str, Any], out: str | Path) -> list[Path]:
    """Write ``out/scorecard.json``, ``out/index.md`` and ``out/index.html``, each atomically
    (``out`` is created; its parent must exist); returns their paths.

    Raises:
        InputError: ``out`` is a file, or its parent folder does not exist.
    """
    out = Path(out)
    check_out(out)
    out.mkdir(exist_ok=True)
    md = scorecard_markdown(card)
    paths = [out / SCORECARD, out / "index.md", out / "index.html"]
    atomic_write_text(paths[0], json.dumps(card, indent=1, allow_nan=False) + "\n")
    atomic_write_text(paths[1], md)
    atomic_write_text(paths[2], markdown_to_html(md, out, title="simbench bench: scorecard"))
    return paths


def check_out(out: str | Path) -> Path:
    """``out`` as a folder to write a scorecard in, refused before any work when it is a file or
    its parent folder does not exist.

    Raises:
        InputError: naming the path.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: expected a folder for the scorecard, got a file")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"--out {out}: folder {parent} does not exist")
    return out


__all__ = [
    "ALPHA",
    "METRICS",
    "SCORECARD",
    "TEST",
    "BenchEstimator",
    "check_out",
    "comparable",
    "compare",
    "load_scorecard",
    "median_ci",
    "paired_test",
    "plan_estimators",
    "run_bench",
    "run_job",
    "scorecard_markdown",
    "select_scenarios",
    "summarise",
    "write_bench",
]
