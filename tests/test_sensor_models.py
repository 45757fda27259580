"""Sensor models: exact at zero, each term with its configured statistics, seeded."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.rotations import matrix_to_quat, matrix_to_rotvec, quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError
from simbench.sensor_models import ImuConfig, TrackerConfig, apply_imu, apply_tracker

F, N = 20_000, 4


@pytest.fixture(scope="module")
def poses():
    rng = np.random.default_rng(0)
    t = np.arange(F) / 100.0
    # sensors at 0.5, 1.0, 1.0, 1.5 m from the transmitter at the origin, slowly turning
    p = np.zeros((F, N, 3))
    p[:, :, 0] = [0.5, 1.0, 1.0, 1.5]
    q = matrix_to_quat(rotvec_to_matrix(rng.normal(size=(F, N, 3))))
    return t, p, q


def test_zero_config_is_exact(poses):
    t, p, q = poses
    p2, q2, valid = apply_tracker(t, p, q, TrackerConfig(), np.random.default_rng(1))
    assert np.array_equal(p2, p) and np.array_equal(q2, q) and valid.all()
    acc = np.random.default_rng(2).normal(size=(F, N, 3))
    out = apply_imu(100.0, acc, acc + 1, acc + 2, ImuConfig(), np.random.default_rng(3))
    for got, want in zip(out, (acc, acc + 1, acc + 2), strict=True):
        assert np.array_equal(got, want)


def test_position_noise_grows_as_r4(poses):
    t, p, q = poses
    cfg = TrackerConfig(position_noise_m=0.002, reference_distance_m=1.0)
    p2, _, _ = apply_tracker(t, p, q, cfg, np.random.default_rng(4))
    std = (p2 - p).std(axis=0).mean(axis=1)  # per sensor
    # 60,000 samples per sensor: the sample std is within 2 % of sigma
    assert std[1] == pytest.approx(0.002, rel=0.02)
    assert std[0] == pytest.approx(0.002 * 0.5**4, rel=0.02)
    assert std[3] == pytest.approx(0.002 * 1.5**4, rel=0.02)
    assert abs((p2 - p).mean()) < 3 * 0.002 * 1.5**4 / np.sqrt(F)


def test_orientation_noise(poses):
    t, p, q = poses
    cfg = TrackerConfig(orientation_noise_rad=0.01)
    _, q2, _ = apply_tracker(t, p, q, cfg, np.random.default_rng(5))
    err = matrix_to_rotvec(quat_to_matrix(q2) @ np.swapaxes(quat_to_matrix(q), -1, -2))
    assert err[:, 1].std() == pytest.approx(0.01, rel=0.02)
    assert err[:, 3].std() == pytest.approx(0.01 * 1.5**3, rel=0.02)


def test_scale_resolution_dropout_latency(poses):
    t, p, q = poses
    p2, _, _ = apply_tracker(t, p, q, TrackerConfig(unit_scale=0.94), np.random.default_rng(6))
    assert_allclose(p2, p / 0.94, rtol=1e-15)
    p3, _, _ = apply_tracker(t, p + 0.0123, q, TrackerConfig(resolution_m=0.004), np.random.default_rng(6))
    assert_allclose(p3 / 0.004, np.round(p3 / 0.004), atol=1e-9)
    assert np.abs(p3 - (p + 0.0123)).max() <= 0.002 + 1e-12
    p4, q4, valid = apply_tracker(t, p, q, TrackerConfig(dropout_rate=0.1), np.random.default_rng(7))
    assert 1 - valid.mean() == pytest.approx(0.1, abs=0.005)  # 80,000 draws: 3 sigma is 0.003
    assert np.isnan(p4[~valid]).all() and np.isnan(q4[~valid]).all() and np.isfinite(p4[valid]).all()
    moving = p.copy()
    moving[:, :, 1] = t[:, None] * 0.5  # 0.5 m/s along y
    p5, _, valid = apply_tracker(t, moving, q, TrackerConfig(latency_s=0.05), np.random.default_rng(8))
    assert not valid[:5].any() and valid[5:].all()
    assert_allclose(p5[5:, :, 1], moving[:-5, :, 1], atol=1e-12)


def test_imu_terms():
    rng = np.random.default_rng(9)
    zero = np.zeros((F, N, 3))
    acc, gyro, mag = apply_imu(100.0, zero, zero, zero, ImuConfig(accel_noise_density=0.002), rng)
    assert acc.std() == pytest.approx(0.002 * 10.0, rel=0.01)  # density x sqrt(100 Hz)
    big = np.full((F, N, 3), 30.0)
    acc, _, _ = apply_imu(100.0, big, zero, zero, ImuConfig(accel_range=19.6), rng)
    assert acc.max() == 19.6
    acc, _, _ = apply_imu(100.0, zero, zero, zero, ImuConfig(accel_bias=0.1), rng)
    assert np.ptp(acc, axis=0).max() == 0.0  # a constant per sensor
    _, gyro, _ = apply_imu(100.0, zero, zero, zero, ImuConfig(gyro_bias_walk=0.01), rng)
    # random walk: variance grows as walk^2 t; at t = 200 s, std = 0.01 sqrt(200)
    end = gyro[-1].ravel()
    assert end.std() == pytest.approx(0.01 * np.sqrt(200.0), rel=0.6)  # only 12 walks: loose
    field = np.tile([0.0, 25.0, -43.3], (F, N, 1))
    _, _, mag = apply_imu(100.0, zero, zero, field, ImuConfig(mag_hard_iron=5.0, mag_soft_iron=0.05), rng)
    offset = mag - field
    assert np.ptp(offset, axis=0).max() < 1e-12 and np.abs(offset).max() > 0.1


def test_seeded(poses):
    t, p, q = poses
    cfg = TrackerConfig(position_noise_m=0.003, orientation_noise_rad=0.01, dropout_rate=0.05)
    a = apply_tracker(t, p, q, cfg, np.random.default_rng(11))
    b = apply_tracker(t, p, q, cfg, np.random.default_rng(11))
    c = apply_tracker(t, p, q, cfg, np.random.default_rng(12))
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0], c[0], equal_nan=True)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: TrackerConfig(position_noise_m=-1.0), "position_noise_m must be a finite number >= 0"),
        (lambda: TrackerConfig(dropout_rate=1.0), r"dropout_rate must be in \[0, 1\)"),
        (lambda: TrackerConfig(unit_scale=0.0), "unit_scale must be > 0"),
        (lambda: ImuConfig(gyro_bias=float("nan")), "gyro_bias must be a finite number"),
    ],
)
def test_bad_configs_name_the_field(make, message):
    with pytest.raises(InputError, match=message):
        make()
