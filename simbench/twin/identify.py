"""What a real IMU recording shows about its sensor, given the optical pose of its housing.

Every function takes arrays in the sensor frame (``(F, 3)``: m/s^2, rad/s, uT) or the world
frame (ENU: x east, y north, z up; ``R_w_s`` rotates sensor to world) and returns plain values;
:func:`simbench.twin.run.twin` calls them in this order, each on what the earlier ones found:

1. :func:`still_phases`: where the sensor rests, from the gyroscope's own noise.
2. :func:`time_offset`: the IMU's clock against the optical one, by cross-correlating the real
   gyroscope with the gyroscope of the optical orientation (sub-sample: a parabola through the
   peak), within :data:`MAX_OFFSET_S`.
3. :func:`bias_and_noise`: each axis's constant bias (the mean of real less ideal over the still
   samples) and white-noise density (the standard deviation about each still phase's own mean,
   over ``sqrt(rate)``), for the gyroscope, the accelerometer and the magnetometer.
4. :func:`misalignment`: the small rotation ``C`` from the optical body frame to the IMU's axes
   (``v_imu = C v_opt``), the least-squares rotation between the ideal and the real (less its
   bias) angular velocities in motion (Wahba's problem, solved by the SVD: Kabsch).
5. :func:`magnetometer`: hard iron ``h``, soft iron ``A`` and the local field ``b`` (world) of
   ``m = A R^T b + h``: with the orientation known the model is bilinear in ``(A, b)`` but
   ``m = sum_i P_i r_i + h`` (``r_i`` the i-th row of ``R_w_s``, ``P_i = b_i A``) is linear in
   ``(P, h)``; ``P`` is then factorised into ``A`` and ``b`` by its best rank-1 approximation
   (SVD of the ``9 x 3`` matrix ``[vec P_1, vec P_2, vec P_3] = vec(A) b^T``), ``A`` scaled to
   ``det A = 1`` (only ``A b`` is observable: the overall gain goes into ``|b|``). Fitted on
   every usable sample, robustly: samples whose residual exceeds :data:`OUTLIER_FACTOR` times the
   inliers' median residual are left out and the fit repeated until the set stops changing (a
   disturbed field: a magnet near the path); the fraction left out is reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft
from scipy.interpolate import CubicSpline
from scipy.optimize import minimize_scalar

from simbench.errors import InputError

#: Still phases: the gyroscope's moving standard deviation (norm over the axes) over windows of
#: this length, s ...
STILL_WINDOW_S = 0.25
#: ... below this multiple of its 5th percentile (the noise floor: BROAD's trials rest 40 % of
#: the time; their floors are 0.0022-0.0032 rad/s, motion is above 0.03) ...
STILL_FACTOR = 2.0
#: ... for at least this long, s.
STILL_MIN_S = 1.0
#: The time offset is searched within +- this, s.
MAX_OFFSET_S = 0.25
#: A magnetometer sample is an outlier when its residual exceeds this multiple of the inliers'
#: median residual (for Gaussian residuals the norm's 99.9th percentile is 2.6 medians).
OUTLIER_FACTOR = 3.0
#: At most this many robust refits.
MAX_REFITS = 20
#: The field's direction in the sensor frame must spread at least this much (standard deviation
#: of the unit vector) along each principal axis for hard iron and field to be told apart:
#: BROAD's rotation trials 0.16-0.36, its translation trials 0.004-0.05 (trial 10's field came
#: out reversed, its hard iron 100 uT).
DIRECTION_SPREAD_MIN = 0.1


def _vectors(x: np.ndarray, what: str, n: int | None = None) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[1] != 3 or (n is not None and x.shape[0] != n):
        expected = f"({n if n is not None else 'F'}, 3)"
        raise InputError(f"expected {what} of shape {expected}, got {x.shape}")
    return x


def _mask(x: np.ndarray | None, n: int, what: str) -> np.ndarray:
    if x is None:
        return np.ones(n, dtype=bool)
    x = np.asarray(x)
    if x.shape != (n,):
        raise InputError(f"expected {what} of shape ({n},), got {x.shape}")
    return x.astype(bool)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the runs of True in a ``(F,)`` mask (``stop`` exclusive)."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def moving_std(x: np.ndarray, window: int) -> np.ndarray:
    """``(F,)`` the norm over the axes of ``x``'s ``(F, 3)`` standard deviation over a centred
    window of ``window`` frames (shorter at the ends)."""
    x = _vectors(x, "x")
    c = np.cumsum(np.vstack([np.zeros((1, 3)), x - x.mean(axis=0)]), axis=0)
    c2 = np.cumsum(np.vstack([np.zeros((1, 3)), (x - x.mean(axis=0)) ** 2]), axis=0)
    f = x.shape[0]
    lo = np.clip(np.arange(f) - window // 2, 0, f)
    hi = np.clip(np.arange(f) + window // 2 + 1, 0, f)
    count = (hi - lo)[:, None]
    mean = (c[hi] - c[lo]) / count
    var = np.clip((c2[hi] - c2[lo]) / count - mean**2, 0.0, None)
    return np.sqrt(var.sum(axis=1))


@dataclass(frozen=True)
class StillPhases:
    """Where the sensor rests.

    Attributes:
        mask: ``(F,)`` True in a still phase.
        threshold_rad_s: the moving standard deviation below which a sample is still, rad/s.
        floor_rad_s: its noise floor (5th percentile), rad/s.
        runs: ``[(start, stop), ...]`` frames of each still phase.
    """

    mask: np.ndarray
    threshold_rad_s: float
    floor_rad_s: float
    runs: list[tuple[int, int]]


def still_phases(gyro: np.ndarray, rate_hz: float, usable: np.ndarray | None = None) -> StillPhases:
    """The still phases of a recording, from the gyroscope's own noise (module docstring, and
    :data:`STILL_WINDOW_S`, :data:`STILL_FACTOR`, :data:`STILL_MIN_S`): bias-free, as a
    standard deviation.

    Args:
        gyro: ``(F, 3)`` rad/s. rate_hz: Hz.
        usable: ``(F,)`` samples that may count (default all).
    """
    gyro = _vectors(gyro, "gyro")
    f = gyro.shape[0]
    ok = _mask(usable, f, "usable") & np.isfinite(gyro).all(axis=1)
    window = max(3, round(STILL_WINDOW_S * rate_hz) | 1)
    s = moving_std(np.where(ok[:, None], gyro, 0.0), window)
    floor = float(np.percentile(s[ok], 5)) if ok.any() else np.nan
    threshold = STILL_FACTOR * floor
    quiet = ok & (s < threshold)
    # a window that reaches a sample not usable is not known to be quiet
    bad = np.convolve((~ok).astype(float), np.ones(window), mode="same") > 0.5
    quiet &= ~bad
    min_len = int(np.ceil(STILL_MIN_S * rate_hz))
    kept = [(a, b) for a, b in runs(quiet) if b - a >= min_len]
    mask = np.zeros(f, dtype=bool)
    for a, b in kept:
        mask[a:b] = True
    return StillPhases(mask, float(threshold), floor, kept)


def time_offset(
    real: np.ndarray,
    ideal: np.ndarray,
    rate_hz: float,
    use: np.ndarray | None = None,
    max_offset_s: float = MAX_OFFSET_S,
) -> tuple[float, float]:
    """The delay of ``real`` behind ``ideal``: ``real(t) ~ ideal(t - offset)``.

    The normalised cross-correlation of the two (each axis's mean over the samples used removed,
    the axes summed) at every whole lag within ``max_offset_s`` (by FFT), its peak refined between the whole
    lags either side with the ideal signal interpolated by a cubic spline. The real samples are
    those of ``use`` at every lag, their partners any finite ideal samples.

    Args:
        real, ideal: ``(F, 3)`` the same quantity (e.g. the real gyroscope and the optical one).
        rate_hz: Hz.
        use: ``(F,)`` the real samples to correlate.
        max_offset_s: the search range, s.

    Returns:
        ``(offset_s, peak)``: positive when the real signal lags; the correlation at the peak.

    Raises:
        InputError: the peak lies at the edge of the range (the offset is not within it).
    """
    real = _vectors(real, "real")
    ideal = _vectors(ideal, "ideal", real.shape[0])
    f = real.shape[0]
    have = np.isfinite(ideal).all(axis=1)
    use = _mask(use, f, "use") & np.isfinite(real).all(axis=1) & have
    if use.sum() < 2:
        raise InputError(f"expected at least 2 samples to correlate, got {int(use.sum())}")
    # the real samples are the same at every lag (only theirs are used); their partners are any
    # ideal samples: masking both would drop pairs at the edges of ``use`` unevenly and bias the peak
    x = np.where(use[:, None], real - real[use].mean(axis=0), 0.0)
    y = np.where(have[:, None], ideal - ideal[use].mean(axis=0), 0.0)
    lmax = max(1, round(max_offset_s * rate_hz))
    if f <= 2 * lmax + 1:
        raise InputError(f"{f} samples are too few to search a time offset of +-{max_offset_s:g} s")
    lags = np.arange(-lmax, lmax + 1)
    xx = float(np.sum(x * x))
    # real at k against ideal at k - lag, summed over k: one FFT correlation for every lag
    num = _correlation(x, y, lags).sum(axis=1)
    yy = _correlation(use[:, None].astype(float), (y * y).sum(axis=1, keepdims=True), lags)[:, 0]
    den = np.sqrt(xx * np.clip(yy, 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    k = int(np.argmax(c))
    if k in (0, lags.size - 1):
        raise InputError(
            f"the cross-correlation of the real and the optical gyroscope peaks at the edge of the "
            f"+-{max_offset_s:g} s searched: the clocks are further apart"
        )
    lag, peak = _refined_peak(x, y, use, have, xx, float(lags[k]))
    return lag / rate_hz, peak


def _correlation(a: np.ndarray, b: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """``(lags, k)`` ``sum_t a[t] b[t - lag]`` per column of ``a`` and ``b`` (``(F, k)``, zero where
    not used) at each lag (``|lag| < F``), by FFT (zero-padded: no wrap-around)."""
    f = a.shape[0]
    size = next_fast_len(f + int(np.abs(lags).max()) + 1, real=True)
    r = irfft(rfft(a, size, axis=0) * np.conj(rfft(b, size, axis=0)), size, axis=0)
    return r[lags % size]


def _refined_peak(
    x: np.ndarray, y: np.ndarray, use: np.ndarray, have: np.ndarray, xx: float, lag: float
) -> tuple[float, float]:
    """The correlation's maximum between the whole lags either side of ``lag`` (samples): the ideal
    signal ``y`` (``(F, 3)``) interpolated by a cubic spline at every fractional lag, against
    ``x``. A parabola through three whole lags is off by up to 0.05 samples when the finite
    recording's correlation is not symmetric about its peak (slow content: a few cycles in the
    record); the spline's own error on a signal sampled 30 times its highest frequency is 1e-3 of
    a sample. Partners are samples whose four spline neighbours are all ideal samples."""
    f = x.shape[0]
    spline = CubicSpline(np.arange(f), y, axis=0)
    idx = np.arange(f)
    pad = np.concatenate([[False], have, [False, False]])  # have[i] at pad[i + 1]

    def corr(s: float) -> float:
        pos = idx - s
        lo = np.floor(pos).astype(np.int64)
        ok = use & (lo >= 1) & (lo <= f - 3)
        lo_ok = np.clip(lo, -1, f)
        ok &= pad[lo_ok] & pad[lo_ok + 1] & pad[lo_ok + 2] & pad[np.minimum(lo_ok + 3, f + 2)]
        b = spline(pos[ok])
        den = np.sqrt(xx * float(np.sum(b * b)))
        return float(np.sum(x[ok] * b) / den) if den > 0 else 0.0

    best = minimize_scalar(
        lambda s: -corr(s), bounds=(lag - 1.0, lag + 1.0), method="bounded", options={"xatol": 1e-4}
    )
    return float(best.x), corr(float(best.x))


@dataclass(frozen=True)
class BiasNoise:
    """A sensor's constant bias and white noise, per axis (its own unit: m/s^2, rad/s, uT).

    Attributes:
        bias: ``(3,)`` mean of real less ideal over the still samples.
        noise_std: ``(3,)`` standard deviation per sample about each still phase's mean.
        noise_density: ``(3,)`` ``noise_std / sqrt(rate)``: per sqrt(Hz) (as
            :class:`simbench.sim.sensor_models.ImuConfig` takes it).
        samples: still samples used.
    """

    bias: np.ndarray
    noise_std: np.ndarray
    noise_density: np.ndarray
    samples: int


def bias_and_noise(real: np.ndarray, ideal: np.ndarray, still: StillPhases, rate_hz: float) -> BiasNoise:
    """Bias and noise of a sensor from the still phases (module docstring).

    Args:
        real, ideal: ``(F, 3)`` the real reading and the ideal one from the optical pose.
        still: :func:`still_phases`.
        rate_hz: Hz.

    Raises:
        InputError: no still phase.
    """
    real = _vectors(real, "real")
    ideal = _vectors(ideal, "ideal", real.shape[0])
    if not still.runs:
        raise InputError(
            f"no still phase of at least {STILL_MIN_S:g} s: biases and noise are identified where the "
            "sensor rests"
        )
    d = real - ideal
    pieces = [real[a:b] - real[a:b].mean(axis=0) for a, b in still.runs]
    dev = np.vstack(pieces)
    dof = dev.shape[0] - len(pieces)
    std = np.sqrt(np.sum(dev**2, axis=0) / max(dof, 1))
    bias = d[still.mask].mean(axis=0)
    return BiasNoise(bias, std, std / np.sqrt(rate_hz), int(still.mask.sum()))


def kabsch(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The rotation ``C`` ``(3, 3)`` minimising ``sum |y_k - C x_k|^2`` over rows ``(K, 3)``."""
    h = x.T @ y
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return vt.T @ np.diag([1.0, 1.0, d]) @ u.T


