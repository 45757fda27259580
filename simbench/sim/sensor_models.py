"""Sensor models: what real trackers make of the exact truth (issue 4, first part).

Every model is a pure function of the truth arrays, a frozen configuration and a
``numpy.random.Generator``: the same inputs and seed give the same output, and a configuration
whose every parameter is zero returns the truth unchanged (bit for bit).

**Magnetic 6-DoF tracker** (:class:`TrackerConfig`, :func:`apply_tracker`), as an Ascension Flock
of Birds or a Polhemus Liberty/Fastrak reports poses:

- white position and orientation noise whose standard deviation grows with the distance ``r``
  from the transmitter: ``sigma = sigma_ref (r / r_ref)^n a(theta)``. A dipole field falls as
  ``r^-3``, so at fixed signal noise the position error grows about as ``r^4`` (``n = 4``,
  docs/conventions.md, after Day et al. 2000) and the orientation error as ``r^3``. The dipole's field is
  twice as strong along its axis (the transmitter's z axis) as across it,
  ``|B| ~ sqrt(1 + 3 cos^2 theta)``, so ``a(theta) ~ (1 + 3 cos^2 theta)^(-n/6)``, normalised to a
  mean of 1 over all directions: ``sigma_ref`` is the direction-averaged noise at ``r_ref`` (as
  vendors quote one figure), 0.57 of it on the axis and 1.43 times it across (``n = 4``) --
  hence the transmitter's pose;
- static field distortion near metal (:class:`Distortion`): a smooth warp of positions (radial,
  away from the object) and orientations (about a fixed axis), Gaussian in the distance to the
  object: ``gain exp(-|p - c|^2 / (2 rho^2))``, negligible a few ``rho`` away;
- the tracker's own sample rate: when polled faster than it measures, it repeats the last
  measurement (zero-order hold);
- the range law: a tracker that turns field strengths into a distance with a slightly wrong
  law (a transmitter that is not a point dipole, a gain that drifts with signal level) reports
  the range ``r`` from the transmitter as ``r (r / r_ref)^k`` along the true direction
  (``range_exponent`` ``k``; 0 = exact). Lengths across the line of sight are scaled by
  ``(r / r_ref)^k``, lengths along it by ``(1 + k) (r / r_ref)^k``, so no single scale factor
  fits the whole volume;
- the unit scale factor: positions are reported in the system's units, ``true / scale``
  (O'Brien et al. measured a factor 0.94 between Flock units and centimetres);
- resolution: positions quantised to ``resolution_m``, orientations' rotation vectors to
  ``resolution_rad``;
- latency: each report shows the pose ``latency_s`` earlier (linear interpolation of positions,
  spherical linear interpolation of orientations, so that a report is one pose of one instant);
  the first ``latency_s`` are dropped (marked missing);
- dropouts: each sample is lost with probability ``dropout_rate`` (marked missing, never zero).

**Inertial/magnetic unit** (:class:`ImuConfig`, :func:`apply_imu`), as the MEMS trackers of
Fontaine et al.: per sensor a constant bias, scale error and axis misalignment drawn once;
white noise from the noise density and the sample rate (``sigma = density sqrt(rate)``);
saturation at the range; quantisation. Magnetometer: white noise, hard-iron offset, soft-iron
matrix. Gyroscope: white noise, constant bias, bias random walk.

**The magnetic field** (:func:`earth_field`, :func:`dipole_field`): the Earth field from its
strength and inclination (world ENU: x east, y north, z up) plus local disturbances from
ferromagnetic objects modelled as magnetic dipoles, ``B = mu0/(4 pi) (3 (m . u) u - m) / d^3``,
strong near the object and falling as ``d^-3``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from calibration.rotations import matrix_to_quat, matrix_to_rotvec, quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError

#: Fields that may be negative.
_SIGNED = frozenset({"range_exponent"})


def _check_non_negative(obj: object) -> None:
    for f in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, tuple | dict):
            continue
        if f.name in _SIGNED:
            if not np.isfinite(value):
                raise InputError(f"{type(obj).__name__}.{f.name} must be a finite number, got {value!r}")
            continue
        if not np.isfinite(value) or value < 0:
            raise InputError(f"{type(obj).__name__}.{f.name} must be a finite number >= 0, got {value!r}")


MU0_OVER_4PI = 1e-7  # T m / A


@dataclass(frozen=True)
class Distortion:
    """Static distortion of a magnetic tracker's field near a metal object.

    Attributes:
        center: ``(3,)`` the object's position in world, m.
        radius_m: ``rho``, the distortion's reach, m (> 0).
        position_gain_m: radial position error at the object, m.
        orientation_gain_rad: orientation error at the object, rad, about ``axis``.
        axis: ``(3,)`` the orientation error's rotation axis in world (normalised).
    """

    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius_m: float = 0.3
    position_gain_m: float = 0.0
    orientation_gain_rad: float = 0.0
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.radius_m) and self.radius_m > 0):
            raise InputError(f"distortion.radius_m must be > 0, got {self.radius_m}")
        for name in ("center", "axis"):
            v = getattr(self, name)
            if len(v) != 3 or not np.all(np.isfinite(v)):
                raise InputError(f"distortion.{name} must be 3 finite numbers, got {v}")
        if np.linalg.norm(self.axis) == 0:
            raise InputError("distortion.axis must not be zero")
        for name in ("position_gain_m", "orientation_gain_rad"):
            if not np.isfinite(getattr(self, name)):
                raise InputError(f"distortion.{name} must be finite")

    def warp(self, p_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position offsets ``(..., 3)`` m and rotation vectors ``(..., 3)`` rad at ``p_w``."""
        rel = p_w - np.asarray(self.center)
        dist = np.linalg.norm(rel, axis=-1, keepdims=True)
        weight = np.exp(-(dist**2) / (2 * self.radius_m**2))
        radial = np.divide(rel, dist, out=np.zeros_like(rel), where=dist > 0)
        axis = np.asarray(self.axis) / np.linalg.norm(self.axis)
        return self.position_gain_m * weight * radial, self.orientation_gain_rad * weight * axis


