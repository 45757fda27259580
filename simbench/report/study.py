"""Plots and the Markdown summary of a study (:mod:`simbench.experiments.study`).

A study's table (``pyarrow.Table``, one row per trial) holds the id columns ``trial``, ``cell``,
``replicate`` and ``seed``, one column per varied parameter (SI), and the metrics: every other
column (:mod:`simbench.experiments.sweep`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from calibration.quantiles import norm_ppf
from simbench.io.atomic import atomic_write_text
from simbench.report.plots import PALETTE, SEQUENTIAL_CMAP, figure_axes, panel_grid, save_figure
from simbench.units import UNITS

#: Columns of a study's table that identify a trial (not parameters, not metrics).
ID_COLUMNS = ("trial", "cell", "replicate", "seed")

#: How a metric is shown, by the suffix of its name (before any ``:<method>``): the unit of the
#: axis and the factor from the table's SI value. Lengths in millimetres.
METRIC_DISPLAY = {"_m": ("mm", 1000.0), "_deg": ("deg", 1.0), "_s": ("s", 1.0)}

#: Metrics that are 0 or 1 per trial: shown as a proportion with a Wilson interval.
BINARY_METRICS = ("hierarchy_correct",)

#: Words for a metric's name where its column name (less the unit suffix, underscores as spaces)
#: would not read well; the others are read from the name.
METRIC_WORDS = {
    "joint_centre_error_m": "joint-centre error",
    "limb_length_error_m": "limb-length error",
    "orientation_rmse_deg": "orientation error, rms",
    "residual_rms_m": "joint residual, rms",
}

#: Metrics that cannot be negative (errors, sizes, times): their confidence bands stop at zero.
NON_NEGATIVE_SUFFIXES = ("_error_m", "_rmse_deg", "_rms_m", "_s", "condition")


def _words(name: str) -> str:
    """A column or parameter name as words: its unit suffix dropped, underscores as spaces."""
    for suffix in (*METRIC_DISPLAY, "_deg"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
            break
    return name.replace("_", " ")


class StudyParameter(Protocol):
    """What the report reads of a varied parameter."""

    name: str
    values: tuple[float, ...]  # the grid's values, SI (empty for random sampling)
    unit: str  # the unit the study gave the values in (shown in it)


class StudyDescription(Protocol):
    """What the report reads of a study (:class:`simbench.experiments.study.Study`)."""

    name: str
    metrics: Sequence[str]
    seed: int
    seeds_per_cell: int
    kind: str  # "grid" or "random"
    base: Mapping[str, Any]
    parameters: Sequence[StudyParameter]


def metric_columns(study: StudyDescription, data: Mapping[str, list]) -> list[str]:
    """The columns of a study's table (``table.to_pydict()``) that hold the metrics the study
    asked for (its ``metrics``; a ``<metric>:<method>`` column counts as ``<metric>``), in table
    order."""
    names = {p.name for p in study.parameters}
    wanted = set(study.metrics)
    return [c for c in data if c not in ID_COLUMNS and c not in names and c.split(":", 1)[0] in wanted]


def metric_display(metric: str) -> tuple[str, float, bool]:
    """``(axis label, factor from SI, binary)`` of a metric column: lengths in mm, a 0/1 metric as
    a proportion, anything else as its name says (:data:`METRIC_DISPLAY`)."""
    base, _, method = metric.partition(":")
    words = METRIC_WORDS.get(base, _words(base)) + (f", {method}" if method else "")
    if base in BINARY_METRICS:
        return f"{words} (proportion)", 1.0, True
    for suffix, (unit, factor) in METRIC_DISPLAY.items():
        if base.endswith(suffix):
            return f"{words} ({unit})", factor, False
    return words, 1.0, False


def mean_of_known(x: np.ndarray) -> float:
    """The mean of the values of ``x`` that are not NaN (``numpy.nanmean``); NaN, and no warning,
    when there is none."""
    x = np.asarray(x, dtype=float)
    known = ~np.isnan(x)
    return float(x[known].mean()) if known.any() else float("nan")


def parameter_display(p: StudyParameter) -> tuple[str, float]:
    """``(axis label, factor from SI)`` of a parameter: in the unit the study gave it in."""
    unit = p.unit
    factor = UNITS[unit][1]
    short = p.name.split(".")[-1]
    if short.endswith("_deg"):  # a field held in degrees: its values are degrees, not SI
        factor /= UNITS["deg"][1]
    words = _words(short)
    return (words if unit == "1" else f"{words} ({unit})"), 1.0 / factor


def wilson_interval(
    successes: np.ndarray, n: np.ndarray, level: float = 0.95
) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval ``(lo, hi)`` of a proportion, inside [0, 1] (``nan`` where n = 0)."""
    k, n = np.asarray(successes, dtype=float), np.asarray(n, dtype=float)
    z = float(norm_ppf(0.5 + level / 2))
    with np.errstate(invalid="ignore", divide="ignore"):
        p = k / n
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return np.clip(centre - half, 0.0, 1.0), np.clip(centre + half, 0.0, 1.0)


