"""Magnetometer calibration from a recording's own samples: hard and soft iron by an ellipsoid fit.

A magnetometer on a sensor board measures ``m = S^-1 b + h``: the Earth field ``b`` (constant
strength ``B`` in the world) distorted by the board's soft iron ``S^-1`` (a symmetric matrix near
the identity) and offset by its hard iron ``h``. As the sensor turns, ``m`` traces the ellipsoid
``(m - h)^T A (m - h) = 1`` with ``A = S^T S / B^2``. Fontaine et al. name this: magnetometers need
re-calibration where the environment changes, and a bad calibration must be detected.

**Fit.** The quadric ``m^T M m + 2 n^T m = 1`` is linear in its nine coefficients
(``x^2, y^2, z^2, 2yz, 2xz, 2xy, 2x, 2y, 2z``; the scale fixed by the right-hand side, which
needs the origin off the ellipsoid: a hard iron smaller than the field), solved by least squares
over every valid sample. Then ``h = -M^-1 n``, ``A = M / (1 + h^T M h)``, and the correction
``b = S (m - h)`` with ``S = B A^(1/2)``, ``B = det(A)^(-1/6)`` (the geometric mean of the semi-axes:
the calibrated field keeps the recording's strength).

**Is it determined?** Turning about one axis only traces a circle of the ellipsoid: the fit is
then singular along the axis. The nine coefficients' covariance (the least-squares residual's
variance times ``(D^T D)^-1``) is carried to the three semi-axes by a numerical Jacobian; the fit
is ``determined`` when every semi-axis is known to :data:`AXIS_TOLERANCE` (its standard error over
its length), the unit-free test the data's own scatter makes. The directions the samples cover
are reported too (the spread of the calibrated directions along their principal axes).

**Fewer directions: hard iron only.** A body segment that hardly turns (pelvis, torso) shows
its magnetometer too few directions for nine coefficients. The hard iron alone, the sphere
``|m - h| = B`` (four coefficients, linear in ``h`` and ``B^2 - |h|^2``), needs fewer: when the
ellipsoid is not determined, the sphere is fitted, and used when its centre is known to
:data:`AXIS_TOLERANCE` of ``B`` (soft iron then taken as the identity; ``model`` says which).

**Turns about one axis: the circle and the dip.** A segment that only turns about the vertical
(the trunk in gait) traces a circle: the sphere's centre is then unknown along the axis. The
circle still gives the hard iron across the axis (three coefficients, linear, in the plane
perpendicular to the samples' axis of least spread) and its radius, the horizontal field ``r``;
along the axis the accelerometer and the field's dip give it: with ``u`` the sensor's mean up
direction (its specific force's mean, in its frame) and the axis near ``u``, the calibrated
field's mean component along ``u`` must be the Earth field's, ``-r tan(dip)``
(:func:`fit_circle_hard_iron`, the dip from the recording's other, calibrated sensors; only the
dip, a ratio, since each magnetometer has its own gain).

**Is it good?** The relative spread of ``|b|`` after calibration (robust: 1.4826 MAD over the
median) against the spread of ``|m|`` before: a calibration that does not make the strength
steadier than it was, or leaves it spread by more than the fit's own residual suggests, is
reported as bad by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.quantiles import mad_std

#: Largest standard error of a semi-axis, over its length, of a determined fit (1 %).
AXIS_TOLERANCE = 0.01

#: Fewest samples for a fit (nine coefficients and their scatter).
MIN_SAMPLES = 30


@dataclass(frozen=True)
class MagnetometerCalibration:
    """Hard and soft iron of one magnetometer, from its samples.

    Attributes:
        hard_iron: ``(3,)`` offset ``h``, in the samples' unit.
        soft_iron: ``(3, 3)`` symmetric correction ``S``: ``b = S (m - h)``.
        field_strength: ``B``, the calibrated field's strength, in the samples' unit.
        axes: ``(3,)`` semi-axes of the fitted ellipsoid, largest first, in the samples' unit.
        axis_error: ``(3,)`` their standard errors over their lengths.
        determined: every semi-axis known to :data:`AXIS_TOLERANCE`.
        coverage: ``(3,)`` spread of the calibrated directions along their principal axes
            (standard deviation of the unit vectors' components, largest first; 0.58 each for
            directions all over the sphere, one of them near 0 for turns about one axis).
        spread_before, spread_after: robust relative spread of ``|m|`` and of ``|b|``.
        n_samples: samples used.
        model: ``"ellipsoid"`` (hard and soft iron), ``"hard iron"`` (the sphere) or
            ``"hard iron, circle"`` (turns about one axis: :func:`fit_circle_hard_iron`).
    """

    hard_iron: np.ndarray
    soft_iron: np.ndarray
    field_strength: float
    axes: np.ndarray
    axis_error: np.ndarray
    determined: bool
    coverage: np.ndarray
    spread_before: float
    spread_after: float
    n_samples: int
    model: str = "ellipsoid"

    def apply(self, mag: np.ndarray) -> np.ndarray:
        """``(..., 3)`` calibrated field ``S (m - h)`` of raw samples ``(..., 3)``."""
        return (np.asarray(mag, dtype=float) - self.hard_iron) @ self.soft_iron.T


def _design(m: np.ndarray) -> np.ndarray:
    x, y, z = m.T
    return np.column_stack([x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y, 2 * x, 2 * y, 2 * z])


def _ellipsoid(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(h, A)`` of the quadric coefficients ``v`` (9,); raises when it is not an ellipsoid."""
    a, b, c, f, g, hh, p, q, r = v
    M = np.array([[a, hh, g], [hh, b, f], [g, f, c]])
    n = np.array([p, q, r])
    h = -np.linalg.solve(M, n)
    A = M / (1.0 + h @ M @ h)
    return h, A


