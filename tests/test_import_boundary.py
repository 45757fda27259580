"""calibration/ must serve real data unchanged: it never imports mujoco, dm_control or simbench."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import calibration

FORBIDDEN = {"mujoco", "dm_control", "simbench"}
FILES = sorted(Path(calibration.__file__).parent.rglob("*.py"))


def imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            roots.add(node.module.split(".")[0])
        elif isinstance(node, ast.Call) and getattr(node.func, "id", None) == "__import__":
            roots |= {a.value.split(".")[0] for a in node.args if isinstance(a, ast.Constant)}
    return roots


def test_package_has_modules():
    assert len(FILES) >= 8


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_no_forbidden_import(path):
    bad = imported_roots(path) & FORBIDDEN
    assert not bad, f"{path.name} imports {sorted(bad)}"


def test_checker_sees_imports(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import numpy\nfrom simbench.x import y\nimport mujoco.viewer\n")
    assert imported_roots(probe) == {"numpy", "simbench", "mujoco"}
