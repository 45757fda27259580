"""The calibrate table's columns are as wide as their values: nothing runs into the next column."""

from __future__ import annotations

import re

import numpy as np
import pytest

from calibration import calibrate
from calibration.rotations import axis_angle_to_matrix, rotvec_to_matrix
from simbench.cli.table import format_table, text_table
from simbench.io.poses import PoseRecording


def test_text_table_sizes_columns_from_values():
    lines = text_table(["name", "value"], [["a", "1.23e+07"], ["a much longer name", "5"]], "lr")
    assert lines == [
        "  name                   value",
        "  a                   1.23e+07",
        "  a much longer name         5",
    ]
    with pytest.raises(ValueError, match="2 headers, align 'l'"):
        text_table(["a", "b"], [["1", "2"]], "l")


def test_a_huge_condition_number_does_not_run_into_its_neighbour():
    """A joint turned about one axis with a 1e-7 rad wobble off it: a condition number of about
    1e7, eight characters, which ran into the max-residual column before."""
    n = 3000
    t = np.arange(n) / 100.0
    axis = np.array([0.0, 0.0, 1.0])
    R_p = rotvec_to_matrix(
        0.5 * np.stack([np.sin(0.7 * t), np.sin(1.1 * t + 1), np.sin(0.3 * t + 2)], axis=1)
    )
    rel = axis_angle_to_matrix(np.broadcast_to(axis, (n, 3)), np.sin(0.9 * t))
    wobble = rotvec_to_matrix(1e-7 * np.stack([np.sin(1.3 * t), np.cos(1.7 * t), np.zeros(n)], axis=1))
    R_c = R_p @ rel @ wobble
    in_parent, in_child = np.array([0.1, 0.0, -0.2]), np.array([0.0, 0.05, 0.2])
    p_p = np.zeros((n, 3))
    p_c = np.einsum("fij,j->fi", R_p, in_parent) - np.einsum("fij,j->fi", R_c, in_child)
    R, p = np.stack([R_p, R_c], axis=1), np.stack([p_p, p_c], axis=1)
    rec = PoseRecording(("thigh", "shank"), t, R, p, np.ones((n, 2), dtype=bool))
    cal = calibrate(R, p, rec.names, parent_of={"shank": "thigh"})
    assert cal.joints[0].fit.condition > 1e6
    table = format_table(rec, cal, [])
    head, row = (
        line for line in table.splitlines() if line.startswith("  thigh -> shank") or "rms mm" in line
    )
    fields = re.split(r"\s{2,}", row.strip())
    assert len(fields) == 6, row  # joint, rms, max, cond, axis, frames: every one apart
    assert float(fields[3]) == pytest.approx(cal.joints[0].fit.condition, rel=1e-2)
    # every value ends where its right-aligned header ends
    for name in ("rms mm", "max mm", "cond", "frames"):
        end = head.index(name) + len(name)
        assert row[:end].rstrip() == row[:end], name
