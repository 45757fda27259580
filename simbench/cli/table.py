"""The table that ``simbench calibrate`` prints: joints, limb lengths, sensor offsets, slip, warnings."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simbench.api import LOCATED_RANK, Calibration, PoseRecording, SlipReport, sample_rate


def format_table(rec: PoseRecording, cal: Calibration, slips: Sequence[tuple[str, SlipReport]]) -> str:
    """A readable summary: joints (mm), limb lengths (cm), sensor offsets (cm), warnings (a joint
    whose centre the motion does not locate, fewer than 5 of 6 directions, has axis ``none`` and
    its lengths and offsets ``not located``); with
    intervals (``calibrate(intervals=True)``) each joint centre's 95 % region (cm) and each limb
    length as ``L ± h`` (cm, the half-width of its 95 % interval).

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
    ]
    rows = []
    for j in cal.joints:
        fit = j.fit
        mx = np.nanmax(fit.frame_residual) if fit.frame_residual is not None else float("nan")
        cond = f"{fit.condition:.3g}" if np.isfinite(fit.condition) else "inf"
        axis = "single" if fit.single_axis else ("none" if fit.rank < LOCATED_RANK else "-")
        rows.append(
            [
                j.parent + " -> " + j.child,
                f"{fit.rms_residual * 1e3:.3f}",
                f"{mx * 1e3:.3f}",
                cond,
                axis,
                str(fit.n_frames),
            ]
        )
    lines += text_table(
        ["joint (parent -> child)", "rms mm", "max mm", "cond", "axis", "frames"], rows, "lrrrlr"
    )
    if cal.rotation_noise_rad2:
        noise = ", ".join(f"{s} {np.degrees(np.sqrt(v)):.3f}" for s, v in cal.rotation_noise_rad2.items())
        lines += ["", f"  corrected for rotation noise (deg rms per axis, read off each sensor): {noise}"]
    if any(j.uncertainty is not None for j in cal.joints):
        lines += _interval_lines(cal)
    # a joint the motion does not locate (fewer than 5 of 6 directions) has no centre to measure from
    unlocated = {j.name for j in cal.joints if j.fit.rank < LOCATED_RANK}
    rows = []
    for k, x in enumerate(cal.lengths):
        if unlocated & {x.joint_a, x.joint_b}:
            rows.append([x.segment, x.joint_a, x.joint_b, "not located"])
            continue
        ci = ""
        if cal.length_uncertainty:
            unc = cal.length_uncertainty[k]
            ci = f" ± {_cm(0.5 * (unc.interval_m[1] - unc.interval_m[0]))}" if unc is not None else " ± -"
        rows.append([x.segment, x.joint_a, x.joint_b, f"{x.length * 100:.2f}{ci}"])
    lines += ["", *text_table(["limb lengths (cm)", "from joint", "to joint", "length"], rows, "lllr")]
    rows = [
        [pl.sensor, name, "not located", "-"]
        if name in unlocated
        else [pl.sensor, name, " ".join(f"{v * 100:7.2f}" for v in off), f"{d * 100:.2f}"]
        for pl in cal.placements
        for name, off, d in zip(pl.joints, pl.offsets, pl.distances, strict=True)
    ]
    lines += [
        "",
        *text_table(["sensor offsets (cm)", "joint", "offset in sensor frame", "dist"], rows, "llrr"),
    ]
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


def text_table(
    headers: Sequence[str], rows: Sequence[Sequence[str]], align: str, indent: int = 2
) -> list[str]:
    """Lines of a plain-text table whose columns are as wide as their widest value (or header),
    two spaces apart, so that no value ever runs into the next column.

    Args:
        headers: one per column.
        rows: the cells, already formatted as text, one list per row.
        align: one letter per column, ``"l"`` (left) or ``"r"`` (right).
        indent: spaces before every line.
    """
    if len(align) != len(headers) or any(len(row) != len(headers) for row in rows):
        raise ValueError(
            f"text_table: {len(headers)} headers, align {align!r}, rows of {[len(r) for r in rows]}"
        )
    widths = [max([len(h), *(len(row[c]) for row in rows)]) for c, h in enumerate(headers)]

    def line(cells: Sequence[str]) -> str:
        out = [
            cell.ljust(w) if a == "l" else cell.rjust(w)
            for cell, w, a in zip(cells, widths, align, strict=True)
        ]
        return (" " * indent + "  ".join(out)).rstrip()

    return [line(headers), *(line(row) for row in rows)]


#: Half-widths beyond this many metres are shown as ">1 m" (the 95 % region is unbounded or
#: meaningless: too few degrees of freedom, a direction the motion barely explored).
WIDE_M = 1.0


def _cm(half_width_m: float) -> str:
    """A half-width in cm with 2 decimals, or ``">1 m"`` when not finite or beyond :data:`WIDE_M`."""
    if not np.isfinite(half_width_m) or half_width_m > WIDE_M:
        return ">1 m"
    return f"{half_width_m * 100:.2f}"


def _interval_lines(cal: Calibration) -> list[str]:
    """Each joint centre's 95 % region in both sensor frames: the ellipsoid's largest semi-axis
    and the per-axis (x, y, z) half-widths of the Student's t intervals, cm."""
    rows = []
    for j in cal.joints:
        unc = j.uncertainty
        if unc is None:
            continue
        for k, part in enumerate(("parent", "child")):
            region = unc.region(part)
            half = 0.5 * (region.intervals_m[:, 1] - region.intervals_m[:, 0])
            label = j.parent + " -> " + j.child if k == 0 else ""
            bias = _cm(float(unc.bias_bound_m)) if k == 0 and np.isfinite(unc.bias_bound_m) else ""
            rows.append(
                [
                    label,
                    part,
                    _cm(float(region.semi_axes_m[0])),
                    *[_cm(h) for h in half],
                    f"{region.dof:.1f}",
                    bias,
                ]
            )
    head = ["joint centre 95% (cm)", "frame", "± max", "± x", "± y", "± z", "dof", "bias ≤"]
    lines = ["", *text_table(head, rows, "llrrrrrr")]
    lines.append("    (± max: the 95% ellipsoid's largest semi-axis; ± x/y/z: 95% intervals per axis)")
    lines.append(
        "    (bias ≤: the most an error of the residual's systematic size that moves with the joint can shift"
        " the centre, noise over range of motion; the regions do not hold it; docs/joint-warnings.md)"
    )
    if cal.robust is not None:
        lines.append(f"    (robust {cal.robust} fits: regions conditional on each joint's inlier frames)")
    return lines
