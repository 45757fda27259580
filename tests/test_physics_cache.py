"""The physics cache: sessions that differ only in their sensors share one run, byte for byte."""

from __future__ import annotations

import os
import tempfile
from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_array_equal

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


def test_an_unreadable_stored_run_is_computed_again(tmp_path):
    fresh = run_session(CONFIG)
    with physics_cache(tmp_path):
        run_session(CONFIG)
        (stored,) = tmp_path.glob("*.npz")
        stored.write_bytes(b"not a run")
        again = run_session(CONFIG)
    _datasets_equal(again, fresh)
    assert stored.stat().st_size > 100  # written again


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
    with physics_cache(tmp_path):
        got = run_session(CONFIG)
    _datasets_equal(got, fresh)
    assert list(tmp_path.iterdir()) == []


def test_no_temporary_folder_means_no_cache(monkeypatch):
    def read_only(*args, **kwargs):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(tempfile, "TemporaryDirectory", read_only)
    with physics_cache() as folder:
        assert folder is None and ENV not in os.environ
        run_session(CONFIG)
