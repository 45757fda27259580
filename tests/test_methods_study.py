"""studies/methods.py: the joint-centre methods side by side, on one tiny ideal session."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from calibration.methods import JOINT_METHODS

SCRIPT = Path(__file__).resolve().parents[1] / "studies" / "methods.py"
CONDITION = "humanoid / ideal"

#: Exact poses (the ideal preset) satisfy the joint constraint to rounding, so every pose-based
#: method recovers the truth to about 1e-12 m (a few 1e-9 m on the worst-conditioned joint): 1e-6 m
#: leaves three orders of magnitude for conditioning and still fails any real error (0.1 mm and up).
EXACT_MM = 1e-3


@pytest.fixture(scope="module")
def study():
    # imported as a module (not run from its path) so that a process pool's workers find its
    # functions by name
    spec = importlib.util.spec_from_file_location("methods_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules["methods_study"] = module
    spec.loader.exec_module(module)
    yield vars(module)
    sys.modules.pop("methods_study", None)


@pytest.fixture(scope="module")
def doc(study):
    return study["run_study"]([1], 4.0, conditions=[CONDITION])


def test_pose_methods_recover_the_truth_on_ideal_data(doc):
    (trial,) = doc["trials"][CONDITION]
    assert len(trial["joints"]) == 15  # the humanoid's 16 sensors
    for method in JOINT_METHODS:
        row = trial["methods"][method]
        assert row["failures"] == {}, method
        if method == "sara":
            # on a ball joint SARA's "axis" is the weakest direction and its point the minimum-norm
            # one: the truth lies on that axis, not at that point
            errors = row["axis_distance_parent_mm"] + row["axis_distance_child_mm"]
        else:
            errors = row["error_parent_mm"] + row["error_child_mm"] + row["length_error_mm"]
        assert len(errors) >= 2 * 15
        assert max(errors) < EXACT_MM, (method, max(errors))  # NaN would fail too
    for method, row in trial["methods"].items():
        assert len(row["time_ms"]) == 15 and min(row["time_ms"]) > 0, method
        assert len(row["length_error_mm"]) == len(trial["length_pairs"])
    for method in ("obrien", "obrien-eiv"):
        coverage = trial["methods"][method]["coverage"]
        assert set(coverage) == {"batch-means", "iid", "bounded"}
        assert all(len(c[part]) == 15 for c in coverage.values() for part in ("parent", "child"))


def test_a_process_pool_gives_the_same_study(study):
    one = study["run_study"]([1, 2], 1.5, conditions=[CONDITION])
    pooled = study["run_study"]([1, 2], 1.5, conditions=[CONDITION], workers=2, keep_trials=False)
    assert pooled["trials"] == {}
    for method, a in one["summary"][CONDITION].items():
        b = pooled["summary"][CONDITION][method]
        assert {k: v for k, v in a.items() if k != "time_ms"} == {
            k: v for k, v in b.items() if k != "time_ms"
        }


def test_json_and_table_are_complete(study, doc):
    assert {"study", "versions", "config", "summary", "trials"} <= set(doc)
    assert doc["config"]["seeds"] == [1] and doc["config"]["duration_s"] == 4.0
    assert [c["name"] for c in doc["config"]["conditions"]] == [CONDITION]
    assert {"numpy", "mujoco", "simbench"} <= set(doc["versions"])
    summary = doc["summary"][CONDITION]
    assert list(summary) == [*JOINT_METHODS, "inertial"]
    for method, s in summary.items():
        assert {"joint_error_mm", "axis_distance_mm", "length_error_mm", "time_ms", "coverage95"} <= set(s)
        assert s["n_fits"] == 15 and s["failures"] == 0
        assert (s["coverage95"] is not None) == (method in ("obrien", "obrien-eiv"))
    back = json.loads(study["json_text"](doc))  # strict JSON (NaN written as null), rounded
    assert back["summary"][CONDITION]["obrien"]["n_fits"] == 15
    assert back["trials"][CONDITION][0]["joints"] == doc["trials"][CONDITION][0]["joints"]
    lines = study["table"](doc).splitlines()
    assert lines[0].startswith("| condition | method |")
    assert len(lines) == 2 + len(summary)
    assert all(line.count("|") == lines[0].count("|") for line in lines)


def test_the_report_quotes_the_coverage_study(doc, study, tmp_path):
    from simbench.experiments.validate import COVERAGE_STUDY, coverage_study
    from simbench.report.validation import _bounded_share, _joint_methods

    assert coverage_study(tmp_path / "absent.json") is None
    noisy = json.loads(study["json_text"](doc))
    noisy["summary"] = {"humanoid / polhemus-liberty": noisy["summary"][CONDITION], CONDITION: {}}
    noisy["command"] = "studies/methods.py --seeds 1"
    path = tmp_path / "methods_coverage_200.json"
    path.write_text(json.dumps(noisy))
    quoted = coverage_study(path)
    assert quoted["seeds"] == 1 and quoted["command"] == "studies/methods.py --seeds 1"
    assert list(quoted["conditions"]) == ["humanoid / polhemus-liberty"]  # exact data left out
    row = quoted["conditions"]["humanoid / polhemus-liberty"]
    assert row["regions"] == 30 and len(row["shares"]) == 4
    assert row["shares"][0] == doc["summary"][CONDITION]["obrien"]["coverage95"]["batch-means"]
    cover = {"covered": 9, "regions": 10}
    section = "\n".join(
        _joint_methods(
            {
                "seeds": 1,
                "duration_s": 4.0,
                "conditions": {
                    "linkage": {
                        "methods": {"obrien": {"centre_error_mm": 1.0, "length_error_mm": 2.0}},
                        "coverage": {"batch-means": cover, "iid": cover, "eiv": cover},
                    }
                },
                "study": quoted,
            }
        )
    )
    assert "Over 1 seeds per condition" in section and "| humanoid / polhemus-liberty |" in section
    assert "| linkage | 90 % of 10 | 90 % of 10 | 90 % of 10 |" in section
    # an unbounded region always holds the truth: the coverage among the bounded ones
    assert _bounded_share({"shares": [0.0, 0.0, 0.9821, 0.0], "bounded": 0.4442}) == "96.0 %"
    assert _bounded_share({"shares": [0.0, 0.0, 0.95, 0.0], "bounded": None}) == "-"
    # the checkout ships the study's results, with the corrected fit's coverage of every noisy condition
    shipped = coverage_study(COVERAGE_STUDY)
    assert shipped is not None and shipped["seeds"] == 200
    assert len(shipped["conditions"]) == 5 and all(
        r["regions"] >= 900 for r in shipped["conditions"].values()
    )
