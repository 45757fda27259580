"""Shared fixtures: analytic articulated captures with exact ground truth."""

from __future__ import annotations

import numpy as np
import pytest

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


@pytest.fixture
def one_blas_thread():
    """BLAS on one thread: small matrices' threads only contend with each other (and with other
    test processes). Modules of many small fits use it for every test (``pytestmark``)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional
        yield
        return
    with threadpool_limits(limits=1):
        yield
