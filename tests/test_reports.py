"""The validation run and its report, single-dataset reports, and accuracy regression (issue 6)."""

from __future__ import annotations

import dataclasses
import html
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from simbench.cli import main
from simbench.estimators import DEFAULT_ORIENTATION as DEFAULT_METHOD
from simbench.experiments import baseline as bl
from simbench.experiments import validate
from simbench.experiments.obrien import human_trial, human_trials, linkage_experiment
from simbench.experiments.pool import worker_pool
from simbench.experiments.realism import DEFAULT_DATA_DIR
from simbench.experiments.validate import Plan
from simbench.io.imu import read_broad
from simbench.orient import estimate


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
    # the report says Gauss-Newton's fontaine and the closed-form wahba reach the same minimum
    assert "(`wahba`: the two rows agree" in md
    f, w = ori["methods"]["fontaine"], ori["methods"]["wahba"]
    assert w["total_rmse_deg"] == pytest.approx(f["total_rmse_deg"], rel=1e-6)
    broad = results["orientation"]["broad"]
    assert set(broad) == {p.stem for p in DEFAULT_DATA_DIR.glob("broad_*.hdf5")}
    # the realism section: each undisturbed BROAD trial's digital twin (the quick run's; the full
    # run makes every trial's), or why there is none
    twins = results["realism"]["twins"]["twins"]
    assert set(twins) == {t for t in broad if "undisturbed" in t}
    assert "### Digital twins of the BROAD trials" in md
    assert not twins or "The trials `broad_*undisturbed*.hdf5` only (`--quick`" in md
    for trial, t in twins.items():
        assert {"acc", "gyro", "mag"} == set(t["readings"]) and set(t["orientation"]) >= {"triad", "vqf"}
        assert f"| {trial} | {t['readings']['acc']['r2']:.4f}" in md
    for trial, r in broad.items():
        assert f"### BROAD trial {trial}" in md and r["methods"]["triad"]["ratio_to_triad"] == 1.0
        assert r["default"] == "skeleton"
        ratio = r["methods"][r["default"]]["total_deg"] / r["methods"]["triad"]["total_deg"]
        assert r["target_met"] == (ratio <= r["target_ratio"])
        assert r["methods"]["vqf (gyro-aided reference)"]["ratio_to_triad"] < 0.5
        gauss_newton, closed_form = r["methods"]["fontaine"], r["methods"]["wahba"]
        assert closed_form["total_deg"] == pytest.approx(gauss_newton["total_deg"], rel=1e-6)
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
        "limb_lengths.png",
        "slip.png",
        "orientation.png",
        "pictures_linkage.png",
    ):
        img = mpimg.imread(quick_report / name)
        assert img.shape[0] >= 200 and img.shape[1] >= 400, name
        assert img[..., :3].std() > 0.01, name  # not a blank image
    html = (quick_report / "index.html").read_text()
    assert html.startswith("<!DOCTYPE html>") and html.count("data:image/png;base64,") == 6  # self-contained


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


def test_validation_is_deterministic(fresh_physics, monkeypatch, tmp_path):
    """The validation's experiments, small, twice: the process pool (two workers) and this process
    give the same figures, and so do two runs of the slip and orientation cases (the simulated
    ones: the BROAD recordings' scores are the default estimator's, once more, below)."""
    plan = dataclasses.replace(Plan.of(quick=True), linkage_s=8.0, humanoid_s=6.0, orientation_s=3.0)
    trials = human_trials(1, 1, 0)[:3]
    args = (*zip(*trials, strict=True), *[[x] * len(trials) for x in (plan.humanoid_s, 1.0)])
    with worker_pool(2) as pool:
        pooled = linkage_experiment(1, plan.linkage_s, 1.0, run=pool.map), list(pool.map(human_trial, *args))
    here = linkage_experiment(1, plan.linkage_s, 1.0), list(map(human_trial, *args))
    assert json.dumps(pooled) == json.dumps(here)
    broad = sorted(DEFAULT_DATA_DIR.glob("broad_*.hdf5"))
    monkeypatch.setattr(validate, "DEFAULT_DATA_DIR", tmp_path)  # no recordings: simulation only
    for experiment in (validate._slip, validate._orientation):
        assert json.dumps(experiment(plan)) == json.dumps(experiment(plan)), experiment.__name__
    if broad:
        rec = read_broad(broad[0])
        n = round(30 * rec.rate_hz)  # its first 30 s: the same estimator, a quarter of the work
        head = {k: getattr(rec, k)[:n] for k in ("time_s", "acc", "gyro", "mag", "valid", "q_true")}
        rec = dataclasses.replace(rec, **head, evaluate=None, saturated=None)
        first, again = (estimate(rec, method=DEFAULT_METHOD).q_enu for _ in range(2))
        assert np.isfinite(first).any()
        np.testing.assert_array_equal(first, again)