def _confidence_band(
    x: np.ndarray, y: np.ndarray, binary: bool = False, non_negative: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(xs, mean, lo, hi)``: the mean of ``y`` at each distinct ``x`` and its 95 % confidence
    band over the finite values there: normal for a measurement (not below zero for a quantity
    that cannot be negative), Wilson's interval (inside [0, 1]) for a 0/1 metric."""
    xs = np.unique(x)
    groups = [y[(x == v) & np.isfinite(y)] for v in xs]
    n = np.array([g.size for g in groups], dtype=float)
    mean = np.array([g.mean() if g.size else np.nan for g in groups])
    if binary:
        lo, hi = wilson_interval(np.array([g.sum() for g in groups]), n)
        return xs, mean, lo, hi
    sem = np.array([g.std(ddof=1) if g.size > 1 else 0.0 for g in groups]) / np.sqrt(np.maximum(n, 1))
    lo = mean - 1.96 * sem
    return xs, mean, np.maximum(lo, 0.0) if non_negative else lo, mean + 1.96 * sem


def non_negative(metric: str) -> bool:
    """Whether a metric column cannot be negative (:data:`NON_NEGATIVE_SUFFIXES`)."""
    return metric.partition(":")[0].endswith(NON_NEGATIVE_SUFFIXES)


def _plot_parameter(
    study: StudyDescription, data: Mapping[str, list], name: str, metrics: list[str], path: Path
) -> None:
    """Every metric against one parameter, one panel each, in rows of at most
    :data:`simbench.report.plots.PANELS_PER_ROW`."""
    parameter = next(p for p in study.parameters if p.name == name)
    x_label, x_factor = parameter_display(parameter)
    x = np.array(data[name], dtype=float) * x_factor
    axes, fig = panel_grid(len(metrics), 3.6, 3.0)
    for ax, m in zip(axes, metrics, strict=False):
        y_label, y_factor, binary = metric_display(m)
        y = np.array(data[m], dtype=float) * y_factor
        ax.set_xlabel(x_label)
        ax.set_ylabel(y_label, fontsize=8)
        if study.kind == "random":  # every trial its own value: a scatter, no bands
            ax.plot(x, y, ".", color=PALETTE[0], alpha=0.7)
            continue
        xs, mean, lo, hi = _confidence_band(x, y, binary, non_negative(m))
        ax.plot(xs, mean, "o-", color=PALETTE[0])
        ax.fill_between(xs, lo, hi, color=PALETTE[0], alpha=0.25)
        if binary:
            ax.set_ylim(-0.05, 1.05)
    fig.tight_layout()
    save_figure(fig, path)


def _plot_heatmap(
    a: StudyParameter, b: StudyParameter, data: Mapping[str, list], metric: str, path: Path
) -> None:
    """The mean of one metric over the grid of two parameters (``a`` vertical, ``b`` across)."""
    xa, xb = np.array(data[a.name]), np.array(data[b.name])
    label, factor, _ = metric_display(metric)
    y = np.array(data[metric], dtype=float) * factor
    grid = np.array([[mean_of_known(y[(xa == va) & (xb == vb)]) for vb in b.values] for va in a.values])
    (a_label, a_factor), (b_label, b_factor) = parameter_display(a), parameter_display(b)
    (ax,), fig = figure_axes(5, 4)
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap=SEQUENTIAL_CMAP)
    ax.set_xticks(range(len(b.values)), [f"{v * b_factor:.3g}" for v in b.values])
    ax.set_yticks(range(len(a.values)), [f"{v * a_factor:.3g}" for v in a.values])
    ax.set_xlabel(b_label)
    ax.set_ylabel(a_label)
    fig.colorbar(im, label=label)
    fig.tight_layout()
    save_figure(fig, path)


def plot_study(study: StudyDescription, table: Any, out: Path) -> list[Path]:
    """Every metric against each parameter, ``out/vs_<parameter>.png``: means with 95 %
    confidence bands over seeds (grid), every trial (random sampling); for two grid parameters
    also ``out/heatmap.png``, the first metric's mean over the grid. Returns the files written.

    Args:
        study: the study.
        table: its ``pyarrow.Table`` (:func:`simbench.experiments.sweep.gather`).
        out: output folder (exists).
    """
    data = table.to_pydict()
    metrics = metric_columns(study, data)
    written: list[Path] = []
    if not metrics:  # no trial gave one
        return written
    for p in study.parameters:
        path = out / f"vs_{p.name.replace('.', '_')}.png"
        _plot_parameter(study, data, p.name, metrics, path)
        written.append(path)
    if len(study.parameters) == 2 and study.kind == "grid":
        path = out / "heatmap.png"
        _plot_heatmap(*study.parameters, data, metrics[0], path)
        written.append(path)
    return written