def _semi_axes(v: np.ndarray) -> np.ndarray:
    _, A = _ellipsoid(v)
    return np.sort(1.0 / np.sqrt(np.linalg.eigvalsh(A)))[::-1]


def _spread(x: np.ndarray) -> float:
    med = float(np.median(x))
    return float(1.4826 * np.median(np.abs(x - med)) / med) if med > 0 else float("inf")


def fit_magnetometer(mag: np.ndarray, valid: np.ndarray | None = None) -> MagnetometerCalibration:
    """Fit hard and soft iron to one magnetometer's samples, or the hard iron alone where the
    samples do not determine the soft iron (module docstring).

    Args:
        mag: ``(F, 3)`` raw samples in the sensor frame, any unit.
        valid: optional ``(F,)`` mask; non-finite samples are always left out.

    Returns:
        The ellipsoid when it is determined; otherwise the sphere (``determined`` says whether
        its centre is).

    Raises:
        CalibrationInputError: not ``(F, 3)``.
        CalibrationError: fewer than :data:`MIN_SAMPLES` samples, or samples on no sphere.
    """
    m = np.asarray(mag, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3:
        raise CalibrationInputError(f"Expected mag of shape (frames, 3), got {m.shape}")
    m = _usable_samples(m, valid)
    try:
        ellipsoid = _fit_ellipsoid(m)
        if ellipsoid.determined:
            return ellipsoid
    except CalibrationError:
        pass
    return _fit_sphere(m)


def _fit_sphere(m: np.ndarray) -> MagnetometerCalibration:
    """The hard iron alone: ``|m|^2 = 2 m.h + (B^2 - |h|^2)``, linear least squares."""
    scale = float(np.median(np.linalg.norm(m, axis=1)))
    x = m / scale
    D = np.column_stack([2 * x, np.ones(len(x))])
    y = np.sum(x * x, axis=1)
    v, *_ = np.linalg.lstsq(D, y, rcond=None)
    h = v[:3]
    r2 = float(v[3] + h @ h)
    if not r2 > 0:
        raise CalibrationError("the magnetometer samples lie on no sphere: a field that changes")
    r = np.sqrt(r2)
    gram = D.T @ D
    if np.linalg.cond(gram) > 1e14:
        error = np.full(3, np.inf)
    else:
        sigma2 = float(np.sum((D @ v - y) ** 2) / max(len(x) - 4, 1))
        error = np.sqrt(np.diag(sigma2 * np.linalg.inv(gram))[:3]) / r
    hard = h * scale
    b = m - hard
    u = b / np.linalg.norm(b, axis=1, keepdims=True)
    return MagnetometerCalibration(
        hard_iron=hard,
        soft_iron=np.eye(3),
        field_strength=r * scale,
        axes=np.full(3, r * scale),
        axis_error=np.sort(error)[::-1],
        determined=bool(np.all(error <= AXIS_TOLERANCE)),
        coverage=np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(u.T)))[::-1].clip(min=0.0)),
        spread_before=_spread(np.linalg.norm(m, axis=1)),
        spread_after=_spread(np.linalg.norm(b, axis=1)),
        n_samples=int(m.shape[0]),
        model="hard iron",
    )