def test_validate_keeps_the_physics_in_the_folder_asked_for(tmp_path, monkeypatch, capsys):
    """``--physics-cache DIR`` makes the folder (parents too) and hands it to the run, whose physics
    cache keeps the runs there and reads them back (byte-identical: tests/test_physics_cache.py);
    without it the run gets none (a temporary folder)."""
    seen: list = []

    def stop_at_once(**kwargs):
        seen.append(kwargs["physics_folder"])
        raise KeyboardInterrupt

    monkeypatch.setattr("simbench.cli.validate.run_validation", stop_at_once)
    folder = tmp_path / "cache" / "physics"
    args = ["validate", "--quick", "--no-progress", "--out", str(tmp_path / "r")]
    assert main([*args, "--physics-cache", str(folder)]) == 130
    assert main(args) == 130
    assert seen == [folder, None] and folder.is_dir()
    (tmp_path / "file").write_text("x")
    assert main([*args, "--physics-cache", str(tmp_path / "file")]) == 2
    assert "--physics-cache" in capsys.readouterr().err and seen == [folder, None]


def _browser() -> str | None:
    return next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


@pytest.mark.skipif(
    _browser() is None, reason="no Chromium on this machine (scripts/install-browser.sh installs one)"
)
def test_html_opens_in_headless_chromium(quick_report, tmp_path):
    done = _chromium(tmp_path, "--dump-dom", (quick_report / "index.html").as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    assert "simbench validation report" in done.stdout and done.stdout.count("<img") == 6


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


# -- the report's figures (issue 18): palette, pictures, limb-length scatter, orientation, sizes --


def _data_colours(fig) -> set[str]:
    """Every colour the figure's visible axes and legends draw lines, markers, patches and
    collections in, as ``#rrggbb`` (alpha dropped; the axes' and legends' own backgrounds and
    frames are not data and are left out)."""
    from matplotlib.colors import to_hex

    colours: list = []
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend())]
    artists = [a for ax in fig.axes if ax.get_visible() for a in (*ax.lines, *ax.patches, *ax.collections)]
    artists += [h for legend in legends for h in legend.legend_handles]
    for a in artists:
        if hasattr(a, "get_markerfacecolor"):  # Line2D
            colours += [a.get_color(), a.get_markerfacecolor(), a.get_markeredgecolor()]
        elif hasattr(a, "get_facecolors"):  # collections: one colour per item
            if a.get_array() is None:  # a colour-mapped one (colour bar) is coloured at drawing
                colours += [*a.get_facecolors(), *a.get_edgecolors()]
        else:  # patches
            colours += [a.get_facecolor(), a.get_edgecolor()]
    return {to_hex(c) for c in colours if not (isinstance(c, str) and c == "none")}


def _two_parameter_study():
    """A small grid study of two parameters and its table (three metrics, one of them 0/1)."""
    from types import SimpleNamespace

    pa = pytest.importorskip("pyarrow")
    parameters = [
        SimpleNamespace(name="sensors.tracker.position_noise_m", values=(0.0, 0.008), unit="mm"),
        SimpleNamespace(name="rate_hz", values=(60.0, 120.0), unit="hz"),
    ]
    metrics = ("joint_centre_error_m", "limb_length_error_m", "hierarchy_correct")
    study = SimpleNamespace(
        name="small", metrics=metrics, seed=3, seeds_per_cell=2, kind="grid", base={}, parameters=parameters
    )
    rows = []
    for cell, (noise, rate) in enumerate([(n, r) for n in (0.0, 0.008) for r in (60.0, 120.0)]):
        for replicate in range(2):
            row = {"trial": 2 * cell + replicate, "cell": cell, "replicate": replicate, "seed": replicate}
            row |= {parameters[0].name: noise, "rate_hz": rate, "hierarchy_correct": float(replicate)}
            rows.append(row | {"joint_centre_error_m": 0.01 + noise, "limb_length_error_m": 0.02 + noise})
    return study, pa.Table.from_pylist(rows)


