"""Studies (issue 7): identical rows for any executor, resumption after a kill, bad files, effects,
the base session's defaults, the error when the optional packages are missing, the report."""

from __future__ import annotations

import contextlib
import json
import re
import subprocess
import sys
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from simbench.cli import main
from simbench.errors import InputError
from simbench.experiments import study as st
from simbench.experiments import sweep as sw
from simbench.report import study as study_report
from simbench.sim.session import SessionConfig, load_session_model, run_session

STUDY = """
name = "small"
seed = 3
seeds_per_cell = 2
estimators = ["calibration"]
metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]
[base]
model = "linkage"
motion = "exercise"
sensors = "ascension-flock"
duration_s = {duration}
[sampling]
kind = "grid"
[[parameter]]
name = "sensors.tracker.position_noise_m"
unit = "mm"
values = {values}
"""


def study_file(tmp_path: Path, duration: float = 3.0, values: str = "[0.0, 8.0]") -> Path:
    path = tmp_path / "study.toml"
    path.write_text(STUDY.format(duration=duration, values=values))
    return path


def parameter_study(
    tmp_path: Path, name: str, unit: str, values: str, *, duration: float = 1.0, seeds: int = 2
) -> Path:
    """The small study varying ``name`` (in ``unit``) over ``values`` instead of the noise."""
    path = tmp_path / "p.toml"
    path.write_text(
        STUDY.format(duration=duration, values=values)
        .replace("sensors.tracker.position_noise_m", name)
        .replace('unit = "mm"', f'unit = "{unit}"')
        .replace("seeds_per_cell = 2", f"seeds_per_cell = {seeds}")
    )
    return path


def sweep_command(path: Path, out: Path, workers: int) -> list[str]:
    """``simbench sweep`` as a subprocess command line."""
    command = [sys.executable, "-m", "simbench", "sweep", str(path), "--out", str(out)]
    return [*command, "--workers", str(workers), "--no-progress"]


def rows(table) -> list[dict]:
    out = table.to_pylist()
    for r in out:
        r.pop("run_time_s")
    return sorted(out, key=lambda r: r["trial"])


def test_one_or_two_workers_give_identical_rows(tmp_path):
    study = st.load_study(study_file(tmp_path))
    one = sw.run_study(study, tmp_path / "one", workers=1)
    two = sw.run_study(study, tmp_path / "two", workers=2)
    assert len(rows(one)) == 4 and rows(one) == rows(two)
    assert (tmp_path / "one" / "results.parquet").is_file()


def test_dask_local_cluster_gives_identical_rows(tmp_path):
    pytest.importorskip("distributed")
    study = st.load_study(study_file(tmp_path))
    local = sw.run_study(study, tmp_path / "local", workers=1)
    with sw.local_dask_executor(2) as executor:  # two worker processes over loopback TCP
        dask = sw.run_study(study, tmp_path / "dask", executor=executor)
    assert rows(dask) == rows(local)


