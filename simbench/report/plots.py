"""Figures of the reports (matplotlib's object API: no pyplot state, no display needed).

Every ``plot_*`` function draws one figure with its ``*_figure`` function and writes it as a PNG
with :func:`save_figure`. Lengths are plotted in the units named on the axes (mm, cm); times in
seconds. Every colour comes from :data:`PALETTE` (Okabe and Ito's colour-blind-safe set) and
images of a quantity use :data:`SEQUENTIAL_CMAP`; no figure is wider than :data:`MAX_WIDTH_PX`.
"""

from __future__ import annotations

import io
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from calibration.pipeline import Joint
from simbench.io.atomic import atomic_open

if TYPE_CHECKING:  # matplotlib is imported where a figure is made (:func:`new_figure`)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

#: Okabe and Ito (2008), "Color Universal Design": eight colours told apart with every common
#: colour-vision deficiency. The one place the reports' colours come from.
OKABE_ITO: dict[str, str] = {
    "black": "#000000",
    "orange": "#E69F00",
    "sky blue": "#56B4E9",
    "bluish green": "#009E73",
    "yellow": "#F0E442",
    "blue": "#0072B2",
    "vermillion": "#D55E00",
    "reddish purple": "#CC79A7",
}
#: The order in which a figure's series take the colours: yellow (faint on white) and black (kept
#: for reference lines, :data:`INK`) last.
PALETTE: tuple[str, ...] = tuple(
    OKABE_ITO[name]
    for name in (
        "blue",
        "orange",
        "bluish green",
        "vermillion",
        "reddish purple",
        "sky blue",
        "yellow",
        "black",
    )
)
#: Reference lines (zero, identity, the truth's time), medians, outlines.
INK = OKABE_ITO["black"]
#: The truth and the estimate wherever both are drawn (pictures, scatter legends).
TRUTH_COLOUR, ESTIMATE_COLOUR = OKABE_ITO["blue"], OKABE_ITO["vermillion"]
#: Colour map of images of a quantity (heat maps): cividis, made to read the same with
#: colour-vision deficiency (Nunez et al. 2018, PLoS ONE 13(7)).
SEQUENTIAL_CMAP = "cividis"

#: No figure is wider than this (a report's page is narrower; wider images only shrink).
MAX_WIDTH_PX = 2000
#: The resolution the figures are written at, dots per inch.
DPI = 100


def save_figure(fig: Figure, path: Path, *, dpi: int = DPI) -> None:
    """Write a figure as PNG, atomically (a crash never leaves a half image).

    Raises:
        ValueError: the figure would be wider than :data:`MAX_WIDTH_PX` pixels.
    """
    width_px = fig.get_figwidth() * dpi
    if width_px > MAX_WIDTH_PX + 0.5:
        raise ValueError(f"{path.name}: {width_px:.0f} px wide, more than {MAX_WIDTH_PX} px")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())


#: At most this many panels in a row: a figure of 4 panels of 4.8 in at 100 dpi is 1920 px wide.
PANELS_PER_ROW = 4


def use_palette(axes: Iterable[Axes]) -> None:
    """Make the axes take their lines' and patches' colours from :data:`PALETTE`, in order."""
    for ax in axes:
        ax.set_prop_cycle(color=PALETTE)


