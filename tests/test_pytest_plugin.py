"""The pytest plugin (simbench.pytest_plugin) in a user's test run, through pytester.

Each test writes a user's test file into a temporary folder and runs pytest on it in-process with
``-p simbench.pytest_plugin``; entry-point plugins are not loaded there
(``PYTEST_DISABLE_PLUGIN_AUTOLOAD``), so an installed simbench does not register it a second time.
"""

from __future__ import annotations

import json
import os
import re
import tomllib
from pathlib import Path

import pytest

from simbench.experiments.suite import SUITE_VERSION
from simbench.versions import __version__

pytest_plugins = ["pytester"]

ROOT = Path(__file__).resolve().parent.parent
KEY = "my-method/linkage-paper"


@pytest.fixture
def run(pytester, monkeypatch):
    """``run(*args)``: pytest on the temporary folder with the plugin."""
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")

    def run(*args: str) -> pytest.RunResult:
        return pytester.runpytest("-p", "simbench.pytest_plugin", "-p", "no:cacheprovider", *args)

    return run


def accepted(pytester, figures: dict[str, float], suite: str = SUITE_VERSION) -> Path:
    path = pytester.path / "simbench_regression.json"
    entry = {"suite_version": suite, "simbench_version": __version__, "figures": figures}
    path.write_text(json.dumps({"format": 1, "figures": {KEY: entry}}), encoding="utf-8")
    return path


def check_test(figures: str, **kwargs: str) -> str:
    args = "".join(f", {k}={v}" for k, v in kwargs.items())
    return f"def test_check(simbench_regression):\n    simbench_regression.check({KEY!r}, {figures}{args})\n"


def test_entry_point_names_the_plugin():
    doc = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert doc["project"]["entry-points"]["pytest11"] == {"simbench": "simbench.pytest_plugin"}


def test_installed_entry_point_loads_it_once(pytester, monkeypatch):
    """An installed simbench (here a distribution's metadata with the entry point of
    pyproject.toml) loads the plugin with no -p: a subprocess, for a fresh entry-point scan."""
    doc = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    ((name, value),) = doc["project"]["entry-points"]["pytest11"].items()
    meta = pytester.path / "site" / "simbench_probe-0.1.dist-info"
    meta.mkdir(parents=True)
    (meta / "METADATA").write_text("Metadata-Version: 2.1\nName: simbench-probe\nVersion: 0.1\n")
    (meta / "entry_points.txt").write_text(f"[pytest11]\n{name} = {value}\n")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(meta.parent), str(ROOT)]))
    monkeypatch.delenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    pytester.makepyfile(
        """
        import simbench.pytest_plugin as plugin

        def test_loaded(request, simbench_scenarios):
            names = [n for n, p in request.config.pluginmanager.list_name_plugin() if p is plugin]
            assert names == ["simbench"] and "linkage-paper" in simbench_scenarios
        """
    )
    pytester.runpytest_subprocess("-p", "no:cacheprovider").assert_outcomes(passed=1)


def test_scenario_fixture_gives_truth_once_per_session(pytester, run):
    pytester.makepyfile(
        """
        import pytest
        import simbench.pytest_plugin as plugin
        from simbench.errors import InputError

        SEEN = []

        def test_first(request, simbench_scenario, simbench_scenarios):
            registered = [n for n, p in request.config.pluginmanager.list_name_plugin() if p is plugin]
            assert registered == ["simbench.pytest_plugin"]
            assert simbench_scenarios[:2] == ["linkage-paper", "linkage-single-axis"]
            ds = simbench_scenario("linkage-paper", seed=1)
            assert ds.truth is not None and len(ds.truth.parent_of) == 5
            assert simbench_scenario("linkage-paper", 1) is ds
            SEEN.append(ds)

        def test_second_shares_it(simbench_scenario, simbench_score):
            assert simbench_scenario("linkage-paper", seed=1) is SEEN[0]
            assert list(simbench_scenario.datasets) == [("linkage-paper", 1)]

            def mine(poses, *, hierarchy=None):
                from simbench.estimators import resolve, run_joints
                return run_joints(resolve("obrien"), poses, hierarchy=hierarchy)

            by_spec = simbench_score("obrien", "linkage-paper")
            assert simbench_score(mine, SEEN[0]) == by_spec
            assert list(simbench_scenario.datasets) == [("linkage-paper", 1)]
            assert 0 < by_spec["joint_centre_error_m"] < 0.02 and by_spec["failed_joints"] == 0

        def test_unknown_scenario(simbench_scenario):
            with pytest.raises(InputError, match="no scenario 'nope'"):
                simbench_scenario("nope")
        """
    )
    run().assert_outcomes(passed=3)


def test_check_passes_within_tolerance_and_fails_worse(pytester, run):
    accepted(pytester, {"joint_centre_error_m": 0.005, "limb_length_error_m": 0.002})
    pytester.makepyfile(
        f"""
        KEY = {KEY!r}

        def test_within(simbench_regression):
            simbench_regression.check(KEY, {{"joint_centre_error_m": 0.0054}}, rel_tol=0.1)

        def test_within_abs_tol(simbench_regression):
            simbench_regression.check(KEY, {{"limb_length_error_m": 0.0029}}, rel_tol=0.0, abs_tol=0.001)

        def test_worse(simbench_regression):
            figures = {{"joint_centre_error_m": 0.0061, "limb_length_error_m": 0.001}}
            simbench_regression.check(KEY, figures, rel_tol=0.1)
        """
    )
    result = run()
    result.assert_outcomes(passed=2, failed=1)
    out = result.stdout.str()
    assert "joint_centre_error_m: 0.0061 is worse than the accepted 0.005 (limit 0.0055: rel_tol 0.1" in out
    assert "limb_length_error_m: 0.001" not in out  # better than accepted: not named
    assert "--simbench-update" in out