def fit_circle_hard_iron(
    mag: np.ndarray,
    up: np.ndarray,
    dip_rad: float,
    valid: np.ndarray | None = None,
) -> MagnetometerCalibration:
    """The hard iron of a magnetometer that turns about one axis only (module docstring).

    Args:
        mag: ``(F, 3)`` raw samples in the sensor frame, any unit.
        up: ``(3,)`` the sensor's mean up direction in its own frame (e.g. the mean of its
            accelerometer's specific force), any length.
        dip_rad: the Earth field's dip below the horizontal, rad (positive in the northern
            hemisphere), within 80 degrees of the horizontal.
        valid: optional ``(F,)`` mask.

    Returns:
        The hard iron (soft iron the identity), ``model="hard iron, circle"``; ``determined``
        when the circle's centre is known to :data:`AXIS_TOLERANCE` of its radius and the axis
        is within 30 degrees of ``up``.

    Raises:
        CalibrationInputError: shapes, a zero ``up``, or a dip beyond 80 degrees.
        CalibrationError: fewer than :data:`MIN_SAMPLES` samples, or samples on no circle.
    """
    m = np.asarray(mag, dtype=float)
    u = np.asarray(up, dtype=float)
    if m.ndim != 2 or m.shape[1] != 3 or u.shape != (3,):
        raise CalibrationInputError(f"Expected mag (frames, 3) and up (3,), got {m.shape} and {u.shape}")
    if not (np.isfinite(dip_rad) and abs(dip_rad) <= np.deg2rad(80) and np.isfinite(u).all() and u @ u > 0):
        raise CalibrationInputError(
            f"Expected a dip within 80 degrees and a nonzero up, got {dip_rad} and {u}"
        )
    m = _usable_samples(m, valid)
    u = u / np.linalg.norm(u)
    _, vecs = np.linalg.eigh(np.cov(m.T))
    axis = vecs[:, 0] * np.sign(vecs[:, 0] @ u or 1.0)  # least spread: the turns' axis
    e1, e2 = vecs[:, 2], vecs[:, 1]
    scale = float(np.median(np.linalg.norm(m, axis=1)))
    x = np.column_stack([m @ e1, m @ e2]) / scale
    D = np.column_stack([2 * x, np.ones(len(x))])
    y = np.sum(x * x, axis=1)
    v, *_ = np.linalg.lstsq(D, y, rcond=None)
    r2 = float(v[2] + v[:2] @ v[:2])
    if not r2 > 0:
        raise CalibrationError("the magnetometer samples lie on no circle: a field that changes")
    r = np.sqrt(r2) * scale
    gram = D.T @ D
    sigma2 = float(np.sum((D @ v - y) ** 2) / max(len(x) - 3, 1))
    error = np.sqrt(np.diag(sigma2 * np.linalg.pinv(gram))[:2]) * scale / r
    in_plane = scale * (v[0] * e1 + v[1] * e2)
    # along the axis: the calibrated field's mean component along up is the Earth field's
    along_u = float(np.mean(m @ u)) - in_plane @ u + r * np.tan(dip_rad)
    hard = in_plane + axis * along_u / (axis @ u)
    b = m - hard
    determined = bool(np.all(error <= AXIS_TOLERANCE) and axis @ u >= np.cos(np.pi / 6))
    un = b / np.linalg.norm(b, axis=1, keepdims=True)
    return MagnetometerCalibration(
        hard_iron=hard,
        soft_iron=np.eye(3),
        field_strength=float(r / np.cos(dip_rad)),
        axes=np.array([r, r, r * np.tan(dip_rad)]),
        axis_error=np.append(np.sort(error)[::-1], 0.0),
        determined=determined,
        coverage=np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(un.T)))[::-1].clip(min=0.0)),
        spread_before=_spread(np.linalg.norm(m, axis=1)),
        spread_after=_spread(np.linalg.norm(b, axis=1)),
        n_samples=int(m.shape[0]),
        model="hard iron, circle",
    )