def test_every_figure_takes_its_colours_from_the_palette(quick_report, monkeypatch, tmp_path):
    """Each figure the validation report and a study draw, from the quick report's figures:
    every line, marker, patch and collection colour is one of Okabe and Ito's (``PALETTE``), and
    heat maps use the colour-blind-safe ``SEQUENTIAL_CMAP``."""
    from types import SimpleNamespace

    from matplotlib.colors import to_hex

    from simbench.report import plots
    from simbench.report import study as study_report
    from simbench.report.pictures import ESTIMATED_MARK, TRUE_MARK

    results = json.loads((quick_report / "results.json").read_text())
    joints = [
        SimpleNamespace(name=f"joint {k}", fit=SimpleNamespace(frame_residual=np.linspace(0, 1, 50)))
        for k in range(5)
    ]
    figures = {
        "residual histograms": plots.residual_histograms_figure(joints, 1.0),
        "limb errors": plots.limb_errors_figure(results["humanoid"]),
        "limb lengths": plots.limb_lengths_figure(results["humanoid"]),
        "slip": plots.slip_figure(results["slip"]),
        "orientation": plots.orientation_figure(results["orientation"]),
        "pictures": plots.pictures_figure(
            [np.zeros((30, 40, 3), np.uint8)] * 2,
            ["a", "b"],
            legend=[TRUE_MARK.legend(), ESTIMATED_MARK.legend()],
        ),
    }
    drawn: list = []  # the study's figures, as plot_study hands them to save_figure
    monkeypatch.setattr(study_report, "save_figure", lambda fig, path: drawn.append((path.name, fig)))
    study, table = _two_parameter_study()
    study_report.plot_study(study, table, tmp_path)
    figures |= dict(drawn)
    assert set(dict(drawn)) == {
        "vs_sensors_tracker_position_noise_m.png",
        "vs_rate_hz.png",
        "heatmap.png",
    }
    palette = {to_hex(c) for c in plots.PALETTE}
    assert len(palette) == 8 and to_hex(plots.INK) in palette
    for name, fig in figures.items():
        colours = _data_colours(fig)
        assert colours and colours <= palette, (name, sorted(colours - palette))
        for ax in fig.axes:  # a quantity's map and its colour bar (not an RGB picture): cividis
            for mapped in (*ax.images, *ax.collections):
                if mapped.get_array() is not None and mapped.get_array().ndim <= 2:
                    assert mapped.get_cmap().name == plots.SEQUENTIAL_CMAP, name
    assert {TRUE_MARK.colour, ESTIMATED_MARK.colour} == {plots.TRUTH_COLOUR, plots.ESTIMATE_COLOUR}
    assert {to_hex(plots.TRUTH_COLOUR), to_hex(plots.ESTIMATE_COLOUR)} <= palette


def test_limb_spread_over_trials_golden():
    from simbench.report.plots import limb_spread

    def trial(subject, motion, computed):
        return {
            "subject": subject,
            "motion": motion,
            "rows": {"arm": {"true_cm": 30.0, "computed_cm": computed}},
        }

    humanoid = {
        "trials": [
            trial("male", "exercise", 31.0),
            trial("female", "walk", 29.0),
            trial("male", "walk", 32.0),
        ]
    }
    male, female = limb_spread(humanoid)
    assert (male.subject, male.limb, male.true_mm, male.motions) == (
        "male",
        "arm",
        300.0,
        ("exercise", "walk"),
    )
    assert male.estimated_mm == pytest.approx((310.0, 320.0), abs=1e-9)  # cm -> mm, exact
    assert male.mean_mm == pytest.approx(315.0, abs=1e-9)
    assert male.sd_mm == pytest.approx(np.sqrt(50.0), abs=1e-9)  # sample s.d. of 310 and 320
    assert female.sd_mm == 0.0 and female.mean_mm == pytest.approx(290.0, abs=1e-9)  # one trial
    humanoid["trials"][0]["rows"]["arm"]["computed_cm"] = None  # not estimated (NaN in results.json)
    male = limb_spread(humanoid)[0]
    assert (
        np.isnan(male.estimated_mm[0]) and male.mean_mm == pytest.approx(320.0, abs=1e-9) and male.sd_mm == 0
    )


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    """The rows of a 2-D array sorted by their first column, then the next."""
    return a[np.lexsort(a.T[::-1])]


