"""The layers of ARCHITECTURE.md: imports go one way only, and at the top of modules.

    cli -> api -> experiments -> report -> score/orient/estimators/twin -> sim -> io -> base -> calibration

A module may import its own layer and the layers below it, never one above. ``calibration/``
never imports mujoco, dm_control or simbench (it serves real recordings unchanged). Imports
inside functions are allowed only for optional heavy dependencies, named in ``LAZY_ALLOWED``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import calibration
import simbench
from simbench import cli, estimators

ROOT = Path(simbench.__file__).resolve().parent.parent

#: Layer of each package/module (a module's layer is that of its longest matching prefix).
LAYERS = {
    "calibration": 0,
    "simbench.errors": 1,
    "simbench.versions": 1,
    "simbench.units": 1,
    "simbench.io": 2,
    "simbench.sim": 3,
    "simbench.score": 4,
    "simbench.orient": 4,
    "simbench.estimators": 4,
    "simbench.twin": 4,
    "simbench.report": 5,
    "simbench.experiments": 6,
    "simbench.api": 7,
    "simbench.pytest_plugin": 7,
    "simbench.cli": 8,
    "simbench.__main__": 8,
}
#: ``simbench/__init__.py`` gathers the public API: it may import every layer.
PACKAGE_INIT = "simbench"

#: Optional heavy dependencies that may be imported inside a function (the feature that needs
#: them says which extra installs them): studies' Parquet files and Dask cluster, per-trial BLAS
#: limits, the benchmark's reference (ahrs), dm_control (seconds to import, needed only for
#: ``dm_control:NAME`` models), and the tables of ``Dataset.to_pandas``/``to_xarray`` (the
#: ``export`` extra); and scipy's subpackages that one function each needs and that cost a large part
#: of every start of the command line (``simbench --help``): signal and stats (0.6 s, stats is
#: imported by signal), integrate; and matplotlib (0.6 s), which only the reports need, where a
#: figure is made (:func:`simbench.report.plots.new_figure`). A name allows its submodules.
LAZY_ALLOWED = {
    "pyarrow",
    "dask",
    "distributed",
    "threadpoolctl",
    "ahrs",
    "dm_control",
    "pandas",
    "xarray",
    "scipy.signal",
    "scipy.stats",
    "scipy.integrate",
    "matplotlib",
}

#: The modules that load their parts when first asked for, inside a function, by
#: ``importlib.import_module`` (PEP 562; the command table): the packages' public names, the command
#: line's commands and the library a command runs. Such an import, when it names its module, is
#: checked against the layers as any other (:func:`imports` reads it);
#: ``test_lazy_tables_name_their_own_layers`` checks the tables they read names from.
LAZY_LOADERS = {"simbench", "simbench.cli", "simbench.estimators", "calibration"}

FORBIDDEN_IN_CALIBRATION = {"mujoco", "dm_control", "simbench"}

MODULES = sorted(
    p
    for pkg in ("calibration", "simbench")
    for p in (ROOT / pkg).rglob("*.py")
    if "__pycache__" not in p.parts
)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(name: str) -> int | None:
    best = None
    for prefix, layer in LAYERS.items():
        if (name == prefix or name.startswith(prefix + ".")) and (best is None or len(prefix) > len(best[0])):
            best = (prefix, layer)
    return None if best is None else best[1]


def imports(path: Path) -> list[tuple[str, int, bool]]:
    """``(module, line, inside_a_function)`` of every absolute import in a file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            if isinstance(child, ast.Import):
                out.extend((alias.name, child.lineno, in_function) for alias in child.names)
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                if child.module == "simbench":  # ``from simbench import x``: x may be a module
                    out.extend((f"simbench.{alias.name}", child.lineno, in_function) for alias in child.names)
                else:
                    out.append((child.module, child.lineno, in_function))
            elif isinstance(child, ast.Call) and (
                getattr(child.func, "id", None) in ("__import__", "import_module")
                or getattr(child.func, "attr", None) == "import_module"
            ):
                out.extend(
                    (a.value, child.lineno, in_function)
                    for a in child.args[:1]
                    if isinstance(a, ast.Constant) and isinstance(a.value, str)
                )
            visit(child, inner)

    visit(tree, False)
    return out


