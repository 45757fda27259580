"""Studies: seeded trials over a grid or a random sample of parameters, on any executor.

A study (TOML) names a base scenario, the parameters to vary, seeds per cell, estimators and
metrics::

    name = "noise"
    seed = 1
    seeds_per_cell = 3
    estimators = ["calibration"]                  # and/or "orientation:fontaine", ...
    metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]
    [base]
    model = "linkage"
    motion = "exercise"
    sensors = "ascension-flock"                   # a preset: the parameters change its fields
    duration_s = 10.0
    rate_hz = 120.0
    [sampling]
    kind = "grid"                                 # or "random", with samples = N
    [[parameter]]
    name = "sensors.tracker.position_noise_m"     # a field of the sensor configuration, or
    unit = "mm"                                   # duration_s / rate_hz; unit converted to SI
    values = [0, 2, 4, 8]                         # grid: values; random: low, high (, log)

**Trials** are independent and seeded from ``(study seed, cell, replicate)``, so the results do not
depend on the number of workers or the order they finish in. They run through any
``concurrent.futures.Executor``: a local process pool by default, or a Dask distributed cluster
(``distributed.Client(address).get_executor()``).

**Results** go to ``OUT/trials/<trial>.parquet`` (one small Parquet file per trial, written
atomically as each finishes) and are gathered into ``OUT/results.parquet``; an interrupted study
resumes where it stopped: finished trials are read back and never run or written twice.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simbench.errors import InputError, load_toml
from simbench.io.atomic import atomic_path
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.units import UNITS

SUFFIX_UNIT = {"_m": "m", "_rad": "rad", "_s": "s", "_hz": "hz"}

METRICS = {
    "joint_centre_error_m": "mean distance of estimated from true joint centres (parent frame), m",
    "limb_length_error_m": "mean absolute limb-length error, m",
    "max_limb_length_error_m": "largest absolute limb-length error, m",
    "hierarchy_correct": "1 if the inferred hierarchy equals the truth (as undirected tree)",
    "residual_m": "mean rms joint residual, m",
    "condition": "mean condition number of the joint fits",
    "orientation_rmse_deg": "orientation RMSE over sensors and frames, degrees",
    "run_time_s": "seconds the trial took",
}
BASE_KEYS = {"model", "motion", "sensors", "duration_s", "rate_hz"}


@dataclass(frozen=True)
class Parameter:
    """One varied parameter: its SI values (grid) or SI range (random)."""

    name: str
    values: tuple[float, ...] = ()
    low: float = math.nan
    high: float = math.nan
    log: bool = False


@dataclass(frozen=True)
class Study:
    """A parsed study file (module docstring)."""

    name: str
    seed: int
    seeds_per_cell: int
    estimators: tuple[str, ...]
    metrics: tuple[str, ...]
    base: dict[str, Any]
    kind: str
    samples: int
    parameters: tuple[Parameter, ...]


def _field_unit(name: str) -> str:
    if name in ("duration_s",):
        return "s"
    if name == "rate_hz":
        return "hz"
    return next((u for suffix, u in SUFFIX_UNIT.items() if name.endswith(suffix)), "1")


def _check_parameter_name(name: str, base_sensors: SensorConfig) -> None:
    if name in ("duration_s", "rate_hz"):
        return
    if name.startswith("placement."):
        parts = name.split(".")
        if len(parts) != 3 or parts[2] not in ("x_m", "y_m", "z_m"):
            raise InputError(f"parameter {name!r}: expected placement.<sensor>.x_m, .y_m or .z_m")
        return
    parts = name.split(".")
    if len(parts) != 3 or parts[0] != "sensors":
        raise InputError(
            f"parameter {name!r}: expected duration_s, rate_hz or sensors.<section>.<field> "
            "(section: tracker, imu, magnetic, skin)"
        )
    section = getattr(base_sensors, parts[1], None)
    if section is None or not dataclasses.is_dataclass(section):
        raise InputError(f"parameter {name!r}: no sensor section {parts[1]!r} (tracker, imu, magnetic, skin)")
    fields = {f.name: f for f in dataclasses.fields(section)}
    if parts[2] not in fields or fields[parts[2]].type != "float":
        numeric = sorted(f for f, v in fields.items() if v.type == "float")
        raise InputError(
            f"parameter {name!r}: {parts[1]} has no numeric field {parts[2]!r}; fields: {numeric}"
        )


def load_study(path: str | os.PathLike[str]) -> Study:
    """Read and check a study file; every problem is reported before any work starts.

    Raises:
        InputError: naming the file and key (unknown keys, parameters or estimators, empty
            ranges, wrong units).
    """
    path = Path(path)
    doc = load_toml(path)
    known = {"name", "seed", "seeds_per_cell", "estimators", "metrics", "base", "sampling", "parameter"}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise InputError(f"{path}: unknown keys {unknown}; expected {sorted(known)}")
    base = dict(doc.get("base", {}))
    bad = sorted(set(base) - BASE_KEYS)
    if bad:
        raise InputError(f"{path}: base: unknown keys {bad}; expected {sorted(BASE_KEYS)}")
    base.setdefault("sensors", "ideal")
    try:
        base_sensors = load_sensor_config(base["sensors"])
    except InputError as exc:
        raise InputError(f"{path}: base.sensors: {exc}") from None
    estimators = tuple(doc.get("estimators", ["calibration"]))
    methods = ("fontaine", "triad", "wahba", "mahony")
    for e in estimators:
        if e != "calibration" and not (e.startswith("orientation:") and e.split(":", 1)[1] in methods):
            expected = f"calibration or orientation:<{'|'.join(methods)}>"
            raise InputError(f"{path}: estimators: unknown {e!r}; expected {expected}")
    metrics = tuple(doc.get("metrics", ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]))
    bad = sorted(set(metrics) - set(METRICS))
    if bad:
        raise InputError(f"{path}: metrics: unknown {bad}; expected some of {sorted(METRICS)}")
    sampling = dict(doc.get("sampling", {"kind": "grid"}))
    kind = sampling.get("kind", "grid")
    if kind not in ("grid", "random"):
        raise InputError(f"{path}: sampling.kind must be 'grid' or 'random', got {kind!r}")
    samples = int(sampling.get("samples", 0))
    if kind == "random" and samples < 1:
        raise InputError(f"{path}: sampling.samples must be >= 1 for random sampling")
    seeds = doc.get("seeds_per_cell", 1)
    if not isinstance(seeds, int) or seeds < 1:
        raise InputError(f"{path}: seeds_per_cell must be an integer >= 1, got {seeds!r}")
    params = []
    raw = doc.get("parameter", [])
    if not raw:
        raise InputError(f"{path}: expected at least one [[parameter]]")
    for k, p in enumerate(raw):
        where = f"{path}: parameter[{k}]"
        extra = sorted(set(p) - {"name", "unit", "values", "low", "high", "log"})
        if extra:
            raise InputError(f"{where}: unknown keys {extra}")
        name = p.get("name")
        if not isinstance(name, str):
            raise InputError(f"{where}: missing name")
        _check_parameter_name(name, base_sensors)
        unit = str(p.get("unit", "1")).lower()
        if unit not in UNITS:
            raise InputError(f"{where} ({name}): unknown unit {unit!r}; expected one of {sorted(UNITS)}")
        si, factor = UNITS[unit]
        field_unit = _field_unit(name.split(".")[-1])
        if si != field_unit:
            raise InputError(f"{where} ({name}): unit {unit!r} does not fit (the field is in {field_unit})")
        if kind == "grid":
            values = p.get("values")
            if (
                not isinstance(values, list)
                or not values
                or not all(isinstance(v, int | float) for v in values)
            ):
                raise InputError(
                    f"{where} ({name}): grid sampling needs a non-empty list of numbers in 'values'"
                )
            params.append(Parameter(name, values=tuple(float(v) * factor for v in values)))
        else:
            low, high = p.get("low"), p.get("high")
            if not isinstance(low, int | float) or not isinstance(high, int | float) or not low < high:
                raise InputError(
                    f"{where} ({name}): random sampling needs low < high, got {low!r} and {high!r}"
                )
            log = bool(p.get("log", False))
            if log and low <= 0:
                raise InputError(f"{where} ({name}): log sampling needs low > 0")
            params.append(Parameter(name, low=float(low) * factor, high=float(high) * factor, log=log))
    return Study(
        name=str(doc.get("name", path.stem)),
        seed=int(doc.get("seed", 0)),
        seeds_per_cell=seeds,
        estimators=estimators,
        metrics=metrics,
        base=base,
        kind=kind,
        samples=samples,
        parameters=tuple(params),
    )


@dataclass(frozen=True)
class Trial:
    """One seeded trial: cell index, replicate, parameter values (SI) and session seed."""

    cell: int
    replicate: int
    params: tuple[tuple[str, float], ...]
    seed: int

    @property
    def trial_id(self) -> str:
        return f"c{self.cell:05d}-r{self.replicate:03d}"


def trials(study: Study) -> list[Trial]:
    """Every trial of the study, in a fixed order."""
    if study.kind == "grid":
        grids = np.meshgrid(*[np.array(p.values) for p in study.parameters], indexing="ij")
        cells = np.stack([g.ravel() for g in grids], axis=1)
    else:
        rng = np.random.default_rng([study.seed, 0xC0FFEE])
        cols = []
        for p in study.parameters:
            u = rng.random(study.samples)
            cols.append(
                np.exp(np.log(p.low) + u * np.log(p.high / p.low)) if p.log else p.low + u * (p.high - p.low)
            )
        cells = np.stack(cols, axis=1)
    out = []
    for c, row in enumerate(cells):
        for r in range(study.seeds_per_cell):
            seed = int(np.random.SeedSequence([study.seed, c, r]).generate_state(1)[0])
            params = tuple((p.name, float(v)) for p, v in zip(study.parameters, row, strict=True))
            out.append(Trial(c, r, params, seed))
    return out


def _trial_config(study: Study, trial: Trial):
    from simbench.sim.session import SessionConfig

    sensors = load_sensor_config(study.base.get("sensors", "ideal"))
    duration = float(study.base.get("duration_s", 10.0))
    rate = float(study.base.get("rate_hz", 120.0))
    shifts: dict[str, list[float]] = {}
    for name, value in trial.params:
        if name == "duration_s":
            duration = value
        elif name == "rate_hz":
            rate = value
        elif name.startswith("placement."):
            _, sensor, axis = name.split(".")
            shifts.setdefault(sensor, [0.0, 0.0, 0.0])["xyz".index(axis[0])] = value
        else:
            _, section, fieldname = name.split(".")
            sec = dataclasses.replace(getattr(sensors, section), **{fieldname: value})
            sensors = dataclasses.replace(sensors, **{section: sec})
    return SessionConfig(
        model=study.base.get("model", "linkage"),
        motion=study.base.get("motion", "exercise"),
        duration_s=duration,
        rate_hz=rate,
        seed=trial.seed,
        sensors=sensors,
        placement=tuple((k, tuple(v)) for k, v in sorted(shifts.items())),
    )


def run_trial(study: Study, trial: Trial) -> dict[str, Any]:
    """Simulate, estimate and score one trial; returns its row.

    A trial uses one core (BLAS limited to one thread): parallelism comes from running trials
    side by side, which scales; threads inside one small trial do not.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return _run_trial(study, trial)


