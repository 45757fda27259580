"""Accuracy regression: accepted figures for fixed seeded scenarios, and the check against them.

``reports/baseline.json`` holds, for every scenario, the accuracy figures accepted last time
(all "lower is better"). :func:`check` recomputes them and reports every figure that got worse
than ``baseline * (1 + rel_tol) + abs_tol``; ``simbench baseline`` runs the check (exit 1 on a
regression) and ``simbench baseline --update`` rewrites the file deliberately, printing the diff.

**Adding a scenario or an estimator.** A scenario is a seeded session (:class:`SessionConfig`)
plus the name of an estimator in :data:`ESTIMATORS`, a function ``dataset -> {metric: value}``
(lower is better). Append a :class:`Scenario` to :data:`SCENARIOS` (or register a new estimator
in :data:`ESTIMATORS` first), run ``simbench baseline --update`` and commit the new baseline.
Figures that are not one session's (a rate over several trials, the realism ratios) come from
:data:`FIGURES`, named functions ``() -> {metric: value}``; one that returns ``None`` could not be
computed here (the real recordings in ``../shared/data`` are missing) and is skipped by
:func:`compare`, which says so.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simbench.errors import InputError, load_toml, not_utf8
from simbench.estimators import TIME_LIMIT_S, names, resolve
from simbench.experiments.metrics import calibration_metrics, joint_method_metrics, orientation_metrics
from simbench.experiments.realism import realism_ratios, run_realism
from simbench.experiments.walk_hierarchy import walk_trial
from simbench.io.atomic import atomic_write_text
from simbench.io.dataset import Dataset
from simbench.io.examples import packaged_baseline
from simbench.sim.session import SessionConfig, load_session_model, run_session

#: The checkout's accepted figures (``simbench baseline --update`` rewrites them there).
CHECKOUT_BASELINE = Path(__file__).resolve().parents[2] / "reports" / "baseline.json"
#: The accepted figures checked by default: the checkout's, or an installed copy's packaged ones.
BASELINE_FILE = CHECKOUT_BASELINE if CHECKOUT_BASELINE.is_file() else packaged_baseline()
REL_TOL = 0.10

#: Absolute slack per metric unit suffix, added to the relative tolerance.
ABS_TOL = {"_cm": 0.05, "_deg": 0.05, "_wrong": 0.0, "_log_ratio": 0.05, "_fraction": 0.0}


def _calibration_metrics(ds: Dataset) -> dict[str, float]:
    m = calibration_metrics(ds)
    return {
        "max_length_error_cm": m["max_limb_length_error_m"] * 100,
        "mean_length_error_cm": m["limb_length_error_m"] * 100,
        "hierarchy_wrong": 1.0 - m["hierarchy_correct"],
    }


def _orientation_metrics(method: str) -> Callable[[Dataset], dict[str, float]]:
    def metrics(ds: Dataset) -> dict[str, float]:
        m = orientation_metrics(ds, method, time_limit_s=TIME_LIMIT_S)
        return {"total_rmse_deg": m["total_rmse_deg"], "heading_rmse_deg": m["heading_rmse_deg"]}

    return metrics


#: The joint-centre methods the baseline holds to their figures: every pose-based built-in but
#: SARA, whose centre on a ball joint is an arbitrary point of an arbitrary axis (its figure would
#: be no accuracy).
BASELINE_JOINT_METHODS = tuple(
    n for n in names("joints", plugins=False) if resolve(n).data == "poses" and n != "sara"
)


def _joint_methods_metrics(ds: Dataset) -> dict[str, float]:
    out = {}
    for method in BASELINE_JOINT_METHODS:
        m = joint_method_metrics(ds, method)
        out[f"{method}_centre_error_cm"] = m["joint_centre_error_m"] * 100
        out[f"{method}_length_error_cm"] = m["limb_length_error_m"] * 100
    return out


#: Estimators by name: ``dataset -> {metric: value}``, lower is better.
ESTIMATORS: dict[str, Callable[[Dataset], dict[str, float]]] = {
    "calibration": _calibration_metrics,
    "orientation:fontaine": _orientation_metrics("fontaine"),
    "orientation:triad": _orientation_metrics("triad"),
    "joint-methods": _joint_methods_metrics,
}


@dataclass(frozen=True)
class Scenario:
    """A seeded session and the estimator scored on it."""

    name: str
    estimator: str
    config: SessionConfig = field(default_factory=SessionConfig)


SCENARIOS: list[Scenario] = [
    Scenario(
        "linkage-flock-exercise",
        "calibration",
        SessionConfig(model="linkage", motion="exercise", duration_s=20.0, seed=1, sensors="ascension-flock"),
    ),
    Scenario(
        "linkage-paper-exercise",
        "calibration",
        SessionConfig(
            model="linkage", motion="exercise", duration_s=20.0, seed=1, sensors="ascension-flock-paper"
        ),
    ),
    Scenario(
        "humanoid-skin-exercise",
        "calibration",
        SessionConfig(
            model="humanoid", motion="exercise", duration_s=30.0, seed=101, sensors="skin-paper-human"
        ),
    ),
    Scenario(
        "linkage-polhemus-exercise-methods",
        "joint-methods",
        SessionConfig(
            model="linkage", motion="exercise", duration_s=20.0, seed=1, sensors="polhemus-liberty"
        ),
    ),
    Scenario(
        "humanoid-mems-static-fontaine",
        "orientation:fontaine",
        SessionConfig(model="humanoid", motion="static", duration_s=5.0, seed=5, sensors="mems-industrial"),
    ),
    Scenario(
        "humanoid-mems-exercise-triad",
        "orientation:triad",
        SessionConfig(
            model="humanoid", motion="exercise", duration_s=10.0, seed=6, sensors="mems-industrial"
        ),
    ),
]


def _realism_figures() -> dict[str, float] | None:
    """``|ln(simulated / real)|`` of every realism statistic (0: the simulation matches), from the
    quick realism run; ``None`` without the real recordings."""
    realism = run_realism(quick=True)
    if not realism["recordings"]:
        return None
    return {
        f"{k.removesuffix('_ratio')}_log_ratio": abs(float(np.log(r)))
        for k, r in realism_ratios(realism).items()
    }


def _walk_hierarchy_figures() -> dict[str, float]:
    """Fraction of wrong trees by each hierarchy method over three 30 s walks with the paper's
    kind of failure (hips about one axis, transmitter on the stand, the pack: seeds 101-103)."""
    trials = [walk_trial(seed, 30.0, True, "sagittal", "stand") for seed in (101, 102, 103)]
    return {
        f"{method}_wrong_fraction": sum(not t["methods"][method]["correct"] for t in trials) / len(trials)
        for method in ("mst", "misfit")
    }


#: Figures that are not one session's: ``name -> () -> {metric: value} | None`` (lower is better).
FIGURES: dict[str, Callable[[], dict[str, float] | None]] = {
    "realism": _realism_figures,
    "walk-hierarchy-paper-failure": _walk_hierarchy_figures,
}


class Figures(dict):
    """``{name: {metric: value}}``, and ``unavailable``: the names of :data:`FIGURES` that could
    not be computed here."""

    unavailable: tuple[str, ...] = ()


def _spec_metrics(estimator: str) -> Callable[[Dataset], dict[str, float]] | None:
    """The figures of ``joint:SPEC`` (centre and limb-length errors, cm; joints not fitted) or
    ``orientation:SPEC`` (total and heading RMSE, degrees) for any estimator spec; ``None`` for
    another name."""
    kind, _, spec = estimator.partition(":")
    if kind == "joint" and spec:

        def joints(ds: Dataset) -> dict[str, float]:
            m = joint_method_metrics(ds, spec, time_limit_s=TIME_LIMIT_S)
            return {
                "centre_error_cm": m["joint_centre_error_m"] * 100,
                "length_error_cm": m["limb_length_error_m"] * 100,
                "failed_joints_wrong": m["failed_joints"],
            }

        return joints
    if kind == "orientation" and spec:
        return _orientation_metrics(spec)
    return None


def estimator_metrics(name: str) -> Callable[[Dataset], dict[str, float]]:
    """The figures function of a scenario's estimator: a name of :data:`ESTIMATORS`, or
    ``joint:SPEC`` / ``orientation:SPEC`` with any spec of :func:`simbench.estimators.resolve`.

    Raises:
        InputError: neither.
    """
    got = ESTIMATORS.get(name) or _spec_metrics(name)
    if got is None:
        raise InputError(
            f"unknown estimator {name!r}: expected one of {sorted(ESTIMATORS)}, joint:SPEC or "
            "orientation:SPEC"
        )
    return got


def compute(scenarios: list[Scenario] | None = None) -> Figures:
    """Every scenario's figures; with simbench's own scenarios (``scenarios`` not given), also
    those of :data:`FIGURES`."""
    out = Figures()
    if scenarios is None:
        for name, figures in FIGURES.items():
            got = figures()
            if got is None:
                out.unavailable += (name,)
            else:
                out[name] = got
    for sc in scenarios or SCENARIOS:
        try:
            metrics = estimator_metrics(sc.estimator)
        except InputError as exc:
            raise InputError(f"scenario {sc.name}: {exc}") from None
        ds = run_session(sc.config, load_session_model(sc.config))
        out[sc.name] = metrics(ds)
    return out


#: Keys of a scenario in a scenarios file, besides ``name`` and ``estimator``: the session.
SCENARIO_SESSION_KEYS = ("model", "motion", "sensors", "duration_s", "rate_hz", "seed")


def load_scenarios(path: str | Path) -> list[Scenario]:
    """A user's baseline scenarios: a TOML file of ``[[scenario]]`` tables, each with ``name``,
    ``estimator`` (``joint:SPEC`` or ``orientation:SPEC``, any spec of
    :func:`simbench.estimators.resolve`; a ``file.py:function`` is found beside the file first) and
    the session (``model``, ``motion``, ``sensors``, ``duration_s``, ``rate_hz``, ``seed``;
    SessionConfig's defaults where missing)::

        [[scenario]]
        name = "linkage-mine"
        estimator = "joint:my_estimator.py:estimate"
        model = "linkage"
        sensors = "polhemus-liberty"
        duration_s = 20.0
        seed = 1

    Raises:
        InputError: naming the file and the scenario: unknown keys, a missing name or estimator,
            names given twice, an estimator that cannot be resolved, a session value that does not fit.
    """
    path = Path(path)
    doc = load_toml(path)
    tables = doc.get("scenario")
    extra = sorted(set(doc) - {"scenario"})
    if extra or not isinstance(tables, list) or not tables:
        raise InputError(
            f"{path}: expected [[scenario]] tables (name, estimator, the session), got keys {sorted(doc)}"
        )
    out, seen = [], set()
    for k, table in enumerate(tables):
        where = f"{path}, scenario {k + 1}"
        if not isinstance(table, dict):
            raise InputError(f"{where}: expected a table, got {table!r}")
        unknown = sorted(set(table) - {"name", "estimator", *SCENARIO_SESSION_KEYS})
        if unknown:
            raise InputError(
                f"{where}: unknown keys {unknown}; expected name, estimator, {list(SCENARIO_SESSION_KEYS)}"
            )
        name, estimator = table.get("name"), table.get("estimator")
        if not isinstance(name, str) or not name or name in seen:
            raise InputError(f"{where}: expected a unique name (a string), got {name!r}")
        seen.add(name)
        if not isinstance(estimator, str):
            raise InputError(f'{where} ({name}): expected estimator = "joint:SPEC" or "orientation:SPEC"')
        kind, _, spec = estimator.partition(":")
        folder_spec = spec.rpartition(":")
        if folder_spec[0].endswith(".py") and (path.parent / folder_spec[0]).is_file():
            estimator = f"{kind}:{path.parent / folder_spec[0]}:{folder_spec[2]}"
        try:
            if estimator not in ESTIMATORS:
                if kind not in ("joint", "orientation"):
                    raise InputError(f"expected joint:SPEC or orientation:SPEC, got {estimator!r}")
                resolve(estimator.partition(":")[2], "joints" if kind == "joint" else "orientation")
            config = SessionConfig(**{key: table[key] for key in SCENARIO_SESSION_KEYS if key in table})
        except (InputError, TypeError) as exc:
            raise InputError(f"{where} ({name}): {exc}") from None
        out.append(Scenario(name, estimator, config))
    return out


def _abs_tol(metric: str) -> float:
    return next((v for suffix, v in ABS_TOL.items() if metric.endswith(suffix)), 0.0)


def compare(
    current: dict[str, dict[str, float]], baseline: dict[str, dict[str, float]], rel_tol: float = REL_TOL
) -> list[str]:
    """Regressions: figures worse than ``baseline (1 + rel_tol) + abs_tol``, and missing ones
    (figure sets ``current`` lists as unavailable are skipped)."""
    problems = []
    for name, figures in baseline.items():
        if name in getattr(current, "unavailable", ()):
            continue
        if name not in current:
            problems.append(f"{name}: scenario missing")
            continue
        for metric, accepted in figures.items():
            value = current[name].get(metric)
            if value is None or not np.isfinite(value):
                problems.append(f"{name}.{metric}: missing or not finite (accepted {accepted:.4g})")
            elif value > accepted * (1 + rel_tol) + _abs_tol(metric):
                problems.append(f"{name}.{metric}: {value:.4g} is worse than the accepted {accepted:.4g}")
    return problems


def load_baseline(path: Path = BASELINE_FILE) -> dict[str, dict[str, float]]:
    """The accepted figures: ``{"scenarios": {name: {metric: number}}}`` in ``path``.

    Raises:
        InputError: naming the file: missing, unreadable, not JSON, or not of that shape.
    """
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no baseline yet; run `simbench baseline --update`") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: {not_utf8(exc)}") from None
    except ValueError as exc:  # not JSON
        raise InputError(f"{path}: not valid JSON ({exc})") from None
    scenarios = doc.get("scenarios") if isinstance(doc, dict) else None
    if not isinstance(scenarios, dict):
        raise InputError(f'{path}: expected an object with "scenarios": {{name: {{metric: number}}}}')
    for name, figures in scenarios.items():
        if not isinstance(figures, dict):
            raise InputError(f"{path}, key scenarios.{name}: expected {{metric: number}}, got {figures!r}")
        for metric, value in figures.items():
            if not (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)):
                raise InputError(
                    f"{path}, key scenarios.{name}.{metric}: expected a finite number, got {value!r}"
                )
    return scenarios


def diff_lines(old: dict[str, dict[str, float]], new: dict[str, dict[str, float]]) -> list[str]:
    """Human-readable changes between two baselines."""
    lines = []
    for name in sorted(set(old) | set(new)):
        for metric in sorted(set(old.get(name, {})) | set(new.get(name, {}))):
            a, b = old.get(name, {}).get(metric), new.get(name, {}).get(metric)
            if a != b:
                old_s = "-" if a is None else f"{a:.4g}"
                new_s = "-" if b is None else f"{b:.4g}"
                lines.append(f"{name}.{metric}: {old_s} -> {new_s}")
    return lines


def write_baseline(figures: dict[str, dict[str, float]], path: Path = BASELINE_FILE) -> None:
    """Write the accepted figures atomically."""
    doc = {
        "about": "accepted accuracy figures (lower is better); `simbench baseline --update` rewrites this",
        "rel_tol": REL_TOL,
        "scenarios": figures,
    }
    atomic_write_text(path, json.dumps(doc, indent=2, sort_keys=True) + "\n")
