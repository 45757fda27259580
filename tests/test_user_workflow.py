"""A user's estimators, outside the repository, through every way in: the two examples of
``examples/estimators`` copied into a temporary folder and run from there with the installed
package (not the checkout's folder) through ``calibrate --method``, a study, ``bench --quick``,
``baseline --scenarios`` and the pytest plugin."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "estimators"
SPHERE = "sphere_fit.py:estimate"
COMMAND = "cmd:python3 pair_fit_cmd.py {poses} {hierarchy} {out}"


def _run(
    folder: Path, *args: str, timeout: float = 300, path: Path | None = None
) -> subprocess.CompletedProcess:
    """``python ARGS`` in ``folder``, with this environment's python3 first on PATH and no
    PYTHONPATH but ``path`` when given (a folder laid out as pip installs a package)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTEST_ADDOPTS")}
    if path is not None:
        env["PYTHONPATH"] = str(path)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # python3: this venv's
    return subprocess.run(
        [sys.executable, *args], cwd=folder, env=env, capture_output=True, text=True, timeout=timeout
    )


def _calibrate(folder: Path, spec: str, out: str, path: Path | None = None) -> subprocess.CompletedProcess:
    """``simbench calibrate poses.csv --hierarchy tree.json --method SPEC --json OUT`` in ``folder``."""
    args = ("-m", "simbench", "calibrate", "poses.csv", "--hierarchy", "tree.json", "--method", spec)
    return _run(folder, *args, "--json", out, path=path)


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    """A user's folder: the two estimators, a simulated recording and its true tree."""
    folder = tmp_path_factory.mktemp("mylab")
    for name in ("sphere_fit.py", "pair_fit_cmd.py"):
        shutil.copy(EXAMPLES / name, folder / name)
    made = _run(
        folder,
        "-m",
        "simbench",
        "simulate",
        "--model",
        "linkage",
        "--sensors",
        "polhemus-liberty",
        "--duration",
        "6",
        "--seed",
        "2",
        "--csv",
        "poses.csv",
        "--truth-json",
        "truth.json",
        "-o",
        "ds.h5",
    )
    assert made.returncode == 0, made.stderr
    truth = json.loads((folder / "truth.json").read_text())
    (folder / "tree.json").write_text(json.dumps({j["child"]: j["parent"] for j in truth["joints"]}))
    return folder


def test_the_package_is_not_imported_from_the_checkout_folder(lab):
    where = _run(lab, "-c", "import simbench, os; print(os.getcwd())")
    assert where.returncode == 0 and Path(where.stdout.strip()) == lab


@pytest.mark.parametrize("spec", [SPHERE, COMMAND])
def test_calibrate_method(lab, spec):
    out = f"cal_{'cmd' if spec == COMMAND else 'py'}.json"
    run = _calibrate(lab, spec, out)
    assert run.returncode == 0, run.stderr
    doc = json.loads((lab / out).read_text())
    truth = json.loads((lab / "truth.json").read_text())
    assert {j["child"] for j in doc["joints"]} == {j["child"] for j in truth["joints"]}
    scored = _run(
        lab, "-c", f"import simbench as sb; print(sb.score({out!r}, sb.read('ds.h5')).mean_centre_error_m)"
    )
    assert scored.returncode == 0, scored.stderr
    assert 0 < float(scored.stdout) < 0.1  # metres: a sphere fit and a pair fit of a noisy tracker
    # a method that fits a given tree, given none: refused, saying how to give one
    bad = _run(lab, "-m", "simbench", "calibrate", "poses.csv", "--method", spec)
    assert bad.returncode == 2 and "give one (--hierarchy FILE.json)" in bad.stderr


def test_a_study(lab):
    (lab / "study.toml").write_text(
        f"""name = "mine"
seed = 1
seeds_per_cell = 1
estimators = ["joint:{SPHERE}", "joint:{COMMAND}", "joint:obrien"]
metrics = ["joint_centre_error_m"]
[base]
model = "linkage"
sensors = "polhemus-liberty"
duration_s = 3.0
rate_hz = 60.0
[[parameter]]
name = "sensors.tracker.position_noise_m"
unit = "mm"
values = [0.0, 2.0]
"""
    )
    run = _run(
        lab, "-m", "simbench", "sweep", "study.toml", "--out", "study", "--workers", "1", "--no-progress"
    )
    assert run.returncode == 0, run.stderr
    import pyarrow.parquet as pq

    table = pq.read_table(lab / "study" / "results.parquet").to_pydict()
    for spec in (SPHERE, COMMAND, "obrien"):
        column = next(k for k in table if k.startswith("joint_centre_error_m:") and k.endswith(spec))
        assert all(0 <= v < 0.2 for v in table[column]), (column, table[column])


def test_bench_quick(lab):
    run = _run(
        lab,
        "-m",
        "simbench",
        "bench",
        "--kind",
        "joints",
        "--quick",
        "--estimator",
        SPHERE,
        "--estimator",
        COMMAND,
        "--out",
        "bench",
        "--workers",
        "2",
    )
    assert run.returncode == 0, run.stderr
    card = json.loads((lab / "bench" / "scorecard.json").read_text())
    scored = {r["estimator"] for r in card["rows"] if r["failures"] < r["n"] + r["failures"]}
    assert {SPHERE, COMMAND, "obrien"} <= scored


