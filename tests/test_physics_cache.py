"""The physics cache: sessions that differ only in their sensors share one run, byte for byte."""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from simbench.cli import main
from simbench.sim import physics
from simbench.sim import physics_cache as pc
from simbench.sim.physics_cache import ENV, code_digest, physics_cache, physics_key
from simbench.sim.plan import plan_session
from simbench.sim.session import SessionConfig, load_session_model, run_session

pytestmark = pytest.mark.usefixtures("fresh_physics")

CONFIG = SessionConfig(model="linkage", motion="exercise", duration_s=2.0, seed=5, sensors="polhemus-liberty")


def _datasets_equal(a, b) -> None:
    """Equal to the bit (NaN where the other has NaN: a tracker's missing samples)."""
    assert_array_equal(a.time_s, b.time_s)
    for field in ("p_w_s", "q_w_s", "valid", "acc", "gyro", "mag"):
        assert_array_equal(getattr(a.measured, field), getattr(b.measured, field), err_msg=field, strict=True)
    assert_array_equal(a.truth.joint_w, b.truth.joint_w, strict=True)
    assert_array_equal(a.truth.actual.q_w_s, b.truth.actual.q_w_s, strict=True)


def _counting_rollout(monkeypatch) -> list[int]:
    calls = []
    real = physics.rollout.rollout

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(physics.rollout, "rollout", counted)
    return calls


def test_a_cached_run_equals_a_fresh_one_and_sensors_share_it(tmp_path, monkeypatch):
    fresh = run_session(CONFIG)
    other_sensors = replace(CONFIG, sensors="ascension-flock")
    fresh_other = run_session(other_sensors)
    calls = _counting_rollout(monkeypatch)
    with physics_cache(tmp_path) as folder:
        assert os.environ[ENV] == str(folder)
        first = run_session(CONFIG)
        n_first = len(calls)
        again = run_session(CONFIG)
        other = run_session(other_sensors)
    assert ENV not in os.environ
    assert n_first > 0
    assert len(calls) == n_first, "the second and third sessions must read the stored run"
    assert len(list(tmp_path.glob("*.npz"))) == 1
    _datasets_equal(first, fresh)
    _datasets_equal(again, fresh)
    _datasets_equal(other, fresh_other)


def test_what_changes_the_physics_changes_the_key():
    cm = load_session_model(CONFIG)
    plan = plan_session(CONFIG, cm)
    key = physics_key(cm, plan, plan.timestep)
    assert key == physics_key(cm, plan_session(CONFIG, load_session_model(CONFIG)), plan.timestep)
    other_seed = replace(CONFIG, seed=6)
    assert key != physics_key(cm, plan_session(other_seed, cm), plan.timestep)
    longer = replace(CONFIG, duration_s=3.0)
    assert key != physics_key(cm, plan_session(longer, cm), plan.timestep)
    assert key != physics_key(cm, plan, plan.timestep / 2)
    assert key != physics_key(cm, plan, plan.timestep, (1.0, 12_000))
    played = replace(CONFIG, sensors="ascension-flock-paper")  # joint play: another model
    cm_played = load_session_model(played)
    assert cm_played.joint_play_m > 0
    assert key != physics_key(cm_played, plan_session(played, cm_played), plan.timestep)


def test_a_change_to_the_simulation_code_changes_the_key(monkeypatch):
    """A folder kept between runs (``simbench validate --physics-cache``) must not give back a
    run made by other code: the key covers the source of simbench.sim and the rotations."""
    cm = load_session_model(CONFIG)
    plan = plan_session(CONFIG, cm)
    key, digest = physics_key(cm, plan, plan.timestep), code_digest()
    for edited in ("programs.py", "rotations.py"):
        real = pc.Path.read_bytes

        def read_bytes(path, real=real, edited=edited):
            return real(path) + (b"# edited" if path.name == edited else b"")

        monkeypatch.setattr(pc.Path, "read_bytes", read_bytes)
        code_digest.cache_clear()
        try:
            assert code_digest() != digest, edited
            assert physics_key(cm, plan, plan.timestep) != key, edited
        finally:
            monkeypatch.undo()
            code_digest.cache_clear()
    assert code_digest() == digest and physics_key(cm, plan, plan.timestep) == key


def _stored_once(folder) -> pc.Path:
    run_session(CONFIG)
    (stored,) = folder.glob("*.npz")
    return stored