def _fit_ellipsoid(m: np.ndarray) -> MagnetometerCalibration:
    """The ellipsoid fit of ``(F, 3)`` finite samples (module docstring)."""
    scale = float(np.median(np.linalg.norm(m, axis=1)))  # work near unit size: the design is then well scaled
    D = _design(m / scale)
    v, *_ = np.linalg.lstsq(D, np.ones(len(m)), rcond=None)
    try:
        h, A = _ellipsoid(v)
        w, U = np.linalg.eigh(A)
    except np.linalg.LinAlgError:
        raise CalibrationError("the magnetometer samples do not lie on an ellipsoid") from None
    if not np.all(w > 0):
        raise CalibrationError(
            "the magnetometer samples do not lie on an ellipsoid (the fitted quadric is not closed): "
            "too few directions, or a field that changes"
        )
    axes = np.sort(1.0 / np.sqrt(w))[::-1]
    # the coefficients' covariance, carried to the semi-axes
    dof = max(len(m) - 9, 1)
    sigma2 = float(np.sum((D @ v - 1.0) ** 2) / dof)
    gram = D.T @ D
    cond = np.linalg.cond(gram)
    if cond > 1e14:
        axis_error = np.full(3, np.inf)
    else:
        cov = sigma2 * np.linalg.inv(gram)
        step = 1e-7 * np.maximum(np.abs(v), 1e-12)
        J = np.empty((3, 9))
        for k in range(9):
            dv = np.zeros(9)
            dv[k] = step[k]
            try:
                J[:, k] = (_semi_axes(v + dv) - _semi_axes(v - dv)) / (2 * step[k])
            except np.linalg.LinAlgError:
                J[:, k] = np.inf
        axis_error = np.sqrt(np.maximum(np.einsum("ik,kl,il->i", J, cov, J), 0.0)) / axes
    W = (U * np.sqrt(w)) @ U.T  # A^(1/2), symmetric
    strength = float(np.prod(axes) ** (1.0 / 3.0))
    soft = strength * W
    hard = h * scale
    b = (m - hard) @ soft.T
    u = b / np.linalg.norm(b, axis=1, keepdims=True)
    coverage = np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(u.T)))[::-1].clip(min=0.0))
    return MagnetometerCalibration(
        hard_iron=hard,
        soft_iron=soft,
        field_strength=strength * scale,
        axes=axes * scale,
        axis_error=axis_error,
        determined=bool(np.all(axis_error <= AXIS_TOLERANCE)),
        coverage=coverage,
        spread_before=_spread(np.linalg.norm(m, axis=1)),
        spread_after=_spread(np.linalg.norm(b, axis=1)),
        n_samples=int(m.shape[0]),
    )