def test_baseline_scenarios(lab):
    (lab / "scenarios.toml").write_text(
        f"""[[scenario]]
name = "linkage-sphere"
estimator = "joint:{SPHERE}"
model = "linkage"
sensors = "polhemus-liberty"
duration_s = 4.0
seed = 1

[[scenario]]
name = "linkage-command"
estimator = "joint:{COMMAND}"
model = "linkage"
sensors = "polhemus-liberty"
duration_s = 4.0
seed = 1
"""
    )
    assert (
        _run(lab, "-m", "simbench", "baseline", "--scenarios", "scenarios.toml", "--update").returncode == 0
    )
    accepted = json.loads((lab / "scenarios.baseline.json").read_text())["scenarios"]
    assert set(accepted) == {"linkage-sphere", "linkage-command"}
    check = _run(lab, "-m", "simbench", "baseline", "--scenarios", "scenarios.toml")
    assert check.returncode == 0 and "no regression" in check.stdout, check.stderr
    # a worse accepted figure in the user's file: the check fails (exit 1) and names it
    accepted["linkage-sphere"]["centre_error_cm"] /= 2
    (lab / "scenarios.baseline.json").write_text(json.dumps({"scenarios": accepted}))
    worse = _run(lab, "-m", "simbench", "baseline", "--scenarios", "scenarios.toml")
    assert worse.returncode == 1 and "linkage-sphere.centre_error_cm" in worse.stderr


def test_the_pytest_plugin(lab):
    (lab / "test_mine.py").write_text(
        """from sphere_fit import estimate


def test_sphere_fit(simbench_scenario, simbench_score, simbench_regression):
    ds = simbench_scenario("linkage-paper", seed=1)
    figures = simbench_score(estimate, ds)
    cmd = simbench_score("cmd:python3 pair_fit_cmd.py {poses} {hierarchy} {out}", ds)
    for key, got in (("sphere", figures), ("cmd", cmd)):
        figure = {"joint_centre_error_m": got["joint_centre_error_m"]}
        simbench_regression.check(f"{key}/linkage-paper/1", figure)
"""
    )
    args = ("-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", "test_mine.py")
    first = _run(lab, *args)
    assert first.returncode == 1 and "--simbench-update" in first.stdout
    assert _run(lab, *args, "--simbench-update").returncode == 0
    assert "sphere/linkage-paper/1" in json.loads((lab / "simbench_regression.json").read_text())["figures"]
    again = _run(lab, *args)
    assert again.returncode == 0, again.stdout


def test_an_installed_plugin(lab, tmp_path):
    """examples/estimators/plugin as pip would install it: the module, and a dist-info whose
    entry_points.txt holds the pyproject's simbench.estimators table (importlib.metadata finds
    both on the path); then its name is a spec like a built-in's."""
    import tomllib

    plugin = EXAMPLES / "plugin"
    table = tomllib.loads((plugin / "pyproject.toml").read_text())["project"]
    site = tmp_path / "site"
    info = site / f"{table['name'].replace('-', '_')}-{table['version']}.dist-info"
    info.mkdir(parents=True)
    shutil.copy(plugin / "mylab_estimators.py", site)
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {table['name']}\nVersion: {table['version']}\n"
    )
    group = table["entry-points"]["simbench.estimators"]
    (info / "entry_points.txt").write_text(
        "[simbench.estimators]\n" + "".join(f"{k} = {v}\n" for k, v in group.items())
    )
    listed = _run(
        lab,
        "-c",
        f"import os, sys; sys.path.insert(0, {str(site)!r}); "
        "import simbench; print(simbench.estimators.names('joints'))",
    )
    assert "mylab-sphere" in listed.stdout, listed.stderr
    run = _calibrate(lab, "mylab-sphere", "plugin.json", path=site)
    assert run.returncode == 0, run.stderr
    mine = json.loads((lab / "plugin.json").read_text())
    assert mine["method"] == "mylab-sphere"
    # the plugin is the same sphere fit as the file example: the same centres
    ours = _calibrate(lab, SPHERE, "file.json")
    assert ours.returncode == 0
    theirs = json.loads((lab / "file.json").read_text())
    for a, b in zip(mine["joints"], theirs["joints"], strict=True):
        assert a["joint_in_parent"] == pytest.approx(b["joint_in_parent"], abs=1e-9)


def test_orient_method_on_a_real_recording(lab):
    """A user's orientation function in a file, on the BROAD excerpt the package ships: the
    command writes its orientations and scores them against the optical reference."""
    from simbench.experiments.suite import DATA_DIR

    (lab / "level.py").write_text(
        "import numpy as np\n\n\ndef estimate(imu):\n"
        "    return np.tile([1.0, 0.0, 0.0, 0.0], (imu.time_s.size, len(imu.names), 1))\n"
    )
    trial = DATA_DIR / "broad_02_undisturbed_slow_rotation_B_60s.hdf5"
    run = _run(
        lab, "-m", "simbench", "orient", str(trial), "--method", "level.py:estimate", "--csv", "level.csv"
    )
    assert run.returncode == 0, run.stderr
    assert "method: level.py:estimate" in run.stdout and "error against the reference" in run.stdout
    lines = (lab / "level.csv").read_text().splitlines()
    assert lines[0] == "time,sensor,qw,qx,qy,qz" and len(lines) == 1 + 17143
