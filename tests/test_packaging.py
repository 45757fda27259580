"""The installable package: the wheel holds every built-in model and preset, and an installed
(non-editable) copy runs from another directory.

The wheel is built from a copy of the sources without build isolation (no network); the fast
test installs it with ``pip --target`` next to this environment's dependencies, the slow one
into a fresh virtual environment with its dependencies from the package index.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

import simbench
from simbench.io.examples import EXAMPLE_FILES
from tests.test_readme import flow_fences, readme_fences

ROOT = Path(simbench.__file__).resolve().parent.parent
SOURCES = ("pyproject.toml", "README.md", "simbench", "calibration")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(ROOT / name, src / name)
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", out, src],
        check=True,
        capture_output=True,
    )
    (path,) = out.glob("simbench-*.whl")
    return path


def test_wheel_holds_every_model_and_preset(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    package = ROOT / "simbench"
    shipped = [
        p.relative_to(ROOT).as_posix()
        for sub in ("models", "sim/presets", "data")
        for p in (package / sub).rglob("*")
        if p.is_file()
    ]
    # 2 models x (xml, scene, README) + README + 6 presets + the BROAD excerpts, README, licence
    assert len(shipped) >= 16
    assert sorted(set(shipped) - names) == []
    assert {"simbench/py.typed", "calibration/py.typed", "simbench/versions.py"} <= names
    assert not any(n.startswith(("tests/", "benchmarks/", "reports/")) for n in names)
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    text = zipfile.ZipFile(wheel).read(metadata).decode()
    assert f"Version: {simbench.__version__}" in text
    assert "Provides-Extra: studies" in text
    # the pytest plugin is found by its entry point once the wheel is installed
    entry_points = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "[pytest11]\nsimbench = simbench.pytest_plugin\n" in text
    assert "simbench/pytest_plugin.py" in names


def test_installed_wheel_runs_from_another_directory(wheel, tmp_path):
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", target, wheel],
        check=True,
        capture_output=True,
    )
    work = tmp_path / "elsewhere"
    work.mkdir()
    env = dict(os.environ, PYTHONPATH=str(target))
    where = subprocess.run(
        [
            sys.executable,
            "-c",
            "import simbench, calibration; print(simbench.__file__, calibration.__file__)",
        ],
        cwd=work,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    assert all(Path(p).is_relative_to(target) for p in where), where  # the installed copy, not the sources
    run = subprocess.run(
        [target / "bin" / "simbench", "simulate", "--model", "humanoid", "--duration", "1", "-o", "h.h5"],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert (work / "h.h5").is_file() and "sensors: 16" in run.stdout
    # the examples come out of the installed package, and the README's first calibration runs on them
    cli = target / "bin" / "simbench"
    run = subprocess.run([cli, "examples", "first"], cwd=work, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    for place in EXAMPLE_FILES.values():
        assert (work / "first" / place).read_bytes() == (ROOT / place).read_bytes(), place
    run = subprocess.run(
        [cli, "calibrate", "examples/linkage_exercise.csv", "--no-slip"],
        cwd=work / "first",
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0 and "hierarchy: inferred" in run.stdout, run.stderr


def test_newcomers_path_runs_from_the_installed_wheel(wheel, tmp_path):
    """The README's install lines, its quickstart and the first steps of docs/getting-started.md, as a
    newcomer runs them: the installed wheel's command and package (not the sources), in a folder of
    their own that ``simbench examples`` fills."""
    pytest.importorskip("pandas")
    pytest.importorskip("distributed")
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", target, wheel],
        check=True,
        capture_output=True,
    )
    env = dict(os.environ, PYTHONPATH=str(target))
    work = tmp_path / "newcomer"
    work.mkdir()
    # the README's install block and the docs' first steps lay out the same folder
    (install,) = [code for _, lang, code in readme_fences() if lang == "bash" and "simbench examples" in code]
    examples = "simbench examples first-steps && cd first-steps"
    assert examples in install and examples in flow_fences()[0].code
    steps = [(f.lang, f.code) for f in flow_fences()]
    steps.append(("python", next(code for _, lang, code in readme_fences() if lang == "python")))
    for lang, code in steps:
        if lang == "python":
            run = subprocess.run(
                [sys.executable, "-c", code], cwd=work, env=env, capture_output=True, text=True
            )
            assert run.returncode == 0, run.stderr
            continue
        for line in code.splitlines():
            line = line.split("  #", 1)[0].strip()
            if not line.startswith("simbench"):  # pip: the wheel is installed above
                continue
            for command in line.split(" && "):
                argv = command.split()
                if argv[0] == "cd":
                    work = work / argv[1]
                    continue
                run = subprocess.run(
                    [target / "bin" / "simbench", *argv[1:]],
                    cwd=work,
                    env=env,
                    capture_output=True,
                    text=True,
                )
                assert run.returncode == 0, (line, run.stderr)
    assert work.name == "first-steps"
    for name in ("first.h5", "first.trc", "first.c3d", "quickstart/summary.md", "first_report/index.html"):
        assert (work / name).stat().st_size > 0, name


@pytest.mark.slow
def test_fresh_venv_runs_quick_validation(wheel, tmp_path):
    """``pip install`` of the wheel into a new venv (dependencies from the index), then
    ``simbench validate --quick`` from another directory."""
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    subprocess.run([python, "-m", "pip", "install", "-q", wheel], check=True, capture_output=True)
    work = tmp_path / "elsewhere"
    work.mkdir()
    run = subprocess.run(
        [env_dir / "bin" / "simbench", "validate", "--quick", "--no-progress", "--out", "report"],
        cwd=work,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert (work / "report" / "index.html").is_file()
