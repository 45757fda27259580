"""The report of a recording's digital twin (``simbench twin --out DIR``).

``index.md``/``index.html``/``results.json`` (:func:`simbench.report.output.write_report_files`)
and two figures: ``traces.png``, the real and the twin's readings overlaid over the window, one
row per sensor kind and one column per axis; ``spectra.png``, the power spectral density of the
real reading, the twin's and their difference per kind (Welch, over the compared samples, summed
over the axes). The tables: what was identified, each kind's R^2 (with the ceiling white noise
leaves), rms and the difference's spectrum, and each orientation method's error on the real
recording and on the twin.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from simbench.report.markdown import markdown_table
from simbench.report.output import write_report_files
from simbench.report.plots import INK, PALETTE, new_figure, save_figure, use_palette
from simbench.twin import compare
from simbench.twin.run import KINDS, RATIO_FACTOR, TwinResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: Each kind's label and unit on the figures.
KIND_LABELS = {
    "acc": ("accelerometer", "m/s^2"),
    "gyro": ("gyroscope", "rad/s"),
    "mag": ("magnetometer", "uT"),
}
REAL_COLOUR, SIM_COLOUR, DIFF_COLOUR = PALETTE[0], PALETTE[1], PALETTE[2]


def traces_figure(result: TwinResult) -> Figure:
    """Real (blue) and twin (orange) readings over ``result.window_s``: rows acc, gyro, mag;
    columns x, y, z; samples not compared (still, or near an optical gap) greyed."""
    start, end = result.window_s
    t = result.time_s
    inside = (t >= start) & (t <= end)
    fig = new_figure(14.4, 8.4)
    axes = fig.subplots(3, 3, sharex=True, squeeze=False)
    use_palette(axes.ravel())
    for row, kind in enumerate(KINDS):
        name, unit = KIND_LABELS[kind]
        for axis in range(3):
            ax = axes[row, axis]
            ax.plot(t[inside], result.real[kind][inside, axis], lw=0.9, color=REAL_COLOUR, label="real")
            ax.plot(t[inside], result.sim[kind][inside, axis], lw=0.9, color=SIM_COLOUR, label="twin")
            out = inside & ~result.compared
            if out.any():
                lo, hi = ax.get_ylim()
                ax.fill_between(
                    t[inside], lo, hi, where=out[inside], color=INK, alpha=0.08, lw=0, label="not compared"
                )
                ax.set_ylim(lo, hi)
            ax.set_title(f"{name} {'xyz'[axis]}", fontsize=9)
            if axis == 0:
                ax.set_ylabel(unit)
            if row == 2:
                ax.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=8, loc="lower left", bbox_to_anchor=(0.0, 1.12), ncol=3, frameon=False)
    fig.tight_layout()
    return fig


def spectra_figure(result: TwinResult) -> Figure:
    """Power spectral density of the real reading, the twin's and their difference, per kind
    (log-log), over the compared samples."""
    fig = new_figure(14.4, 4.0)
    axes = fig.subplots(1, 3, squeeze=False).ravel()
    use_palette(axes)
    for ax, kind in zip(axes, KINDS, strict=True):
        name, unit = KIND_LABELS[kind]
        real, sim = result.real[kind], result.sim[kind]
        for x, label, colour in (
            (real, "real", REAL_COLOUR),
            (sim, "twin", SIM_COLOUR),
            (real - sim, "real - twin", DIFF_COLOUR),
        ):
            f, p = compare.spectrum(x, result.rate_hz, result.compared)
            ax.loglog(f[1:], p[1:], lw=0.9, color=colour, label=label)
        ax.set_title(f"{name}: R^2 {result.readings[kind]['r2']:.4f}", fontsize=9)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel(f"PSD ({unit})^2/Hz, axes summed")
    axes[0].legend(fontsize=8, frameon=False)
    fig.tight_layout()
    return fig


def _vec(values: Any, fmt: str = "{:.3g}") -> str:
    return "(" + ", ".join(fmt.format(v) for v in values) + ")"


def identified_rows(ident: Mapping[str, Any]) -> list[list[Any]]:
    """The identified quantities as table rows ``[quantity, value, how]`` (``ident``:
    :meth:`simbench.twin.Identified.as_dict`)."""
    off = ident["time_offset_ms"]
    return [
        [
            "still phases",
            f"{100 * ident['still']['fraction']:.0f} % of the samples, {ident['still']['phases']}",
            ident["still"]["rule"],
        ],
        [
            "time offset, gyroscope (ms)",
            f"{off['gyro']:.2f}",
            "cross-correlation of the real and the optical gyroscope, parabolic peak",
        ],
        ["time offset, accelerometer (ms)", f"{off['acc']:.2f}", "cross-correlation, as the gyroscope"],
        [
            "time offset, magnetometer (ms)",
            f"{off['mag']:.2f}",
            "cross-correlation with the fitted field model",
        ],
        ["gyroscope bias (rad/s)", _vec(ident["gyro_bias_rad_s"]), "mean of real less optical, still phases"],
        [
            "gyroscope noise density (rad/s/sqrt(Hz))",
            _vec(ident["gyro_noise_density_rad_s_per_sqrt_hz"]),
            "std about each still phase's mean / sqrt(rate)",
        ],
        [
            "accelerometer bias (m/s^2)",
            _vec(ident["acc_bias_m_s2"]),
            "mean of real less optical, still phases",
        ],
        [
            "accelerometer noise density (m/s^2/sqrt(Hz))",
            _vec(ident["acc_noise_density_m_s2_per_sqrt_hz"]),
            "as the gyroscope",
        ],
        ["magnetometer noise (uT)", _vec(ident["mag_noise_ut"]), "std about each still phase's mean"],
        [
            "axis misalignment (deg)",
            f"{ident['misalignment_deg']:.3f} about {_vec(ident['misalignment_rotvec_deg'])}",
            "Kabsch of the gyroscope vectors in motion; applied to all three sensors",
        ],
        [
            "accelerometer lever arm (mm)",
            _vec(ident["lever_arm_mm"], "{:.1f}"),
            "least squares of the rotation's accelerations (IMU frame)",
        ],
        [
            "hard iron (uT)",
            _vec(ident["hard_iron_ut"]),
            "m = A R^T (b + G dp) + h, least squares"
            + (
                ""
                if ident["mag_field_determined"]
                else "; NOT DETERMINED apart from the field: the orientations span too little (direction "
                f"spread {_vec(ident['mag_direction_spread'], '{:.3f}')}), the readings are predicted all "
                "the same"
            ),
        ],
        ["soft iron A (det 1), rows", "; ".join(_vec(r, "{:.4f}") for r in ident["soft_iron"]), "as above"],
        [
            "local field b, ENU (uT)",
            f"{_vec(ident['field_w_ut'])}: {ident['field_strength_ut']:.1f} uT, dip "
            f"{ident['field_inclination_deg']:.1f} deg, declination {ident['field_declination_deg']:.1f} deg",
            "as above",
        ],
        [
            "field gradient G (uT/m), rows",
            "; ".join(_vec(r, "{:.2f}") for r in ident["field_gradient_ut_per_m"]),
            "symmetric, traceless",
        ],
        [
            "magnetometer samples left out as disturbed",
            f"{100 * ident['mag_disturbed_fraction']:.1f} %",
            "residual above 3 x the inliers' median, refitted",
        ],
    ]


def readings_rows(readings: Mapping[str, Any]) -> list[list[Any]]:
    """Per kind: R^2, noise ceiling, rms, the difference's median and peak frequency and band shares."""
    rows = []
    for kind in KINDS:
        r = readings[kind]
        spec = r["spectrum"]
        rows.append(
            [
                KIND_LABELS[kind][0],
                f"{r['r2']:.4f}",
                f"{r['r2_noise_ceiling']:.4f}",
                f"{r['rms']:.3g} {r['unit']}",
                f"{spec['median_frequency_hz']:.2f}",
                f"{spec['peak_frequency_hz']:.2f}",
                ", ".join(f"{100 * v:.0f} %" for v in spec["band_share"].values()),
            ]
        )
    return rows


