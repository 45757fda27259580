"""Outputs never destroy inputs or each other, and writes keep what a path is (issue 45)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from simbench.cli import main
from simbench.errors import InputError
from simbench.io.atomic import atomic_write_text


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    folder = tmp_path_factory.mktemp("outputs")
    path = folder / "d.h5"
    assert main(["simulate", "--duration", "1", "-o", str(path)]) == 0
    return path


def _refused(argv, capsys) -> str:
    before = {p: p.stat().st_mtime_ns for p in map(Path, argv) if p.is_file()}
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "internal error" not in err[0]
    for p, mtime in before.items():  # nothing written over
        assert p.stat().st_mtime_ns == mtime
    return err[0]


def test_an_output_over_the_input_is_refused(dataset, capsys):
    d = str(dataset)
    assert "writing it would destroy the input" in _refused(["calibrate", d, "--json", d], capsys)
    assert "writing it would destroy the input" in _refused(["export", d, "--sto", d], capsys)


def test_an_output_over_the_input_through_a_link_is_refused(dataset, tmp_path, capsys):
    link = tmp_path / "link.h5"
    link.symlink_to(dataset)
    err = _refused(["calibrate", str(link), "--json", str(dataset)], capsys)
    assert "destroy the input" in err and str(link) in err


def test_two_outputs_on_one_file_are_refused(tmp_path, capsys):
    out = str(tmp_path / "d.h5")
    err = _refused(["simulate", "--duration", "1", "-o", out, "--truth-json", out], capsys)
    assert "name the same file" in err and not (tmp_path / "d.h5").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_output_is_refused_not_replaced(tmp_path, capsys):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    err = _refused(["simulate", "--duration", "1", "-o", str(fifo)], capsys)
    assert "not a regular file" in err and fifo.is_fifo()
    with pytest.raises(InputError, match="not a regular file"):
        atomic_write_text(fifo, "x")
    assert fifo.is_fifo()


def test_a_symlinked_output_is_written_through(tmp_path):
    target = tmp_path / "real.txt"
    target.write_text("old")
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    atomic_write_text(link, "new")
    assert link.is_symlink() and target.read_text() == "new"