def test_error_grows_with_noise(tmp_path):
    study = st.load_study(study_file(tmp_path, duration=6.0, values="[0.0, 12.0]"))
    table = sw.run_study(study, tmp_path / "noise", executor=ProcessPoolExecutor(2))
    data = table.to_pydict()
    noise = np.array(data["sensors.tracker.position_noise_m"])
    err = np.array(data["joint_centre_error_m"])
    # 12 mm of noise vs the preset's orientation noise alone: clearly larger error (a real effect)
    assert err[noise > 0].mean() > 2.0 * err[noise == 0].mean()


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        (
            ("sensors.tracker.position_noise_m", "sensors.tracker.noise"),
            "tracker has no numeric field 'noise'",
        ),
        (('unit = "mm"', 'unit = "deg"'), "unit 'deg' does not fit"),
        (("values = [0.0, 8.0]", "values = []"), "needs a non-empty list"),
        (("seeds_per_cell = 2", "seeds_per_cell = 0"), "seeds_per_cell must be an integer >= 1"),
        (("[sampling]", "colour = 1\n[sampling]"), r"unknown keys \['colour'\]"),
        (('estimators = ["calibration"]', 'estimators = ["magic"]'), "unknown 'magic'"),
        (
            ('estimators = ["calibration"]', 'estimators = ["joint:magic"]'),
            r"'joint:magic': unknown estimator 'magic': expected one of obrien, obrien-eiv, obrien-robust",
        ),
        (
            ('estimators = ["calibration"]', 'estimators = ["joint:fontaine"]'),
            r"'fontaine' estimates orientation, not joints",
        ),
        (
            ('estimators = ["calibration"]', 'estimators = ["joint:nowhere.py:fit"]'),
            r"no file nowhere.py",
        ),
        (('kind = "grid"', 'kind = "random"\nsamples = 4'), "random sampling needs low < high"),
    ],
)
def test_bad_study_files_are_rejected_before_any_work(tmp_path, patch, message):
    path = study_file(tmp_path)
    path.write_text(path.read_text().replace(*patch))
    with pytest.raises(InputError, match=message):
        st.load_study(path)


def test_cli_rejects_bad_study_without_output(tmp_path, capsys):
    path = study_file(tmp_path)
    path.write_text(path.read_text().replace("ascension-flock", "no-such-preset"))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "unknown sensor preset" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_random_sampling_is_seeded_and_in_range(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text(
        STUDY.format(duration=2.0, values="[0]")
        .replace('kind = "grid"', 'kind = "random"\nsamples = 50')
        .replace("values = [0]", "low = 1.0\nhigh = 10.0\nlog = true")
    )
    study = st.load_study(path)
    a, b = st.trials(study), st.trials(study)
    assert a == b and len(a) == 100
    v = np.array([t.params[0][1] for t in a])
    assert v.min() >= 0.001 and v.max() <= 0.010  # mm converted to metres


def test_placement_parameter_moves_the_sensor(tmp_path):
    base = run_session(SessionConfig(duration_s=1.0))
    shifted_cfg = SessionConfig(duration_s=1.0, placement=(("forearm_l", (0.05, -0.02, 0.0)),))
    shifted = run_session(shifted_cfg, load_session_model(shifted_cfg))
    k = base.sensors.index("forearm_l")
    assert np.allclose(shifted.truth.p_b_s[k] - base.truth.p_b_s[k], [0.05, -0.02, 0.0], atol=1e-12)
    others = [i for i in range(len(base.sensors)) if i != k]
    assert np.array_equal(shifted.truth.p_b_s[others], base.truth.p_b_s[others])
    path = parameter_study(tmp_path, "placement.forearm_l.x_m", "cm", "[-5.0, 5.0]", duration=2.0)
    study = st.load_study(path)
    assert [t.params for t in st.trials(study)][::2] == [
        (("placement.forearm_l.x_m", -0.05),),
        (("placement.forearm_l.x_m", 0.05),),
    ]
    path.write_text(path.read_text().replace("placement.forearm_l.x_m", "placement.forearm_l.w"))
    with pytest.raises(InputError, match=r"expected placement\.<sensor>\.x_m"):
        st.load_study(path)


def test_base_session_takes_session_config_defaults(tmp_path):
    path = study_file(tmp_path)
    text = path.read_text().replace('model = "linkage"\n', "").replace("duration_s = 3.0\n", "")
    path.write_text(text.replace('sensors = "ascension-flock"\n', ""))
    study = st.load_study(path)
    assert study.base == {"motion": "exercise", "sensors": SessionConfig().sensors}
    config = st.trial_config(study, st.trials(study)[-1])
    defaults = SessionConfig()
    assert (config.model, config.duration_s, config.rate_hz) == (
        defaults.model,
        defaults.duration_s,
        defaults.rate_hz,
    )
    assert config.sensors.tracker.position_noise_m == 0.008  # the trial's value, in metres
    assert config.seed == st.trials(study)[-1].seed


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        (("duration_s = 3.0", "duration_s = 0.0"), "base: duration must be > 0 s"),
        (("duration_s = 3.0", 'duration_s = "3"'), "base.duration_s: expected a number"),
        (('model = "linkage"', "model = 1"), "base.model: expected a string"),
    ],
)
def test_bad_base_session_is_rejected_when_loading(tmp_path, patch, message):
    path = study_file(tmp_path)
    path.write_text(path.read_text().replace(*patch))
    with pytest.raises(InputError, match=message):
        st.load_study(path)


