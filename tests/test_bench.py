"""``simbench bench``: the suite run with every built-in and users' estimators, scored and compared.

The runs here are small (one or two linkage scenarios, a few seeds, few built-ins): a linkage
session simulates in about half a second.
"""

from __future__ import annotations

import json
import math
import sys
import textwrap
from pathlib import Path

import pytest

from simbench.cli import main
from simbench.errors import InputError
from simbench.experiments import suite
from simbench.experiments.bench import (
    ALPHA,
    METRICS,
    comparable,
    load_scorecard,
    median_ci,
    paired_test,
    run_bench,
    write_bench,
)

SHIFTED = '''
import simbench.estimators as E


def estimate(poses, *, hierarchy=None):
    """O'Brien's joints, every centre moved 1 cm along x in both sensors' frames."""
    got = E.run_joints(E.resolve("obrien"), poses, hierarchy=hierarchy).joints
    joints = [
        {
            "parent": p,
            "child": c,
            "joint_in_parent": [float(a) + (0.01 if k == 0 else 0.0) for k, a in enumerate(jp)],
            "joint_in_child": [float(a) + (0.01 if k == 0 else 0.0) for k, a in enumerate(jc)],
        }
        for p, c, jp, jc in zip(got.parent, got.child, got.joint_in_parent, got.joint_in_child)
    ]
    assert poses.unit == "m"
    return {"joints": joints, "units": "m"}
'''

COPY = """
import simbench.estimators as E


def estimate(poses, *, hierarchy=None):
    return E.run_joints(E.resolve("obrien"), poses, hierarchy=hierarchy)
"""

CRASH = """
def estimate(poses, *, hierarchy=None):
    raise RuntimeError("deliberately broken")
"""

# every joint of the given tree at each sensor's origin: a (bad) estimator in another process
ZEROS = """
import json, sys
poses, hierarchy, out = sys.argv[1:4]
tree = json.load(open(hierarchy))
joints = [{"parent": p, "child": c, "joint_in_parent": [0, 0, 0], "joint_in_child": [0, 0, 0]}
          for c, p in tree.items()]
json.dump({"joints": joints, "units": "m"}, open(out, "w"))
"""

SLOW = """
import time
time.sleep(30)
"""

SCENARIOS = ("linkage-paper", "linkage-single-axis")
SEEDS = (1, 2, 3, 4, 5)


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text))
    return path


@pytest.fixture(scope="module")
def specs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("estimators")
    return {
        "shifted": f"{_write(folder, 'shifted.py', SHIFTED)}:estimate",
        "copy": f"{_write(folder, 'copy.py', COPY)}:estimate",
        "crash": f"{_write(folder, 'crash.py', CRASH)}:estimate",
        "cmd": f"cmd:{sys.executable} {_write(folder, 'zeros.py', ZEROS)} {{poses}} {{hierarchy}} {{out}}",
        "slow": f"cmd:{sys.executable} {_write(folder, 'slow.py', SLOW)} {{poses}} {{out}}",
    }


@pytest.fixture(scope="module")
def card(specs: dict[str, str]) -> dict:
    """Both linkage scenarios over five seeds: obrien beside the four users' estimators."""
    return run_bench(
        [specs["shifted"], specs["copy"], specs["crash"], specs["cmd"]],
        workers=2,
        scenarios=SCENARIOS,
        seeds=SEEDS,
        builtins=("obrien",),
    )


def _row(card: dict, estimator: str, scenario: str, metric: str) -> dict:
    (row,) = [
        r
        for r in card["rows"]
        if (r["estimator"], r["scenario"], r["metric"]) == (estimator, scenario, metric)
    ]
    return row


