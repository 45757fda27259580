"""Atomic writes: a failure mid-write leaves the old file and no temporary behind."""

from __future__ import annotations

import os
import stat

import pytest

from simbench.errors import InputError
from simbench.io.atomic import atomic_open, atomic_write_text


def test_success_replaces_and_keeps_usual_permissions(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old")
    atomic_write_text(path, "new")
    assert path.read_text() == "new"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_failure_mid_write_keeps_old_file(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old")
    with pytest.raises(RuntimeError, match="crash"), atomic_open(path) as fh:
        fh.write("half of the new content")
        raise RuntimeError("crash")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_missing_folder_is_a_clear_error(tmp_path):
    with pytest.raises(InputError, match=r"folder .* does not exist"):
        atomic_write_text(tmp_path / "nope" / "out.txt", "x")
    (tmp_path / "taken").mkdir()
    with pytest.raises(InputError, match=r"cannot write .*taken: it is a folder"):
        atomic_write_text(tmp_path / "taken", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]  # no temporary file left
