"""Sourceless orientation from accelerometer and magnetometer (Fontaine et al.), and references.

A tracker of three accelerometers and three magnetometers, no gyroscope, no source: at every
sample the accelerometer's specific force points up (when the sensor does not accelerate) and the
magnetometer sees the Earth field; the orientation ``R_w_s`` (sensor to world) is the rotation
that best carries those two measured vectors onto the world's up and field directions.

**Frames.** World ENU by default (x east, y north, z up; the field points north and down by its
inclination ``I``: ``b_w = (0, cos I, -sin I)``), or NED (x north, y east, z down). Every result
says its frame. Quaternions are scalar-first ``(w, x, y, z)`` of ``R_w_s``. All functions are
vectorised over any leading ``(...)`` axes (frames, sensors).

**Estimators.**

- :func:`triad`: TRIAD, the classic closed form; the accelerometer is the primary vector (it
  defines "up" exactly), the magnetometer only the heading.
- :func:`wahba`: the optimal weighted solution of Wahba's problem, ``min sum_i w_i |v_wi -
  R v_si|^2``. For two observations it has a closed form: the optimal rotation maps ``v_s1 x
  v_s2`` onto ``v_w1 x v_w2``, which leaves one angle about that axis, solved exactly
  (``method="closed"``, the default); ``method="svd"`` is the general SVD solution (Markley), kept
  as the reference.
- :func:`fontaine`: Fontaine et al.'s estimator: minimise the quadratic error between the
  measured (normalised) accelerometer and magnetometer vectors and those modelled from gravity
  and the Earth field, ``E(R) = w_a |a_s - R^T u_w|^2 + w_m |m_s - R^T b_w|^2``, iteratively. The
  paper iterates on Euler angles; here Gauss-Newton updates a rotation vector on the current
  estimate, ``R <- R exp([d]x)``, which has no gimbal lock (Euler-angle Jacobians are singular at
  +-90 degrees pitch, where a tracker on a limb spends real time). Started from TRIAD; with
  normalised vectors its minimum is the weighted Wahba solution, reached in 2-4 iterations.
- **Disturbance weighting** (Fontaine 2.1.2, :class:`Weighting`): the accelerometer is
  down-weighted as ``|a|`` departs from ``g`` (the sensor accelerates), the magnetometer as
  ``|m|`` departs from the field's strength or its dip from the inclination (a ferromagnetic
  disturbance): ``w = 1 / (1 + (x / tau)^2)`` for each departure ``x``, tolerances ``tau``
  configurable. Both :func:`wahba` and :func:`fontaine` take the weights.
- :func:`mahony`: a gyro-aided reference, Mahony et al.'s explicit complementary filter (2008),
  so users can see how far gyro-free estimation is from an established fusion filter. It runs
  frame by frame (vectorised over sensors): a reference, not a hot path.
- :func:`smooth_vectors`: optional temporal smoothing of the measured vectors by a zero-phase
  (forward-backward) Butterworth low-pass: no lag behind a real rotation. In :func:`fontaine`
  (``temporal_hz``) the smoothing is weighted by the disturbance weights (normalised
  convolution), which is where the weighting pays: a sample whose accelerometer sees the body's
  acceleration takes "up" from its calmer neighbours.

Samples that cannot be estimated -- NaN input, a zero or near-zero vector, accelerometer and
magnetometer (nearly) parallel, or masked out -- come back as NaN, never dropped, so outputs stay
aligned with inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.rotations import orthonormal_to_quat, quat_to_matrix

#: Standard gravity, m/s^2 (MuJoCo's default is 9.81).
GRAVITY = 9.81

#: Vectors shorter than this fraction of their reference length are treated as missing.
MIN_NORM_FRACTION = 1e-3

#: Accelerometer and magnetometer directions closer than this (sin of the angle) are collinear.
MIN_SIN_ANGLE = 1e-3

FRAMES = ("enu", "ned")

#: NED from ENU: x_ned = y_enu (north), y_ned = x_enu (east), z_ned = -z_enu (down).
R_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class Reference:
    """The world's reference vectors in one frame.

    Attributes:
        frame: ``"enu"`` or ``"ned"``.
        up_w: ``(3,)`` unit vector up (what a resting accelerometer's specific force points to).
        field_w: ``(3,)`` the Earth field, uT.
        gravity: ``g``, m/s^2.
    """

    frame: str
    up_w: np.ndarray
    field_w: np.ndarray
    gravity: float

    @property
    def inclination(self) -> float:
        """The field's dip below the horizontal, rad."""
        return float(np.arcsin(-(self.field_w @ self.up_w) / np.linalg.norm(self.field_w)))


def reference(
    frame: str = "enu",
    *,
    field_strength_ut: float = 50.0,
    inclination_deg: float = 60.0,
    gravity: float = GRAVITY,
) -> Reference:
    """The reference vectors of a world frame.

    Args:
        frame: ``"enu"`` (default) or ``"ned"``.
        field_strength_ut: Earth field intensity, uT (> 0).
        inclination_deg: dip of the field below the horizontal, degrees (northern hemisphere > 0).
        gravity: m/s^2 (> 0).
    """
    if frame not in FRAMES:
        raise CalibrationInputError(f"frame must be one of {FRAMES}, got {frame!r}")
    if not (np.isfinite(field_strength_ut) and field_strength_ut > 0):
        raise CalibrationInputError(f"field_strength_ut must be > 0, got {field_strength_ut}")
    if not (np.isfinite(gravity) and gravity > 0):
        raise CalibrationInputError(f"gravity must be > 0, got {gravity}")
    inc = np.deg2rad(inclination_deg)
    up = np.array([0.0, 0.0, 1.0])
    field = field_strength_ut * np.array([0.0, np.cos(inc), -np.sin(inc)])
    if frame == "ned":
        up, field = R_NED_ENU @ up, R_NED_ENU @ field
    return Reference(frame, up, field, float(gravity))


def reference_from_data(
    acc: np.ndarray, mag: np.ndarray, frame: str = "enu", *, valid: np.ndarray | None = None
) -> Reference:
    """Reference vectors estimated from a recording itself (one rule for every recording).

    Gravity is the median ``|a|``, the field strength the median ``|m|``, the inclination the
    median dip of ``m`` below the plane normal to ``a``; medians, so that accelerations and local
    disturbances during part of the recording do not move them.

    Args:
        acc, mag: ``(..., 3)`` measured vectors in the sensor frames.
        frame: world frame of the result.
        valid: optional ``(...)`` mask of samples to use.
    """
    acc, mag = _check_vectors(acc, mag)
    a_n = np.linalg.norm(acc, axis=-1)
    m_n = np.linalg.norm(mag, axis=-1)
    use = np.isfinite(a_n) & np.isfinite(m_n) & (a_n > 0) & (m_n > 0)
    if valid is not None:
        use &= np.asarray(valid, dtype=bool)
    if not use.any():
        raise CalibrationInputError("no usable accelerometer and magnetometer samples to estimate the field")
    cos = np.sum(acc[use] * mag[use], axis=-1) / (a_n[use] * m_n[use])
    dip = np.rad2deg(np.median(np.arcsin(np.clip(-cos, -1.0, 1.0))))
    return reference(
        frame,
        field_strength_ut=float(np.median(m_n[use])),
        inclination_deg=float(dip),
        gravity=float(np.median(a_n[use])),
    )


def change_frame(q_w_s: np.ndarray, from_frame: str, to_frame: str) -> np.ndarray:
    """Re-express orientations ``(..., 4)`` of ``R_w_s`` from one world frame in another."""
    for f in (from_frame, to_frame):
        if f not in FRAMES:
            raise CalibrationInputError(f"frame must be one of {FRAMES}, got {f!r}")
    if from_frame == to_frame:
        return np.array(q_w_s, dtype=float)
    R = quat_to_matrix(q_w_s)
    return orthonormal_to_quat(R_NED_ENU @ R)  # R_NED_ENU is its own inverse


def _check_vectors(acc: np.ndarray, mag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    if acc.shape[-1:] != (3,) or mag.shape != acc.shape:
        raise CalibrationInputError(
            f"Expected acc and mag of the same shape (..., 3), got {acc.shape} and {mag.shape}"
        )
    return acc, mag


def _unit(v: np.ndarray, min_norm: float) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(n[..., 0]) & (n[..., 0] > min_norm)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(ok[..., None], v / np.where(n > 0, n, 1.0), np.nan)
    return u, ok


def _frame_from(v1: np.ndarray, v2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal triad ``(..., 3, 3)`` (columns v1, v1 x v2, v1 x (v1 x v2)) and validity."""
    t2 = np.cross(v1, v2)
    s = np.linalg.norm(t2, axis=-1, keepdims=True)
    ok = np.isfinite(s[..., 0]) & (s[..., 0] > MIN_SIN_ANGLE)
    with np.errstate(invalid="ignore", divide="ignore"):
        t2 = t2 / np.where(s > 0, s, 1.0)
    t3 = np.cross(v1, t2)
    return np.stack([v1, t2, t3], axis=-1), ok


@dataclass(frozen=True)
class Estimate:
    """Orientations estimated from vector measurements.

    Attributes:
        q_w_s: ``(..., 4)`` scalar-first quaternions of ``R_w_s`` in ``frame``; NaN where not
            estimable.
        ok: ``(...)`` bool, the sample was estimated.
        frame: the world frame.
        weights: ``(..., 2)`` accelerometer and magnetometer weights used (``None`` if fixed).
        iterations: iterations taken (iterative methods), else 0.
    """

    q_w_s: np.ndarray
    ok: np.ndarray
    frame: str
    weights: np.ndarray | None = None
    iterations: int = 0


def _prepare(
    acc: np.ndarray, mag: np.ndarray, ref: Reference, valid: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    acc, mag = _check_vectors(acc, mag)
    a, ok_a = _unit(acc, MIN_NORM_FRACTION * ref.gravity)
    m, ok_m = _unit(mag, MIN_NORM_FRACTION * np.linalg.norm(ref.field_w))
    ok = ok_a & ok_m
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != acc.shape[:-1]:
            raise CalibrationInputError(f"Expected valid of shape {acc.shape[:-1]}, got {valid.shape}")
        ok &= valid
    return a, m, ok


def triad(
    acc: np.ndarray, mag: np.ndarray, ref: Reference | None = None, *, valid: np.ndarray | None = None
) -> Estimate:
    """TRIAD orientation, the accelerometer as the primary vector.

    Args:
        acc: ``(..., 3)`` specific force in the sensor frame, m/s^2.
        mag: ``(..., 3)`` magnetic field in the sensor frame (any unit; only its direction counts).
        ref: the world's reference vectors (default ENU, 50 uT, 60 degrees).
        valid: optional ``(...)`` bool mask of usable samples.
    """
    ref = ref or reference()
    a, m, ok = _prepare(acc, mag, ref, valid)
    S, ok_s = _frame_from(a, m)
    W, _ = _frame_from(ref.up_w, ref.field_w / np.linalg.norm(ref.field_w))
    ok &= ok_s
    R = W @ np.swapaxes(S, -1, -2)
    q = orthonormal_to_quat(np.where(ok[..., None, None], R, np.eye(3)))
    q[~ok] = np.nan
    return Estimate(q, ok, ref.frame)


def _rotate_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: ``(..., 3, 3)`` rotations by ``angle`` about unit ``axis``."""
    K = np.zeros((*axis.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -axis[..., 2], axis[..., 1], -axis[..., 0]
    K = K - np.swapaxes(K, -1, -2)
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _weights_array(weights: np.ndarray | tuple[float, float] | None, shape: tuple[int, ...]) -> np.ndarray:
    if weights is None:
        return np.ones((*shape, 2))
    w = np.broadcast_to(np.asarray(weights, dtype=float), (*shape, 2)).copy()
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise CalibrationInputError("weights must be finite and >= 0")
    return w


def wahba(
    acc: np.ndarray,
    mag: np.ndarray,
    ref: Reference | None = None,
    *,
    weights: np.ndarray | tuple[float, float] | None = None,
    valid: np.ndarray | None = None,
    method: str = "closed",
) -> Estimate:
    """The optimal weighted solution of Wahba's problem for the two measured directions.

    Args:
        acc, mag: ``(..., 3)`` measured vectors in the sensor frame.
        ref: reference vectors (default ENU).
        weights: ``(..., 2)`` or ``(2,)`` accelerometer and magnetometer weights (default equal).
        valid: optional ``(...)`` bool mask.
        method: ``"closed"`` (two-observation closed form, fast) or ``"svd"``.
    """
    ref = ref or reference()
    a, m, ok = _prepare(acc, mag, ref, valid)
    w = _weights_array(weights, a.shape[:-1])
    ok &= (w[..., 0] + w[..., 1]) > 0
    b_w = ref.field_w / np.linalg.norm(ref.field_w)
    if method == "svd":
        B = w[..., 0, None, None] * ref.up_w[:, None] * a[..., None, :]
        B = B + w[..., 1, None, None] * b_w[:, None] * m[..., None, :]
        B = np.where(ok[..., None, None], B, np.eye(3))
        U, _, Vt = np.linalg.svd(B)
        d = np.linalg.det(U) * np.linalg.det(Vt)
        D = np.ones((*d.shape, 3))
        D[..., 2] = d
        R = (U * D[..., None, :]) @ Vt
        ok &= np.isfinite(R).all(axis=(-1, -2))
    elif method == "closed":
        # TRIAD with the accelerometer primary maps a -> up and a x m -> up x b exactly; the
        # optimum also maps a x m -> up x b, leaving one angle phi about n = (up x b)/|up x b|
        S, ok_s = _frame_from(a, m)
        W, _ = _frame_from(ref.up_w, b_w)
        ok &= ok_s
        R0 = W @ np.swapaxes(S, -1, -2)
        n = W[:, 1]
        c2 = np.einsum("...ij,...j->...i", R0, m)  # the magnetometer after R0, in the plane
        delta = np.arctan2(np.cross(b_w, c2) @ n, c2 @ b_w)
        phi = np.arctan2(-w[..., 1] * np.sin(delta), w[..., 0] + w[..., 1] * np.cos(delta))
        R = _rotate_about(np.broadcast_to(n, a.shape), phi) @ R0
    else:
        raise CalibrationInputError(f"method must be 'closed' or 'svd', got {method!r}")
    q = orthonormal_to_quat(np.where(ok[..., None, None], R, np.eye(3)))
    q[~ok] = np.nan
    return Estimate(q, ok, ref.frame, weights=w)


@dataclass(frozen=True)
class Weighting:
    """Fontaine's disturbance weighting: ``w = 1 / (1 + (x / tau)^2)`` per departure ``x``.

    Attributes:
        acc_tol: ``tau`` of ``| |a| - g | / g`` (relative).
        mag_tol: ``tau`` of ``| |m| - |B| | / |B|`` (relative).
        dip_tol_deg: ``tau`` of the measured dip's departure from the inclination, degrees.
    """

    acc_tol: float = 0.05
    mag_tol: float = 0.05
    dip_tol_deg: float = 3.0

    def __post_init__(self) -> None:
        for name in ("acc_tol", "mag_tol", "dip_tol_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise CalibrationInputError(f"Weighting.{name} must be > 0, got {v}")

    def weights(self, acc: np.ndarray, mag: np.ndarray, ref: Reference) -> np.ndarray:
        """``(..., 2)`` accelerometer and magnetometer weights in (0, 1]."""
        g = ref.gravity
        b = np.linalg.norm(ref.field_w)
        xa = (np.linalg.norm(acc, axis=-1) - g) / g
        xm = (np.linalg.norm(mag, axis=-1) - b) / b
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.sum(acc * mag, axis=-1) / (np.linalg.norm(acc, axis=-1) * np.linalg.norm(mag, axis=-1))
        dip = np.arcsin(np.clip(-cos, -1.0, 1.0))
        xd = np.rad2deg(dip - ref.inclination)
        wa = 1.0 / (1.0 + (xa / self.acc_tol) ** 2)
        wm = 1.0 / (1.0 + (xm / self.mag_tol) ** 2) / (1.0 + (xd / self.dip_tol_deg) ** 2)
        return np.stack([wa, wm], axis=-1)


def _skew(u: np.ndarray) -> np.ndarray:
    K = np.zeros((*u.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2] = -u[..., 2], u[..., 1]
    K[..., 1, 0], K[..., 1, 2] = u[..., 2], -u[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -u[..., 1], u[..., 0]
    return K


def _solve3(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Solve batched 3x3 systems by the adjugate (vectorised; LAPACK per matrix is slow)."""
    c0 = np.cross(H[..., :, 1], H[..., :, 2])
    c1 = np.cross(H[..., :, 2], H[..., :, 0])
    c2 = np.cross(H[..., :, 0], H[..., :, 1])
    det = np.sum(H[..., :, 0] * c0, axis=-1)
    adj = np.stack([c0, c1, c2], axis=-2)  # rows: inverse's rows times det
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("...ij,...j->...i", adj, g) / det[..., None]


def fontaine(
    acc: np.ndarray,
    mag: np.ndarray,
    ref: Reference | None = None,
    *,
    weighting: Weighting | None = None,
    valid: np.ndarray | None = None,
    max_iter: int = 20,
    tol_rad: float = 1e-12,
    rate_hz: float | None = None,
    temporal_hz: float | None = None,
) -> Estimate:
    """Fontaine et al.'s iterative estimator (module docstring), Gauss-Newton on a rotation vector.

    Args:
        acc, mag: ``(..., 3)`` measured vectors in the sensor frame (m/s^2, uT); with
            ``temporal_hz``, frames first.
        ref: reference vectors (default ENU, 50 uT, 60 degrees).
        weighting: disturbance weighting, or ``None`` for equal fixed weights.
        valid: optional ``(...)`` bool mask.
        max_iter: Gauss-Newton iterations at most.
        tol_rad: stop when every update is smaller than this, rad.
        rate_hz: sample rate, Hz (needed with ``temporal_hz``).
        temporal_hz: weighted zero-phase smoothing (:func:`weighted_smooth`) of the measured
            directions with this cutoff before the fit: a sample whose accelerometer (or
            magnetometer) is disturbed takes that direction from its undisturbed neighbours. With
            two vectors per sample the weights alone only share the error between them; over
            time they decide whose direction to trust. Zero phase: no lag.
    """
    ref = ref or reference()
    acc, mag = _check_vectors(acc, mag)
    w = weighting.weights(acc, mag, ref) if weighting is not None else np.ones((*acc.shape[:-1], 2))
    if temporal_hz is not None:
        if rate_hz is None:
            raise CalibrationInputError("temporal_hz needs rate_hz")
        usable = np.isfinite(acc).all(axis=-1) & np.isfinite(mag).all(axis=-1)
        if valid is not None:
            usable &= np.asarray(valid, dtype=bool)
        wa = np.where(usable, np.nan_to_num(w[..., 0]), 0.0)
        wm = np.where(usable, np.nan_to_num(w[..., 1]), 0.0)
        a_dir, _ = _unit(acc, MIN_NORM_FRACTION * ref.gravity)
        m_dir, _ = _unit(mag, MIN_NORM_FRACTION * np.linalg.norm(ref.field_w))
        acc = ref.gravity * weighted_smooth(np.nan_to_num(a_dir), wa, rate_hz, temporal_hz)
        mag = np.linalg.norm(ref.field_w) * weighted_smooth(np.nan_to_num(m_dir), wm, rate_hz, temporal_hz)
        acc[~usable] = np.nan
        mag[~usable] = np.nan
    start = triad(acc, mag, ref, valid=valid)
    ok = start.ok
    a, _ = _unit(acc, MIN_NORM_FRACTION * ref.gravity)
    m, _ = _unit(mag, MIN_NORM_FRACTION * np.linalg.norm(ref.field_w))
    w = np.where(ok[..., None], w, 0.0)
    R = quat_to_matrix(np.where(ok[..., None], start.q_w_s, [1.0, 0.0, 0.0, 0.0]))
    up = ref.up_w
    b_w = ref.field_w / np.linalg.norm(ref.field_w)
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 - kept for the report
        ua = np.einsum("...ji,j->...i", R, up)  # modelled vectors in the sensor frame, R^T v
        um = np.einsum("...ji,j->...i", R, b_w)
        ra, rm = a - ua, m - um
        # r(d) ~ r - [u]x d for R <- R exp([d]x): normal equations of the weighted residuals
        Ka, Km = _skew(ua), _skew(um)
        H = (
            w[..., 0, None, None] * np.swapaxes(Ka, -1, -2) @ Ka
            + w[..., 1, None, None] * np.swapaxes(Km, -1, -2) @ Km
        )
        g = w[..., 0, None] * np.einsum("...ji,...j->...i", Ka, ra) + w[..., 1, None] * np.einsum(
            "...ji,...j->...i", Km, rm
        )
        d = _solve3(H, g)
        d = np.where(ok[..., None] & np.isfinite(d), d, 0.0)
        angle = np.linalg.norm(d, axis=-1)
        axis = np.divide(d, angle[..., None], out=np.zeros_like(d), where=angle[..., None] > 0)
        R = R @ _rotate_about(axis, angle)
        if not np.any(angle > tol_rad):
            break
    q = orthonormal_to_quat(R)
    q[~ok] = np.nan
    return Estimate(q, ok, ref.frame, weights=w, iterations=iterations)


def mahony(
    acc: np.ndarray,
    gyro: np.ndarray,
    mag: np.ndarray,
    rate_hz: float,
    ref: Reference | None = None,
    *,
    kp: float = 1.0,
    ki: float = 0.0,
    q0: np.ndarray | None = None,
    valid: np.ndarray | None = None,
) -> Estimate:
    """Mahony's explicit complementary filter with magnetometer (gyro-aided reference).

    Args:
        acc, gyro, mag: ``(F, ..., 3)`` measurements in the sensor frame (m/s^2, rad/s, uT),
            frames first.
        rate_hz: sample rate, Hz.
        ref: reference vectors (default ENU).
        kp, ki: proportional and integral gains of the correction, 1/s.
        q0: ``(..., 4)`` initial orientation; default the TRIAD estimate of the first sample.
        valid: optional ``(F, ...)`` mask; invalid samples are propagated with the gyro only (and
            output NaN).
    """
    ref = ref or reference()
    acc, mag = _check_vectors(acc, mag)
    gyro = np.asarray(gyro, dtype=float)
    if gyro.shape != acc.shape:
        raise CalibrationInputError(f"Expected gyro of shape {acc.shape}, got {gyro.shape}")
    if not rate_hz > 0:
        raise CalibrationInputError(f"rate_hz must be > 0, got {rate_hz}")
    dt = 1.0 / rate_hz
    a, m, ok = _prepare(acc, mag, ref, valid)
    if q0 is None:
        first = triad(acc[:1], mag[:1], ref).q_w_s[0]
        q0 = np.where(np.isfinite(first), first, [1.0, 0.0, 0.0, 0.0])
    R = quat_to_matrix(np.broadcast_to(q0, (*acc.shape[1:-1], 4)))
    b_w = ref.field_w / np.linalg.norm(ref.field_w)
    bias = np.zeros(acc.shape[1:])
    out = np.full((*acc.shape[:-1], 4), np.nan)
    for t in range(acc.shape[0]):  # a recursive filter: one step per sample
        v_a = np.einsum("...ji,j->...i", R, ref.up_w)
        v_m = np.einsum("...ji,j->...i", R, b_w)
        e = np.where(ok[t, ..., None], np.cross(a[t], v_a) + np.cross(m[t], v_m), 0.0)
        bias = bias + ki * e * dt
        w = np.where(np.isfinite(gyro[t]), gyro[t], 0.0) + kp * e + bias
        angle = np.linalg.norm(w, axis=-1) * dt
        axis = np.divide(
            w, np.linalg.norm(w, axis=-1, keepdims=True), out=np.zeros_like(w), where=angle[..., None] > 0
        )
        R = R @ _rotate_about(axis, angle)
        out[t] = np.where(ok[t, ..., None], orthonormal_to_quat(R), np.nan)
    return Estimate(out, ok, ref.frame)


def smooth_vectors(x: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase (forward-backward) 2nd-order Butterworth low-pass along axis 0.

    No lag behind a real rotation (the phase of the forward pass is undone by the backward one).
    NaN samples are filled by linear interpolation for filtering and set back to NaN.
    """
    from scipy.signal import butter, filtfilt

    x = np.asarray(x, dtype=float)
    if not 0 < cutoff_hz < rate_hz / 2:
        raise CalibrationInputError(f"cutoff_hz must be in (0, {rate_hz / 2}), got {cutoff_hz}")
    flat = x.reshape(x.shape[0], -1).copy()
    bad = ~np.isfinite(flat)
    idx = np.arange(flat.shape[0])
    for k in np.flatnonzero(bad.any(axis=0)):
        good = ~bad[:, k]
        flat[:, k] = np.interp(idx, idx[good], flat[good, k]) if good.any() else 0.0
    b, a = butter(2, cutoff_hz / (rate_hz / 2))
    if flat.shape[0] <= 3 * max(len(a), len(b)):
        return x.copy()
    out = filtfilt(b, a, flat, axis=0)
    out[bad] = np.nan
    return out.reshape(x.shape)


def weighted_smooth(x: np.ndarray, w: np.ndarray, rate_hz: float, cutoff_hz: float) -> np.ndarray:
    """Normalised convolution: ``LP(w x) / LP(w)`` with :func:`smooth_vectors`' zero-phase
    low-pass along axis 0; samples of low weight take their value from their neighbours.

    Args:
        x: ``(F, ..., 3)`` values. w: ``(F, ...)`` weights >= 0.
    """
    num = smooth_vectors(x * w[..., None], rate_hz, cutoff_hz)
    den = smooth_vectors(w[..., None], rate_hz, cutoff_hz)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-9, num / den, x)


def orientation_errors(q_est: np.ndarray, q_true: np.ndarray, up_w: np.ndarray | None = None) -> np.ndarray:
    """BROAD's error angles: total, heading and inclination, rad, ``(..., 3)``.

    With ``q_err = q_est (x) q_true^-1`` (in the world frame), the total error is its rotation
    angle, the heading error the part about the vertical (swing-twist decomposition with twist
    about ``up_w``), the inclination error the rest. NaN where either input is NaN.
    """
    up = np.array([0.0, 0.0, 1.0]) if up_w is None else np.asarray(up_w, dtype=float)
    qe = np.asarray(q_est, dtype=float)
    qt = np.asarray(q_true, dtype=float)
    # q_err = q_est * conj(q_true)
    w1, v1 = qe[..., :1], qe[..., 1:]
    w2, v2 = qt[..., :1], -qt[..., 1:]
    w = w1 * w2 - np.sum(v1 * v2, axis=-1, keepdims=True)
    v = w1 * v2 + w2 * v1 + np.cross(v1, v2)
    # angles by atan2 of the vector and scalar parts: exact near zero (arccos is not)
    vnorm = np.linalg.norm(v, axis=-1)
    total = 2 * np.arctan2(vnorm, np.abs(w[..., 0]))
    twist_v = np.sum(v * up, axis=-1)
    heading = 2 * np.arctan2(np.abs(twist_v), np.abs(w[..., 0]))
    # swing = q_err (x) twist^-1 has scalar part |(w, t)| and vector part the rest of v
    tw = np.sqrt(w[..., 0] ** 2 + twist_v**2)
    inclination = 2 * np.arctan2(np.sqrt(np.clip(vnorm**2 - twist_v**2, 0.0, None)), tw)
    out = np.stack([total, heading, inclination], axis=-1)
    out[~(np.isfinite(qe).all(axis=-1) & np.isfinite(qt).all(axis=-1))] = np.nan
    return out