def _run_trial(study: Study, trial: Trial) -> dict[str, Any]:
    from simbench.experiments.metrics import calibration_metrics, orientation_metrics
    from simbench.sim.session import load_session_model, run_session

    t0 = time.perf_counter()
    config = _trial_config(study, trial)
    ds = run_session(config, load_session_model(config))
    row: dict[str, Any] = {
        "trial": trial.trial_id,
        "cell": trial.cell,
        "replicate": trial.replicate,
        "seed": trial.seed,
    }
    row.update(dict(trial.params))
    several = sum(e.startswith("orientation:") for e in study.estimators) > 1
    for est in study.estimators:
        if est == "calibration":
            row.update(calibration_metrics(ds))
        else:
            method = est.split(":", 1)[1]
            key = f"orientation_rmse_deg:{method}" if several else "orientation_rmse_deg"
            row[key] = orientation_metrics(ds, method)["total_rmse_deg"]
    row["run_time_s"] = time.perf_counter() - t0
    return row


def _write_row(out: Path, row: dict[str, Any]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([row])
    with atomic_path(out / "trials" / f"{row['trial']}.parquet") as tmp:
        pq.write_table(table, tmp)


def finished(out: Path) -> set[str]:
    """Trial ids already written (a resumed study skips them)."""
    folder = out / "trials"
    return {p.stem for p in folder.glob("*.parquet")} if folder.is_dir() else set()


def gather(out: Path):
    """All finished trials as one table, sorted by trial id, also written to results.parquet."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    parts = sorted((out / "trials").glob("*.parquet"))
    tables = [pq.read_table(p) for p in parts]
    table = pa.concat_tables(tables, promote_options="default") if tables else pa.table({})
    if tables:
        table = table.sort_by("trial")
        with atomic_path(out / "results.parquet") as tmp:
            pq.write_table(table, tmp)
    return table


def _submit_all(executor: Executor, study: Study, todo: list[Trial]) -> Iterator[Future]:
    futures = [executor.submit(run_trial, study, t) for t in todo]
    yield from as_completed(futures)


def run_study(
    study: Study,
    out: Path,
    *,
    executor: Executor | None = None,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    limit: int | None = None,
):
    """Run every unfinished trial of a study, writing each as it finishes; returns the table.

    Args:
        study: the study.
        out: output folder (created); finished trials there are skipped.
        executor: where trials run; default a local process pool of ``workers``.
        workers: size of the default pool.
        progress: called with ``(done, total)`` as trials finish.
        limit: run at most this many trials now (the rest on a later call).
    """
    (out / "trials").mkdir(parents=True, exist_ok=True)
    every = trials(study)
    done = finished(out)
    todo = [t for t in every if t.trial_id not in done]
    if limit is not None:
        todo = todo[:limit]
    own = executor is None
    if own:
        executor = ProcessPoolExecutor(max_workers=workers)
    count = len(done)
    try:
        for fut in _submit_all(executor, study, todo):
            _write_row(out, fut.result())
            count += 1
            if progress:
                progress(count, len(every))
    finally:
        if own:
            executor.shutdown(cancel_futures=True)
    return gather(out)


def plot_study(study: Study, table, out: Path) -> list[Path]:
    """Metric vs each parameter: means with 95 % confidence bands over seeds (grid), every trial
    (random sampling); a heat map of the first metric for two grid parameters."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simbench.report.validation import _savefig

    data = table.to_pydict()
    metrics = [m for m in data if m in METRICS or m.startswith("orientation_rmse_deg")]
    written = []
    for p in study.parameters:
        x = np.array(data[p.name])
        fig, axes = plt.subplots(1, len(metrics), figsize=(3.6 * len(metrics), 3), squeeze=False)
        for ax, m in zip(axes[0], metrics, strict=True):
            y = np.array(data[m], dtype=float)
            if study.kind == "random":  # every trial its own value: a scatter, no bands
                ax.plot(x, y, ".", alpha=0.7)
                ax.set_xlabel(p.name.split(".", 1)[-1])
                ax.set_title(m, fontsize=8)
                continue
            xs = np.unique(x)
            mean = np.array([np.nanmean(y[x == v]) for v in xs])
            n = np.array([np.sum(np.isfinite(y[x == v])) for v in xs])
            sem = np.array(
                [np.nanstd(y[x == v], ddof=1) if c > 1 else 0.0 for v, c in zip(xs, n, strict=True)]
            ) / np.sqrt(np.maximum(n, 1))
            ax.plot(xs, mean, "o-")
            ax.fill_between(xs, mean - 1.96 * sem, mean + 1.96 * sem, alpha=0.25)
            ax.set_xlabel(p.name.split(".")[-1])
            ax.set_title(m, fontsize=8)
        fig.tight_layout()
        path = out / f"vs_{p.name.replace('.', '_')}.png"
        _savefig(fig, path)
        plt.close(fig)
        written.append(path)
    if len(study.parameters) == 2 and study.kind == "grid":
        a, b = study.parameters
        m = metrics[0]
        xa, xb, y = np.array(data[a.name]), np.array(data[b.name]), np.array(data[m], dtype=float)
        grid = np.array([[np.nanmean(y[(xa == va) & (xb == vb)]) for vb in b.values] for va in a.values])
        fig, ax = plt.subplots(figsize=(5, 4))
        im = ax.imshow(grid, origin="lower", aspect="auto")
        ax.set_xticks(range(len(b.values)), [f"{v:.3g}" for v in b.values])
        ax.set_yticks(range(len(a.values)), [f"{v:.3g}" for v in a.values])
        ax.set_xlabel(b.name.split(".")[-1])
        ax.set_ylabel(a.name.split(".")[-1])
        fig.colorbar(im, label=m)
        fig.tight_layout()
        path = out / "heatmap.png"
        _savefig(fig, path)
        plt.close(fig)
        written.append(path)
    return written


def summary_markdown(study: Study, table, plots: list[Path]) -> str:
    """A short Markdown summary: the study, mean metrics per cell, the plots."""
    data = table.to_pydict()
    metrics = [m for m in data if m in METRICS or m.startswith("orientation_rmse_deg")]
    names = [p.name for p in study.parameters]
    lines = [
        f"# Study {study.name}",
        "",
        f"{len(data.get('trial', []))} trials: {study.kind} over {', '.join(names)}, {study.seeds_per_cell} "
        f"seed(s) per cell, study seed {study.seed}, base {study.base}.",
        "",
        "| " + " | ".join([*names, *[f"mean {m}" for m in metrics]]) + " |",
        "|" + "---|" * (len(names) + len(metrics)),
    ]
    cells = sorted(set(data.get("cell", [])))
    cell_arr = np.array(data.get("cell", []))
    for c in cells:
        sel = cell_arr == c
        first = int(np.flatnonzero(sel)[0])
        vals = [f"{data[n][first]:.4g}" for n in names]
        vals += [f"{np.nanmean(np.array(data[m], dtype=float)[sel]):.4g}" for m in metrics]
        lines.append("| " + " | ".join(vals) + " |")
    if "condition" in data and "joint_centre_error_m" in data:
        from scipy.stats import spearmanr

        cond = np.array(data["condition"], dtype=float)
        err = np.array(data["joint_centre_error_m"], dtype=float)
        ok = np.isfinite(cond) & np.isfinite(err)
        if ok.sum() > 2:
            rho = spearmanr(cond[ok], err[ok]).statistic
            lines += [
                "",
                "Rank correlation of the joint fits' condition number with the joint-centre error: "
                f"{rho:.2f}.",
            ]
        if study.kind == "random" and ok.sum() > 2:
            lines += ["", "| parameter | rank correlation with the joint-centre error |", "|---|---|"]
            for n in names:
                r = spearmanr(np.array(data[n], dtype=float)[ok], err[ok]).statistic
                lines.append(f"| {n} | {r:+.2f} |")
        best = int(np.nanargmin([np.nanmean(err[cell_arr == c]) for c in cells]))
        pick = int(np.flatnonzero(cell_arr == cells[best])[0])
        lines += [
            "",
            "Smallest mean joint-centre error: "
            + ", ".join(f"{n} = {data[n][pick]:.4g}" for n in names)
            + ".",
        ]
    lines += ["", *[f"![{p.stem}]({p.name})" for p in plots], ""]
    return "\n".join(lines)