def violations(path: Path) -> list[str]:
    me = module_name(path)
    my_layer = layer_of(me)
    problems = []
    for target, line, in_function in imports(path):
        root = target.split(".")[0]
        where = f"{path.relative_to(ROOT)}:{line}"
        if me.split(".")[0] == "calibration" and root in FORBIDDEN_IN_CALIBRATION:
            problems.append(f"{where}: calibration imports {target}")
        heavy = any(target == a or target.startswith(a + ".") for a in LAZY_ALLOWED)
        if in_function and not heavy and me not in LAZY_LOADERS:
            problems.append(f"{where}: function-local import of {target} (not an optional heavy dependency)")
        their_layer = layer_of(target)
        if me != PACKAGE_INIT and their_layer is not None and my_layer is not None and their_layer > my_layer:
            problems.append(f"{where}: {me} (layer {my_layer}) imports {target} (layer {their_layer})")
        if target == PACKAGE_INIT and me != PACKAGE_INIT:
            problems.append(f"{where}: {me} imports the package root (import the module that defines it)")
    return problems


def test_every_module_has_a_layer():
    assert len(MODULES) >= 40
    assert [module_name(p) for p in MODULES if layer_of(module_name(p)) is None] == [PACKAGE_INIT]


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_go_one_way(path):
    assert violations(path) == []


def write(tmp_path: Path, rel: str, text: str) -> Path:
    path = tmp_path / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def test_checker_rejects_a_reverse_import(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    io_module = write(tmp_path, "simbench/io/probe.py", "from simbench.sim.session import run_session\n")
    assert violations(io_module) == [
        "simbench/io/probe.py:1: simbench.io.probe (layer 2) imports simbench.sim.session (layer 3)"
    ]
    report = write(tmp_path, "simbench/report/probe.py", "from simbench import cli\n")
    assert "layer 8" in violations(report)[0]


def test_checker_rejects_local_and_forbidden_imports(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    local = write(
        tmp_path, "simbench/sim/probe.py", "def f():\n    import json\n\n\ndef g():\n    import pyarrow\n"
    )
    assert violations(local) == [
        "simbench/sim/probe.py:2: function-local import of json (not an optional heavy dependency)"
    ]
    core = write(tmp_path, "calibration/probe.py", "import mujoco.viewer\n")
    assert violations(core) == ["calibration/probe.py:1: calibration imports mujoco.viewer"]
    up = write(tmp_path, "simbench/score.py", "import simbench\n")
    assert violations(up) == [
        "simbench/score.py:1: simbench.score imports the package root (import the module that defines it)"
    ]


def test_checker_reads_import_module_and_allows_it_lazily_only_in_loaders(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    probe = write(
        tmp_path,
        "simbench/io/probe.py",
        "import importlib\n\n\ndef f():\n    return importlib.import_module('simbench.api')\n",
    )
    assert violations(probe) == [
        "simbench/io/probe.py:5: function-local import of simbench.api (not an optional heavy dependency)",
        "simbench/io/probe.py:5: simbench.io.probe (layer 2) imports simbench.api (layer 7)",
    ]
    loader = write(
        tmp_path,
        "simbench/cli/__init__.py",
        "import importlib\n\n\ndef f():\n    importlib.import_module('json')\n",
    )
    assert violations(loader) == []


def test_lazy_tables_name_their_own_layers():
    """What the loaders import by a name from a table: the command line its own modules, the
    calibration core its own (``simbench``'s init may import every layer)."""
    assert all(layer_of(module) == LAYERS["simbench.cli"] for module, _ in cli.COMMANDS.values())
    assert all(module.startswith("calibration.") for module in calibration._LAZY.values())
    assert set(calibration._LAZY) == set(calibration.__all__)
    assert all(module.startswith("simbench.estimators.") for module in estimators._LAZY.values())
    assert set(estimators._LAZY) == set(estimators.__all__)


def test_calibration_package_is_importable_alone():
    assert calibration.__name__ == "calibration"