#: A sample departs from the recording's field strength when ``| |m| / B - 1 |`` exceeds this
#: many robust standard deviations of the recording's own (1.4826 MAD): a Gaussian sample does
#: so once in 500 million.
SPAN_THRESHOLD = 6.0

#: Departing samples closer than this in time, s, belong to one span; a span whose fit does not
#: apply is tried again split at gaps longer than :data:`SPAN_SPLIT_S` (a magnet that moves
#: with the sensor leaves the field strength near the Earth's at some orientations, so one
#: attachment shows as departures with gaps; two attachments in a row are two hard irons).
SPAN_GAP_S = 5.0
SPAN_SPLIT_S = 1.0

#: A span's fit is fitted again on the samples it explains at most this many times (a magnet
#: put on or taken off within the span: :func:`fit_disturbed_spans`); a sample is explained
#: within :data:`SPAN_THRESHOLD` robust standard deviations of the recording's field strength,
#: or :data:`TRIM` of the fit's own while that is the larger (the first fits, pulled by the
#: samples of the putting-on).
REFITS = 5
TRIM = 3.0

#: A change of calibration (a magnet put on or taken off, :func:`follow_fits`) has to be paid for
#: by this long of samples that the new calibration explains and the old does not, s. Measured on
#: BROAD's attached-magnet trials 32-35: the result is the same from 0.1 to 2 s.
SWITCH_S = 0.5


@dataclass(frozen=True)
class SpanCalibration:
    """A span of a recording whose magnetometer sees a different field: a magnet attached to
    the sensor, or carried with it, for a while (Fontaine et al.: "magnetometers need
    re-calibration where the environment changes").

    Attributes:
        start, stop: the span's samples ``[start, stop)``.
        fit: the fit of the span's own samples, or ``None`` if it has too few.
        applied: the fit is determined and brings the span's field strength back to the
            recording's (within :data:`SPAN_THRESHOLD` of its spread, relative, and its spread
            within a factor 2 of the recording's): the span is calibrated with it. Otherwise it
            stays as it was, and the estimator has to carry the heading across it.
    """

    start: int
    stop: int
    fit: MagnetometerCalibration | None
    applied: bool


@dataclass(frozen=True)
class _Departures:
    """One magnetometer's samples judged against the field strength ``B``: ``use`` ``(F,)``
    usable, ``spread`` the robust relative spread of ``|m|``, ``out`` the departing samples'
    indices (ascending)."""

    use: np.ndarray
    strength: float
    spread: float
    out: np.ndarray

    def spans(self, rate_hz: float, gap_s: float) -> list[tuple[int, int]]:
        """The departing samples joined across gaps shorter than ``gap_s``."""
        if self.out.size == 0:
            return []
        gap = max(1, round(gap_s * rate_hz))
        breaks = np.flatnonzero(np.diff(self.out) > gap)
        starts = np.r_[self.out[0], self.out[breaks + 1]]
        stops = np.r_[self.out[breaks], self.out[-1]] + 1
        return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _departures(m: np.ndarray, valid: np.ndarray | None, strength: float | None) -> _Departures:
    n = np.linalg.norm(m, axis=1)
    use = np.isfinite(n) & (n > 0)
    if valid is not None:
        use &= np.asarray(valid, dtype=bool)
    none = np.zeros(0, dtype=int)
    if use.sum() < MIN_SAMPLES:
        return _Departures(use, float("nan"), float("nan"), none)
    B = float(np.median(n[use])) if strength is None else float(strength)
    x = n / B - 1.0
    spread = mad_std(x[use])
    if not spread > 0:
        return _Departures(use, B, spread, none)
    out = np.flatnonzero(use & (np.abs(x - np.median(x[use])) > SPAN_THRESHOLD * spread))
    return _Departures(use, B, spread, out)