def misalignment(real: np.ndarray, ideal: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """The rotation ``C`` from the optical body frame to the IMU's axes, ``real ~ C ideal``
    (Kabsch), over the samples ``use``.

    Args:
        real: ``(F, 3)`` the gyroscope less its bias, rad/s. ideal: ``(F, 3)`` the optical one.

    Returns:
        ``(3, 3)`` rotation matrix.

    Raises:
        InputError: too few samples, or rotation about less than two axes (not determined).
    """
    real = _vectors(real, "real")
    ideal = _vectors(ideal, "ideal", real.shape[0])
    use = _mask(use, real.shape[0], "use") & np.isfinite(real).all(axis=1) & np.isfinite(ideal).all(axis=1)
    x, y = ideal[use], real[use]
    if x.shape[0] < 3:
        raise InputError(f"expected at least 3 samples in motion to fit the misalignment, got {x.shape[0]}")
    s = np.linalg.svd(x, compute_uv=False)
    if s[1] <= 1e-3 * s[0]:
        raise InputError("the recording turns about one axis only: the axis misalignment is not determined")
    return kabsch(x, y)


def rotation_angle_deg(C: np.ndarray) -> float:
    """The angle of a rotation matrix, degrees."""
    return float(np.rad2deg(np.arccos(np.clip((np.trace(C) - 1) / 2, -1.0, 1.0))))


#: The symmetric, traceless ``3 x 3`` matrices a field gradient is made of (a static field in
#: air is free of curl and divergence): 5 parameters.
GRADIENT_BASIS = np.array(
    [
        [[1, 0, 0], [0, -1, 0], [0, 0, 0]],
        [[0, 0, 0], [0, 1, 0], [0, 0, -1]],
        [[0, 1, 0], [1, 0, 0], [0, 0, 0]],
        [[0, 0, 1], [0, 0, 0], [1, 0, 0]],
        [[0, 0, 0], [0, 0, 1], [0, 1, 0]],
    ],
    dtype=float,
)


@dataclass(frozen=True)
class MagnetometerFit:
    """``m = A R_w_s^T (b + G (p - p0)) + h`` (module docstring).

    Attributes:
        soft_iron: ``(3, 3)`` ``A``, ``det A = 1``.
        hard_iron_ut: ``(3,)`` ``h``, uT.
        field_w_ut: ``(3,)`` ``b``, the local field in world (ENU) at ``p0``, uT.
        gradient_ut_per_m: ``(3, 3)`` ``G``, symmetric and traceless, uT/m (zeros: not fitted).
        origin_m: ``(3,)`` ``p0``, m (the mean position of the samples used).
        inliers: ``(F,)`` the samples the final fit used.
        excluded_fraction: share of the usable samples left out as disturbed.
        rms_ut: rms residual norm over the inliers, uT.
        rank1_ratio: the linear fit's second over first singular value of ``[vec P_i]`` (0 for the
            model exact).
        refits: robust refits made.
        direction_spread: ``(3,)`` the standard deviations of the field's direction in the sensor
            frame (``R^T b / |b|``) over the inliers along its principal axes, largest first: where
            the smallest is below :data:`DIRECTION_SPREAD_MIN` the orientations span too little to
            tell the hard iron from the field (:attr:`determined`; the readings are predicted all
            the same).
    """

    soft_iron: np.ndarray
    hard_iron_ut: np.ndarray
    field_w_ut: np.ndarray
    gradient_ut_per_m: np.ndarray
    origin_m: np.ndarray
    inliers: np.ndarray
    excluded_fraction: float
    rms_ut: float
    rank1_ratio: float
    refits: int
    direction_spread: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))

    @property
    def determined(self) -> bool:
        """The hard iron, soft iron and field are each determined (:attr:`direction_spread`)."""
        return bool(self.direction_spread.min() >= DIRECTION_SPREAD_MIN)

    def field_at(self, p_w: np.ndarray) -> np.ndarray:
        """``(F, 3)`` the modelled world field at positions ``(F, 3)`` m, uT."""
        return self.field_w_ut + (np.asarray(p_w, dtype=float) - self.origin_m) @ self.gradient_ut_per_m.T

    def predict(self, unit: np.ndarray, p_w: np.ndarray | None = None) -> np.ndarray:
        """``(F, 3)`` the modelled readings: ``unit`` ``(F, 3, 3)`` the ideal readings of a unit field
        along each world axis (last index), ``p_w`` ``(F, 3)`` the positions (``None``: the
        field at ``origin_m`` everywhere)."""
        b = self.field_w_ut[None] if p_w is None else self.field_at(p_w)
        ideal = np.einsum("fij,fj->fi", unit, np.broadcast_to(b, (unit.shape[0], 3)))
        return ideal @ self.soft_iron.T + self.hard_iron_ut

    @property
    def strength_ut(self) -> float:
        return float(np.linalg.norm(self.field_w_ut))

    @property
    def inclination_deg(self) -> float:
        """The field's dip below the horizontal, degrees (positive: pointing down)."""
        b = self.field_w_ut
        return float(np.rad2deg(np.arctan2(-b[2], np.hypot(b[0], b[1]))))

    @property
    def declination_deg(self) -> float:
        """The horizontal field's angle from world +y (north) towards +x (east), degrees."""
        b = self.field_w_ut
        return float(np.rad2deg(np.arctan2(b[0], b[1])))