def _comparison(card: dict, a: str, b: str, scenario: str, metric: str) -> dict:
    (c,) = [
        c
        for c in card["comparisons"]
        if (c["a"], c["b"], c["scenario"], c["metric"]) == (a, b, scenario, metric)
    ]
    return c


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_a_centre_moved_1_cm_is_significantly_worse(card: dict, specs: dict[str, str], scenario: str) -> None:
    c = _comparison(card, specs["shifted"], "obrien", scenario, "joint_centre_error_m")
    assert c["n"] == len(SEEDS)
    assert c["significant"] and c["p_value"] < ALPHA
    assert c["a_lower"] == 0  # worse on every seed
    assert c["median_difference"] > 0.003  # metres: a 1 cm shift adds several mm of mean error
    shifted = _row(card, specs["shifted"], scenario, "joint_centre_error_m")["median"]
    obrien = _row(card, "obrien", scenario, "joint_centre_error_m")["median"]
    assert shifted > obrien
    # the same shift of both ends of a segment leaves its length alone: no difference there
    limb = _comparison(card, specs["shifted"], "obrien", scenario, "limb_length_error_m")
    assert not limb["significant"]
    assert abs(limb["median_difference"]) < 1e-9


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_an_exact_copy_is_not_significantly_different(
    card: dict, specs: dict[str, str], scenario: str
) -> None:
    for metric in METRICS["joints"]:
        c = _comparison(card, specs["copy"], "obrien", scenario, metric)
        assert c["n"] == len(SEEDS)
        assert not c["significant"]
        assert c["p_value"] == 1.0 and c["median_difference"] == 0.0
        assert (
            _row(card, specs["copy"], scenario, metric)["median"]
            == _row(card, "obrien", scenario, metric)["median"]
        )


def test_a_crashing_estimator_fails_on_every_seed_and_the_run_goes_on(
    card: dict, specs: dict[str, str]
) -> None:
    for scenario in SCENARIOS:
        for metric in METRICS["joints"]:
            row = _row(card, specs["crash"], scenario, metric)
            assert row["failures"] == len(SEEDS) and row["n"] == 0
            assert row["median"] is None and row["ci95"] == [None, None]
            assert row["errors"] and "deliberately broken" in row["errors"][0]
            assert "RuntimeError" in row["errors"][0]
            # the others were scored on the same datasets
            assert _row(card, "obrien", scenario, metric)["n"] == len(SEEDS)
    crash = [c for c in card["comparisons"] if specs["crash"] in (c["a"], c["b"])]
    assert crash and all(c["n"] == 0 and c["p_value"] is None and not c["significant"] for c in crash)
    assert card["rankings"]["linkage-paper"][-1] == specs["crash"]  # no median: last


def test_a_command_estimator_is_scored(card: dict, specs: dict[str, str]) -> None:
    for scenario in SCENARIOS:
        row = _row(card, specs["cmd"], scenario, "joint_centre_error_m")
        assert row["n"] == len(SEEDS) and row["failures"] == 0
        # every centre at the sensor's origin: decimetres off, far worse than obrien
        assert row["median"] > 0.05
        c = _comparison(card, specs["cmd"], "obrien", scenario, "joint_centre_error_m")
        assert c["significant"] and c["median_difference"] > 0.05


def test_scorecard_rows_and_header(card: dict, specs: dict[str, str]) -> None:
    keys = {"estimator", "scenario", "metric", "median", "ci95", "n", "failures", "errors"}
    names = {"obrien", specs["shifted"], specs["copy"], specs["crash"], specs["cmd"]}
    assert len(card["rows"]) == len(names) * len(SCENARIOS) * len(METRICS["joints"])
    for r in card["rows"]:
        assert keys <= r.keys()
        assert r["metric"] in ("joint_centre_error_m", "limb_length_error_m")
        assert r["n"] + r["failures"] == len(SEEDS)
        if r["median"] is not None:
            low, high = r["ci95"]
            assert low <= r["median"] <= high
            assert 0 < r["median"] < 1  # metres
    assert {r["estimator"] for r in card["rows"]} == names
    assert card["suite_version"] == suite.SUITE_VERSION and card["seeds"] == list(SEEDS)
    assert card["simbench_version"]
    fingerprints = {s["name"]: s["fingerprint"] for s in card["scenarios"]}
    assert fingerprints == {n: suite.scenario_fingerprint(suite.scenario(n)) for n in SCENARIOS}
    assert all(s["about"] for s in card["scenarios"])
    assert "t-test" in card["test"] and card["alpha"] == ALPHA
    assert card["run_time_s"] > 0 and card["quick"] is False
    for c in card["comparisons"]:
        assert {"scenario", "metric", "a", "b", "median_difference", "p_value", "significant"} <= c.keys()


