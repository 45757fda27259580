"""The ``--hierarchy`` file of ``simbench calibrate`` (:mod:`simbench.io.hierarchy_json`)."""

from __future__ import annotations

import json

import pytest

from simbench.errors import InputError
from simbench.io.hierarchy_json import read_hierarchy_json


def test_reads_child_to_parent(tmp_path):
    path = tmp_path / "h.json"
    parent_of = {"head": "chest", "upper_arm_l": "chest", "forearm_l": "upper_arm_l"}
    path.write_text(json.dumps(parent_of), encoding="utf-8")
    assert read_hierarchy_json(path) == parent_of
    assert read_hierarchy_json(str(path)) == parent_of


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"head": "chest", "head": "neck"}', r"h\.json: sensors given a parent twice: \['head'\]"),
        ('{"head": "chest",\n oops}', r"h\.json, line 2: not valid JSON"),
        ('["head", "chest"]', r'expected a JSON object \{"child": "parent", \.\.\.\} of sensor names'),
        ('{"head": 3}', "expected a JSON object"),
    ],
)
def test_bad_files_name_the_problem(tmp_path, text, message):
    path = tmp_path / "h.json"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputError, match=message):
        read_hierarchy_json(path)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="cannot read: No such file"):
        read_hierarchy_json(tmp_path / "missing.json")
