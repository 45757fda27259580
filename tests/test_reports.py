"""The validation run and its report, single-dataset reports, and accuracy regression (issue 6)."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess

import numpy as np
import pytest

from simbench.cli import main
from simbench.experiments import baseline as bl
from simbench.experiments import validate
from simbench.experiments.obrien import human_trial, human_trials, linkage_experiment
from simbench.experiments.pool import worker_pool
from simbench.experiments.realism import DEFAULT_DATA_DIR
from simbench.experiments.validate import Plan


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    assert main(["validate", "--quick", "--out", str(out), "--no-progress"]) == 0
    return out


def test_quick_validate_writes_a_complete_report(quick_report):
    md = (quick_report / "index.md").read_text()
    for heading in (
        "The paper and simbench side by side",
        "Linkage (Table 1)",
        "Human subject",
        "Slip detection",
        "Sourceless orientation",
        "Decisions against their targets",
        "The paper's tables side by side",
        "Table 4: the female subject",
        "Realism",
    ):
        assert heading in md
    for row in ("Neck - Left Shoulder", "Between Shoulders", "Right Lower Leg", "Left Upper Arm"):
        assert row in md
    results = json.loads((quick_report / "results.json").read_text())
    # every estimator on each BROAD trial at hand, against TRIAD and the target
    ori = results["orientation"]
    assert ori["default"] == "skeleton"
    assert ori["target_met"] == (ori["methods"]["skeleton"]["total_rmse_deg"] <= 8)
    assert "Target for the default gyro-free estimator (skeleton): total RMSE at most 8 degrees" in md
    broad = results["orientation"]["broad"]
    assert set(broad) == {p.stem for p in DEFAULT_DATA_DIR.glob("broad_*.hdf5")}
    for trial, r in broad.items():
        assert f"### BROAD trial {trial}" in md and r["methods"]["triad"]["ratio_to_triad"] == 1.0
        assert r["default"] == "skeleton"
        ratio = r["methods"][r["default"]]["total_deg"] / r["methods"]["triad"]["total_deg"]
        assert r["target_met"] == (ratio <= r["target_ratio"])
        assert r["methods"]["vqf (gyro-aided reference)"]["ratio_to_triad"] < 0.5
    for t in results["humanoid"]["trials"]:  # a wrong tree names its wrong edges, both methods
        assert isinstance(t["wrong_joints"], list) and isinstance(t["wrong_joints_mst"], list)
        assert (t["wrong_joints_mst"] == []) == t["hierarchy_correct_mst"]
    s = results["summary"]
    assert s["linkage_sets"] == 2 and 0 < s["linkage_max_error_cm"] < 5
    assert s["slip_found"] is True
    assert all(np.isfinite(v) and v > 0 for v in s["orientation_total_rmse_deg"].values())
    assert set(results["versions"]) >= {"simbench", "numpy", "mujoco"} and results["run_time_s"] > 0
    for table in results["linkage"]["sets"]:
        assert len(table["rows"]) == 5 and all(np.isfinite(r["computed_cm"]) for r in table["rows"].values())
    d = results["decisions"]
    cases = d["false_alarms"]["cases"]
    assert set(cases) == {
        "linkage exercise, ascension-flock-paper",
        "humanoid exercise, skin-paper-human",
        "humanoid walk, skin-paper-human",
    }
    assert cases["linkage exercise, ascension-flock-paper"]["joint_hours"] == pytest.approx(
        2 * 5 * 12.0 / 3600
    )
    assert [r["sessions"] for r in d["detection"]["by_motion"]["exercise"].values()] == [1, 1, 1]
    assert (
        d["hinge"]["hinge (2 deg wobble)"]["single_axis"] == 3
        and d["hinge"]["ball, 3 axes"]["single_axis"] == 0
    )
    assert d["clusters"] == {"seeds": 5, "right": 5, "target": 5}
    tables = {t["key"]: t for t in results["paper_tables"]}
    assert list(tables) == ["table_1", "table_2", "table_3", "table_4"]
    assert tables["table_4"]["paper"]["n"] == 24 and len(tables["table_4"]["rows"]) == 8
    for key in ("table_1", "table_2"):  # the quick run measures the causes of these two
        assert set(tables[key]["causes"]) >= {"all"} and "Why:" in tables[key]["explanation"]
        assert tables[key]["explanation"] in md
    assert tables["table_1"]["simbench"]["n"] == 10  # 2 sets x 5 rows


def test_report_images_are_real_pictures(quick_report):
    import matplotlib.image as mpimg

    for name in (
        "residual_histograms.png",
        "limb_errors.png",
        "slip.png",
        "orientation.png",
        "pictures_linkage.png",
    ):
        img = mpimg.imread(quick_report / name)
        assert img.shape[0] >= 200 and img.shape[1] >= 400, name
        assert img[..., :3].std() > 0.01, name  # not a blank image
    html = (quick_report / "index.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and html.count("data:image/png;base64,") == 5  # self-contained


def test_report_html_renders_the_markdown(quick_report):
    md = (quick_report / "index.md").read_text()
    html = (quick_report / "index.html").read_text()
    assert "|:---|---:|---:|---:|---:|---:|" in md  # linkage table: names left, numbers right
    assert (
        "<title>simbench validation report</title>" in html and "<code>ascension-flock-paper</code>" in html
    )
    assert '<td style="text-align:left">Neck - Left Shoulder</td>' in html
    assert html.count('<td style="text-align:right">') > 40
    assert "`" not in html and "|---" not in html  # inline code and tables were rendered


def test_validation_is_deterministic():
    """The validation's experiments, small, twice: the process pool (two workers) and this process
    give the same figures, and so do two runs of the slip and orientation cases."""
    plan = dataclasses.replace(Plan.of(quick=True), linkage_s=8.0, humanoid_s=6.0, orientation_s=3.0)
    trials = human_trials(1, 1, 0)[:3]
    args = (*zip(*trials, strict=True), *[[x] * len(trials) for x in (plan.humanoid_s, 1.0)])
    with worker_pool(2) as pool:
        pooled = linkage_experiment(1, plan.linkage_s, 1.0, run=pool.map), list(pool.map(human_trial, *args))
    here = linkage_experiment(1, plan.linkage_s, 1.0), list(map(human_trial, *args))
    assert json.dumps(pooled) == json.dumps(here)
    for experiment in (validate._slip, validate._orientation):
        assert json.dumps(experiment(plan)) == json.dumps(experiment(plan)), experiment.__name__


def _browser() -> str | None:
    return next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


@pytest.mark.skipif(
    _browser() is None, reason="no Chromium on this machine (scripts/install-browser.sh installs one)"
)
def test_html_opens_in_headless_chromium(quick_report, tmp_path):
    done = subprocess.run(
        [
            _browser(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-first-run",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--dump-dom",
            (quick_report / "index.html").as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "simbench validation report" in done.stdout and done.stdout.count("<img") == 5


def test_dataset_report(tmp_path, capsys):
    h5 = tmp_path / "run.h5"
    assert main(["simulate", "--duration", "8", "--sensors", "ascension-flock", "-o", str(h5)]) == 0
    cal_json = tmp_path / "cal.json"
    assert main(["calibrate", str(h5), "--json", str(cal_json), "--no-slip"]) == 0
    for extra, label in (([], "calibrated here"), (["--calibration", str(cal_json)], "from")):
        out = tmp_path / f"rep{len(extra)}"
        assert main(["report", str(h5), "--out", str(out), *extra]) == 0
        md = (out / "index.md").read_text()
        assert label in md and "Hierarchy: correct" in md and "chest: chest-head / chest-upper_arm_l" in md
        doc = json.loads((out / "results.json").read_text())
        assert len(doc["joints"]) == 5 and len(doc["lengths_cm"]) == 5
        html = (out / "index.html").read_text()
        assert f"<title>simbench report: {h5}</title>" in html and html.count("data:image/png;base64,") == 1
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    capsys.readouterr()
    assert main(["report", str(h5), "--calibration", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "not a calibration JSON" in capsys.readouterr().err
    other = json.loads(cal_json.read_text())
    other["joints"][0]["child"] = "tail"
    bad.write_text(json.dumps(other))
    assert main(["report", str(h5), "--calibration", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "bad.json: names sensors the data lacks: ['tail']" in capsys.readouterr().err


def test_accuracy_has_not_regressed():
    """Recompute the accepted figures of reports/baseline.json; fail on any that got worse."""
    problems = bl.compare(bl.compute(), bl.load_baseline())
    assert problems == [], problems


def test_compare_flags_regressions_and_tolerates_noise():
    base = {"s": {"max_length_error_cm": 1.0, "hierarchy_wrong": 0.0}}
    assert (
        bl.compare({"s": {"max_length_error_cm": 1.1, "hierarchy_wrong": 0.0}}, base) == []
    )  # within 10 % + 0.05
    worse = bl.compare({"s": {"max_length_error_cm": 1.3, "hierarchy_wrong": 1.0}}, base)
    assert len(worse) == 2 and "worse than the accepted 1" in worse[0]
    assert bl.compare({}, base) == ["s: scenario missing"]
    elsewhere = bl.Figures()
    elsewhere.unavailable = ("s",)  # e.g. the realism figures without ../shared/data
    assert bl.compare(elsewhere, base) == []
    assert bl.diff_lines(base, {"s": {"max_length_error_cm": 2.0, "hierarchy_wrong": 0.0}}) == [
        "s.max_length_error_cm: 1 -> 2"
    ]


def test_baseline_update_shows_the_diff(tmp_path, capsys, monkeypatch):
    path = tmp_path / "baseline.json"
    bl.write_baseline({"linkage-flock-exercise": {"max_length_error_cm": 99.0}}, path)
    monkeypatch.setattr(bl, "SCENARIOS", bl.SCENARIOS[:1])
    monkeypatch.setattr(bl, "FIGURES", {})
    assert main(["baseline", "--file", str(path)]) == 0  # 99 cm accepted: anything better passes
    bl.write_baseline({"linkage-flock-exercise": {"max_length_error_cm": 1e-6}}, path)
    assert main(["baseline", "--file", str(path)]) == 1
    assert "accuracy got worse" in capsys.readouterr().err
    assert main(["baseline", "--update", "--file", str(path)]) == 0
    assert "max_length_error_cm: 1e-06 ->" in capsys.readouterr().out
    assert json.loads(path.read_text())["scenarios"]["linkage-flock-exercise"]["max_length_error_cm"] < 1


def test_a_wrong_tree_is_named_by_its_edges():
    from simbench.report.validation import _tree_verdict

    assert _tree_verdict(True, []) == "correct"
    assert (
        _tree_verdict(False, ["thigh_l-thigh_r", "upper_arm_l-hand_l"])
        == "wrong: thigh_l-thigh_r, upper_arm_l-hand_l"
    )
    assert _tree_verdict(False, []) == "wrong: (edges not recorded)"
