"""The light start (issue 44): ``simbench --help`` and ``import calibration`` load no numerical
library; a command's module, and the library it runs, are loaded when the command is named; and
the library loads matplotlib only when a report draws.

Each case runs in a fresh interpreter (this process has loaded everything already) and lists what
it imported; the times themselves are measured in ``benchmarks/bench_startup.py``, not here.
"""

from __future__ import annotations

import importlib
import json
import subprocess
import sys
import types

import pytest

#: Heavy libraries that a light start must not import.
HEAVY = ("numpy", "scipy", "matplotlib", "mujoco", "h5py", "dm_control", "tqdm")


def loaded(code: str) -> set[str]:
    """The modules a fresh interpreter has imported after running ``code``."""
    probe = (
        "import contextlib, io, json, sys\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        f"    {code}\n"
        "print(json.dumps(sorted(sys.modules)))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(json.loads(done.stdout))


def ours(modules: set[str]) -> set[str]:
    return {m for m in modules if m.split(".")[0] in ("simbench", "calibration")}


def heavy(modules: set[str]) -> set[str]:
    return {m for m in modules if m.split(".")[0] in HEAVY}


def test_simbench_help_loads_the_command_table_alone():
    got = loaded("from simbench.cli import main\n    try: main(['--help'])\n    except SystemExit: pass")
    assert heavy(got) == set()
    assert ours(got) <= {
        "simbench",
        "simbench.versions",
        "simbench.errors",
        "simbench.cli",
        "simbench.cli.help_examples",
        "calibration",
        "calibration.errors",
    }


@pytest.mark.parametrize("command", ["scale", "examples"])
def test_a_command_loads_its_own_module_not_the_others(command):
    from simbench.cli import COMMANDS

    got = loaded(
        f"from simbench.cli import main\n    try: main([{command!r}, '--help'])\n    except SystemExit: pass"
    )
    commands = {module for module, _ in COMMANDS.values()}
    assert commands & got == {COMMANDS[command][0]}


def test_calibrate_help_loads_no_numerical_library():
    """``simbench calibrate --help`` lists the estimators, defaults and choices from light modules
    (the estimator catalog, the core's defaults), not from the registry's code; the command's run
    (``simbench.cli.calibrate_run``) is loaded when it runs."""
    got = loaded(
        "from simbench.cli import main\n    try: main(['calibrate', '--help'])\n    except SystemExit: pass"
    )
    assert heavy(got) == set()
    assert "simbench.estimators.catalog" in got and "simbench.cli.calibrate_run" not in got


def test_the_library_loads_no_plotting_until_a_report_draws():
    """``simbench.api`` (every command's door) leaves matplotlib to the reports' figures."""
    got = loaded("import simbench.api")
    assert "simbench.report.twin" in got and not any(m.split(".")[0] == "matplotlib" for m in got)


def test_import_calibration_loads_nothing_until_a_name_is_asked_for():
    got = loaded("import calibration")
    assert heavy(got) == set() and ours(got) == {"calibration"}
    got = loaded("from calibration import SINGLE_AXIS_RATIO")
    assert "calibration.joint" in got and "calibration.slip" not in got


def test_calibration_gives_its_public_names_and_only_them():
    import calibration
    from calibration.pipeline import calibrate

    assert calibration.calibrate is calibrate
    assert dir(calibration) == sorted(calibration.__all__)
    with pytest.raises(AttributeError, match="module 'calibration' has no attribute 'nothing'"):
        _ = calibration.nothing


@pytest.mark.parametrize("package", ["simbench", "calibration"])
def test_no_stray_names_in_the_packages_namespace(package):
    """A public name of the package is in its ``__all__`` or is one of its own submodules (the
    modules the lazy loaders use are kept under private names)."""
    module = importlib.import_module(package)
    stray = [
        name
        for name, value in vars(module).items()
        if name.isidentifier()  # pytest's assertion rewriting adds '@py_builtins' to a plugin's package
        and not name.startswith("_")
        and name not in module.__all__
        and not (isinstance(value, types.ModuleType) and value.__name__ == f"{package}.{name}")
    ]
    assert stray == []
