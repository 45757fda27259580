"""Shared fixtures: analytic articulated captures with exact ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from simbench.experiments.pool import one_blas_thread
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
    only contend with each other (and with the pools' workers and other test processes)."""
    config._simbench_blas = one_blas_thread()