def _field_features(unit: np.ndarray, dp: np.ndarray | None) -> np.ndarray:
    """``(F, 3, K)``: the readings of each field parameter at 1 (``b``'s three, then the
    gradient's five), before the soft iron."""
    feats = [unit]
    if dp is not None:
        # G dp for each basis matrix, seen through the unit readings
        g = np.einsum("kjl,fl->fjk", GRADIENT_BASIS, dp)  # (F, 3 world, 5)
        feats.append(np.einsum("fij,fjk->fik", unit, g))
    return np.concatenate(feats, axis=2)


def _rank1(
    mag: np.ndarray, unit: np.ndarray, use: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(A, h, b, ratio)``: the linear least squares ``m = sum_i P_i r_i + h`` and its rank-1
    factorisation (module docstring), ``A`` with ``det A = 1``."""
    n = mag.shape[0]
    # unit[:, :, j] = R^T e_j = r_j, the j-th row of R_w_s
    X = np.concatenate([unit.transpose(0, 2, 1).reshape(n, 9), np.ones((n, 1))], axis=1)
    M, *_ = np.linalg.lstsq(X[use], mag[use], rcond=None)  # m^T = X_row M, (10, 3)
    K = np.stack([M[3 * i : 3 * i + 3, :].T.reshape(9) for i in range(3)], axis=1)  # vec(P_i) = b_i vec(A)
    u, s, vt = np.linalg.svd(K, full_matrices=False)
    A0 = u[:, 0].reshape(3, 3)
    det = float(np.linalg.det(A0))
    if not abs(det) > 1e-12:
        raise InputError(
            "the magnetometer's soft-iron matrix came out singular: the readings do not follow the field"
        )
    c = float(np.cbrt(1.0 / det))
    return c * A0, M[9], s[0] * vt[0] / c, float(s[1] / s[0])


@dataclass(frozen=True)
class _Moments:
    """The sums over the samples that the bilinear fit's cost and normal equations need, so that
    each step of the fit costs nothing in the number of samples: with ``F`` ``(n, 3, K)`` the
    features and ``y`` ``(n, 3)`` the readings, ``n``, ``Syy = sum |y|^2``, ``Sy = sum y``,
    ``SF = sum F`` ``(3, K)``, ``SyF[i, j, k] = sum y_i F_jk``, ``SFF[i, k, j, l] = sum F_ik F_jl``."""

    n: int
    Syy: float
    Sy: np.ndarray
    SF: np.ndarray
    SyF: np.ndarray
    SFF: np.ndarray

    @classmethod
    def of(cls, y: np.ndarray, F: np.ndarray) -> _Moments:
        n, _, k = F.shape
        flat = F.reshape(n, 3 * k)
        return cls(
            n,
            float(np.sum(y * y)),
            y.sum(axis=0),
            flat.sum(axis=0).reshape(3, k),
            (y.T @ flat).reshape(3, 3, k),
            (flat.T @ flat).reshape(3, k, 3, k),
        )

    def cost(self, A: np.ndarray, h: np.ndarray, theta: np.ndarray) -> float:
        """``sum |y - A F theta - h|^2``."""
        Suu = np.einsum("ikjl,k,l->ij", self.SFF, theta, theta)
        Su = self.SF @ theta
        Syu = self.SyF @ theta
        return float(
            self.Syy
            - 2 * np.sum(A * Syu)
            - 2 * h @ self.Sy
            + np.sum((A.T @ A) * Suu)
            + 2 * h @ A @ Su
            + self.n * h @ h
        )

    def normal(self, A: np.ndarray, h: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(J^T J, J^T r)`` of the residual ``r = y - A F theta - h`` in the parameters
        ``(vec A row by row, h, theta)``."""
        k = theta.size
        Suu = np.einsum("ikjl,k,l->ij", self.SFF, theta, theta)
        Su = self.SF @ theta
        Syu = self.SyF @ theta
        AtA = A.T @ A
        p = 12 + k
        JtJ = np.zeros((p, p))
        JtJ[:9, :9] = np.kron(np.eye(3), Suu)
        JtJ[9:12, 9:12] = self.n * np.eye(3)
        JtJ[:9, 9:12] = np.kron(np.eye(3), Su[:, None])
        JtJ[12:, 12:] = np.einsum("jm,jkml->kl", AtA, self.SFF)
        # d pred_i / d A_ab = delta_ia u_b; d pred_i / d theta_k = (A F)_ik
        JtJ[:9, 12:] = np.einsum("aj,bljk,l->abk", A, self.SFF, theta).reshape(9, k)
        JtJ[9:12, 12:] = A @ self.SF
        JtJ[9:12, :9] = JtJ[:9, 9:12].T
        JtJ[12:, :9] = JtJ[:9, 12:].T
        JtJ[12:, 9:12] = JtJ[9:12, 12:].T
        g_A = Syu - A @ Suu - np.outer(h, Su)
        g_h = self.Sy - A @ Su - self.n * h
        g_t = (
            np.einsum("ij,ijk->k", A, self.SyF)
            - np.einsum("jm,jlmk,l->k", AtA, self.SFF, theta)
            - (h @ A) @ self.SF
        )
        return JtJ, np.concatenate([g_A.reshape(9), g_h, g_t])


def _least_squares(
    mag: np.ndarray, feats: np.ndarray, use: np.ndarray, A: np.ndarray, h: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least squares of the bilinear ``m = A (feats theta) + h`` by Levenberg-Marquardt from
    the given start, on the samples' sums (:class:`_Moments`), ``A`` scaled to ``det A = 1`` at
    the end (the scale is a free direction of the model: the damping keeps the steps off it)."""
    mom = _Moments.of(mag[use], feats[use])
    x = np.concatenate([A.reshape(9), h, theta])

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return x[:9].reshape(3, 3), x[9:12], x[12:]

    cost = mom.cost(*unpack(x))
    lam = 1e-3
    for _ in range(LM_ITERATIONS):
        JtJ, Jtr = mom.normal(*unpack(x))
        d = np.maximum(np.diag(JtJ), 1e-12 * max(float(np.max(np.diag(JtJ))), 1e-300))
        while True:
            step = np.linalg.solve(JtJ + lam * np.diag(d), Jtr)
            new = mom.cost(*unpack(x + step))
            if new < cost or lam > 1e12:
                break
            lam *= 4.0
        if not new < cost:
            break
        x = x + step
        done = cost - new <= 1e-12 * max(cost, 1e-300)
        cost, lam = new, max(lam / 3.0, 1e-12)
        if done:
            break
    A, h, theta = unpack(x)
    c = float(np.cbrt(1.0 / np.linalg.det(A)))
    return c * A, h, theta / c


#: At most this many Levenberg-Marquardt steps.
LM_ITERATIONS = 1000


def magnetometer(
    mag: np.ndarray,
    unit: np.ndarray,
    usable: np.ndarray | None = None,
    p_w: np.ndarray | None = None,
) -> MagnetometerFit:
    """Hard and soft iron and the local field, robustly (module docstring).

    The linear fit and its rank-1 factorisation start a Levenberg-Marquardt least squares of the
    bilinear model, which gives the least-squares ``(A, b, h)``: the factorisation alone is not,
    where the orientations span little (a trial that translates more than it turns: BROAD's
    trial 10, magnetometer R^2 -17 from the factorisation, 0.89 from the least squares). With
    ``p_w``, a field gradient ``G`` too (symmetric and traceless: :data:`GRADIENT_BASIS`).

    Args:
        mag: ``(F, 3)`` the real readings, uT.
        unit: ``(F, 3, 3)`` the ideal readings of a unit field along each world axis (last
            index): ``R_w_s^T e_j``, with whatever time offset and misalignment the IMU has.
        usable: ``(F,)`` samples that may be used (e.g. not near an optical gap).
        p_w: ``(F, 3)`` the sensor's positions, m, to fit a gradient; ``None``: a uniform field.

    Raises:
        InputError: shapes, or too few samples to fit.
    """
    mag = _vectors(mag, "mag")
    n = mag.shape[0]
    unit = np.asarray(unit, dtype=float)
    if unit.shape != (n, 3, 3):
        raise InputError(f"expected unit of shape ({n}, 3, 3), got {unit.shape}")
    usable = _mask(usable, n, "usable") & np.isfinite(mag).all(axis=1) & np.isfinite(unit).all(axis=(1, 2))
    if p_w is not None:
        p_w = _vectors(p_w, "p_w", n)
        usable &= np.isfinite(p_w).all(axis=1)
    if usable.sum() < 100:
        raise InputError(f"expected at least 100 usable magnetometer samples, got {int(usable.sum())}")
    origin = p_w[usable].mean(axis=0) if p_w is not None else np.zeros(3)
    dp = None if p_w is None else p_w - origin
    feats = _field_features(unit, dp)
    inliers = usable.copy()
    refits = 0
    while True:
        A, h, b, ratio = _rank1(mag, unit, inliers)
        theta0 = np.concatenate([b, np.zeros(feats.shape[2] - 3)])
        A, h, theta = _least_squares(mag, feats, inliers, A, h, theta0)
        G = np.einsum("k,kij->ij", theta[3:], GRADIENT_BASIS) if p_w is not None else np.zeros((3, 3))
        fit = MagnetometerFit(A, h, theta[:3], G, origin, inliers, 0.0, 0.0, ratio, refits)
        r = np.linalg.norm(mag - fit.predict(unit, p_w), axis=1)
        limit = OUTLIER_FACTOR * np.median(r[inliers])
        new = usable & (r <= limit)
        if np.array_equal(new, inliers) or refits >= MAX_REFITS:
            break
        inliers = new
        refits += 1
    rms = float(np.sqrt(np.mean(r[inliers] ** 2)))
    excluded = float(1.0 - inliers.sum() / usable.sum())
    u = np.einsum("fij,j->fi", unit[inliers], theta[:3] / np.linalg.norm(theta[:3]))
    spread = np.linalg.svd(u - u.mean(axis=0), compute_uv=False) / np.sqrt(u.shape[0])
    return MagnetometerFit(A, h, theta[:3], G, origin, inliers, excluded, rms, ratio, refits, spread)


def lever_arm(residual: np.ndarray, basis: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """The accelerometer's position ``r`` in the body frame relative to the tracked point, m: the
    least squares of ``residual ~ basis r`` over the samples ``use``.

    Args:
        residual: ``(F, 3)`` the real accelerometer less its bias and the ideal reading at the
            tracked point, m/s^2.
        basis: ``(F, 3, 3)`` what a lever arm of 1 m along each body axis (last index) adds to
            the ideal reading (``alpha x e_j + omega x (omega x e_j)``), m/s^2.

    Raises:
        InputError: shapes, or too few samples.
    """
    residual = _vectors(residual, "residual")
    n = residual.shape[0]
    basis = np.asarray(basis, dtype=float)
    if basis.shape != (n, 3, 3):
        raise InputError(f"expected basis of shape ({n}, 3, 3), got {basis.shape}")
    use = _mask(use, n, "use") & np.isfinite(residual).all(axis=1) & np.isfinite(basis).all(axis=(1, 2))
    if use.sum() < 3:
        raise InputError(f"expected at least 3 samples in motion to fit the lever arm, got {int(use.sum())}")
    r, *_ = np.linalg.lstsq(basis[use].reshape(-1, 3), residual[use].reshape(-1), rcond=None)
    return r