def _cell_means(study: StudyDescription, data: Mapping[str, list], metrics: list[str]) -> list[str]:
    """Markdown table: each cell's parameter values (in the study's units) and mean metrics (as
    the plots show them)."""
    shown = [parameter_display(p) for p in study.parameters]
    metric_shown = [metric_display(m) for m in metrics]
    lines = [
        "| "
        + " | ".join(
            [
                *(f"{p.name} ({p.unit})" if p.unit != "1" else p.name for p in study.parameters),
                *[f"mean {label}" for label, _, _ in metric_shown],
            ]
        )
        + " |",
        "|" + "---|" * (len(shown) + len(metrics)),
    ]
    cell_arr = np.array(data.get("cell", []))
    for c in sorted(set(data.get("cell", []))):
        sel = cell_arr == c
        first = int(np.flatnonzero(sel)[0])
        vals = [f"{data[p.name][first] * f:.4g}" for p, (_, f) in zip(study.parameters, shown, strict=True)]
        vals += [
            f"{mean_of_known(np.array(data[m], dtype=float)[sel]) * f:.4g}"
            for m, (_, f, _) in zip(metrics, metric_shown, strict=True)
        ]
        lines.append("| " + " | ".join(vals) + " |")
    return lines


def _joint_centre_findings(study: StudyDescription, data: Mapping[str, list], names: list[str]) -> list[str]:
    """What predicts the joint-centre error: rank correlations with the fits' condition number
    (and with each parameter, for random sampling), and the best cell."""
    cell_arr = np.array(data["cell"])
    cells = sorted(set(data["cell"]))
    cond = np.array(data["condition"], dtype=float)
    err = np.array(data["joint_centre_error_m"], dtype=float)
    ok = np.isfinite(cond) & np.isfinite(err)
    # here, not at the top: scipy.stats costs 0.6 s at every start of the command line
    from scipy.stats import spearmanr

    lines = []
    if ok.sum() > 2:
        rho = spearmanr(cond[ok], err[ok]).statistic
        lines += [
            "",
            f"Rank correlation of the joint fits' condition number with the joint-centre error: {rho:.2f}.",
        ]
    if study.kind == "random" and ok.sum() > 2:
        lines += ["", "| parameter | rank correlation with the joint-centre error |", "|---|---|"]
        for n in names:
            r = spearmanr(np.array(data[n], dtype=float)[ok], err[ok]).statistic
            lines.append(f"| {n} | {r:+.2f} |")
    means = np.array([mean_of_known(err[cell_arr == c]) for c in cells])
    if not np.isfinite(means).any():  # no trial gave a joint-centre error
        return lines
    best = int(np.nanargmin(means))
    pick = int(np.flatnonzero(cell_arr == cells[best])[0])
    best_cell = ", ".join(
        f"{p.name} = {data[p.name][pick] * parameter_display(p)[1]:.4g}"
        + ("" if p.unit == "1" else f" {p.unit}")
        for p in study.parameters
    )
    return [*lines, "", f"Smallest mean joint-centre error: {best_cell}."]


def _failures(data: Mapping[str, list]) -> list[str]:
    """Lines on the trials whose values could not make a session or an estimate (their
    ``error``), each named; none when every trial ran."""
    errors = [e for e in data.get("error", []) if e]
    if not errors:
        return []
    shown = [f"- {e}" for e in errors[:10]]
    more = (
        [f"- ... and {len(errors) - 10} more (the `error` column of results.parquet)"]
        if len(errors) > 10
        else []
    )
    return [
        f"{len(errors)} of {len(data.get('trial', []))} trials gave no metrics (left out of the means):",
        "",
        *shown,
        *more,
        "",
    ]


def summary_markdown(study: StudyDescription, table: Any, plots: list[Path]) -> str:
    """A short Markdown summary (``summary.md`` beside the plots): the study, mean metrics per
    cell, what predicts the joint-centre error (when the table has it), the plots.

    Args:
        study: the study.
        table: its ``pyarrow.Table``.
        plots: the plots (:func:`plot_study`), linked by file name.
    """
    data = table.to_pydict()
    metrics = metric_columns(study, data)
    names = [p.name for p in study.parameters]
    lines = [
        f"# Study {study.name}",
        "",
        f"{len(data.get('trial', []))} trials: {study.kind} over {', '.join(names)}, {study.seeds_per_cell} "
        f"seed(s) per cell, study seed {study.seed}, base {study.base}.",
        "",
        *_failures(data),
        *_cell_means(study, data, metrics),
    ]
    if "condition" in data and "joint_centre_error_m" in data:
        lines += _joint_centre_findings(study, data, names)
    lines += ["", *[f"![{p.stem}]({p.name})" for p in plots], ""]
    return "\n".join(lines)


def write_summary(study: StudyDescription, table: Any, plots: list[Path], out: Path) -> Path:
    """Write :func:`summary_markdown` to ``out/summary.md``, atomically; returns its path."""
    path = Path(out) / "summary.md"
    atomic_write_text(path, summary_markdown(study, table, plots))
    return path