@pytest.mark.parametrize("missing", ["pyarrow.parquet"])
def test_missing_optional_package_names_the_extra(tmp_path, monkeypatch, missing):
    study = st.load_study(study_file(tmp_path))
    monkeypatch.setitem(sys.modules, missing, None)  # importing it now raises ImportError
    with pytest.raises(InputError, match=r"simbench sweep needs .* pip install 'simbench\[studies\]'"):
        sw.run_study(study, tmp_path / "out")
    assert not (tmp_path / "out").exists()  # refused before any work


def test_missing_dask_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with (
        pytest.raises(InputError, match=r"--scheduler needs .*'distributed'.*simbench\[studies\]"),
        sw.dask_executor("tcp://127.0.0.1:1"),
    ):
        pass


def test_report_plots_and_summary_of_a_two_parameter_grid(tmp_path):
    pa = pytest.importorskip("pyarrow")
    path = study_file(tmp_path)
    text = path.read_text() + '[[parameter]]\nname = "rate_hz"\nunit = "hz"\nvalues = [60, 120]\n'
    path.write_text(text)
    study = st.load_study(path)
    every = st.trials(study)
    err = [0.01 * (1 + t.cell) for t in every]  # cell 3 (8 mm, 120 Hz) has the largest error
    table = pa.Table.from_pylist(
        [
            {"trial": t.trial_id, "cell": t.cell, "replicate": t.replicate, "seed": t.seed}
            | dict(t.params)
            | {"joint_centre_error_m": e, "condition": 10.0 + e, "run_time_s": 1.0}
            for t, e in zip(every, err, strict=True)
        ]
    )
    # only the metrics the study asks for (condition and run time are in the table, not asked for)
    assert study_report.metric_columns(study, table.to_pydict()) == ["joint_centre_error_m"]
    plots = study_report.plot_study(study, table, tmp_path)
    assert [p.name for p in plots] == [
        "vs_sensors_tracker_position_noise_m.png",
        "vs_rate_hz.png",
        "heatmap.png",
    ]
    assert all(p.read_bytes()[:4] == b"\x89PNG" for p in plots)
    text = study_report.summary_markdown(study, table, plots)
    # parameters in the study's units (the noise in mm as the file gave it), lengths in mm
    assert "| sensors.tracker.position_noise_m (mm) | rate_hz (hz) | mean joint-centre error (mm) |" in text
    assert "| 8 | 120 | 40 |" in text  # cell 3's parameters and mean
    assert "condition number with the joint-centre error: 1.00." in text
    assert (
        "Smallest mean joint-centre error: sensors.tracker.position_noise_m = 0 mm, rate_hz = 60 hz." in text
    )
    assert "![heatmap](heatmap.png)" in text


