"""studies/orientation_seeds.py's paired comparison: a run against itself changes nothing, every
session 20 % worse is called worse at the stated false-alarm rate, a mixed run is counted both
ways."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import numpy as np
import pytest

STUDY = Path(__file__).resolve().parents[1] / "studies" / "orientation_seeds.py"


@pytest.fixture(scope="module")
def study():
    sys.path.insert(0, str(STUDY.parent))  # the study imports studies/orientation.py as a script does
    try:
        return runpy.run_path(str(STUDY), run_name="study_script")
    finally:
        sys.path.remove(str(STUDY.parent))


def runs(errors, seconds=1.0):
    return {f"walk/{i}/truth": {"total_deg": float(e), "cpu_s": seconds} for i, e in enumerate(errors)}


def test_a_run_against_itself(study):
    before = runs(np.linspace(1.0, 20.0, 12))
    c = study["compare"](before, before)
    assert (c["moved"], c["median_ratio"], c["wilcoxon_p"], c["worse_by_10pct"]) == (0, 1.0, 1.0, 0)


def test_every_session_worse_is_called_worse(study):
    e = np.linspace(1.0, 20.0, 12)
    c = study["compare"](runs(e), runs(1.2 * e * (1 + 0.01 * np.sin(np.arange(12))), seconds=0.5))
    assert c["wilcoxon_p"] < study["FALSE_ALARM"]
    assert c["worse_by_10pct"] == 12 and c["better_by_10pct"] == 0
    assert c["median_ratio"] == pytest.approx(1.2, rel=0.02)
    assert c["cpu_ratio"] == pytest.approx(0.5)


def test_moves_both_ways_are_counted_and_too_few_sessions_refused(study):
    e = np.ones(8)
    after = e * np.array([2.0, 0.5, 1.0, 1.0, 1.05, 1.0, 1.0, 1.0])
    c = study["compare"](runs(e), runs(after))
    assert (c["moved"], c["worse_by_10pct"], c["better_by_10pct"]) == (3, 1, 1)
    assert c["wilcoxon_p"] == 1.0  # fewer than 6 moved sessions: no test
    with pytest.raises(ValueError, match="at least 6 sessions"):
        study["compare"](runs(e[:5]), runs(e[:5]))
