"""Shared fixtures: analytic articulated captures with exact ground truth."""

from __future__ import annotations

import os
import shutil
import tempfile

import numpy as np
import pytest

from simbench.experiments.pool import one_blas_thread
from simbench.sim.physics_cache import ENV
from simbench.sim.synthetic import SyntheticCapture, linkage, simulate_motion


@pytest.fixture(scope="session")
def linkage_exact() -> SyntheticCapture:
    """O'Brien's linkage, 800 noise-free frames at 120 Hz."""
    return simulate_motion(linkage(), n_frames=800, rate_hz=120.0, rng=np.random.default_rng(11))


@pytest.fixture(scope="session")
def linkage_noisy() -> SyntheticCapture:
    """O'Brien's linkage, 2400 frames, 3 mm position and 0.5 degree rotation noise."""
    return simulate_motion(
        linkage(),
        n_frames=2400,
        rate_hz=120.0,
        rng=np.random.default_rng(12),
        position_noise_m=0.003,
        rotation_noise_rad=np.deg2rad(0.5),
    )


def pytest_configure(config):
    """BLAS on one thread for the whole run: the tests' problems are small, where BLAS's threads
    only contend with each other (and with the pools' workers and other test processes).

    And one physics cache (:mod:`simbench.sim.physics_cache`) for the run, shared by the test
    workers (they inherit the variable): the tests simulate the same sessions many times (the
    validation's, the CLI's defaults), and a stored run is byte-identical to a fresh one
    (``tests/test_physics_cache.py``). Tests about the physics itself take ``fresh_physics``.
    """
    config._simbench_blas = one_blas_thread()
    if not os.environ.get(ENV):
        config._simbench_physics = tempfile.mkdtemp(prefix="simbench-test-physics-")
        os.environ[ENV] = config._simbench_physics


def pytest_unconfigure(config):
    folder = getattr(config, "_simbench_physics", None)
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)
        os.environ.pop(ENV, None)


@pytest.fixture
def fresh_physics(monkeypatch):
    """No physics cache: every session in the test runs its own physics."""
    monkeypatch.delenv(ENV, raising=False)