def test_limb_length_scatter_shows_every_trial_and_the_spread(quick_report):
    """The scatter's points are each trial's (true, estimated) lengths in mm; its error bars are
    each subject's limb's mean and sample s.d. over trials; the right panel is the same, less the
    truth; the identity line is drawn; the report shows the figure and a table of the spread."""
    from matplotlib.collections import PathCollection
    from matplotlib.container import ErrorbarContainer

    from simbench.report.plots import limb_lengths_figure

    humanoid = json.loads((quick_report / "results.json").read_text())["humanoid"]
    fig = limb_lengths_figure(humanoid)
    ax, ax_diff = fig.axes
    trials = humanoid["trials"]
    points = np.array(
        [(10 * r["true_cm"], 10 * r["computed_cm"]) for t in trials for r in t["rows"].values()]
    )
    spread = []  # (true, mean, sample s.d.) of each subject's limb over that subject's trials, mm
    for subject in {t["subject"] for t in trials}:
        mine = [t for t in trials if t["subject"] == subject]
        for limb, row in mine[0]["rows"].items():
            estimates = np.array([10 * t["rows"][limb]["computed_cm"] for t in mine])
            sd = estimates.std(ddof=1) if estimates.size > 1 else 0.0
            spread.append((10 * row["true_cm"], estimates.mean(), sd))
    spread = np.array(spread)
    # every limb named beside its error bar in the error panel, once per subject
    named = sorted(t.get_text() for t in ax_diff.texts)
    subjects = {t["subject"] for t in trials}
    assert named == sorted(limb for limb in trials[0]["rows"] for _ in subjects)
    for axes, minus_truth in ((ax, 0.0), (ax_diff, 1.0)):
        drawn = np.concatenate([c.get_offsets() for c in axes.collections if isinstance(c, PathCollection)])
        want = points - [0.0, minus_truth] * points[:, :1]
        # cm from the JSON times 10: equal to rounding
        np.testing.assert_allclose(_sorted_rows(drawn), _sorted_rows(want), atol=1e-9)
        bars = []
        for bar in (c for c in axes.containers if isinstance(c, ErrorbarContainer)):
            (x,), (y,) = bar.lines[0].get_data()
            (segment,) = bar.lines[2][0].get_segments()
            bars.append((x, y + minus_truth * x, 0.5 * (segment[1, 1] - segment[0, 1])))
        np.testing.assert_allclose(_sorted_rows(np.array(bars)), _sorted_rows(spread), atol=1e-9)
    diagonal = [
        line
        for line in ax.lines
        if np.array_equal(line.get_xdata(), line.get_ydata()) and len(line.get_xdata()) == 2
    ]
    assert diagonal, "no identity line"
    md = (quick_report / "index.md").read_text()
    assert "![Limb lengths: estimate against truth" in md and "(limb_lengths.png)" in md
    assert "| subject | limb | true (mm) | mean estimate (mm) | s.d. (mm) | trials |" in md


