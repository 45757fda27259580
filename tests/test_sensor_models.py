"""Sensor models: exact at zero, each term with its configured statistics, seeded."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.rotations import (
    axis_angle_to_matrix,
    matrix_to_quat,
    matrix_to_rotvec,
    quat_to_matrix,
    rotvec_to_matrix,
)
from simbench.errors import InputError
from simbench.sim.sensor_models import ImuConfig, TrackerConfig, apply_imu, apply_tracker

F, N = 20_000, 4


@pytest.fixture(scope="module")
def poses():
    rng = np.random.default_rng(0)
    t = np.arange(F) / 100.0
    # sensors on the transmitter's axis (z) at 0.5, 1.0, 1.0, 1.5 m, randomly turned
    p = np.zeros((F, N, 3))
    p[:, :, 2] = [0.5, 1.0, 1.0, 1.5]
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
    from simbench.sim.sensor_models import dipole_anisotropy

    t, p, q = poses
    cfg = TrackerConfig(position_noise_m=0.002, reference_distance_m=1.0)
    p2, _, _ = apply_tracker(t, p, q, cfg, np.random.default_rng(4))
    std = (p2 - p).std(axis=0).mean(axis=1)  # per sensor
    on_axis = 0.002 * dipole_anisotropy(1.0, 4.0)  # the sensors lie on the transmitter's axis
    # 60,000 samples per sensor: the sample std is within 2 % of sigma
    assert std[1] == pytest.approx(on_axis, rel=0.02)
    assert std[0] == pytest.approx(on_axis * 0.5**4, rel=0.02)
    assert std[3] == pytest.approx(on_axis * 1.5**4, rel=0.02)
    assert abs((p2 - p).mean()) < 3 * on_axis * 1.5**4 / np.sqrt(F)


def test_anisotropy_averages_to_one():
    from simbench.sim.sensor_models import dipole_anisotropy

    cos = np.random.default_rng(0).uniform(-1, 1, 2_000_000)  # directions uniform on the sphere
    for n in (3.0, 4.0):
        assert dipole_anisotropy(cos, n).mean() == pytest.approx(1.0, abs=2e-3)
        assert dipole_anisotropy(0.0, n) / dipole_anisotropy(1.0, n) == pytest.approx(2 ** (n / 3))


def test_noise_is_larger_across_the_dipole_axis(poses):
    t, _, q = poses
    p = np.zeros((F, N, 3))
    p[:, 0, 2] = 1.0  # on the axis
    p[:, 1, 0] = 1.0  # in the equatorial plane, same distance
    p[:, 2, :] = [0.0, np.sqrt(0.5), np.sqrt(0.5)]  # 45 degrees
    p[:, 3, 2] = -1.0  # on the axis, other side
    cfg = TrackerConfig(position_noise_m=0.002, orientation_noise_rad=0.01)
    p2, _, _ = apply_tracker(t, p, q, cfg, np.random.default_rng(13))
    std = (p2 - p).std(axis=0).mean(axis=1)
    # dipole: |B| ~ sqrt(1 + 3 cos^2): twice as strong on the axis; sigma ~ |B|^(-4/3)
    assert std[1] / std[0] == pytest.approx(2 ** (4 / 3), rel=0.03)
    assert std[2] / std[0] == pytest.approx((2 / np.sqrt(2.5)) ** (4 / 3), rel=0.03)
    assert std[3] / std[0] == pytest.approx(1.0, rel=0.03)


def test_distortion_is_local(poses):
    from simbench.sim.sensor_models import Distortion

    t, _, q = poses
    p = np.zeros((F, N, 3))
    p[:, :, 0] = [0.1, 0.3, 0.9, 2.0]  # distances from a metal object at the origin
    metal = Distortion(center=(0.0, 0.0, 0.0), radius_m=0.3, position_gain_m=0.05, orientation_gain_rad=0.1)
    p2, q2, _ = apply_tracker(t, p, q, TrackerConfig(distortion=(metal,)), np.random.default_rng(14))
    shift = np.linalg.norm(p2 - p, axis=2)[0]
    expected = 0.05 * np.exp(-(np.array([0.1, 0.3, 0.9, 2.0]) ** 2) / (2 * 0.09))
    # the Gaussian law exactly, to the rounding of metre-sized positions (~1e-16 m)
    assert_allclose(shift, expected, rtol=1e-9, atol=1e-15)
    assert shift[0] > 0.04 and shift[3] < 1e-10  # large near it, nothing far away
    turn = np.linalg.norm(
        matrix_to_rotvec(quat_to_matrix(q2) @ np.swapaxes(quat_to_matrix(q), -1, -2)), axis=2
    )[0]
    assert turn[0] > 0.09 and turn[3] < 1e-9


def test_sample_rate_holds_last_measurement(poses):
    t, p, q = poses
    moving = p.copy()
    moving[:, :, 1] = t[:, None]
    p2, _, valid = apply_tracker(t, moving, q, TrackerConfig(sample_rate_hz=25.0), np.random.default_rng(15))
    assert valid.all()
    # 100 Hz capture of a 25 Hz tracker: every value repeated four times
    assert np.array_equal(p2[0::4, :, 1], p2[1::4, :, 1]) and np.array_equal(p2[0::4], p2[3::4])
    assert_allclose(p2[::4, 0, 1], t[::4], atol=1e-12)


def test_orientation_noise(poses):
    t, p, q = poses
    cfg = TrackerConfig(orientation_noise_rad=0.01)
    _, q2, _ = apply_tracker(t, p, q, cfg, np.random.default_rng(5))  # sensors on the axis
    err = matrix_to_rotvec(quat_to_matrix(q2) @ np.swapaxes(quat_to_matrix(q), -1, -2))
    from simbench.sim.sensor_models import dipole_anisotropy

    on_axis = 0.01 * dipole_anisotropy(1.0, 3.0)
    assert err[:, 1].std() == pytest.approx(on_axis, rel=0.02)
    assert err[:, 3].std() == pytest.approx(on_axis * 1.5**3, rel=0.02)


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
    # the orientation is reported from the same instant as the position: a sensor turning at
    # 2 rad/s about z shows the turn of 0.05 s earlier (and between frames, the interpolated one)
    z, base = np.array([0.0, 0.0, 1.0]), quat_to_matrix(q[0])  # (N, 3, 3) each sensor's mounting
    turning = matrix_to_quat(axis_angle_to_matrix(z, 2.0 * t)[:, None] @ base)
    for latency in (0.05, 0.0035):
        cfg = TrackerConfig(latency_s=latency)
        p6, q6, valid = apply_tracker(t, moving, turning, cfg, np.random.default_rng(8))
        want = axis_angle_to_matrix(z, 2.0 * (t - latency))[:, None] @ base
        err = matrix_to_rotvec(quat_to_matrix(q6[valid[:, 0]]) @ np.swapaxes(want[valid[:, 0]], -1, -2))
        assert np.abs(err).max() < 1e-9, latency
        assert_allclose(p6[valid[:, 0], :, 1], moving[valid[:, 0], :, 1] - 0.5 * latency, atol=1e-12)


def test_field_models():
    from simbench.sim.sensor_models import dipole_field, earth_field

    b = earth_field(50.0, 60.0)
    assert np.linalg.norm(b) == pytest.approx(50.0) and b[0] == 0 and b[2] < 0
    assert np.degrees(np.arctan2(-b[2], b[1])) == pytest.approx(60.0)
    # a 1 A m^2 dipole along z: on its axis at 0.1 m the field is 2 mu0/(4 pi) m / d^3 = 200 uT
    on_axis = dipole_field(np.array([0.0, 0.0, 0.1]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    assert_allclose(on_axis, [0.0, 0.0, 200.0], rtol=1e-12)
    far = dipole_field(np.array([0.0, 0.0, 2.0]), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    assert far[2] == pytest.approx(200.0 / 20**3)  # falls as d^-3: local


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


def test_imu_per_sensor_terms_have_their_spread():
    """Constant per-sensor terms (bias, scale, misalignment, hard iron): the spread across many
    sensors is the configured standard deviation; white noise is white."""
    n_sensors, frames = 4000, 50
    a_true = np.tile([9.81, 0.0, 0.0], (frames, n_sensors, 1))
    zero = np.zeros((frames, n_sensors, 3))
    rng = np.random.default_rng(21)
    # 4,000 sensors: a sample std is within 5 % of sigma with probability > 0.999
    acc, _, _ = apply_imu(100.0, zero, zero, zero, ImuConfig(accel_bias=0.05), rng)
    assert acc[0].std() == pytest.approx(0.05, rel=0.05)
    acc, _, _ = apply_imu(100.0, a_true, zero, zero, ImuConfig(accel_scale_error=0.02), rng)
    assert (acc[0, :, 0] / 9.81 - 1).std() == pytest.approx(0.02, rel=0.05)
    assert np.abs(acc[0, :, 1:]).max() == 0.0  # scale alone does not mix axes
    acc, _, _ = apply_imu(100.0, a_true, zero, zero, ImuConfig(accel_misalignment_rad=0.01), rng)
    # a small rotation theta about z or y moves a bit of x into y or z: 9.81 theta
    assert (acc[0, :, 1] / 9.81).std() == pytest.approx(0.01, rel=0.05)
    assert np.linalg.norm(acc[0], axis=1) == pytest.approx(9.81, rel=1e-12)  # a rotation keeps |a|
    _, _, mag = apply_imu(100.0, zero, zero, zero, ImuConfig(mag_hard_iron=10.0, mag_noise=0.0), rng)
    assert mag[0].std() == pytest.approx(10.0, rel=0.05) and np.ptp(mag, axis=0).max() == 0.0
    _, gyro, _ = apply_imu(100.0, zero, zero, zero, ImuConfig(gyro_noise_density=0.001, gyro_bias=0.0), rng)
    assert gyro.std() == pytest.approx(0.001 * 10.0, rel=0.02)
    lag1 = np.mean(gyro[1:] * gyro[:-1]) / np.mean(gyro * gyro)
    assert abs(lag1) < 0.02  # white: no correlation between neighbouring samples
    acc, _, _ = apply_imu(100.0, a_true + 0.0123, zero, zero, ImuConfig(accel_resolution=0.01), rng)
    assert_allclose(acc / 0.01, np.round(acc / 0.01), atol=1e-9)