def test_written_scorecard_and_report(card: dict, specs: dict[str, str], tmp_path: Path) -> None:
    paths = write_bench(card, tmp_path / "out")
    assert [p.name for p in paths] == ["scorecard.json", "index.md", "index.html"]
    back = load_scorecard(tmp_path / "out")
    assert back["rows"] == json.loads(json.dumps(card["rows"]))
    md = (tmp_path / "out" / "index.md").read_text()
    assert "## Ranking" in md and "## Significant differences" in md and "t-test" in md
    assert "## Run time" in md and "nothing is tested" not in md
    assert all(s["fingerprint"] in md for s in card["scenarios"])
    assert f"`{specs['crash']}` on linkage-paper: 5 of 5 seed(s) failed" in md
    obrien = _row(card, "obrien", "linkage-paper", "joint_centre_error_m")["median"]
    assert f"{obrien * 1000:.2f}" in md  # millimetres in the table
    html = (tmp_path / "out" / "index.html").read_text()
    assert "<table>" in html and "deliberately broken" in html


def test_medians_are_deterministic_whatever_the_workers() -> None:
    kwargs = dict(scenarios=("linkage-single-axis",), seeds=(1, 2), builtins=("obrien", "sphere-geometric"))
    one = run_bench(workers=1, **kwargs)
    two = run_bench(workers=2, **kwargs)
    assert [(r["median"], r["ci95"]) for r in one["rows"]] == [(r["median"], r["ci95"]) for r in two["rows"]]
    assert all(r["n"] == 2 for r in one["rows"])
    # two seeds: below the comparisons' minimum, never significant
    assert all(c["p_value"] is None and not c["significant"] for c in one["comparisons"])


def test_a_command_gets_the_time_limit(specs: dict[str, str]) -> None:
    card = run_bench(
        [specs["slow"].replace("{poses}", "{poses} {hierarchy}")],
        scenarios=("linkage-single-axis",),
        seeds=(1,),
        builtins=(),
        time_limit_s=0.5,
    )
    (row, _) = [r for r in card["rows"]]
    assert row["failures"] == 1 and "time limit of 0.5 s" in row["errors"][0]


def test_cli_quick_with_a_crashing_estimator_exits_0(specs: dict[str, str], tmp_path: Path, capsys) -> None:
    out = tmp_path / "bench"
    args = ["bench", "--quick", "--kind", "joints", "--estimator", specs["crash"], "--out", str(out)]
    code = main([*args, "--no-progress", "--workers", "2"])
    assert code == 0
    said = capsys.readouterr().out
    assert f"2 scenario(s) x {suite.QUICK_SEEDS} seed(s), 9 estimator(s)" in said
    doc = json.loads((out / "scorecard.json").read_text())
    assert doc["quick"] is True and doc["seeds"] == list(suite.SEEDS[: suite.QUICK_SEEDS])
    assert [s["name"] for s in doc["scenarios"]] == [
        s.name for s in suite.SCENARIOS if s.quick and s.kind == "joints"
    ]
    crash = [r for r in doc["rows"] if r["estimator"] == specs["crash"]]
    assert crash and all(r["failures"] == r["failures"] + r["n"] == suite.QUICK_SEEDS for r in crash)
    assert (out / "index.md").is_file() and (out / "index.html").is_file()