def orientation_rows(orientation: Mapping[str, Any]) -> list[list[Any]]:
    """Per method: error on the real recording, on the twin, their ratio, within the factor."""
    return [
        [
            method,
            f"{v['real_deg']:.2f}",
            f"{v['twin_deg']:.2f}",
            f"{v['ratio']:.2f}",
            "yes" if 1 / RATIO_FACTOR <= v["ratio"] <= RATIO_FACTOR else "NO",
        ]
        for method, v in orientation.items()
    ]


def twin_markdown(d: Mapping[str, Any], images: Mapping[str, str]) -> str:
    """The report in Markdown (``d``: :meth:`simbench.twin.TwinResult.as_dict`)."""
    cov, settings = d["coverage"], d["settings"]
    bands = ", ".join(next(iter(d["readings"].values()))["spectrum"]["band_share"])
    start, end = d["window_s"]
    lines = [
        f"# Digital twin of `{Path(d['file']).name}`",
        "",
        "The IMU's readings simulated from the optical pose of its housing (orientation smoothed below "
        f"{settings['cutoff_hz']:g} Hz, position below {settings['position_cutoff_hz']:g} Hz, "
        "Savitzky-Golay), "
        "with the deterministic errors the recording shows, compared sample by sample with the real "
        f"readings over the motion phase ({100 * cov['compared_fraction']:.0f} % of the samples; "
        f"{100 * cov['optical_gap_fraction']:.1f} % of the rows have no optical pose, and "
        f"{100 * cov['motion_excluded_fraction']:.1f} % of the motion samples lie within the smoothing's "
        "half-window of such a gap and are left out). Random noise cannot match sample by sample: R^2 and "
        "rms compare the deterministic twin; the noise ceiling is the R^2 a twin exact but for the sensor's "
        "white noise would reach.",
        "",
        "## Identified",
        "",
        markdown_table(["quantity", "value", "how"], identified_rows(d["identified"])),
        "",
        "## Readings",
        "",
        markdown_table(
            [
                "sensor",
                "R^2",
                "noise ceiling",
                "rms",
                "difference: median Hz",
                "peak Hz",
                f"power in {bands}",
            ],
            readings_rows(d["readings"]),
        ),
        "",
    ]
    if d["orientation"]:
        lines += [
            "## Orientation",
            "",
            "Each method through the estimator registry on the real recording and on the twin with white "
            f"noise of the identified densities (seed {d['seed']}), BROAD's total error (RMSE, deg) over the "
            f"samples compared; the twin predicts the real error when the ratio is within {RATIO_FACTOR:g}x.",
            "",
            markdown_table(
                ["method", "real (deg)", "twin (deg)", "twin / real", f"within {RATIO_FACTOR:g}x"],
                orientation_rows(d["orientation"]),
            ),
            "",
        ]
    lines += [f"## Figures (window {start:g}-{end:g} s)", ""]
    lines += [f"![{title}]({name})\n\n*{title}*\n" for title, name in images.items()]
    if d["notes"]:
        lines += ["## Notes", "", *[f"- {n}" for n in d["notes"]], ""]
    versions = ", ".join(f"{k} {v}" for k, v in d["versions"].items())
    lines += ["## Provenance", "", f"`{d['file']}`; {versions}; {d['run_time_s']:.1f} s.", ""]
    return "\n".join(lines)


def write_twin_report(result: TwinResult, out: Path) -> dict[str, Path]:
    """Write the report into ``out`` (made if missing); returns the paths written (``md``,
    ``html``, ``json``, ``traces``, ``spectra``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    save_figure(traces_figure(result), out / "traces.png")
    save_figure(spectra_figure(result), out / "spectra.png")
    images = {
        "Real and twin readings over the window (grey: not compared)": "traces.png",
        "Spectra of the real reading, the twin's and their difference": "spectra.png",
    }
    d = result.as_dict()
    paths = write_report_files(out, twin_markdown(d, images), d)
    return {**paths, "traces": out / "traces.png", "spectra": out / "spectra.png"}