def test_a_changed_study_is_refused_in_the_same_folder(tmp_path):
    """A study edited and rerun into the same folder is refused before any trial (the folder holds
    the other study's trials); the same study resumes; --force starts over with the new one."""
    path = study_file(tmp_path, duration=1.0, values="[0.0]")
    out = tmp_path / "out"
    original = st.load_study(path)
    assert len(sw.run_study(original, out)) == 2
    assert st.study_fingerprint(st.load_study(path)) == st.study_fingerprint(original)
    assert sw.run_study(st.load_study(path), out).num_rows == 2  # the same study: resumed, nothing run
    path.write_text(path.read_text().replace("values = [0.0]", "values = [0.0, 4.0]"))
    changed = st.load_study(path)
    before = sorted(p.name for p in (out / "trials").iterdir())
    with pytest.raises(
        InputError, match=r"out: holds 2 trial\(s\) of another study, not of 'small'.*--force"
    ):
        sw.run_study(changed, out)
    assert sorted(p.name for p in (out / "trials").iterdir()) == before  # nothing touched
    assert sw.run_study(changed, out, force=True).num_rows == 4
    assert st.study_fingerprint(changed) != st.study_fingerprint(original)


def test_a_cell_that_cannot_run_is_found_before_any_trial(tmp_path):
    """A rate above the model's physics rate in the second cell: refused, naming the cell and its
    value, before the first cell's trials run."""
    path = tmp_path / "rate.toml"
    path.write_text(
        STUDY.format(duration=1.0, values="[0.0]")
        .replace("sensors.tracker.position_noise_m", "rate_hz")
        .replace('unit = "mm"', 'unit = "hz"')
        .replace("values = [0.0]", "values = [120.0, 5000.0]")
    )
    out = tmp_path / "out"
    with pytest.raises(InputError, match=r"cell 1 \(rate_hz = 5000\).*physics rate"):
        sw.run_study(st.load_study(path), out)
    assert not (out / "trials").exists() or not list((out / "trials").iterdir())


def _children(pid: int) -> set[int]:
    found = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            found |= {int(x) for x in (task / "children").read_text().split()}
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has died


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_workers_die_with_a_killed_parent(tmp_path):
    """SIGKILL of the study's own process only (not its group): its pool workers die too."""
    path = study_file(tmp_path, duration=20.0, values="[0.0, 2.0, 4.0, 8.0]")
    cmd = sweep_command(path, tmp_path / "out", workers=2)
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    workers: set[int] = set()
    while time.time() < deadline and len(workers) < 2:
        workers = _children(proc.pid)
        time.sleep(0.1)
    assert len(workers) >= 2, workers
    proc.kill()
    proc.wait()
    deadline = time.time() + 20
    while time.time() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers)


def test_any_joint_centre_method_is_an_estimator(tmp_path):
    """``joint:<method>`` scores a method of :mod:`calibration.methods` on the true hierarchy, as
    the calibration's O'Brien fit is scored: O'Brien's fit joint by joint gives the calibration's
    error; with 8 mm of tracker noise the geometric sphere fit is off by more than it."""
    path = study_file(tmp_path, duration=10.0)
    estimators = 'estimators = ["calibration", "joint:obrien", "joint:sphere-geometric"]'
    path.write_text(path.read_text().replace('estimators = ["calibration"]', estimators))
    study = st.load_study(path)
    noise = "sensors.tracker.position_noise_m"
    for trial in st.trials(study)[:: study.seeds_per_cell]:
        row = sw.run_trial(study, trial)
        for method in ("obrien", "sphere-geometric"):
            assert row[f"failed_joints:{method}"] == 0
            assert np.isfinite(row[f"limb_length_error_m:{method}"])
        assert row["joint_centre_error_m:obrien"] == pytest.approx(row["joint_centre_error_m"], rel=1e-6)
        assert row["limb_length_error_m:obrien"] == pytest.approx(row["limb_length_error_m"], rel=1e-6)
        if dict(trial.params)[noise] > 0:
            assert row["joint_centre_error_m:sphere-geometric"] > row["joint_centre_error_m:obrien"]