def test_orientation_figure_is_a_distribution_per_method_and_one_trace(quick_report, tmp_path):
    """One box per estimator with its per-frame median, the default's trace beside it, the
    legend above the data, at most 2000 px wide."""
    from simbench.report.plots import orientation_figure, save_figure

    orientation = json.loads((quick_report / "results.json").read_text())["orientation"]
    fig = orientation_figure(orientation)
    ax_box, ax_time = fig.axes
    methods = orientation["methods"]
    assert len(ax_box.patches) == len(methods)
    labels = [t.get_text().split("\n")[0] for t in ax_box.get_yticklabels()]
    assert labels == list(methods) and ax_box.get_xscale() == "log" and "deg" in ax_box.get_xlabel()
    boxes = {m: np.median(methods[m]["per_frame_deg"]) for m in methods}
    drawn = {line.get_xdata()[0] for line in ax_box.lines if len(set(line.get_xdata())) == 1}
    assert all(any(abs(d - b) < 1e-9 for d in drawn) for b in boxes.values()), (boxes, drawn)
    trace, _ = ax_time.lines  # the default's trace, its RMS level
    np.testing.assert_array_equal(trace.get_ydata(), methods[orientation["default"]]["per_frame_deg"])
    assert "deg" in ax_time.get_ylabel() and orientation["default"] in trace.get_label()
    fig.draw_without_rendering()  # the legend lies above the data, not over it
    assert ax_time.get_legend().get_window_extent().y0 >= ax_time.get_window_extent().y1 - 1
    save_figure(fig, tmp_path / "orientation.png")
    assert fig.get_figwidth() * 100 <= 2000


def test_every_report_png_is_at_most_2000_px_wide(quick_report, tmp_path):
    import matplotlib.image as mpimg
    from matplotlib.figure import Figure

    from simbench.report.plots import MAX_WIDTH_PX, save_figure

    pngs = sorted(quick_report.glob("*.png"))
    assert len(pngs) == 6
    for png in pngs:
        height, width = mpimg.imread(png).shape[:2]
        assert 300 <= width <= MAX_WIDTH_PX and height >= 200, (png.name, width, height)
    with pytest.raises(ValueError, match=r"wide\.png: 2100 px wide, more than 2000 px"):
        save_figure(Figure(figsize=(21, 2)), tmp_path / "wide.png")
    assert not (tmp_path / "wide.png").exists()


def _colour_pixels(image: np.ndarray, colour: str) -> np.ndarray:
    """``(height, width)`` bool: the pixels of an RGB image (0-1) of a colour's hue, lit or
    shaded: saturated (> 0.5) and within 0.03 of its hue (the grey model, floor and the pale sky
    are unsaturated; the palette's blue and vermillion are 0.49 apart in hue)."""
    from matplotlib.colors import rgb_to_hsv, to_rgb

    hsv = rgb_to_hsv(image[..., :3])
    hue = rgb_to_hsv(np.array(to_rgb(colour)))[0]
    distance = np.abs((hsv[..., 0] - hue + 0.5) % 1.0 - 0.5)
    return (hsv[..., 1] > 0.5) & (hsv[..., 2] > 0.2) & (distance < 0.03)


