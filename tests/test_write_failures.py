"""Every write checked: a full disk names the file, a truncated C3D is never called written, and a
command that fails part way leaves none of its outputs (issue 45)."""

from __future__ import annotations

import contextlib
import os
import subprocess
from pathlib import Path

import ezc3d
import numpy as np
import pytest

from simbench.cli import main
from simbench.cli import simulate as cli_simulate
from simbench.errors import InputError
from simbench.io.atomic import atomic_open, atomic_write_text, output_set
from simbench.io.c3d import read_c3d, write_c3d_markers

LABELS = [f"M{k}" for k in range(5)]


def _markers(n_frames: int = 600) -> np.ndarray:
    x = np.random.default_rng(3).normal(scale=0.3, size=(n_frames, len(LABELS), 3))
    x[10:20, 2] = np.nan  # not seen
    return x


def _left_in(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_a_c3d_that_ezc3d_truncates_is_not_written(tmp_path, monkeypatch):
    """ezc3d's write reports nothing on a full disk and leaves 384 of 600 frames: that file must
    not become the output (it crashes ezc3d when read)."""
    real = ezc3d.c3d.write

    def truncating(self, path, *args, **kwargs):
        real(self, path, *args, **kwargs)
        size = os.path.getsize(path)
        with open(path, "r+b") as fh:
            fh.truncate(size - 216 * 5 * 16)  # 216 frames of 5 markers short

    monkeypatch.setattr(ezc3d.c3d, "write", truncating)
    out = tmp_path / "m.c3d"
    with pytest.raises(InputError, match=rf"cannot write {out}: the C3D written is \d+ bytes, \d+ expected"):
        write_c3d_markers(out, LABELS, _markers(), 100.0)
    assert _left_in(tmp_path) == []


def test_a_c3d_that_reads_back_otherwise_is_not_written(tmp_path, monkeypatch):
    real = ezc3d.c3d.write

    def shifted(self, path, *args, **kwargs):
        self["data"]["points"] = self["data"]["points"] + np.array([1.0, 0.0, 0.0, 0.0])[:, None, None]
        real(self, path, *args, **kwargs)

    monkeypatch.setattr(ezc3d.c3d, "write", shifted)
    with pytest.raises(InputError, match="other positions"):
        write_c3d_markers(tmp_path / "m.c3d", LABELS, _markers(), 100.0)
    assert _left_in(tmp_path) == []


def test_a_whole_c3d_is_written_and_reads_back(tmp_path):
    x = _markers()
    write_c3d_markers(tmp_path / "m.c3d", LABELS, x, 100.0)
    back = read_c3d(tmp_path / "m.c3d")
    np.testing.assert_allclose(back.xyz_m, x, atol=1e-6)  # float32 mm
    assert _left_in(tmp_path) == ["m.c3d"]


def test_a_full_disk_names_the_file_and_leaves_nothing(tmp_path):
    out = tmp_path / "r.json"

    def full(*args):
        raise OSError(28, "No space left on device")

    with pytest.raises(InputError, match=rf"cannot write {out}: No space left on device"):
        with atomic_open(out, "w") as fh:
            fh.write("{")
            full()
    assert _left_in(tmp_path) == []


@contextlib.contextmanager
def _tmpfs(path: Path, size: str = "1m"):
    """A 1 MB tmpfs at ``path``, or skip where it cannot be mounted (not root, no mount)."""
    path.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {mounted.stderr.decode(errors='replace').strip()}")
    try:
        yield path
    finally:
        subprocess.run(["umount", str(path)], capture_output=True)


def test_a_real_full_disk_names_each_file_and_leaves_none(tmp_path):
    with _tmpfs(tmp_path / "small") as small:
        with pytest.raises(InputError, match=rf"cannot write {small / 'm.c3d'}: .*(No space|disk full)"):
            write_c3d_markers(small / "m.c3d", LABELS, _markers(20_000), 100.0)  # 1.6 MB
        assert _left_in(small) == []
        with pytest.raises(InputError, match=rf"cannot write {small / 'big.txt'}: No space left"):
            atomic_write_text(small / "big.txt", "x" * 2_000_000)
        assert _left_in(small) == []


def test_a_set_of_outputs_is_written_whole_or_not_at_all(tmp_path):
    first, second = tmp_path / "a.txt", tmp_path / "b.txt"
    first.write_text("old")
    with pytest.raises(RuntimeError):
        with output_set():
            atomic_write_text(first, "new")
            assert first.read_text() == "old", "replaced only when the whole set is written"
            atomic_write_text(second, "new")
            raise RuntimeError("the third output fails")
    assert first.read_text() == "old" and _left_in(tmp_path) == ["a.txt"]
    with output_set():
        atomic_write_text(first, "new")
        atomic_write_text(second, "one")
        atomic_write_text(second, "two")  # written twice: the last kept
    assert first.read_text() == "new" and second.read_text() == "two"
    assert _left_in(tmp_path) == ["a.txt", "b.txt"]


def test_simulate_that_fails_at_its_last_output_leaves_none(tmp_path, monkeypatch, capsys):
    """``simulate -o d.h5 --csv p.csv --truth-json t.json`` whose truth JSON meets a full disk:
    before, d.h5 and p.csv stayed (an earlier d.h5 replaced); now none of the set is written."""
    h5, csv, truth = tmp_path / "d.h5", tmp_path / "p.csv", tmp_path / "t.json"
    h5.write_bytes(b"an earlier dataset")

    def full_disk(path, doc):
        with atomic_open(path, "w") as fh:
            fh.write("{")
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(cli_simulate, "write_calibration", full_disk)
    argv = ["simulate", "--duration", "1", "-o", str(h5), "--csv", str(csv), "--truth-json", str(truth)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"simbench: error: cannot write {truth}: No space left on device" in err
    assert h5.read_bytes() == b"an earlier dataset"
    assert _left_in(tmp_path) == ["d.h5"]
