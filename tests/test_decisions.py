"""The validation's decision checks (issue 12): each trial judged against the truth, the section
says "NOT met" exactly where a figure misses its target."""

from __future__ import annotations

import pytest

from simbench.experiments.decisions import (
    HINGE_CASES,
    SLIP_FIRST_SEED,
    DecisionPlan,
    cluster_trial,
    hinge_trial,
)
from simbench.experiments.obrien import _human_config
from simbench.experiments.validate import Plan
from simbench.report.decisions import decisions_markdown


@pytest.mark.parametrize("case", list(HINGE_CASES))
def test_hinge_trial_gives_the_verdict_the_joint_has(case):
    amp, single = HINGE_CASES[case]
    run = hinge_trial(amp, seed=5)
    assert run["single_axis"] is single
    assert (run["weak_ratio"] < 0.05) is single  # the ratio is reported beside the verdict


def test_cluster_trial_checks_the_grouping():
    run = cluster_trial(7)
    assert run["right"] is True and run["left_out"] == 0 and 4 <= run["segments"] <= 6


def _decisions(per_hour: float, detected: int, flagged_balls: int, right_clusters: int) -> dict:
    row = {"sessions": 2, "right_frame": detected, "median_abs_time_error_s": 0.004, "other_alarms": 0}
    return {
        "false_alarms": {
            "target_per_hour": 6.0,
            "cases": {
                "humanoid exercise": {
                    "sessions": 2,
                    "joint_hours": 0.5,
                    "alarms": per_hour / 2,
                    "per_hour": per_hour,
                }
            },
        },
        "detection": {
            "tolerance_s": 0.5,
            "by_motion": {
                "walk": {"1 cm": {**row, "detected": detected, "rate": detected / 2, "target": 0.95}}
            },
        },
        "hinge": {
            "ball": {
                "seeds": 4,
                "single_axis": flagged_balls,
                "target_single_axis": 0,
                "weak_ratio_range": [0.2, 0.3],
            }
        },
        "clusters": {"seeds": 5, "right": right_clusters, "target": 5},
    }


def test_section_marks_every_missed_target():
    good = "\n".join(decisions_markdown(_decisions(0.0, 2, 0, 5)))
    assert "NOT met" not in good and good.count(": met") == 4
    # 2 of 2 detected cannot show a 95 % rate: 59 sessions without a miss can (0.95**59 < 0.05)
    assert "met in this sample (n >= 59 shows it)" in good
    for bad in (
        _decisions(12.0, 2, 0, 5),
        _decisions(0.0, 1, 0, 5),
        _decisions(0.0, 2, 1, 5),
        _decisions(0.0, 2, 0, 4),
    ):
        text = "\n".join(decisions_markdown(bad))
        assert text.count("NOT met") == 1 and text.count(": met") == 3


@pytest.mark.parametrize("quick", [True, False])
def test_slip_sessions_ride_the_male_trials_motions(quick):
    """The validation's slip sessions are its male subject's trials (seed and length) with a slip:
    the physics cache then gives them those trials' physics instead of computing it again."""
    slips, plan = DecisionPlan.of(quick), Plan.of(quick)
    assert slips.slip_s == plan.humanoid_s
    trials = {"exercise": plan.exercise_trials, "walk": plan.walk_trials}
    for motion in slips.slip_motions:
        assert slips.slip_seeds <= trials[motion]
        for k in range(slips.slip_seeds):
            trial = _human_config("male", motion, k + 1, plan.humanoid_s, "skin-paper-human")
            assert trial.seed == SLIP_FIRST_SEED + k and trial.duration_s == slips.slip_s
