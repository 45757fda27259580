"""The table that ``simbench calibrate`` prints: joints, limb lengths, sensor offsets, slip, warnings."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from calibration import Calibration, SlipReport
from simbench.io.poses import PoseRecording, sample_rate


def format_table(rec: PoseRecording, cal: Calibration, slips: Sequence[tuple[str, SlipReport]]) -> str:
    """A readable summary: joints (mm), limb lengths (cm), sensor offsets (cm), warnings.

    Args:
        rec: the recording that was calibrated (source, sensors, frames, rate, times in s, notes).
        cal: its calibration (lengths in m).
        slips: ``(joint name, slip report)`` per joint checked; empty when slip detection was
            skipped (then the table has no slip section).
    """
    rate_hz, bursty = sample_rate(rec.time_s)
    how = " (count over span: bursty time stamps)" if bursty else ""
    span_s = float(rec.time_s[-1] - rec.time_s[0]) if rec.n_frames else 0.0
    lines = [
        f"simbench calibrate: {rec.source}",
        f"  sensors: {len(rec.names)}   frames: {rec.n_frames} over {span_s:.4g} s   "
        f"rate: {rate_hz:.4g} Hz{how}   calibrated in {cal.seconds.get('total', float('nan')):.3f} s",
        f"  hierarchy: {'given' if cal.hierarchy_given else 'inferred'}, root {cal.root}",
        "",
        f"  {'joint (parent -> child)':<34}{'rms mm':>9}{'max mm':>9}{'cond':>8}  {'axis':<12}{'frames':>8}",
    ]
    for j in cal.joints:
        fit = j.fit
        mx = np.nanmax(fit.frame_residual) if fit.frame_residual is not None else float("nan")
        cond = f"{fit.condition:.3g}" if np.isfinite(fit.condition) else "inf"
        axis = "single" if fit.single_axis else ("none" if fit.rank < 5 else "-")
        lines.append(
            f"  {j.parent + ' -> ' + j.child:<34}{fit.rms_residual * 1e3:>9.3f}{mx * 1e3:>9.3f}"
            f"{cond:>8}  {axis:<12}{fit.n_frames:>8}"
        )
    lines += ["", f"  {'limb lengths (cm)':<22}{'from joint':<30}{'to joint':<30}{'length':>8}"]
    for x in cal.lengths:
        lines.append(f"  {x.segment:<22}{x.joint_a:<30}{x.joint_b:<30}{x.length * 100:>8.2f}")
    lines += ["", f"  {'sensor offsets (cm)':<22}{'joint':<30}{'offset in sensor frame':<28}{'dist':>8}"]
    for pl in cal.placements:
        for name, off, d in zip(pl.joints, pl.offsets, pl.distances, strict=True):
            vec = " ".join(f"{v * 100:7.2f}" for v in off)
            lines.append(f"  {pl.sensor:<22}{name:<30}{vec:<28}{d * 100:>8.2f}")
    events = [(name, ev) for name, rep in slips for ev in rep.events]
    if slips:
        lines += ["", "  slip events (residual offset jumps)"]
        if not events:
            lines.append("    none found")
        for name, ev in events:
            lines.append(
                f"    {name}: at {rec.time_s[ev.frame]:.3f} s, jump {ev.jump * 1e3:.1f} mm "
                f"(steady in the {ev.sensor_frame} frame, z {ev.z:.3g})"
            )
    notes = [*rec.notes, *cal.warnings]
    if notes:
        lines += ["", "  warnings"]
        lines += [f"    - {w}" for w in notes]
    return "\n".join(lines)