@dataclass(frozen=True)
class TrackerConfig:
    """Magnetic tracker imperfections (module docstring). Zero everywhere: an ideal tracker.

    Attributes:
        position_noise_m: position noise standard deviation per axis at ``reference_distance_m``.
        orientation_noise_rad: orientation noise (rotation-vector component std) at the same.
        reference_distance_m: ``r_ref``, m (> 0).
        position_exponent: ``n`` of the position noise's distance law (4 for a dipole field).
        orientation_exponent: ``n`` of the orientation noise's distance law (3).
        transmitter_pos: ``(3,)`` transmitter position in world, m.
        transmitter_axis: ``(3,)`` the transmitter dipole's axis in world (normalised).
        range_exponent: ``k`` of the range law: the range from the transmitter is reported as
            ``r (r / reference_distance_m)^k`` (0 = exact; may be negative).
        unit_scale: reported positions are ``true / unit_scale`` (1 = metres, 0.94 = O'Brien's
            Flock); 0 is not allowed.
        resolution_m: position quantisation step, m (0 = none).
        resolution_rad: orientation quantisation step of the rotation vector, rad (0 = none).
        latency_s: report delay, s.
        sample_rate_hz: the tracker's own measurement rate, Hz (0 = every capture frame).
        dropout_rate: probability that a sample is lost, in [0, 1).
        distortion: static distortions near metal objects.
    """

    position_noise_m: float = 0.0
    orientation_noise_rad: float = 0.0
    reference_distance_m: float = 1.0
    position_exponent: float = 4.0
    orientation_exponent: float = 3.0
    transmitter_pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    transmitter_axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    range_exponent: float = 0.0
    unit_scale: float = 1.0
    resolution_m: float = 0.0
    resolution_rad: float = 0.0
    latency_s: float = 0.0
    sample_rate_hz: float = 0.0
    dropout_rate: float = 0.0
    distortion: tuple[Distortion, ...] = ()

    def __post_init__(self) -> None:
        _check_non_negative(self)
        if self.reference_distance_m <= 0:
            raise InputError(
                f"TrackerConfig.reference_distance_m must be > 0, got {self.reference_distance_m}"
            )
        if self.unit_scale <= 0:
            raise InputError(f"TrackerConfig.unit_scale must be > 0, got {self.unit_scale}")
        if self.dropout_rate >= 1:
            raise InputError(f"TrackerConfig.dropout_rate must be in [0, 1), got {self.dropout_rate}")
        if len(self.transmitter_pos) != 3 or not np.all(np.isfinite(self.transmitter_pos)):
            raise InputError(
                f"TrackerConfig.transmitter_pos must be 3 finite numbers, got {self.transmitter_pos}"
            )
        axis = np.asarray(self.transmitter_axis, dtype=float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or not np.any(axis != 0):
            raise InputError(
                f"TrackerConfig.transmitter_axis must be 3 finite numbers, not all zero, got "
                f"{self.transmitter_axis}"
            )


def dipole_anisotropy(cos_theta: np.ndarray, exponent: float) -> np.ndarray:
    """Noise factor ``(1 + 3 cos^2)^(-n/6)`` normalised to mean 1 over the sphere.

    Args:
        cos_theta: cosine of the angle between the transmitter axis and the direction to the
            sensor.
        exponent: ``n`` of the noise's distance law (the field falls as ``r^-3``, its strength
            goes as ``sqrt(1 + 3 cos^2)``, so noise at fixed signal noise goes as
            ``|B|^(-n/3)``).
    """
    nodes, weights = np.polynomial.legendre.leggauss(64)  # mean over cos uniform in [-1, 1]
    mean = 0.5 * np.sum(weights * (1 + 3 * nodes**2) ** (-exponent / 6))
    return (1 + 3 * np.asarray(cos_theta) ** 2) ** (-exponent / 6) / mean


def _slerp_at(time_s: np.ndarray, q_wxyz: np.ndarray, at_s: np.ndarray) -> np.ndarray:
    """``(F, N, 4)`` the orientations ``(F, N, 4)`` sampled at ``time_s`` interpolated to the times
    ``at_s`` (spherical linear interpolation, clamped at the ends): the same instants as the
    positions' linear interpolation, so that a delayed report is one consistent pose."""
    if time_s.size < 2:
        return q_wxyz[np.zeros(np.size(at_s), dtype=np.int64)]
    t = np.clip(at_s, time_s[0], time_s[-1])
    i = np.clip(np.searchsorted(time_s, t, side="right") - 1, 0, time_s.size - 2)
    frac = ((t - time_s[i]) / (time_s[i + 1] - time_s[i]))[:, None, None]
    R0, R1 = quat_to_matrix(q_wxyz[i]), quat_to_matrix(q_wxyz[i + 1])
    step = matrix_to_rotvec(np.swapaxes(R0, -1, -2) @ R1)  # (F, N, 3) body-frame increment
    return matrix_to_quat(R0 @ rotvec_to_matrix(frac * step))


def _quantise(x: np.ndarray, step: float) -> np.ndarray:
    return x if step == 0 else np.round(x / step) * step


def apply_tracker(
    time_s: np.ndarray,
    p_w_s: np.ndarray,
    q_w_s: np.ndarray,
    config: TrackerConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What a magnetic tracker reports for exact sensor poses.

    Args:
        time_s: ``(F,)`` sample times, s, strictly increasing.
        p_w_s: ``(F, N, 3)`` true sensor positions in world, m.
        q_w_s: ``(F, N, 4)`` true sensor orientations (R_w_s), wxyz.
        config: the tracker.
        rng: the only source of randomness.

    Returns:
        ``(p, q, valid)``: reported positions ``(F, N, 3)`` in the system's units (m divided by
        ``unit_scale``), orientations ``(F, N, 4)``, and ``(F, N)`` bool, False where a sample
        was lost; lost samples are NaN.
    """
    f, n = p_w_s.shape[:2]
    p = np.array(p_w_s, dtype=float)
    q = np.array(q_w_s, dtype=float)
    valid = np.ones((f, n), dtype=bool)
    measured_at = np.array(time_s, dtype=float)
    if config.sample_rate_hz > 0:  # zero-order hold of the tracker's own measurements
        measured_at = np.floor(measured_at * config.sample_rate_hz + 1e-9) / config.sample_rate_hz
    measured_at = measured_at - config.latency_s
    if config.sample_rate_hz > 0 or config.latency_s > 0:
        for k in range(n):
            for a in range(3):
                p[:, k, a] = np.interp(measured_at, time_s, p_w_s[:, k, a])
        q = _slerp_at(time_s, q, measured_at)
        valid &= (measured_at >= time_s[0] - 1e-9)[:, None]
    R = None
    for dist in config.distortion:
        dp, rv = dist.warp(p)
        R = quat_to_matrix(q) if R is None else R
        R = rotvec_to_matrix(rv) @ R
        p = p + dp
    rel = p - np.asarray(config.transmitter_pos)
    r = np.linalg.norm(rel, axis=2)
    axis = np.asarray(config.transmitter_axis) / np.linalg.norm(config.transmitter_axis)
    cos = np.divide(rel @ axis, r, out=np.ones_like(r), where=r > 0)
    r = r / config.reference_distance_m
    if config.range_exponent != 0:
        p = p + rel * (np.power(r, config.range_exponent, where=r > 0, out=np.ones_like(r)) - 1)[..., None]
    if config.position_noise_m > 0:
        n_p = config.position_exponent
        sigma = config.position_noise_m * r**n_p * dipole_anisotropy(cos, n_p)
        p = p + rng.normal(size=p.shape) * sigma[..., None]
    if config.orientation_noise_rad > 0 or config.resolution_rad > 0 or R is not None:
        R = quat_to_matrix(q) if R is None else R
        if config.orientation_noise_rad > 0:
            n_o = config.orientation_exponent
            sigma = config.orientation_noise_rad * r**n_o * dipole_anisotropy(cos, n_o)
            R = rotvec_to_matrix(rng.normal(size=(f, n, 3)) * sigma[..., None]) @ R
        if config.resolution_rad > 0:
            R = rotvec_to_matrix(_quantise(matrix_to_rotvec(R), config.resolution_rad))
        q = matrix_to_quat(R)
    p = _quantise(p / config.unit_scale, config.resolution_m / config.unit_scale)
    if config.dropout_rate > 0:
        valid &= rng.random((f, n)) >= config.dropout_rate
    p[~valid] = np.nan
    q[~valid] = np.nan
    return p, q, valid


@dataclass(frozen=True)
class ImuConfig:
    """Accelerometer, magnetometer and gyroscope imperfections (module docstring).

    Attributes:
        accel_noise_density: m/s^2/sqrt(Hz) (60-230 ug/sqrt(Hz) for MEMS parts, docs/conventions.md).
        accel_bias: std of each sensor's constant bias per axis, m/s^2.
        accel_scale_error: std of each axis's relative scale error.
        accel_misalignment_rad: std of each sensor's small axis misalignment (rotation), rad.
        accel_range: saturation, m/s^2 (0 = none).
        accel_resolution: quantisation step, m/s^2 (0 = none).
        mag_noise: white noise std per axis, uT.
        mag_hard_iron: std of each sensor's constant offset per axis, uT.
        mag_soft_iron: std of each entry of the soft-iron matrix's departure from identity.
        gyro_noise_density: rad/s/sqrt(Hz).
        gyro_bias: std of each sensor's constant bias per axis, rad/s.
        gyro_bias_walk: bias random walk, rad/s/sqrt(s).
    """

    accel_noise_density: float = 0.0
    accel_bias: float = 0.0
    accel_scale_error: float = 0.0
    accel_misalignment_rad: float = 0.0
    accel_range: float = 0.0
    accel_resolution: float = 0.0
    mag_noise: float = 0.0
    mag_hard_iron: float = 0.0
    mag_soft_iron: float = 0.0
    gyro_noise_density: float = 0.0
    gyro_bias: float = 0.0
    gyro_bias_walk: float = 0.0

    def __post_init__(self) -> None:
        _check_non_negative(self)


def apply_imu(
    rate_hz: float,
    acc: np.ndarray,
    gyro: np.ndarray,
    mag: np.ndarray,
    config: ImuConfig,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What inertial/magnetic sensors report for exact readings.

    Args:
        rate_hz: sample rate, Hz.
        acc: ``(F, N, 3)`` true specific force in the sensor frames, m/s^2.
        gyro: ``(F, N, 3)`` true angular velocity, rad/s.
        mag: ``(F, N, 3)`` true magnetic field, uT.
        config: the sensors.
        rng: the only source of randomness.

    Returns:
        ``(acc, gyro, mag)`` as reported, same shapes and units.
    """
    if not rate_hz > 0:
        raise InputError(f"rate must be > 0 Hz, got {rate_hz}")
    f, n = acc.shape[:2]
    a = np.array(acc, dtype=float)
    if config.accel_scale_error > 0 or config.accel_misalignment_rad > 0:
        scale = 1.0 + config.accel_scale_error * rng.normal(size=(n, 3))
        mis = rotvec_to_matrix(config.accel_misalignment_rad * rng.normal(size=(n, 3)))
        a = np.einsum("nij,fnj->fni", mis * scale[:, :, None], a)
    if config.accel_bias > 0:
        a = a + config.accel_bias * rng.normal(size=(1, n, 3))
    if config.accel_noise_density > 0:
        a = a + config.accel_noise_density * np.sqrt(rate_hz) * rng.normal(size=a.shape)
    if config.accel_range > 0:
        a = np.clip(a, -config.accel_range, config.accel_range)
    a = _quantise(a, config.accel_resolution)
    m = np.array(mag, dtype=float)
    if config.mag_soft_iron > 0:
        soft = np.eye(3) + config.mag_soft_iron * rng.normal(size=(n, 3, 3))
        m = np.einsum("nij,fnj->fni", soft, m)
    if config.mag_hard_iron > 0:
        m = m + config.mag_hard_iron * rng.normal(size=(1, n, 3))
    if config.mag_noise > 0:
        m = m + config.mag_noise * rng.normal(size=m.shape)
    g = np.array(gyro, dtype=float)
    if config.gyro_bias > 0:
        g = g + config.gyro_bias * rng.normal(size=(1, n, 3))
    if config.gyro_bias_walk > 0:
        steps = config.gyro_bias_walk / np.sqrt(rate_hz) * rng.normal(size=(f, n, 3))
        g = g + np.cumsum(steps, axis=0)
    if config.gyro_noise_density > 0:
        g = g + config.gyro_noise_density * np.sqrt(rate_hz) * rng.normal(size=g.shape)
    return a, g, m


def earth_field(strength_ut: float, inclination_deg: float) -> np.ndarray:
    """The Earth field in world ENU (x east, y north, z up), uT: ``(3,)``.

    Args:
        strength_ut: total intensity, uT (25-65 on Earth).
        inclination_deg: dip below the horizontal, degrees (positive: field points down, as in
            the northern hemisphere).
    """
    inc = np.deg2rad(inclination_deg)
    return strength_ut * np.array([0.0, np.cos(inc), -np.sin(inc)])


def dipole_field(p_w: np.ndarray, position: np.ndarray, moment_am2: np.ndarray) -> np.ndarray:
    """Field of a magnetic dipole at points ``p_w`` ``(..., 3)`` m, in uT, world frame.

    ``B = mu0/(4 pi) (3 (m . u) u - m) / d^3`` with ``u`` the unit vector from the dipole to
    the point and ``d`` the distance; moment in A m^2.
    """
    rel = p_w - np.asarray(position)
    d = np.linalg.norm(rel, axis=-1, keepdims=True)
    u = rel / d
    m = np.asarray(moment_am2)
    b_tesla = MU0_OVER_4PI * (3 * np.sum(u * m, axis=-1, keepdims=True) * u - m) / d**3
    return b_tesla * 1e6