def disturbed_spans(
    mag: np.ndarray,
    rate_hz: float,
    valid: np.ndarray | None = None,
    strength: float | None = None,
    gap_s: float = SPAN_GAP_S,
) -> tuple[list[tuple[int, int]], float]:
    """Spans ``[start, stop)`` of samples whose field strength departs from the recording's.

    Args:
        mag: ``(F, 3)`` (calibrated) samples.
        rate_hz: sample rate, Hz.
        valid: optional ``(F,)`` mask.
        strength: the field strength ``B`` (default: the median ``|m|``).

    Returns:
        The spans (departing samples joined across gaps shorter than ``gap_s``), and the robust
        relative spread of ``|m|`` they were judged by.
    """
    d = _departures(np.asarray(mag, dtype=float), valid, strength)
    return d.spans(rate_hz, gap_s), d.spread


def fit_disturbed_spans(
    mag: np.ndarray, rate_hz: float, valid: np.ndarray | None = None, strength: float | None = None
) -> list[SpanCalibration]:
    """Each span where the field strength departs (:func:`disturbed_spans`), fitted on its own
    samples (:func:`fit_magnetometer`) and judged: a magnet that moves with the sensor is a new
    hard (and soft) iron for as long as it stays, which the span's own turns determine; a field
    that changes in the world (a magnet the sensor passes) fits no ellipsoid and is left to the
    estimator. The samples of a span that the first fit leaves departing (by
    :data:`SPAN_THRESHOLD` of the recording's spread: a magnet being put on or taken off) are
    dropped and the fit made again, up to :data:`REFITS` times (:data:`TRIM`), while it explains
    at least half of the span (a simulated forearm, a magnet put on over 1 s of a 7 s span: |b| spread 4.7 %
    with the ramps, not applied; without them, applied)."""
    m = np.asarray(mag, dtype=float)
    d = _departures(m, valid, strength)
    spans, fine = d.spans(rate_hz, SPAN_GAP_S), d.spans(rate_hz, SPAN_SPLIT_S)
    use, B, spread = d.use, d.strength, d.spread

    def judged(a: int, b: int) -> SpanCalibration:
        try:
            fit = fit_magnetometer(m[a:b], use[a:b])
            # refit on the samples the fit explains: while a magnet is put on or taken off the
            # field changes whatever the sensor does, and those samples fit no ellipsoid
            kept = use[a:b]
            for _ in range(REFITS):
                with np.errstate(invalid="ignore"):
                    x = np.linalg.norm(fit.apply(m[a:b]), axis=1) / fit.field_strength - 1.0
                bound = max(SPAN_THRESHOLD * spread, TRIM * fit.spread_after)
                explained = use[a:b] & (np.abs(x) <= bound)
                if np.array_equal(explained, kept) or 2 * explained.sum() < use[a:b].sum():
                    break
                kept = explained
                fit = fit_magnetometer(m[a:b], kept)
        except CalibrationError:
            return SpanCalibration(a, b, None, False)
        ok = (
            fit.determined
            and abs(fit.field_strength / B - 1.0) <= SPAN_THRESHOLD * spread
            and fit.spread_after <= 2.0 * spread
        )
        return SpanCalibration(a, b, fit, bool(ok))

    out = []
    for a, b in spans:
        whole = judged(a, b)
        parts = [(c, d) for c, d in fine if a <= c and d <= b]
        out += [whole] if whole.applied or len(parts) < 2 else [judged(c, d) for c, d in parts]
    return out


