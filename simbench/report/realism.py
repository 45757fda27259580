"""The validation report's "Realism" section: real recordings beside their simulated counterparts.

Renders the figures of :func:`simbench.experiments.realism.run_realism`: one table per real
recording (statistic, real, simulated, ratio, within the factor), the counterpart that was
simulated (preset, model, motion, seeds), and for every statistic outside the factor a sentence
on what limits it; then each BROAD trial's digital twin (readings R^2 against issue 41's targets,
what was identified, the orientation methods on the real recording and on the twin). Lengths are
printed in mm, angles in degrees, fractions in per cent; ratios are unit-free.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from simbench.report.markdown import markdown_table
from simbench.twin import R2_TARGETS, RATIO_FACTOR

#: How each statistic is labelled and printed: (label, scale, format).
_FORMATS: dict[str, tuple[str, float, str]] = {
    "accel_norm_spread": ("|a| spread, std / median (%)", 100.0, "{:.2f}"),
    "mag_norm_spread": ("|m| spread, std / median (%)", 100.0, "{:.2f}"),
    "mag_norm_outliers": ("|m| more than 10 % off its median (% of samples)", 100.0, "{:.3f}"),
    "dip_median_deg": ("dip angle, median (deg)", 1.0, "{:.1f}"),
    "dip_spread_deg": ("dip angle, spread (q84 - q16) / 2 (deg)", 1.0, "{:.2f}"),
    "acc_disturbed_fraction": ("accelerometer flagged disturbed (% of samples)", 100.0, "{:.1f}"),
    "mag_disturbed_fraction": ("magnetometer flagged disturbed (% of samples)", 100.0, "{:.1f}"),
    "hip_residual_rms_m": ("hip joint residual, rms (mm)", 1e3, "{:.2f}"),
    "knee_residual_rms_m": ("knee joint residual, rms (mm)", 1e3, "{:.2f}"),
    "hip_residual_relative_frequency": ("hip residual median frequency / motion's", 1.0, "{:.2f}"),
    "hip_residual_hf_fraction": ("hip residual power above 2 Hz (%)", 100.0, "{:.2f}"),
    "rigidity_pelvis_m": ("pelvis cluster rigidity residual, median (mm)", 1e3, "{:.2f}"),
    "rigidity_thigh_r_m": ("thigh cluster rigidity residual, median (mm)", 1e3, "{:.2f}"),
    "rigidity_shank_r_m": ("shank cluster rigidity residual, median (mm)", 1e3, "{:.2f}"),
    "slip_alarms_per_hour": ("slip alarms per hour of joint time", 1.0, "{:.1f}"),
}


def _label(stat: str) -> str:
    return _FORMATS.get(stat, (stat, 1.0, "{:.4g}"))[0]


def _value(stat: str, value: float) -> str:
    _, scale, fmt = _FORMATS.get(stat, (stat, 1.0, "{:.4g}"))
    return fmt.format(value * scale)


def _ratio(r: float | None) -> str:
    return "undefined (real 0)" if r is None else f"{r:.2f}"


def _rows(rec: Mapping[str, Any]) -> list[list[Any]]:
    return [
        [
            _label(stat),
            _value(stat, real),
            _value(stat, rec["simulated"][stat]),
            _ratio(rec["ratios"][stat]),
            "yes" if rec["within_factor"][stat] else "NO",
        ]
        for stat, real in rec["real"].items()
    ]


def _counterpart(cp: Mapping[str, Any]) -> str:
    seeds = ", ".join(str(s) for s in cp["seeds"])
    where = cp.get("sensor") or ", ".join(cp.get("sensors", []))
    return (
        f"Simulated counterpart: preset `{cp['preset']}`, model `{cp['model']}` ({where}), "
        f"{cp['motion']}; {cp['duration_s']:g} s at {cp['rate_hz']:.1f} Hz, seeds {seeds} (averaged)."
    )


def _limits(rec: Mapping[str, Any]) -> list[str]:
    out = []
    for stat, ok in rec["within_factor"].items():
        if ok:
            continue
        why = rec.get("limits", {}).get(stat, "no cause identified yet")
        out.append(f"- *{_label(stat)}*: ratio {_ratio(rec['ratios'][stat])}, outside the factor: {why}.")
    return out


def realism_markdown(realism: Mapping[str, Any]) -> list[str]:
    """The section's Markdown lines (a ``## Realism`` heading, one table per recording).

    Args:
        realism: the result of :func:`simbench.experiments.realism.run_realism`.
    """
    factor = realism["factor"]
    lines = [
        "## Realism",
        "",
        f"The statistics an estimator sees on each real recording in `{realism['data_dir']}`, beside "
        f"those of a simulated counterpart (same kind of sensors, similar motion), computed by the "
        f"same functions on both; a statistic is realistic when simulated / real lies within a factor "
        f"{factor:g} (between {1 / factor:.2f} and {factor:g}). Which preset values are cited and "
        "which fitted to which recording is written in the presets (`simbench/sim/presets/`).",
        "",
    ]
    if realism["missing"]:
        lines += [f"Not found, skipped: {', '.join(f'`{m}`' for m in realism['missing'])}.", ""]
    for name, rec in realism["recordings"].items():
        n_in = sum(rec["within_factor"].values())
        lines += [
            f"### {name} (`{rec['file']}`)",
            "",
            _counterpart(rec["counterpart"]),
            "",
            markdown_table(["statistic", "real", "simulated", "ratio", f"within {factor:g}x"], _rows(rec)),
            "",
            f"{n_in} of {len(rec['within_factor'])} statistics within the factor.",
        ]
        if "alarms" in rec:
            real, sim = rec["alarms"]["real"], rec["alarms"]["simulated"]
            lines += [
                "",
                f"Slip alarms: {real['alarms']} in {real['joint_hours'] * 60:.1f} joint-minutes of the real "
                f"recording, {sim['alarms']} in {sim['joint_hours'] * 60:.1f} simulated (a short recording: "
                "the rate is a count of a few events at most).",
            ]
        limits = _limits(rec)
        if limits:
            lines += ["", *limits]
        lines.append("")
    if "twins" in realism:
        lines += twins_markdown(realism["twins"])
    return lines


def _twin_rows(twins: Mapping[str, Any]) -> list[list[Any]]:
    rows = []
    for stem, t in twins.items():
        r, off = t["readings"], t["identified"]["time_offset_ms"]
        rows.append(
            [
                stem,
                *(f"{r[k]['r2']:.4f} ({r[k]['r2_noise_ceiling']:.3f})" for k in ("acc", "gyro", "mag")),
                f"{off['gyro']:.1f} / {off['acc']:.1f} / {off['mag']:.1f}",
                f"{t['identified']['misalignment_deg']:.2f}",
                ", ".join(f"{x:.1f}" for x in t["identified"]["lever_arm_mm"]),
                f"{100 * t['identified']['mag_disturbed_fraction']:.1f}",
            ]
        )
    return rows


def _twin_orientation_rows(twins: Mapping[str, Any]) -> list[list[Any]]:
    return [
        [
            stem,
            method,
            f"{o['real_deg']:.2f}",
            f"{o['twin_deg']:.2f}",
            f"{o['ratio']:.2f}",
            "yes" if 1 / RATIO_FACTOR <= o["ratio"] <= RATIO_FACTOR else "NO",
        ]
        for stem, t in twins.items()
        for method, o in t["orientation"].items()
    ]


def twins_markdown(run: Mapping[str, Any]) -> list[str]:
    """The digital twins' subsection (``run``: :func:`simbench.experiments.realism.run_twins`)."""
    lines = ["### Digital twins of the BROAD trials", ""]
    twins = run["twins"]
    pattern = run.get("pattern", "broad_*.hdf5")
    if not twins:
        return [*lines, f"No BROAD trial (`{pattern}`) in `{run['data_dir']}`: no twin.", ""]
    targets = ", ".join(f"{k} {v:g}" for k, v in R2_TARGETS.items())
    if pattern != "broad_*.hdf5":
        lines += [f"The trials `{pattern}` only (`--quick`; the full run makes every trial's twin).", ""]
    lines += [
        "Each trial's IMU simulated from the optical pose of its housing, with the errors the recording "
        "shows identified (`simbench twin`, `docs/twin.md`), compared sample by sample over the motion "
        f"phase: R^2 (in brackets the ceiling the sensor's white noise leaves); issue 41's targets for the "
        f"undisturbed trials: {targets}.",
        "",
        markdown_table(
            [
                "trial",
                "acc R^2",
                "gyro R^2",
                "mag R^2",
                "time offset gyro / acc / mag (ms)",
                "misalignment (deg)",
                "lever arm (mm)",
                "mag disturbed (%)",
            ],
            _twin_rows(twins),
        ),
        "",
    ]
    for stem, t in twins.items():
        missed = {k: v for k, v in t["targets"].items() if not v["met"]}
        if "undisturbed" in stem and missed:
            lines += [
                f"- *{stem}*, {k} R^2 {v['r2']:.4f} below {v['target']:g}: {v['why']}."
                for k, v in missed.items()
            ]
        elif "undisturbed" in stem:
            lines.append(f"- *{stem}*: every target met.")
    pairs = _twin_orientation_rows(twins)
    within = sum(row[-1] == "yes" for row in pairs)
    lines += [
        "",
        f"Each orientation method ({', '.join(run['methods'])}) on the real recording and on the twin "
        f"with noise of the identified densities (seed {run['seed']}), BROAD's total error over the same "
        f"samples; {within} of {len(pairs)} (trial, method) pairs within {RATIO_FACTOR:g}x (issue 41's "
        "target: 80 %).",
        "",
        markdown_table(
            ["trial", "method", "real (deg)", "twin (deg)", "twin / real", f"within {RATIO_FACTOR:g}x"], pairs
        ),
        "",
    ]
    return lines