def test_unknown_spec_is_refused_before_any_work(tmp_path: Path, capsys) -> None:
    with pytest.raises(InputError, match="no-such-estimator"):
        run_bench(["no-such-estimator"], scenarios=("linkage-paper",), seeds=(1,))
    out = tmp_path / "never"
    assert main(["bench", "--estimator", "no-such-estimator", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown estimator 'no-such-estimator'" in err
    assert not out.exists()


def test_a_spec_of_a_kind_not_run_is_refused() -> None:
    with pytest.raises(InputError, match="estimates orientation"):
        run_bench(["vqf"], kind="joints", builtins=())
    with pytest.raises(InputError, match="no scenario 'nope'"):
        run_bench(scenarios=("nope",))


def test_out_that_is_a_file_is_refused(tmp_path: Path, capsys) -> None:
    path = tmp_path / "file"
    path.write_text("x")
    assert main(["bench", "--quick", "--out", str(path), "--no-progress"]) == 2
    assert "got a file" in capsys.readouterr().err
    assert main(["bench", "--quick", "--out", str(tmp_path / "a" / "b"), "--no-progress"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_median_interval_and_paired_test() -> None:
    assert median_ci([0.2]) == (0.2, 0.2, 0.2)
    assert all(math.isnan(x) for x in median_ci([]))
    med, low, high = median_ci([1.0, 2.0, 3.0, 4.0, 100.0])
    assert med == 3.0 and 1.0 <= low < med < high <= 100.0
    assert median_ci([1.0, 2.0, 3.0, 4.0, 100.0]) == (med, low, high)  # seeded
    assert paired_test([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]) == (0.0, 1.0)
    diff, p = paired_test([1.1, 2.3, 3.2, 4.4], [1.0, 2.0, 3.0, 4.0])
    assert diff > 0 and p < ALPHA
    diff, p = paired_test([1.1, 1.9, 3.2, 3.8], [1.0, 2.0, 3.0, 4.0])
    assert p > ALPHA
    assert math.isnan(paired_test([1.0, 2.0], [2.0, 3.0])[1])  # fewer than 3 pairs: no test


def test_comparable(card: dict) -> None:
    assert comparable(card, card) == []
    other = json.loads(json.dumps(card))
    other["suite_version"] = "0"
    other["seeds"] = [1, 2]
    other["scenarios"][0]["fingerprint"] = "0" * 16
    del other["scenarios"][1]
    reasons = comparable(card, other)
    assert len(reasons) == 4
    assert any("suite version" in r for r in reasons) and any("only in the first" in r for r in reasons)
    assert any("fingerprint" in r for r in reasons) and any("seeds" in r for r in reasons)


def test_a_real_recording_is_scored_against_its_reference() -> None:
    """The package's BROAD excerpt: one run (n = 1, nothing tested on it), scored with BROAD's
    definitions over its movement samples; the gyro-aided reference beats the two-vector fix by
    far on an undisturbed field (0.97 against 6.18 degrees when measured)."""
    sc = suite.scenario("broad-02-undisturbed")
    assert sc.real and (suite.DATA_DIR / sc.recording).is_file()
    card = run_bench(kind="orientation", scenarios=(sc.name,), builtins=("triad", "vqf"), seeds=(1, 2, 3))
    rows = {r["estimator"]: r for r in card["rows"] if r["scenario"] == sc.name}
    assert rows["vqf"]["n"] == rows["triad"]["n"] == 1
    assert rows["vqf"]["median"] < 0.5 * rows["triad"]["median"]
    assert not [c for c in card["comparisons"] if c["scenario"] == sc.name and c["significant"]]
    # the fingerprint is the recording's bytes
    assert suite.scenario_fingerprint(sc) != suite.scenario_fingerprint(suite.scenario("broad-30-magnet"))
