"""Figures of the reports (matplotlib's object API: no pyplot state, no display needed).

Every ``plot_*`` function draws one figure and writes it as a PNG with :func:`save_figure`.
Lengths are plotted in the units named on the axes (mm, cm); times in seconds.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from calibration.pipeline import Joint
from simbench.io.atomic import atomic_open


def save_figure(fig: Figure, path: Path, *, dpi: int = 100) -> None:
    """Write a figure as PNG, atomically (a crash never leaves a half image)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())


#: At most this many panels in a row: a figure of 4 panels of 4.8 in at 100 dpi is 1920 px wide.
PANELS_PER_ROW = 4


def panel_grid(n: int, width_in: float, height_in: float) -> tuple[np.ndarray, Figure]:
    """``(axes, figure)``: ``n`` panels of ``width_in x height_in`` inches in rows of at most
    :data:`PANELS_PER_ROW` (``axes`` flat, the unused ones hidden)."""
    cols = max(1, min(PANELS_PER_ROW, n))
    rows = max(1, -(-n // cols))
    fig = Figure(figsize=(width_in * cols, height_in * rows))
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return axes, fig


def plot_residual_histograms(joints: Sequence[Joint], path: Path, scale: float) -> None:
    """Residual-norm histogram of every joint (O'Brien Figures 6-7).

    Args:
        joints: the calibrated joints; each ``fit.frame_residual`` is ``(frames,)`` residual
            norms in the input's units (NaN where a frame was dropped).
        path: the PNG to write.
        scale: metres per input unit (the residuals are plotted in mm).
    """
    joints = list(joints)
    axes, fig = panel_grid(len(joints), 3.2, 2.8)
    for k, (ax, joint) in enumerate(zip(axes, joints, strict=False)):
        residual_mm = np.asarray(joint.fit.frame_residual) * scale * 1e3
        ax.hist(residual_mm[np.isfinite(residual_mm)], bins=40, color="#4477aa")
        ax.set_title(joint.name, fontsize=9)
        ax.set_xlabel("residual norm (mm)")
        if k % PANELS_PER_ROW == 0:
            ax.set_ylabel("frames")
    fig.tight_layout()
    save_figure(fig, path)


def plot_limb_errors(humanoid: dict[str, Any], path: Path) -> None:
    """Limb-length error (true - computed, cm) per segment and trial.

    Args:
        humanoid: the validation's ``results["humanoid"]``: ``trials``, each with ``trial`` (its
            name) and ``rows`` ``{limb: {"difference_cm": ...}}``.
        path: the PNG to write.
    """
    trials = humanoid["trials"]
    labels = list(trials[0]["rows"])
    x = np.arange(len(labels))
    width = 0.8 / len(trials)
    fig = Figure(figsize=(10, 3.6))
    ax = fig.subplots()
    for k, trial in enumerate(trials):
        differences_cm = [trial["rows"][label]["difference_cm"] for label in labels]
        ax.bar(x + k * width, differences_cm, width, label=trial["trial"])
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(x + 0.4 - width / 2, labels, rotation=20, fontsize=8)
    ax.set_ylabel("true - computed (cm)")
    ax.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    save_figure(fig, path)


def plot_slip(slip: dict[str, Any], path: Path) -> None:
    """A joint's residual over time with the detected slip intervals.

    Args:
        slip: the validation's ``results["slip"]``: ``time_s`` ``(frames,)``, ``residual_mm`` and
            ``jump_statistic_mm`` ``(frames,)``, ``intervals_s`` ``[(start, end), ...]``,
            ``true_slip_s`` and ``joint`` (its name).
        path: the PNG to write.
    """
    time_s = np.asarray(slip["time_s"])
    fig = Figure(figsize=(10, 3))
    ax = fig.subplots()
    ax.plot(time_s, slip["residual_mm"], lw=0.6, label=f"residual of {slip['joint']}")
    ax.plot(time_s, slip["jump_statistic_mm"], lw=0.8, label="window jump statistic")
    for start_s, end_s in slip["intervals_s"]:
        ax.axvspan(start_s, end_s, color="orange", alpha=0.2, label="detected slipped interval")
    ax.axvline(slip["true_slip_s"], color="k", ls="--", lw=0.8, label="true slip")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    save_figure(fig, path)


def plot_orientation(orientation: dict[str, Any], path: Path) -> None:
    """Orientation error (RMS over sensors) over time for each estimator.

    Args:
        orientation: the validation's ``results["orientation"]``: ``time_s`` ``(frames,)`` and
            ``methods`` ``{label: {"per_frame_deg": (frames,), "total_rmse_deg": ...}}``.
        path: the PNG to write.
    """
    time_s = np.asarray(orientation["time_s"])
    fig = Figure(figsize=(10, 3))
    ax = fig.subplots()
    for label, method in orientation["methods"].items():
        ax.plot(
            time_s,
            method["per_frame_deg"],
            lw=0.7,
            label=f"{label} ({method['total_rmse_deg']:.1f} deg RMS)",
        )
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("error (deg, RMS over sensors)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def plot_pictures(images: Sequence[np.ndarray], titles: Sequence[str], path: Path) -> None:
    """Rendered pictures side by side, each with its title.

    Args:
        images: ``(height, width, 3)`` uint8 RGB pictures.
        titles: one title per picture.
        path: the PNG to write.
    """
    if len(images) != len(titles):
        raise ValueError(f"plot_pictures: {len(images)} pictures, {len(titles)} titles")
    axes, fig = panel_grid(len(images), 4.8, 3.8)
    for ax, image, title in zip(axes, images, titles, strict=False):
        ax.imshow(image)
        ax.set_title(title, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    save_figure(fig, path)
