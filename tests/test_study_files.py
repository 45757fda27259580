"""The shipped studies: every study file loads, every study script imports only names that exist."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest

from simbench.errors import load_toml
from simbench.experiments import study as st

STUDIES = Path(__file__).resolve().parents[1] / "studies"
#: Study files (not cluster specifications such as hip_c3d.toml).
STUDY_FILES = sorted(p for p in STUDIES.glob("*.toml") if "parameter" in load_toml(p))
SCRIPTS = sorted(STUDIES.glob("*.py"))


def test_the_shipped_studies_are_found():
    assert {p.stem for p in STUDY_FILES} >= {"noise", "placement", "slip"}
    assert {p.stem for p in SCRIPTS} >= {"hip_c3d", "orientation", "paper_tracker"}


@pytest.mark.parametrize("path", STUDY_FILES, ids=lambda p: p.name)
def test_study_file_loads(path):
    study = st.load_study(path)
    assert study.name == path.stem
    assert "duration_s" in study.base  # the shipped studies do not rely on SessionConfig's default
    assert len(st.trials(study)) >= 2


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_study_script_imports(path):
    namespace = runpy.run_path(str(path), run_name="study_script")  # not "__main__": nothing runs
    assert callable(namespace["main"])