def follow_fits(
    mag: np.ndarray,
    rate_hz: float,
    fits: list[MagnetometerCalibration],
    valid: np.ndarray | None = None,
    strength: float | None = None,
) -> np.ndarray:
    """Which of ``fits`` (e.g. the applied span fits, :func:`fit_disturbed_spans`), or none, each
    sample's field follows.

    A magnet attached to the sensor is one hard iron from the moment it is put on to the moment
    it is taken off; but its spans of departing field strength end where the sensor's turn
    happens to bring ``|m|`` back near the Earth's, and a span that holds the putting-on (the
    field changing while the sensor is still) fits no ellipsoid, so the span fits alone leave
    such stretches to the estimator (BROAD trial 33: 41-54 s). Here each sample costs, under each
    calibration, its departure ``(|b| / B - 1)`` in units of :data:`SPAN_THRESHOLD` robust
    standard deviations of the recording's field strength, squared and capped at 1 (a sample
    that departs under a calibration costs 1); the cheapest sequence of calibrations over the
    recording (Viterbi), a change costing :data:`SWITCH_S` seconds of samples, says which
    calibration each sample follows: it carries a fit over the stretches where the strength is
    near the Earth's under both, and stops where the magnet comes off.

    Args:
        mag: ``(F, 3)`` samples (calibrated for the recording as a whole, as the fits were fitted).
        rate_hz: sample rate, Hz.
        fits: the candidate calibrations.
        valid: optional ``(F,)`` mask (other samples follow their neighbours).
        strength: the recording's field strength ``B`` (default: the median ``|m|``).

    Returns:
        ``(F,)`` the index into ``fits`` each sample follows, ``-1`` for none (the samples as they
        are).
    """
    m = np.asarray(mag, dtype=float)
    d = _departures(m, valid, strength)
    if not fits or not d.spread > 0:
        return np.full(m.shape[0], -1)
    scale = SPAN_THRESHOLD * d.spread
    cost = np.empty((len(fits) + 1, m.shape[0]))
    for k, (b, B) in enumerate([(m, d.strength)] + [(f.apply(m), f.field_strength) for f in fits]):
        with np.errstate(invalid="ignore"):
            x = (np.linalg.norm(b, axis=1) / B - 1.0) / scale
        cost[k] = np.where(d.use, np.minimum(np.nan_to_num(x, nan=1.0) ** 2, 1.0), 0.0)
    return _cheapest_path(cost, SWITCH_S * rate_hz) - 1


def _cheapest_path(cost: np.ndarray, change: float) -> np.ndarray:
    """The states ``(F,)`` of the path through ``cost`` ``(K, F)`` (state by sample) whose costs
    plus ``change`` per change of state sum least, starting in state 0 (Viterbi; every change
    costs the same, so each step keeps only whether a state stayed or came from the best)."""
    n_states, f = cost.shape
    rows = cost.T.tolist()
    states = range(n_states)
    total = [rows[0][0]] + [rows[0][k] + change for k in range(1, n_states)]
    came_from = []
    for t in range(1, f):
        best = min(total)
        jump = best + change
        source = total.index(best)
        here = rows[t]
        step = [-1] * n_states
        new = [0.0] * n_states
        for k in states:
            if total[k] <= jump:
                new[k] = total[k] + here[k]
            else:
                new[k] = jump + here[k]
                step[k] = source
        came_from.append(step)
        total = new
    path = np.empty(f, dtype=int)
    k = total.index(min(total))
    path[-1] = k
    for t in range(f - 1, 0, -1):
        if came_from[t - 1][k] >= 0:
            k = came_from[t - 1][k]
        path[t - 1] = k
    return path


def _usable_samples(m: np.ndarray, valid: np.ndarray | None) -> np.ndarray:
    """The finite, non-zero rows of ``m`` (``(F, 3)``) that ``valid`` keeps, or an error when
    fewer than :data:`MIN_SAMPLES` remain (a reading of exactly zero is no reading: no field is
    that weak)."""
    use = np.isfinite(m).all(axis=1) & np.any(m != 0, axis=1)
    if valid is not None:
        use &= np.asarray(valid, dtype=bool)
    m = m[use]
    if m.shape[0] < MIN_SAMPLES:
        raise CalibrationError(f"a magnetometer fit needs at least {MIN_SAMPLES} samples, got {m.shape[0]}")
    return m