def new_figure(width_in: float, height_in: float) -> Figure:
    """An empty figure of ``width_in x height_in`` inches. matplotlib is imported here, the first
    time a report draws (0.6 s, a third of a command's start): the commands that draw nothing
    (``calibrate``, ``simulate``, ``--help``) do not load it."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in))


def legend_mark(**style: Any) -> Line2D:
    """A legend entry drawn as a line or marker of ``style`` (matplotlib's ``Line2D`` keywords)."""
    from matplotlib.lines import Line2D

    return Line2D([], [], **style)


def figure_axes(
    width_in: float, height_in: float, *, width_ratios: Sequence[float] = (1.0,)
) -> tuple[np.ndarray, Figure]:
    """``(axes, figure)``: one row of ``len(width_ratios)`` panels in a ``width_in x height_in``
    inch figure, coloured from :data:`PALETTE`."""
    fig = new_figure(width_in, height_in)
    axes = fig.subplots(1, len(width_ratios), squeeze=False, width_ratios=list(width_ratios)).ravel()
    use_palette(axes)
    return axes, fig


def panel_grid(n: int, width_in: float, height_in: float) -> tuple[np.ndarray, Figure]:
    """``(axes, figure)``: ``n`` panels of ``width_in x height_in`` inches in rows of at most
    :data:`PANELS_PER_ROW` (``axes`` flat, the unused ones hidden), coloured from
    :data:`PALETTE`."""
    cols = max(1, min(PANELS_PER_ROW, n))
    rows = max(1, -(-n // cols))
    fig = new_figure(width_in * cols, height_in * rows)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    use_palette(axes)
    for ax in axes[n:]:
        ax.set_visible(False)
    return axes, fig


def residual_histograms_figure(joints: Sequence[Joint], scale: float, session: str = "") -> Figure:
    """Residual-norm histogram of every joint (O'Brien Figures 6-7).

    Args:
        joints: the calibrated joints; each ``fit.frame_residual`` is ``(frames,)`` residual
            norms in the input's units (NaN where a frame was dropped).
        scale: metres per input unit (the residuals are plotted in mm).
        session: what the residuals are of (a file, a trial), the figure's title.
    """
    joints = list(joints)
    axes, fig = panel_grid(len(joints), 3.2, 2.8)
    for k, (ax, joint) in enumerate(zip(axes, joints, strict=False)):
        residual_mm = np.asarray(joint.fit.frame_residual) * scale * 1e3
        ax.hist(residual_mm[np.isfinite(residual_mm)], bins=40, color=PALETTE[0])
        ax.set_title(joint.name, fontsize=9)
        ax.set_xlabel("residual norm (mm)")
        if k % PANELS_PER_ROW == 0:
            ax.set_ylabel("frames")
    if session:
        fig.suptitle(f"joint residuals: {session}", fontsize=10)
    fig.tight_layout()
    return fig


def plot_residual_histograms(joints: Sequence[Joint], path: Path, scale: float, session: str = "") -> None:
    """Write :func:`residual_histograms_figure` to ``path`` (PNG)."""
    save_figure(residual_histograms_figure(joints, scale, session), path)


#: Bars of the trials of one group (subject and motion) share its colour and differ in hatching.
HATCHES = ("", "//", "..", "xx", "\\\\", "--")
#: The marker of each motion in the limb-length scatter (any other motion: a diamond).
MOTION_MARKERS = {"exercise": "o", "walk": "^"}


def _trial_groups(trials: Sequence[dict[str, Any]]) -> dict[tuple[str, str], str]:
    """``{(subject, motion): colour}`` in the order the groups first appear."""
    groups = dict.fromkeys((t["subject"], t["motion"]) for t in trials)
    return {g: PALETTE[k % len(PALETTE)] for k, g in enumerate(groups)}


def limb_errors_figure(humanoid: dict[str, Any]) -> Figure:
    """Limb-length error (computed - true, cm) per segment and trial: one colour per subject
    and motion, the trials of one by their hatching; the legend below the axes.

    Args:
        humanoid: the validation's ``results["humanoid"]``: ``trials``, each with ``trial`` (its
            name), ``subject``, ``motion`` and ``rows`` ``{limb: {"difference_cm": ...}}``.
    """
    trials = humanoid["trials"]
    labels = list(trials[0]["rows"])
    colours = _trial_groups(trials)
    x = np.arange(len(labels))
    width = 0.8 / len(trials)
    (ax,), fig = figure_axes(10, 4.2)
    seen: dict[tuple[str, str], int] = {}
    for k, trial in enumerate(trials):
        group = (trial["subject"], trial["motion"])
        seen[group] = seen.get(group, -1) + 1
        differences_cm = [trial["rows"][label]["difference_cm"] for label in labels]
        hatch = HATCHES[seen[group] % len(HATCHES)]
        ax.bar(
            x + k * width,
            differences_cm,
            width,
            label=trial["trial"],
            color=colours[group],
            hatch=hatch,
            edgecolor=INK,
            linewidth=0.3,
        )
    ax.axhline(0, color=INK, lw=0.8)
    ax.set_xticks(x + 0.4 - width / 2, labels, rotation=20, fontsize=8)
    ax.set_ylabel("computed - true (cm)")
    ax.legend(fontsize=7, ncol=5, loc="upper center", bbox_to_anchor=(0.5, -0.25), frameon=False)
    fig.tight_layout()
    return fig


def plot_limb_errors(humanoid: dict[str, Any], path: Path) -> None:
    """Write :func:`limb_errors_figure` to ``path`` (PNG)."""
    save_figure(limb_errors_figure(humanoid), path)


def _finite(values: Any) -> np.ndarray:
    """The finite values of a series (``None`` from JSON counts as missing)."""
    x = np.array([np.nan if v is None else v for v in values], dtype=float)
    return x[np.isfinite(x)]


@dataclass(frozen=True)
class LimbSpread:
    """One limb of one subject over the trials: its true length and each trial's estimate.

    Attributes:
        subject: the subject (``male``, ``female``).
        limb: the limb (``Right Lower Leg``).
        true_mm: the true length, mm.
        estimated_mm: ``(trials,)`` the estimated length of each of the subject's trials, mm
            (NaN where a trial has none).
        motions: ``(trials,)`` each trial's motion (``exercise``, ``walk``).
    """

    subject: str
    limb: str
    true_mm: float
    estimated_mm: tuple[float, ...]
    motions: tuple[str, ...]

    def __post_init__(self) -> None:
        if len(self.estimated_mm) != len(self.motions):
            raise ValueError(
                f"{self.subject} {self.limb}: {len(self.estimated_mm)} estimates, {len(self.motions)} motions"
            )

    @property
    def mean_mm(self) -> float:
        """The mean estimate over the trials that have one, mm (NaN when none has)."""
        finite = np.asarray(self.estimated_mm)[np.isfinite(self.estimated_mm)]
        return float(finite.mean()) if finite.size else float("nan")

    @property
    def sd_mm(self) -> float:
        """The estimates' sample standard deviation over trials, mm (0 with fewer than two)."""
        finite = np.asarray(self.estimated_mm)[np.isfinite(self.estimated_mm)]
        return float(finite.std(ddof=1)) if finite.size > 1 else 0.0


def limb_spread(humanoid: dict[str, Any]) -> list[LimbSpread]:
    """Each subject's limbs over that subject's trials (seeds), in the order they first appear.

    Args:
        humanoid: the validation's ``results["humanoid"]``: ``trials``, each with ``subject``,
            ``motion`` and ``rows`` ``{limb: {"true_cm": ..., "computed_cm": ...}}`` (``None``
            for a length not estimated).
    """
    spreads = []
    for subject in dict.fromkeys(t["subject"] for t in humanoid["trials"]):
        trials = [t for t in humanoid["trials"] if t["subject"] == subject]
        for limb, row in trials[0]["rows"].items():
            computed_cm = [t["rows"][limb]["computed_cm"] for t in trials]
            spreads.append(
                LimbSpread(
                    subject=subject,
                    limb=limb,
                    true_mm=10.0 * row["true_cm"],
                    estimated_mm=tuple(np.nan if c is None else 10.0 * c for c in computed_cm),
                    motions=tuple(t["motion"] for t in trials),
                )
            )
    return spreads


def _limb_legend(subjects: dict[str, str]) -> list[Line2D]:
    """Legend handles of the limb-length scatter: subjects by colour, motions by marker."""
    handles = [
        legend_mark(color=colour, marker="s", ls="none", label=subject)
        for subject, colour in subjects.items()
    ]
    handles += [
        legend_mark(color=INK, marker=marker, ls="none", mfc="none", label=f"one {motion} trial")
        for motion, marker in MOTION_MARKERS.items()
    ]
    handles.append(legend_mark(color=INK, marker="_", ms=12, label="mean +/- 1 s.d. over trials"))
    handles.append(legend_mark(color=INK, ls="--", lw=0.8, label="estimate = truth"))
    return handles


def _draw_spread(ax: Axes, spread: LimbSpread, colour: str, *, minus_truth: bool) -> None:
    """One limb's trials (a marker each) and their mean +/- 1 s.d. at its true length."""
    offset = spread.true_mm if minus_truth else 0.0
    estimated = np.asarray(spread.estimated_mm) - offset
    for motion in dict.fromkeys(spread.motions):
        picked = np.array([m == motion for m in spread.motions])
        ax.scatter(
            np.full(picked.sum(), spread.true_mm),
            estimated[picked],
            s=22,
            marker=MOTION_MARKERS.get(motion, "D"),
            facecolors="none",
            edgecolors=colour,
            linewidths=1.0,
        )
    ax.errorbar(
        spread.true_mm, spread.mean_mm - offset, yerr=spread.sd_mm, fmt="_", ms=12, color=colour, capsize=3
    )


def limb_lengths_figure(humanoid: dict[str, Any]) -> Figure:
    """Estimated against true limb lengths (mm) with the spread over each subject's trials
    (seeds): left the lengths with the identity line, right the estimate minus the truth.

    Args:
        humanoid: the validation's ``results["humanoid"]`` (see :func:`limb_spread`).
    """
    spreads = limb_spread(humanoid)
    subjects = {s: PALETTE[k % len(PALETTE)] for k, s in enumerate(dict.fromkeys(x.subject for x in spreads))}
    (ax, ax_diff), fig = figure_axes(12, 4.6, width_ratios=(1.0, 1.0))
    for k, spread in enumerate(spreads):
        _draw_spread(ax, spread, subjects[spread.subject], minus_truth=False)
        _draw_spread(ax_diff, spread, subjects[spread.subject], minus_truth=True)
        if np.isfinite(spread.mean_mm):  # the limb named beside its error bar, alternately above and below
            ax_diff.annotate(
                spread.limb,
                (spread.true_mm, spread.mean_mm - spread.true_mm),
                xytext=(4, 6 if k % 2 else -9),
                textcoords="offset points",
                fontsize=6,
                color=subjects[spread.subject],
            )
    lengths_mm = _finite([x for s in spreads for x in (s.true_mm, *s.estimated_mm)])
    span = np.array([lengths_mm.min() - 20.0, lengths_mm.max() + 20.0])
    ax.plot(span, span, "--", color=INK, lw=0.8)
    ax_diff.axhline(0.0, ls="--", color=INK, lw=0.8)
    ax.set(xlabel="true length (mm)", ylabel="estimated length (mm)", title="estimate against truth")
    ax_diff.set(xlabel="true length (mm)", ylabel="estimated - true (mm)", title="error, over trials")
    ax.set(xlim=span, ylim=span, aspect="equal")
    fig.legend(handles=_limb_legend(subjects), loc="lower center", ncol=6, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


def plot_limb_lengths(humanoid: dict[str, Any], path: Path) -> None:
    """Write :func:`limb_lengths_figure` to ``path`` (PNG)."""
    save_figure(limb_lengths_figure(humanoid), path)


def slip_figure(slip: dict[str, Any]) -> Figure:
    """A joint's residual over time with the detected slip intervals.

    Args:
        slip: the validation's ``results["slip"]``: ``time_s`` ``(frames,)``, ``residual_mm`` and
            ``jump_statistic_mm`` ``(frames,)``, ``intervals_s`` ``[(start, end), ...]``,
            ``true_slip_s`` and ``joint`` (its name).
    """
    time_s = np.asarray(slip["time_s"])
    (ax,), fig = figure_axes(10, 3)
    ax.plot(time_s, slip["residual_mm"], lw=0.6, color=PALETTE[0], label=f"residual of {slip['joint']}")
    ax.plot(time_s, slip["jump_statistic_mm"], lw=0.8, color=PALETTE[1], label="window jump statistic")
    for k, (start_s, end_s) in enumerate(slip["intervals_s"]):
        label = "detected slipped interval" if k == 0 else None
        ax.axvspan(start_s, end_s, color=PALETTE[2], alpha=0.2, label=label)
    ax.axvline(slip["true_slip_s"], color=INK, ls="--", lw=0.8, label="true slip")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig


def plot_slip(slip: dict[str, Any], path: Path) -> None:
    """Write :func:`slip_figure` to ``path`` (PNG)."""
    save_figure(slip_figure(slip), path)


def orientation_figure(orientation: dict[str, Any]) -> Figure:
    """Orientation error per estimator: left its distribution over the frames (box plot), right
    the default estimator's error over time, the legend above the data.

    Args:
        orientation: the validation's ``results["orientation"]``: ``time_s`` ``(frames,)``,
            ``default`` (a method's label) and ``methods`` ``{label: {"per_frame_deg":
            (frames,), "total_rmse_deg": ...}}``; each frame's error is the RMS over sensors.
    """
    methods = orientation["methods"]
    default = orientation.get("default", next(iter(methods)))
    (ax_box, ax_time), fig = figure_axes(14, 4.2, width_ratios=(1.0, 1.15))
    labels = list(methods)
    boxes = ax_box.boxplot(
        [_finite(methods[m]["per_frame_deg"]) for m in labels],
        orientation="horizontal",
        whis=(5, 95),
        showfliers=False,
        patch_artist=True,
        tick_labels=[f"{m}\n{methods[m]['total_rmse_deg']:.1f} deg RMS" for m in labels],
        medianprops={"color": INK},
        whiskerprops={"color": INK},
        capprops={"color": INK},
    )
    for k, box in enumerate(boxes["boxes"]):
        box.set(facecolor=PALETTE[k % len(PALETTE)], edgecolor=INK, alpha=0.8)
    ax_box.invert_yaxis()  # the first method on top
    ax_box.set_xscale("log")
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # where a figure is made

    ax_box.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax_box.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax_box.xaxis.set_minor_formatter(NullFormatter())
    ax_box.tick_params(axis="y", labelsize=7)
    ax_box.set_xlabel("error per frame (deg, RMS over sensors; log scale)")
    ax_box.set_title("over frames: median, quartiles, 5-95 %", fontsize=9)
    trace = methods[default]
    time_s = np.asarray(orientation["time_s"])
    per_frame = np.array([np.nan if v is None else v for v in trace["per_frame_deg"]], dtype=float)
    colour = PALETTE[labels.index(default) % len(PALETTE)]
    ax_time.plot(time_s, per_frame, lw=0.8, color=colour, label=f"{default} (the default), per frame")
    rms = trace["total_rmse_deg"]
    ax_time.axhline(rms, color=INK, ls="--", lw=0.8, label=f"its RMS over the session, {rms:.2f} deg")
    ax_time.set_ylim(bottom=0.0)
    ax_time.set_xlabel("time (s)")
    ax_time.set_ylabel("error (deg, RMS over sensors)")
    ax_time.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2, frameon=False)
    fig.tight_layout()
    return fig


def plot_orientation(orientation: dict[str, Any], path: Path) -> None:
    """Write :func:`orientation_figure` to ``path`` (PNG)."""
    save_figure(orientation_figure(orientation), path)


@dataclass(frozen=True)
class LegendMark:
    """A legend entry of a picture's marks: its text, colour and matplotlib marker."""

    label: str
    colour: str
    marker: str


def pictures_figure(
    images: Sequence[np.ndarray], titles: Sequence[str], *, legend: Sequence[LegendMark] = ()
) -> Figure:
    """Rendered pictures in rows of at most :data:`PANELS_PER_ROW`, each with its title, and a
    legend of their marks below them.

    Args:
        images: ``(height, width, 3)`` uint8 RGB pictures.
        titles: one title per picture.
        legend: the marks drawn in the pictures (none: no legend).

    Raises:
        ValueError: not one title per picture.
    """
    if len(images) != len(titles):
        raise ValueError(f"plot_pictures: {len(images)} pictures, {len(titles)} titles")
    axes, fig = panel_grid(len(images), 4.8, 3.9)
    fig.set_layout_engine("constrained")  # keeps the titles of aspect-locked images inside
    for ax, image, title in zip(axes, images, titles, strict=False):
        ax.imshow(image)
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    if legend:
        handles = [
            legend_mark(ls="none", marker=m.marker, ms=10, color=m.colour, mec=INK, label=m.label)
            for m in legend
        ]
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9, frameon=False)
    return fig


def plot_pictures(
    images: Sequence[np.ndarray], titles: Sequence[str], path: Path, *, legend: Sequence[LegendMark] = ()
) -> None:
    """Write :func:`pictures_figure` to ``path`` (PNG)."""
    save_figure(pictures_figure(images, titles, legend=legend), path)
