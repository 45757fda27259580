"""The validation report's "decisions" section: each estimator decision against its target.

Renders the figures of :func:`simbench.experiments.decisions.run_decisions`: slip false alarms per
hour on sessions without slip, slip detection by size, hinge verdicts and cluster grouping, each
with its sample size, its target and whether the target is met.
"""

from __future__ import annotations

import math
from typing import Any

from simbench.report.markdown import markdown_table


def _met(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _rate_met(detected: int, sessions: int, target: float) -> str:
    """Whether a detection rate meets ``target``, and whether the sample could show it: with no
    miss, ``n`` sessions show a rate of at least ``target`` at 95 % confidence once
    ``target**n <= 0.05``."""
    if detected < target * sessions:
        return "NOT met"
    needed = math.ceil(math.log(0.05) / math.log(target))
    return "met" if sessions >= needed else f"met in this sample (n >= {needed} shows it)"


def _alarm_rows(false_alarms: dict[str, Any]) -> list[list[Any]]:
    target = false_alarms["target_per_hour"]
    return [
        [
            case,
            c["sessions"],
            c["joint_hours"] * 60.0,
            c["alarms"],
            c["per_hour"],
            f"<= {target:g}/h: {_met(c['per_hour'] <= target)}",
        ]
        for case, c in false_alarms["cases"].items()
    ]


def _detection_rows(detection: dict[str, Any]) -> list[list[Any]]:
    rows = []
    for motion, by_size in detection["by_motion"].items():
        for size, r in by_size.items():
            err = r["median_abs_time_error_s"]
            rows.append(
                [
                    f"{motion}, {size}",
                    f"{r['detected']} of {r['sessions']}",
                    f"{r['right_frame']} of {r['sessions']}",
                    "-" if err is None else f"{err * 1e3:.0f}",
                    r["other_alarms"],
                    f">= {r['target']:.0%}: {_rate_met(r['detected'], r['sessions'], r['target'])}",
                ]
            )
    return rows


def _hinge_rows(hinge: dict[str, Any]) -> list[list[Any]]:
    return [
        [
            case,
            f"{h['single_axis']} of {h['seeds']}",
            f"{h['weak_ratio_range'][0]:.4f} - {h['weak_ratio_range'][1]:.4f}",
            f"{h['target_single_axis']} of {h['seeds']}: {_met(h['single_axis'] == h['target_single_axis'])}",
        ]
        for case, h in hinge.items()
    ]


def decisions_markdown(decisions: dict[str, Any]) -> list[str]:
    """The section's Markdown lines."""
    clusters = decisions["clusters"]
    tol = decisions["detection"]["tolerance_s"]
    return [
        "## Decisions against their targets",
        "",
        "Small samples run with this report (the full studies: `studies/slip_detection.py`, "
        "`studies/hinge_verdict.py`, `studies/cluster_finding.py`, results in `studies/results/`).",
        "",
        "**Slip false alarms** on the sessions above (no sensor slips), every joint, the detector's "
        "defaults (1 expected false alarm per hour, 2 s window):",
        "",
        markdown_table(
            ["sessions", "n", "joint minutes", "alarms", "per hour", "target"],
            _alarm_rows(decisions["false_alarms"]),
        ),
        "",
        f"**Slip detection** of slips injected on a skin-mounted humanoid sensor (`skin-paper-human`): "
        f"an event on a joint of that sensor within {tol:g} s; right frame: attributed to that sensor.",
        "",
        markdown_table(
            ["motion, slip", "detected", "right frame", "median time error (ms)", "other alarms", "target"],
            _detection_rows(decisions["detection"]),
        ),
        "",
        "**Single-axis verdicts** on simulated joints with 2 mm play, skin-like offsets and tracker "
        "noise (60 s at 100 Hz); s_min/s_max is the reported ratio (the old fixed rule was < 0.01):",
        "",
        markdown_table(["joint", "single-axis", "s_min/s_max", "target"], _hinge_rows(decisions["hinge"])),
        "",
        f"**Cluster grouping** of simulated skin-mounted marker sets (2-7 mm distance spread within "
        f"clusters, static markers beside): grouped right in {clusters['right']} of {clusters['seeds']} "
        f"seeds (target {clusters['target']} of {clusters['seeds']}: "
        f"{_met(clusters['right'] == clusters['target'])}).",
        "",
    ]
