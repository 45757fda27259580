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
from matplotlib.figure import Figure
from scipy.stats import spearmanr

from simbench.report.plots import save_figure

#: Columns of a study's table that identify a trial (not parameters, not metrics).
ID_COLUMNS = ("trial", "cell", "replicate", "seed")


class StudyParameter(Protocol):
    """What the report reads of a varied parameter."""

    name: str
    values: tuple[float, ...]  # the grid's values, SI (empty for random sampling)


class StudyDescription(Protocol):
    """What the report reads of a study (:class:`simbench.experiments.study.Study`)."""

    name: str
    seed: int
    seeds_per_cell: int
    kind: str  # "grid" or "random"
    base: Mapping[str, Any]
    parameters: Sequence[StudyParameter]


def metric_columns(study: StudyDescription, data: Mapping[str, list]) -> list[str]:
    """The metric columns of a study's table (``table.to_pydict()``), in table order."""
    names = {p.name for p in study.parameters}
    return [c for c in data if c not in ID_COLUMNS and c not in names]


def _confidence_band(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(xs, mean, half_width)``: the mean of ``y`` at each distinct ``x`` and its 95 % normal
    confidence half-width over the finite values there."""
    xs = np.unique(x)
    mean = np.array([np.nanmean(y[x == v]) for v in xs])
    n = np.array([np.sum(np.isfinite(y[x == v])) for v in xs])
    sem = np.array(
        [np.nanstd(y[x == v], ddof=1) if c > 1 else 0.0 for v, c in zip(xs, n, strict=True)]
    ) / np.sqrt(np.maximum(n, 1))
    return xs, mean, 1.96 * sem


def _plot_parameter(
    study: StudyDescription, data: Mapping[str, list], name: str, metrics: list[str], path: Path
) -> None:
    """Every metric against one parameter, one panel each."""
    x = np.array(data[name])
    fig = Figure(figsize=(3.6 * len(metrics), 3))
    axes = fig.subplots(1, len(metrics), squeeze=False)
    for ax, m in zip(axes[0], metrics, strict=True):
        y = np.array(data[m], dtype=float)
        if study.kind == "random":  # every trial its own value: a scatter, no bands
            ax.plot(x, y, ".", alpha=0.7)
            ax.set_xlabel(name.split(".", 1)[-1])
            ax.set_title(m, fontsize=8)
            continue
        xs, mean, half = _confidence_band(x, y)
        ax.plot(xs, mean, "o-")
        ax.fill_between(xs, mean - half, mean + half, alpha=0.25)
        ax.set_xlabel(name.split(".")[-1])
        ax.set_title(m, fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def _plot_heatmap(
    a: StudyParameter, b: StudyParameter, data: Mapping[str, list], metric: str, path: Path
) -> None:
    """The mean of one metric over the grid of two parameters (``a`` vertical, ``b`` across)."""
    xa, xb, y = np.array(data[a.name]), np.array(data[b.name]), np.array(data[metric], dtype=float)
    grid = np.array([[np.nanmean(y[(xa == va) & (xb == vb)]) for vb in b.values] for va in a.values])
    fig = Figure(figsize=(5, 4))
    ax = fig.subplots()
    im = ax.imshow(grid, origin="lower", aspect="auto")
    ax.set_xticks(range(len(b.values)), [f"{v:.3g}" for v in b.values])
    ax.set_yticks(range(len(a.values)), [f"{v:.3g}" for v in a.values])
    ax.set_xlabel(b.name.split(".")[-1])
    ax.set_ylabel(a.name.split(".")[-1])
    fig.colorbar(im, label=metric)
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
    written = []
    for p in study.parameters:
        path = out / f"vs_{p.name.replace('.', '_')}.png"
        _plot_parameter(study, data, p.name, metrics, path)
        written.append(path)
    if len(study.parameters) == 2 and study.kind == "grid":
        path = out / "heatmap.png"
        _plot_heatmap(*study.parameters, data, metrics[0], path)
        written.append(path)
    return written


def _cell_means(data: Mapping[str, list], names: list[str], metrics: list[str]) -> list[str]:
    """Markdown table: each cell's parameter values and mean metrics."""
    lines = [
        "| " + " | ".join([*names, *[f"mean {m}" for m in metrics]]) + " |",
        "|" + "---|" * (len(names) + len(metrics)),
    ]
    cell_arr = np.array(data.get("cell", []))
    for c in sorted(set(data.get("cell", []))):
        sel = cell_arr == c
        first = int(np.flatnonzero(sel)[0])
        vals = [f"{data[n][first]:.4g}" for n in names]
        vals += [f"{np.nanmean(np.array(data[m], dtype=float)[sel]):.4g}" for m in metrics]
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
    best = int(np.nanargmin([np.nanmean(err[cell_arr == c]) for c in cells]))
    pick = int(np.flatnonzero(cell_arr == cells[best])[0])
    best_cell = ", ".join(f"{n} = {data[n][pick]:.4g}" for n in names)
    return [*lines, "", f"Smallest mean joint-centre error: {best_cell}."]


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
        *_cell_means(data, names, metrics),
    ]
    if "condition" in data and "joint_centre_error_m" in data:
        lines += _joint_centre_findings(study, data, names)
    lines += ["", *[f"![{p.stem}]({p.name})" for p in plots], ""]
    return "\n".join(lines)