def test_pictures_are_bright_with_visible_marks_and_a_legend(quick_report):
    """The linkage's pictures, rendered again from a short session: bright, with the true and the
    estimated joint centres in their palette colours; the report's PNG has the legend below."""
    import matplotlib.image as mpimg

    import simbench as sb
    from simbench.report.pictures import ESTIMATED_MARK, TRUE_MARK, render_pictures
    from simbench.report.plots import pictures_figure
    from simbench.sim.models import load_capture_model

    ds = sb.simulate("linkage", "exercise", sensors="ascension-flock", duration_s=8.0, seed=3)
    cal = sb.calibrate(ds)
    n = ds.time_s.size
    images = render_pictures(
        load_capture_model("linkage"), ds, cal.joints, ds.position_unit_scale, [n // 5, n // 2]
    )
    if images is None:
        pytest.skip("no offscreen GL context on this machine")
    for image in images:
        rgb = image / 255.0
        # mean luminance (Rec. 709): the old pictures (black sky, dark floor) were 0.03; a lit
        # light floor and pale sky with the model in grey are about 0.78. 0.5 is half white.
        assert (rgb @ [0.2126, 0.7152, 0.0722]).mean() > 0.5
        # five joints: each true sphere is about 300 px (radius 4 % of the span at 1.8 spans),
        # the estimated cubes mostly inside them show their corners
        assert _colour_pixels(rgb, TRUE_MARK.colour).sum() > 500
        assert _colour_pixels(rgb, ESTIMATED_MARK.colour).sum() > 50
    fig = pictures_figure(images, ["a", "b"], legend=[TRUE_MARK.legend(), ESTIMATED_MARK.legend()])
    (legend,) = fig.legends
    assert [t.get_text() for t in legend.get_texts()] == [TRUE_MARK.label, ESTIMATED_MARK.label]
    written = mpimg.imread(quick_report / "pictures_linkage.png")[..., :3]
    below = written[-30:]  # the legend's strip under the panels
    assert (
        _colour_pixels(below, TRUE_MARK.colour).any() and _colour_pixels(below, ESTIMATED_MARK.colour).any()
    )
    assert (written @ [0.2126, 0.7152, 0.0722]).mean() > 0.5


_MEASURE = """<script>
window.addEventListener('load', function () {
  var page = document.documentElement;
  var wide = Array.from(document.querySelectorAll('body *')).filter(function (e) {
    return e.getBoundingClientRect().width > page.clientWidth + 0.5;
  }).map(function (e) { return e.tagName; });
  var out = document.createElement('pre');
  out.id = 'simbench-measure';
  var scrolled = Array.from(document.querySelectorAll('table')).filter(function (t) {
    return t.scrollWidth > t.clientWidth + 0.5;
  }).map(function (t) { return t.rows[0].textContent.slice(0, 60); });
  out.textContent = JSON.stringify({
    scrollWidth: page.scrollWidth, clientWidth: page.clientWidth, wide: wide, scrolled: scrolled,
    images: Array.from(document.images).map(function (i) { return [i.complete, i.naturalWidth]; })
  });
  document.body.appendChild(out);
});
</script>"""


def _chromium(tmp_path, *args: str) -> subprocess.CompletedProcess:
    """Headless Chromium with a throw-away profile, the report's page at a laptop's width."""
    return subprocess.run(
        [
            _browser(),
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--no-first-run",
            "--hide-scrollbars",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--window-size=1280,2400",
            "--virtual-time-budget=10000",  # let the load event fire before the dump
            *args,
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


@pytest.mark.skipif(
    _browser() is None, reason="no Chromium on this machine (scripts/install-browser.sh installs one)"
)
def test_report_screenshot_in_headless_chromium(quick_report, tmp_path):
    """The page renders (a screenshot that is not blank), every image loads, and nothing is
    wider than the page (no sideways scrolling of the page at 1280 px)."""
    import matplotlib.image as mpimg

    shot = tmp_path / "shot.png"
    done = _chromium(tmp_path, f"--screenshot={shot}", (quick_report / "index.html").as_uri())
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    pixels = mpimg.imread(shot)[..., :3]
    assert pixels.shape[1] == 1280 and pixels.std() > 0.05  # text, tables and figures, not blank
    assert (pixels.mean(axis=-1) < 0.5).mean() > 0.005  # dark text on the page
    page = tmp_path / "index.html"  # the same page with a script that writes its measurements
    page.write_text((quick_report / "index.html").read_text().replace("</body>", _MEASURE + "</body>"))
    done = _chromium(tmp_path, "--dump-dom", page.as_uri())
    assert done.returncode == 0, done.stderr[-2000:]
    found = re.search(r'<pre id="simbench-measure">(.*?)</pre>', done.stdout)
    assert found, done.stdout[-2000:]
    measured = json.loads(html.unescape(found.group(1)))
    assert len(measured["images"]) == 6 and all(ok and width > 0 for ok, width in measured["images"])
    assert measured["scrollWidth"] <= measured["clientWidth"], measured
    assert measured["wide"] == [], measured["wide"]
    assert measured["scrolled"] == [], measured["scrolled"]  # every table fits its column, unscrolled


def test_length_tables_of_many_trials_stay_narrow():
    """Five trials' computed lengths and differences side by side made a 21-column table 1,439 px
    wide in the full report's 1,100 px column; now two tables of at most 2 + trials columns."""
    from simbench.report.validation import _lengths_table

    trials = [
        {"rows": {limb: {"true_cm": 40.0, "computed_cm": 40.5, "difference_cm": 0.5} for limb in ("a", "b")}}
        for _ in range(5)
    ]
    text = _lengths_table("limb", trials, [f"t{k}" for k in range(5)], [f"diff t{k}" for k in range(5)])
    headers = [line for line in text.splitlines() if line.startswith("| limb")]
    assert [h.count("|") - 1 for h in headers] == [7, 6]  # limb, true, 5 computed; limb, 5 differences
    assert "| a | 40.00 | 40.50 |" in text and "| a | 0.50 | 0.50 |" in text