def test_study_plots_show_proportions_in_0_1_and_panels_in_a_grid(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import matplotlib.image as mpimg

    from simbench.experiments.study import METRICS

    path = study_file(tmp_path)
    asked = sorted(set(METRICS) - {"orientation_rmse_deg"})  # 7 metrics: two rows of panels
    path.write_text(
        path.read_text().replace(
            'metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]',
            f"metrics = {json.dumps(asked)}",
        )
    )
    study = st.load_study(path)
    every = st.trials(study)
    table = pa.Table.from_pylist(
        [
            {"trial": t.trial_id, "cell": t.cell, "replicate": t.replicate, "seed": t.seed}
            | dict(t.params)
            | {m: 0.01 for m in asked}
            | {"hierarchy_correct": float(t.replicate == 0)}  # one of two right in every cell
            for t in every
        ]
    )
    assert study_report.metric_columns(study, table.to_pydict()) == [
        m for m in table.column_names if m in asked
    ]
    (plot,) = study_report.plot_study(study, table, tmp_path)
    height, width = mpimg.imread(plot).shape[:2]
    assert width <= 2000 and height >= 2 * 250  # 4 panels a row (1440 px), 2 rows
    # a 0/1 metric: the share right, with Wilson's interval, never outside [0, 1]
    x = np.array([0.0, 0.0, 1.0, 1.0])
    _, mean, lo, hi = study_report._confidence_band(x, np.array([0.0, 0.0, 1.0, 1.0]), binary=True)
    assert list(mean) == [0.0, 1.0] and (lo >= 0).all() and (hi <= 1).all()
    assert lo[0] == 0.0 and hi[0] == pytest.approx(0.6576, abs=1e-4)  # Wilson, 0 of 2
    assert lo[1] == pytest.approx(0.3424, abs=1e-4) and hi[1] == 1.0
    # words and units on the axes, never a column's name
    assert study_report.metric_display("hierarchy_correct") == ("hierarchy correct (proportion)", 1.0, True)
    assert study_report.metric_display("joint_centre_error_m:score") == (
        "joint-centre error, score (mm)",
        1000.0,
        False,
    )
    assert study_report.metric_display("run_time_s") == ("run time (s)", 1.0, False)
    assert study_report.parameter_display(study.parameters[0]) == (
        "position noise (mm)",
        pytest.approx(1000.0),
    )
    # a band of a quantity that cannot be negative stops at zero (two seeds: a wide band)
    errors = np.array([0.1, 3.0, 0.2, 0.25])
    _, mean, lo, _ = study_report._confidence_band(x, errors, non_negative=True)
    assert (lo >= 0).all() and lo[0] == 0.0 and mean[0] == pytest.approx(1.55)
    assert study_report._confidence_band(x, errors)[2][0] < 0  # the plain normal band would dip
    assert study_report.non_negative("joint_centre_error_m:score") and not study_report.non_negative("bias_m")


def test_figures_of_many_panels_wrap_into_rows(tmp_path):
    """The dm_control humanoid has 28 joints: their residual histograms were one row of 28 panels
    (8960 x 280 px); now 7 rows of at most 4."""
    from types import SimpleNamespace

    import matplotlib.image as mpimg

    from simbench.report.plots import PANELS_PER_ROW, plot_pictures, plot_residual_histograms

    rng = np.random.default_rng(0)
    joints = [
        SimpleNamespace(name=f"joint {k}", fit=SimpleNamespace(frame_residual=rng.normal(size=200)))
        for k in range(28)
    ]
    plot_residual_histograms(joints, tmp_path / "hist.png", scale=1.0)
    height, width = mpimg.imread(tmp_path / "hist.png").shape[:2]
    assert PANELS_PER_ROW == 4 and width <= 2000 and height >= 7 * 250
    plot_pictures([np.zeros((40, 60, 3), np.uint8)] * 5, [f"p{k}" for k in range(5)], tmp_path / "pic.png")
    height, width = mpimg.imread(tmp_path / "pic.png").shape[:2]
    assert width <= 2000 and height >= 2 * 350  # 5 pictures: 4 and 1
    with pytest.raises(ValueError, match="2 pictures, 1 titles"):
        plot_pictures([np.zeros((4, 4, 3), np.uint8)] * 2, ["one"], tmp_path / "bad.png")


def test_a_study_names_a_parameter_once_and_fingerprints_the_files_it_names(tmp_path):
    path = study_file(tmp_path, values="[0.0]")
    text = path.read_text()
    twice = text + '[[parameter]]\nname = "sensors.tracker.position_noise_m"\nunit = "mm"\nvalues = [1.0]\n'
    path.write_text(twice)
    with pytest.raises(
        InputError, match=r"parameter\(s\) \['sensors.tracker.position_noise_m'\] declared more"
    ):
        st.load_study(path)
    # the base's sensors from a TOML file: editing the file changes the study
    sensors = tmp_path / "mysensors.toml"
    sensors.write_text("[tracker]\nposition_noise_m = 0.001\n")
    path.write_text(text.replace('sensors = "ascension-flock"', f'sensors = "{sensors}"'))
    before = st.study_fingerprint(st.load_study(path))
    assert st.study_fingerprint(st.load_study(path)) == before
    sensors.write_text("[tracker]\nposition_noise_m = 0.002\n")
    assert st.study_fingerprint(st.load_study(path)) != before


def test_a_trial_that_fails_is_a_row_named_with_its_values_and_the_study_goes_on(tmp_path, capsys):
    """A tracker that drops 99.5 % of its poses: no pair to fit. That trial is a row without
    metrics, its error naming the trial, cell and value; the other cell's trials run; the summary
    counts it. A study where every trial fails still finishes, with no plot."""
    path = parameter_study(tmp_path, "sensors.tracker.dropout_rate", "1", "[0.0, 0.995]", seeds=1)
    table = sw.run_study(st.load_study(path), tmp_path / "out")
    data = rows(table)
    assert [r["trial"] for r in data] == ["c00000-r000", "c00001-r000"]
    assert data[0].get("error") is None and data[0]["joint_centre_error_m"] is not None
    assert data[1]["error"].startswith("trial c00001-r000 (cell 1: sensors.tracker.dropout_rate = 0.995): ")
    assert data[1]["joint_centre_error_m"] is None
    assert main(["sweep", str(path), "--out", str(tmp_path / "cli"), "--no-progress"]) == 0
    assert "2 of 2 trials" in capsys.readouterr().out
    summary = (tmp_path / "cli" / "summary.md").read_text()
    assert "1 of 2 trials gave no metrics" in summary and "c00001-r000" in summary
    only = parameter_study(tmp_path, "sensors.tracker.dropout_rate", "1", "[0.995]", seeds=1)
    assert main(["sweep", str(only), "--out", str(tmp_path / "all"), "--no-progress"]) == 0
    assert "1 of 1 trials gave no metrics" in (tmp_path / "all" / "summary.md").read_text()


def test_compound_and_degree_fields_take_their_own_units(tmp_path):
    """A stiffness in N/m is a plain number (a length unit for it was accepted and divided it by
    1000); an inclination held in degrees takes deg (or rad, converted to degrees)."""
    path = tmp_path / "s.toml"
    base = STUDY.format(duration=1.0, values="[0.0]")
    for name, unit, values, expect in (
        ("sensors.skin.mount_stiffness_n_per_m", None, "[2000.0]", (2000.0,)),
        ("sensors.magnetic.inclination_deg", "deg", "[60.0]", (60.0,)),
        ("sensors.magnetic.inclination_deg", "rad", "[1.0]", (np.rad2deg(1.0),)),
    ):
        text = base.replace("sensors.tracker.position_noise_m", name).replace(
            "values = [0.0]", f"values = {values}"
        )
        text = text.replace('unit = "mm"\n', "" if unit is None else f'unit = "{unit}"\n')
        path.write_text(text)
        (param,) = st.load_study(path).parameters
        assert param.values == pytest.approx(expect), name
        _label, factor = study_report.parameter_display(param)
        assert param.values[0] * factor == pytest.approx(float(values.strip("[]")))  # shown as given
    path.write_text(base.replace("sensors.tracker.position_noise_m", "sensors.skin.mount_stiffness_n_per_m"))
    with pytest.raises(InputError, match=r"unit 'mm' does not fit: the field is in 1"):
        st.load_study(path)


def test_only_the_study_s_trial_files_count_and_a_broken_one_is_named(tmp_path):
    path = study_file(tmp_path, duration=1.0, values="[0.0]")
    out = tmp_path / "out"
    study = st.load_study(path)
    assert sw.run_study(study, out).num_rows == 2
    stray = out / "trials" / "notes.parquet"
    stray.write_bytes((out / "trials" / "c00000-r000.parquet").read_bytes())  # a copy under another name
    assert sw.run_study(study, out).num_rows == 2  # not counted, not gathered
    (out / "trials" / "c00000-r001.parquet").write_bytes(b"PAR1 cut short")
    with pytest.raises(InputError, match=r"c00000-r001.parquet: not a readable trial file .* delete it"):
        sw.run_study(study, out)


def test_a_sensor_file_beside_the_study_is_found_from_anywhere(tmp_path, monkeypatch):
    folder = tmp_path / "study"
    folder.mkdir()
    (folder / "mysensors.toml").write_text("[tracker]\ndropout_rate = 0.01\n")
    path = study_file(folder, values="[0.0]")
    path.write_text(path.read_text().replace('sensors = "ascension-flock"', 'sensors = "mysensors.toml"'))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # the working directory holds no mysensors.toml
    study = st.load_study(path)
    config = st.trial_config(study, st.trials(study)[0])
    assert config.sensors.tracker.dropout_rate == 0.01  # the file beside the study was read


def test_a_metric_with_no_value_in_a_cell_is_nan_without_a_warning():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(study_report.mean_of_known(np.array([np.nan, np.nan])))
        assert study_report.mean_of_known(np.array([1.0, np.nan, 3.0])) == 2.0
        assert np.isnan(study_report.mean_of_known(np.array([])))


def test_a_users_estimator_in_a_study_fails_alone_and_its_file_is_fingerprinted(tmp_path):
    """A user's estimator file beside the study: found there, its failure is its own error column
    (the built-in beside it still scores the trial), and editing its code changes the study."""
    fit = tmp_path / "fit.py"
    fit.write_text("def estimate(poses, *, hierarchy=None):\n    raise RuntimeError('not yet')\n")
    path = parameter_study(tmp_path, "duration_s", "s", "[1.0]", seeds=1)
    path.write_text(
        path.read_text().replace(
            'estimators = ["calibration"]', 'estimators = ["joint:fit.py:estimate", "joint:score"]'
        )
    )
    study = st.load_study(path)
    spec = f"{tmp_path / 'fit.py'}:estimate"
    assert study.estimators == (f"joint:{spec}", "joint:score")
    (row,) = rows(sw.run_study(study, tmp_path / "out", workers=1))
    assert row[f"error:{spec}"] == f"estimator '{spec}' raised RuntimeError: not yet"
    assert 0 < row["joint_centre_error_m:score"] < 0.05 and row.get("error") is None
    before = st.study_fingerprint(study)
    fit.write_text("def estimate(poses, *, hierarchy=None):\n    raise RuntimeError('still not')\n")
    assert st.study_fingerprint(st.load_study(path)) != before


def test_a_users_estimator_that_hangs_is_stopped_at_the_time_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(sw, "TIME_LIMIT_S", 1.0)  # the workers are forked: they see it
    (tmp_path / "slow.py").write_text(
        "import time\n\ndef estimate(poses, *, hierarchy=None):\n    time.sleep(60)\n"
    )
    path = parameter_study(tmp_path, "duration_s", "s", "[1.0]", seeds=1)
    path.write_text(
        path.read_text().replace('estimators = ["calibration"]', 'estimators = ["joint:slow.py:estimate"]')
    )
    (row,) = rows(sw.run_study(st.load_study(path), tmp_path / "out", workers=1))
    spec = f"{tmp_path / 'slow.py'}:estimate"
    assert row[f"error:{spec}"] == f"estimator '{spec}' did not return within its time limit of 1 s; stopped"


class _TamperingExecutor(Executor):
    """Runs each trial here and then alters the row it sends back, as a compromised worker could."""

    def __init__(self, tamper):
        self.tamper = tamper

    def submit(self, fn, *args, **kwargs):
        fut = Future()
        fut.set_result(self.tamper(fn(*args, **kwargs)))
        return fut


@pytest.mark.parametrize(
    ("tamper", "said"),
    [
        (lambda row: {**row, "trial": "../../escaped"}, "trial '../../escaped'"),
        (lambda row: {**row, "cell": row["cell"] + 1}, "cell"),
        (lambda row: {**row, "payload": object()}, "column 'payload' = a object"),
        (lambda row: [row], "a list, not a row"),
    ],
    ids=["path-in-id", "other-cell", "object-value", "not-a-row"],
)
def test_a_row_a_worker_alters_is_refused_and_never_names_a_file(tmp_path, tamper, said):
    pytest.importorskip("pyarrow")
    study = st.load_study(study_file(tmp_path, duration=1.0))
    out = tmp_path / "deep" / "er" / "out"
    out.parent.mkdir(parents=True)
    with pytest.raises(InputError, match=re.escape(said)):
        sw.run_study(study, out, executor=_TamperingExecutor(tamper))
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["study.json", "study.toml"]


def test_a_plain_scheduler_off_this_machine_is_refused_before_any_work(tmp_path, capsys):
    path = study_file(tmp_path)
    out = tmp_path / "out"
    assert (
        main(["sweep", str(path), "--out", str(out), "--scheduler", "tcp://10.1.2.3:8786", "--no-progress"])
        == 2
    )
    err = capsys.readouterr().err
    assert "a plain tcp:// connection off this machine" in err and "--tls-ca-file" in err
    assert not out.exists()
    for address in ("tcp://127.0.0.1:8786", "tcp://localhost:8786", "127.0.0.1:8786", "tcp://[::1]:8786"):
        sw.check_scheduler(address)  # this machine: allowed
    sw.check_scheduler("tls://10.1.2.3:8786")
    sw.check_scheduler("tcp://10.1.2.3:8786", insecure=True)
    with pytest.raises(InputError, match="off this machine"):
        sw.check_scheduler("10.1.2.3:8786")


def test_dask_tls_settings_are_checked_and_require_encryption(tmp_path):
    distributed = pytest.importorskip("distributed")
    files = {}
    for name in ("ca", "cert", "key"):
        files[name] = tmp_path / f"{name}.pem"
        files[name].write_text("-----BEGIN CERTIFICATE-----\n")
    assert sw.dask_security(None, None, None) is None
    with pytest.raises(InputError, match="--tls-key missing"):
        sw.dask_security(str(files["ca"]), str(files["cert"]), None)
    with pytest.raises(InputError, match=r"--tls-cert .*nowhere.pem: no such file"):
        sw.dask_security(str(files["ca"]), str(tmp_path / "nowhere.pem"), str(files["key"]))
    security = sw.dask_security(str(files["ca"]), str(files["cert"]), str(files["key"]))
    assert isinstance(security, distributed.Security) and security.require_encryption
    assert security.tls_ca_file == str(files["ca"]) and security.tls_client_key == str(files["key"])
    sw.check_scheduler("tcp://10.1.2.3:8786", security)  # TLS settings given: Dask enforces them