def test_update_writes_the_file_and_a_rerun_passes(pytester, run):
    path = accepted(pytester, {"total_rmse_deg": 1.5})
    doc = json.loads(path.read_text(encoding="utf-8"))
    doc["figures"] = {"zz-other": doc["figures"][KEY]}
    path.write_text(json.dumps(doc), encoding="utf-8")
    pytester.makepyfile(check_test('{"limb_length_error_m": 0.002, "joint_centre_error_m": 0.0053}'))
    result = run("--simbench-update")
    result.assert_outcomes(passed=1)
    assert "simbench regression figures accepted" in result.stdout.str()
    text = path.read_text(encoding="utf-8")
    written = json.loads(text)
    assert list(written["figures"]) == [KEY, "zz-other"]  # merged, sorted
    assert written["figures"]["zz-other"]["figures"] == {"total_rmse_deg": 1.5}
    assert written["figures"][KEY] == {
        "figures": {"joint_centre_error_m": 0.0053, "limb_length_error_m": 0.002},
        "simbench_version": __version__,
        "suite_version": SUITE_VERSION,
    }
    assert text == json.dumps(written, indent=2, sort_keys=True) + "\n"
    run().assert_outcomes(passed=1)


def test_missing_key_fails_saying_to_update(pytester, run):
    pytester.makepyfile(check_test('{"joint_centre_error_m": 0.0053}'))
    result = run()
    result.assert_outcomes(failed=1)
    result.stdout.re_match_lines(
        [
            r".*no accepted figures in .*simbench_regression.json; run pytest with "
            r"--simbench-update.*"
        ]
    )
    accepted(pytester, {"limb_length_error_m": 0.002})  # the key, but not this figure
    result = run()
    result.assert_outcomes(failed=1)
    assert "joint_centre_error_m: 0.0053 has no accepted figure yet (run pytest with --simbench-update)" in (
        result.stdout.str()
    )


def test_suite_version_mismatch_fails_until_updated(pytester, run):
    path = accepted(pytester, {"joint_centre_error_m": 0.0053}, suite="0")
    pytester.makepyfile(check_test('{"joint_centre_error_m": 0.0053}'))
    result = run()
    result.assert_outcomes(failed=1)
    out = result.stdout.str()
    assert "accepted with suite version '0'" in out and f"this is suite version {SUITE_VERSION!r}" in out
    assert "not comparable" in out
    run("--simbench-update").assert_outcomes(passed=1)
    assert json.loads(path.read_text(encoding="utf-8"))["figures"][KEY]["suite_version"] == SUITE_VERSION
    run().assert_outcomes(passed=1)


def test_non_finite_figures_fail_even_when_updating(pytester, run):
    pytester.makepyfile(check_test('{"joint_centre_error_m": float("nan"), "residual_m": 0.001}'))
    for args in ((), ("--simbench-update",)):
        result = run(*args)
        result.assert_outcomes(failed=1)
        assert "figures must be finite numbers" in result.stdout.str()
        assert "joint_centre_error_m: nan" in result.stdout.str()
    assert not (pytester.path / "simbench_regression.json").exists()


def test_ini_option_and_path_argument_name_the_file(pytester, run):
    pytester.makeini("[pytest]\nsimbench_regression_file = figures/regression.json\n")
    (pytester.path / "figures").mkdir()
    pytester.makepyfile(
        f"""
        def test_ini(simbench_regression):
            simbench_regression.check({KEY!r}, {{"a": 1.0}})

        def test_path(simbench_regression):
            simbench_regression.check({KEY!r}, {{"b": 2.0}}, path="own.json")
        """
    )
    run("--simbench-update").assert_outcomes(passed=2)
    ini = json.loads((pytester.path / "figures" / "regression.json").read_text(encoding="utf-8"))
    own = json.loads((pytester.path / "own.json").read_text(encoding="utf-8"))
    assert ini["figures"][KEY]["figures"] == {"a": 1.0}
    assert own["figures"][KEY]["figures"] == {"b": 2.0}
    run().assert_outcomes(passed=2)


def docs_files() -> dict[str, str]:
    """The python blocks of docs/pytest-plugin.md, by the file name each names on its first line."""
    text = (ROOT / "docs" / "pytest-plugin.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)
    files = {}
    for block in blocks:
        first = block.splitlines()[0]
        assert first.startswith("# ") and first.endswith(".py"), first
        files[first[2:]] = block
    return files


def test_docs_example_runs_verbatim(pytester, run):
    files = docs_files()
    assert sorted(files) == ["my_joints.py", "test_my_joints.py"]
    for name, text in files.items():
        (pytester.path / name).write_text(text, encoding="utf-8")
    run().assert_outcomes(passed=1, failed=2)  # nothing accepted yet
    run("--simbench-update").assert_outcomes(passed=3)
    doc = json.loads((pytester.path / "simbench_regression.json").read_text(encoding="utf-8"))
    assert sorted(doc["figures"]) == [f"shifted-obrien/linkage-paper/{s}" for s in (1, 2)]
    run().assert_outcomes(passed=3)
    # the method regresses: its centres 8 mm off rather than 2 mm
    module = pytester.path / "my_joints.py"
    module.write_text(files["my_joints.py"].replace("shift_m=0.002", "shift_m=0.008"), encoding="utf-8")
    result = run()
    result.assert_outcomes(passed=1, failed=2)
    assert "joint_centre_error_m: 0.0" in result.stdout.str()
    assert "is worse than the accepted" in result.stdout.str()