def _rewrite(path, **arrays) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _entry(path) -> tuple[np.ndarray, dict]:
    with np.load(path) as f:
        return f["sensordata"], json.loads(str(f["header"]))


def _flip_a_bit(path) -> None:
    data, header = _entry(path)
    data = data.copy()
    data.reshape(-1).view(np.uint8)[data.nbytes // 2] ^= 1
    _rewrite(path, sensordata=data, header=np.array(json.dumps(header)))


def _flip_a_file_byte(path) -> None:  # the zip's own CRC or the checksum: either names it
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0x10
    path.write_bytes(bytes(raw))


def _truncate(path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _nan(path) -> None:  # a consistent entry (checksum of its bytes) that holds NaN
    data, header = _entry(path)
    data = data.copy()
    data[len(data) // 2, 0] = np.nan
    header["sha256"] = pc._digest(data)
    _rewrite(path, sensordata=data, header=np.array(json.dumps(header)))


def _int8(path) -> None:
    data, header = _entry(path)
    small = data.astype(np.int8)
    header.update(dtype=small.dtype.str, sha256=pc._digest(small))
    _rewrite(path, sensordata=small, header=np.array(json.dumps(header)))


def _old_layout(path) -> None:
    data, header = _entry(path)
    _rewrite(path, sensordata=data, warnings=np.array(json.dumps(header["warnings"])))


@pytest.mark.parametrize(
    ("damage", "said"),
    [
        (lambda p: p.write_bytes(b"not a run"), "unreadable"),
        (_truncate, "unreadable"),
        (_flip_a_bit, "checksum"),
        (_flip_a_file_byte, ""),
        (_nan, "not finite"),
        (_int8, "dtype int8"),
        (_old_layout, "not a run of this version"),
    ],
    ids=["garbage", "truncated", "bit-flipped", "file-byte-flipped", "nan", "int8", "old-layout"],
)
def test_a_damaged_stored_run_is_named_and_computed_again(tmp_path, damage, said):
    fresh = run_session(CONFIG)
    with physics_cache(tmp_path):
        stored = _stored_once(tmp_path)
        damage(stored)
        with pytest.warns(pc.PhysicsCacheWarning, match=f"{re.escape(str(stored))}: .*{said}"):
            again = run_session(CONFIG)
        after = pc.check_entry(stored, stored.stem)
    _datasets_equal(again, fresh)
    assert not isinstance(after, str), f"written again: {after}"


def test_runs_swapped_between_files_are_refused_by_their_keys(tmp_path):
    """Two entries swapped (each a valid run of another session) must not give a session another's
    physics (a session of another duration, a slip found where there is none)."""
    longer = replace(CONFIG, duration_s=3.0)
    fresh, fresh_longer = run_session(CONFIG), run_session(longer)
    with physics_cache(tmp_path):
        run_session(CONFIG)
        (a,) = tmp_path.glob("*.npz")
        run_session(longer)
        (b,) = set(tmp_path.glob("*.npz")) - {a}
        data_a, data_b = a.read_bytes(), b.read_bytes()
        a.write_bytes(data_b)
        b.write_bytes(data_a)
        with pytest.warns(pc.PhysicsCacheWarning, match="stored under key"):
            got = run_session(CONFIG)
        with pytest.warns(pc.PhysicsCacheWarning, match="stored under key"):
            got_longer = run_session(longer)
    _datasets_equal(got, fresh)
    _datasets_equal(got_longer, fresh_longer)


def test_a_temporary_cache_is_removed_and_an_active_one_shared(tmp_path):
    with physics_cache() as alone:
        assert os.environ[ENV] == str(alone) and alone.is_dir()
        run_session(CONFIG)
        assert len(list(alone.glob("*.npz"))) == 1
    assert not alone.exists() and ENV not in os.environ
    outer = tmp_path / "outer"
    with physics_cache(outer):
        with physics_cache() as inner:  # a cache already active is shared, not replaced
            assert inner == outer and os.environ[ENV] == str(outer)
            run_session(CONFIG)
        assert os.environ[ENV] == str(outer)
    assert ENV not in os.environ and len(list(outer.glob("*.npz"))) == 1


def test_a_run_that_cannot_be_stored_is_used_all_the_same(tmp_path, monkeypatch):
    """The cache only saves time: a full disk (here: every write fails) leaves no file, partial or
    whole, and the session is the fresh one."""
    fresh = run_session(CONFIG)

    def full_disk(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez", full_disk)
    monkeypatch.setattr(pc, "_UNWRITABLE", set())
    with physics_cache(tmp_path):
        with pytest.warns(pc.PhysicsCacheWarning, match=f"{re.escape(str(tmp_path))}: .*No space left"):
            got = run_session(CONFIG)
    _datasets_equal(got, fresh)
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_cannot_be_written_is_said_and_still_read(tmp_path, monkeypatch):
    with physics_cache(tmp_path):
        first = run_session(CONFIG)
    real_mkstemp = tempfile.mkstemp

    def read_only(*args, dir=None, **kwargs):
        if dir is not None and pc.Path(dir) == tmp_path:
            raise OSError(30, "Read-only file system")
        return real_mkstemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    monkeypatch.setattr(pc, "_UNWRITABLE", set())
    calls = _counting_rollout(monkeypatch)
    with pytest.warns(pc.PhysicsCacheWarning, match=f"{re.escape(str(tmp_path))}: cannot keep runs there"):
        with physics_cache(tmp_path):
            again = run_session(CONFIG)
    assert calls == [], "the run already there is read"
    _datasets_equal(again, first)


def test_leftovers_of_killed_runs_are_swept_and_live_ones_kept(tmp_path):
    host = socket.gethostname()
    gone = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    dead_pid = int(gone.stdout)
    folders = {}
    for name, owner, age_s in [
        ("killed", {"pid": dead_pid, "host": host}, 0.0),
        ("running", {"pid": os.getpid(), "host": host}, 10 * pc.LEFTOVER_AGE_S),
        ("old-unowned", None, 2 * pc.LEFTOVER_AGE_S),
        ("new-unowned", None, 0.5 * pc.LEFTOVER_AGE_S),
        ("old-other-host", {"pid": os.getpid(), "host": host + "-elsewhere"}, 2 * pc.LEFTOVER_AGE_S),
    ]:
        folder = tmp_path / f"{pc.TEMP_PREFIX}{name}"
        folder.mkdir()
        (folder / "run.npz").write_bytes(b"x" * 100)
        if owner is not None:
            (folder / pc.OWNER_FILE).write_text(json.dumps(owner))
        then = time.time() - age_s
        os.utime(folder, (then, then))
        folders[name] = folder
    unrelated = tmp_path / "somebody-elses-folder"
    unrelated.mkdir()
    os.utime(unrelated, (0, 0))
    removed = pc.sweep_leftovers(tmp_path)
    assert sorted(p.name for p in removed) == sorted(
        f"{pc.TEMP_PREFIX}{n}" for n in ("killed", "old-unowned", "old-other-host")
    )
    assert {p.name for p in tmp_path.iterdir()} == {
        f"{pc.TEMP_PREFIX}running",
        f"{pc.TEMP_PREFIX}new-unowned",
        "somebody-elses-folder",
    }


def test_a_temporary_cache_names_its_owner_and_sweeps_before_it_starts(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.delenv(ENV, raising=False)
    left = tmp_path / f"{pc.TEMP_PREFIX}left"
    left.mkdir()
    os.utime(left, (0, 0))
    with physics_cache() as folder:
        owner = json.loads((folder / pc.OWNER_FILE).read_text())
        assert owner["pid"] == os.getpid() and owner["host"] == socket.gethostname()
        assert not left.exists()


def test_no_temporary_folder_means_no_cache(monkeypatch):
    def read_only(*args, **kwargs):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryDirectory", read_only)
    with physics_cache() as folder:
        assert folder is None and ENV not in os.environ
        run_session(CONFIG)


def test_the_command_line_names_a_damaged_entry_in_one_line(tmp_path, monkeypatch, capsys):

    cache = tmp_path / "cache"
    monkeypatch.setenv(ENV, str(cache))
    cache.mkdir()
    argv = [
        "simulate",
        "--model",
        "linkage",
        "--duration",
        "2",
        "--seed",
        "5",
        "--sensors",
        "polhemus-liberty",
    ]
    assert main([*argv, "-o", str(tmp_path / "a.h5")]) == 0
    (stored,) = cache.glob("*.npz")
    _truncate(stored)
    capsys.readouterr()
    assert main([*argv, "-o", str(tmp_path / "b.h5")]) == 0
    err = capsys.readouterr().err
    assert f"simbench: note: physics cache: {stored}: unreadable" in err, err
    assert "PhysicsCacheWarning" not in err and "\n  " not in err  # one line, no source line
    assert (tmp_path / "a.h5").read_bytes() != b"" and not isinstance(
        pc.check_entry(stored, stored.stem), str
    )
