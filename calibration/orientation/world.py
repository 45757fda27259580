"""World frames and their reference vectors, the estimators' common result, and error angles.

**Frames.** World ENU by default (x east, y north, z up; the field points north and down by its
inclination ``I``: ``b_w = (0, cos I, -sin I)``), or NED (x north, y east, z down). Quaternions
are scalar-first ``(w, x, y, z)`` of ``R_w_s``.

Also the input handling every estimator shares (:func:`check_vectors`,
:func:`measured_directions`): samples that cannot be estimated -- NaN input, a zero or near-zero
vector, or masked out -- are flagged, never dropped, so outputs stay aligned with inputs.
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
    def field_strength(self) -> float:
        """``|field_w|``, uT."""
        return np.linalg.norm(self.field_w)

    @property
    def field_dir_w(self) -> np.ndarray:
        """``(3,)`` unit vector along the Earth field."""
        return self.field_w / self.field_strength

    @property
    def inclination(self) -> float:
        """The field's dip below the horizontal, rad."""
        return float(np.arcsin(-(self.field_w @ self.up_w) / self.field_strength))


def check_frame(frame: str) -> None:
    """Raise :class:`CalibrationInputError` unless ``frame`` is one of :data:`FRAMES`."""
    if frame not in FRAMES:
        raise CalibrationInputError(f"frame must be one of {FRAMES}, got {frame!r}")


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
    check_frame(frame)
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
        acc: ``(..., 3)`` measured specific force in the sensor frames, m/s^2.
        mag: ``(..., 3)`` measured magnetic field in the sensor frames, uT.
        frame: world frame of the result.
        valid: optional ``(...)`` mask of samples to use.
    """
    acc, mag = check_vectors(acc, mag)
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
    check_frame(from_frame)
    check_frame(to_frame)
    if from_frame == to_frame:
        return np.array(q_w_s, dtype=float)
    R = quat_to_matrix(q_w_s)
    return orthonormal_to_quat(R_NED_ENU @ R)  # R_NED_ENU is its own inverse


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


def check_vectors(acc: np.ndarray, mag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``acc`` and ``mag`` as float arrays of one shape ``(..., 3)``, or an input error."""
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    if acc.shape[-1:] != (3,) or mag.shape != acc.shape:
        raise CalibrationInputError(
            f"Expected acc and mag of the same shape (..., 3), got {acc.shape} and {mag.shape}"
        )
    return acc, mag


def unit_vectors(v: np.ndarray, min_norm: float) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 3)`` unit vectors along ``v`` (NaN where ``|v| <= min_norm`` or not finite), and
    ``(...)`` which were usable."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(n[..., 0]) & (n[..., 0] > min_norm)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(ok[..., None], v / np.where(n > 0, n, 1.0), np.nan)
    return u, ok


def measured_directions(
    acc: np.ndarray, mag: np.ndarray, ref: Reference, valid: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit accelerometer and magnetometer directions ``(..., 3)`` and the ``(...)`` samples
    usable: both vectors longer than :data:`MIN_NORM_FRACTION` of their reference, and ``valid``.
    """
    acc, mag = check_vectors(acc, mag)
    a, ok_a = unit_vectors(acc, MIN_NORM_FRACTION * ref.gravity)
    m, ok_m = unit_vectors(mag, MIN_NORM_FRACTION * ref.field_strength)
    ok = ok_a & ok_m
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != acc.shape[:-1]:
            raise CalibrationInputError(f"Expected valid of shape {acc.shape[:-1]}, got {valid.shape}")
        ok &= valid
    return a, m, ok


def quat_where(R: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """``(..., 4)`` quaternions of orthonormal ``R`` ``(..., 3, 3)``, NaN where not ``ok``."""
    q = orthonormal_to_quat(np.where(ok[..., None, None], R, np.eye(3)))
    q[~ok] = np.nan
    return q


def orientation_errors(q_est: np.ndarray, q_true: np.ndarray, up_w: np.ndarray | None = None) -> np.ndarray:
    """BROAD's error angles: total, heading and inclination, rad, ``(..., 3)``.

    With ``q_err = q_est (x) q_true^-1`` (in the world frame), the total error is its rotation
    angle, the heading error the part about the vertical (swing-twist decomposition with twist
    about ``up_w``, default ENU's ``(0, 0, 1)``), the inclination error the rest. NaN where either
    input is NaN or zero (no rotation); neither needs unit length.

    Args:
        q_est: ``(..., 4)`` estimated scalar-first quaternions of ``R_w_s``.
        q_true: ``(..., 4)`` reference quaternions, the same layout and world frame.
        up_w: ``(3,)`` unit vector up in that world frame.
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
    # a zero quaternion is no rotation (its angles would come out 0): no error either
    known = np.isfinite(qe).all(axis=-1) & np.isfinite(qt).all(axis=-1)
    known &= np.any(qe != 0, axis=-1) & np.any(qt != 0, axis=-1)
    out[~known] = np.nan
    return out
