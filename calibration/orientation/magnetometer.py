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

**Is it determined?** Each parameter the correction applies -- the hard iron's component along
each principal axis of the samples, and the soft iron as a whole (its eigenvalues' departures from
one, the largest bound against the largest departure) -- is judged on its own by its error bound:
:data:`BOUND_Z` standard errors, the standard error from the fit's Jacobian and its residuals (a
sandwich: the residual times the design summed over each of :data:`BLOCKS` consecutive blocks of
samples, so that a residual that follows the motion -- soft iron a model leaves out, a field that
is not uniform -- counts as the correlated error it is, not as independent noise that averages
out; along a direction the samples barely cover the fit magnifies it by the inverse of that
spread). A parameter is determined when its bound is at most :data:`CORRECTION_FRACTION` of its
correction (then applying it cannot move the field farther from the truth than leaving it out
does) or at most :data:`FIELD_FRACTION` of the field (too small to matter either way). The
ellipsoid is used when all its parameters are determined; otherwise the sphere (hard iron alone),
its undetermined components left out one at a time (the least determined first, and first any
direction the samples do not spread along beyond the noise, :data:`NOISE_SPREAD`; the others
fitted again with it held at zero) until what remains is determined; nothing determined, no
correction (``model="none"``). ``left_out`` says what was left out and why. Turning about one
axis, the component along the axis is left out: the fit does not pull the field strength along a
direction it cannot see (the issue-43 failure: 50 -> 42 uT, heading 0.94 -> 5.27 degrees). The
semi-axes' standard errors (the residual as independent noise, ``axis_error``) and the directions
the samples cover (the spread of the calibrated directions along their principal axes) are
reported too.

**Fewer directions: hard iron only.** A body segment that hardly turns (pelvis, torso) shows
its magnetometer too few directions for nine coefficients. The hard iron alone, the sphere
``|m - h| = B`` (four coefficients, linear in ``h`` and ``B^2 - |h|^2``), needs fewer: when the
ellipsoid is not determined, the sphere is fitted, each component of its centre judged as above
(soft iron then taken as the identity; ``model`` says which).

**Soft iron the sphere leaves out.** The sphere's error bounds are those of its own model; a
soft iron (or a cross-axis coupling) that the samples' few directions leave undetermined can move
its centre by more, and no standard error of the sphere shows it: turning about one axis, a
magnetometer axis that picks up the field across it makes ``|m|`` vary with the heading as an
offset in the plane does (RepoIMU's trial 04_2: an offset of 3.3 % of the field applied where
the truth gives 0.5 %, the heading 1.0 -> 5.9 degrees). Where the ellipsoid could be fitted, the
sphere's centre is tested against its (Hausman's test, :func:`_hausman`: both are consistent
without soft iron, the sphere the more precise, so their difference's variance is the
ellipsoid's less the sphere's), at :data:`BOUND_Z` standard errors; where it departs, each
component of the sphere is known only as well as the ellipsoid knows it (its bound taken as at
least the ellipsoid's), and judged as above.

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

import dataclasses
from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.quantiles import mad_std

#: Largest standard error of a semi-axis, over its length, of a determined fit (1 %): the circle
#: (:func:`fit_circle_hard_iron`), whose component along the axis comes from the dip.
AXIS_TOLERANCE = 0.01

#: A parameter is determined when its error bound is at most this fraction of its correction
#: (module docstring): at a half, ``|estimate - truth| <= |estimate| / 2`` gives
#: ``|estimate - truth| <= |truth|``, so applying it is no worse than leaving it out.
CORRECTION_FRACTION = 0.5

#: A parameter's error bound, in standard errors (a Gaussian estimate is off by more once in
#: 370), the standard error from the fit's residuals summed over this many consecutive blocks of
#: samples (a batch-means sandwich): a residual that follows the motion -- soft iron a model leaves
#: out, a field that is not uniform -- is correlated from sample to sample and does not average
#: out as independent noise would.
BOUND_Z = 3.0
BLOCKS = 20

#: A direction along which the samples spread no more than this many times the sphere's own
#: residual (radial, per axis) is not seen at all: the spread may be the noise itself, and a
#: sphere fitted to a circle and its noise centres on the circle's plane (a radius of the
#: horizontal field), which no standard error reveals.
NOISE_SPREAD = 2.0

#: ... or when its error bound is at most this fraction of the field strength (a field direction
#: off by 0.6 degrees at most).
FIELD_FRACTION = 0.01

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
        axis_error: ``(3,)`` their standard errors over their lengths (the residual as
            independent noise).
        determined: every parameter the correction applies is determined (module docstring);
            ``False`` for ``model="none"``, which corrects nothing.
        coverage: ``(3,)`` spread of the calibrated directions along their principal axes
            (standard deviation of the unit vectors' components, largest first; 0.58 each for
            directions all over the sphere, one of them near 0 for turns about one axis).
        spread_before, spread_after: robust relative spread of ``|m|`` and of ``|b|``.
        n_samples: samples used.
        model: ``"ellipsoid"`` (hard and soft iron), ``"hard iron"`` (the sphere, or the
            components of its centre that are determined: ``left_out``), ``"hard iron, circle"``
            (turns about one axis: :func:`fit_circle_hard_iron`) or ``"none"`` (nothing
            determined: the identity).
        left_out: what the samples do not determine and the correction leaves out, one line each
            with its error bound against its size (empty when nothing was).
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
    left_out: tuple[str, ...] = ()

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
    left_out: tuple[str, ...] = ()
    free = None
    try:
        ellipsoid, free = _fit_ellipsoid(m)
        if ellipsoid.determined:
            return ellipsoid
        left_out = ellipsoid.left_out
    except CalibrationError as exc:
        left_out = (f"soft iron: {exc}",)
    sphere = _fit_sphere(m, free)
    return dataclasses.replace(sphere, left_out=left_out + sphere.left_out)


def _bounds(D: np.ndarray, r: np.ndarray, grads: np.ndarray) -> np.ndarray:
    """Error bounds ``(P,)`` of ``P`` functions of a linear least-squares fit's coefficients,
    their gradients ``grads`` ``(P, K)``, over the design ``D`` ``(F, K)`` (samples in time order)
    with residual ``r`` ``(F,)``: :data:`BOUND_Z` standard errors from the covariance
    ``G (sum_b s_b s_b^T) G``, ``G = (D^T D)^-1``, ``s_b`` the sum of ``D_t r_t`` over each of
    :data:`BLOCKS` consecutive blocks of samples (module docstring); ``inf`` where the design does
    not determine them."""
    gram = D.T @ D
    if not np.all(np.isfinite(grads)) or np.linalg.cond(gram) > 1e14:
        return np.full(grads.shape[0], np.inf)
    k = min(BLOCKS, D.shape[0])
    scores = np.add.reduceat(D * r[:, None], np.linspace(0, D.shape[0], k, endpoint=False).astype(int))
    Ga = np.linalg.solve(gram, grads.T)  # (K, P)
    var = np.sum((scores @ Ga) ** 2, axis=0) * k / max(k - 1, 1)
    return BOUND_Z * np.sqrt(var)


def _judge(size: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Which parameters (corrections ``size``, error bounds ``bound``, both as fractions of the
    field) are determined: :data:`CORRECTION_FRACTION`, :data:`FIELD_FRACTION`."""
    return (bound <= CORRECTION_FRACTION * np.abs(size)) | (bound <= FIELD_FRACTION)


def _principal_axes(m: np.ndarray) -> np.ndarray:
    """``(3, 3)`` the samples' principal axes as columns, largest spread first."""
    _, vecs = np.linalg.eigh(np.cov(m.T))
    return vecs[:, ::-1]


def _axis_text(e: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.2f}" for x in e) + ")"


def _hausman(h: np.ndarray, bound: np.ndarray, ellipsoid: np.ndarray) -> tuple[float, int]:
    """Hausman's test of the sphere against the ellipsoid: the sphere's centre ``h`` ``(3,)``
    and error bounds ``bound`` ``(3,)``, the ellipsoid's ``(3, 2)`` (centre, bound), all along the
    samples' principal axes as fractions of the field. Without soft iron both are consistent and
    the sphere the more precise, so their difference has the variance of the ellipsoid's less the
    sphere's; with soft iron the sphere's centre moves (a soft iron that couples the axis to the
    plane of a turn about one axis makes ``|m|`` vary as an offset in the plane does). Returns the
    largest difference in standard errors and its axis."""
    se, ss = ellipsoid[:, 1] / BOUND_Z, bound / BOUND_Z
    sd = np.where(se > ss, np.sqrt(np.abs(se**2 - ss**2)), se)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(h - ellipsoid[:, 0]) / sd
    z = np.where(np.isfinite(z), z, 0.0)
    j = int(np.argmax(z))
    return float(z[j]), j


def _fit_sphere(m: np.ndarray, ellipsoid: np.ndarray | None = None) -> MagnetometerCalibration:
    """The hard iron alone: ``|m|^2 = 2 m.h + (B^2 - |h|^2)``, linear least squares, in the
    samples' principal axes; the components not determined left out (held at zero) one at a
    time, the least determined first, until what remains is determined. ``ellipsoid`` ``(3, 2)``:
    the ellipsoid's hard iron and its error bounds along the same axes (fractions of the field),
    the soft iron free: a sphere whose centre departs from it is not used (:func:`_hausman`)."""
    scale = float(np.median(np.linalg.norm(m, axis=1)))
    E = _principal_axes(m)
    x = (m / scale) @ E  # in the principal axes
    y = np.sum(x * x, axis=1)
    keep = [0, 1, 2]
    left_out: list[str] = []
    floor = None
    while True:
        D = np.column_stack([2 * x[:, keep], np.ones(len(x))])
        v, *_ = np.linalg.lstsq(D, y, rcond=None)
        h = np.zeros(3)
        h[keep] = v[:-1]
        r2 = float(v[-1] + h @ h)
        if not r2 > 0:
            raise CalibrationError("the magnetometer samples lie on no sphere: a field that changes")
        r = np.sqrt(r2)
        res = y - D @ v
        bound = _bounds(D, res, np.eye(len(keep) + 1)[:-1]) / r
        if ellipsoid is not None and len(keep) == 3 and floor is None:
            z, j = _hausman(h / r, bound, ellipsoid)
            floor = ellipsoid[:, 1] if z > BOUND_Z else np.zeros(3)
            if z > BOUND_Z:
                left_out.append(
                    f"hard iron: the sphere's centre departs from the ellipsoid's (the soft iron free) by "
                    f"{z:.2g} standard errors along {_axis_text(E[:, j])}: the soft iron that the sphere "
                    "leaves out moves it, so each component is known only as well as the ellipsoid knows it"
                )
        if floor is not None:
            bound = np.maximum(bound, floor[keep])
        # the radial noise per axis, from the residual of |x|^2 (about 2 r times it)
        noise = float(np.sqrt(np.mean(res**2))) / (2 * r)
        seen = np.std(x[:, keep], axis=0) > NOISE_SPREAD * noise
        ok = _judge(h[keep] / r, bound) & seen
        if ok.all():
            break
        # first a direction not seen (the least spread), then the least determined
        ratio = bound / np.maximum(np.abs(h[keep] / r), 1e-300)
        worst = int(np.argmin(np.std(x[:, keep], axis=0)) if not seen.all() else np.argmax(ratio))
        j = keep.pop(worst)
        left_out.append(
            f"hard iron along {_axis_text(E[:, j])}: {h[j] * scale:.3g}, known to "
            f"{bound[worst] * r * scale:.2g} only (the samples' spread along it is "
            f"{np.std(x[:, j]) * scale:.2g})"
        )
        if not keep:
            break
    if not keep:
        error = np.full(3, np.inf)
        hard = np.zeros(3)
        r = float(np.median(np.linalg.norm(m, axis=1))) / scale
    else:
        sigma2 = float(np.sum((D @ v - y) ** 2) / max(len(x) - D.shape[1], 1))
        error = np.zeros(3)
        error[keep] = np.sqrt(np.diag(sigma2 * np.linalg.pinv(D.T @ D))[:-1]) / r
        hard = E @ h * scale
    b = m - hard
    u = b / np.linalg.norm(b, axis=1, keepdims=True)
    return MagnetometerCalibration(
        hard_iron=hard,
        soft_iron=np.eye(3),
        field_strength=r * scale,
        axes=np.full(3, r * scale),
        axis_error=np.sort(error)[::-1],
        determined=bool(keep),
        coverage=np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(u.T)))[::-1].clip(min=0.0)),
        spread_before=_spread(np.linalg.norm(m, axis=1)),
        spread_after=_spread(np.linalg.norm(b, axis=1)),
        n_samples=int(m.shape[0]),
        model="hard iron" if keep else "none",
        left_out=tuple(left_out),
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


def _fit_ellipsoid(m: np.ndarray) -> tuple[MagnetometerCalibration, np.ndarray]:
    """The ellipsoid fit of ``(F, 3)`` finite samples (module docstring), and its hard iron's
    error bounds ``(3,)`` along the samples' principal axes, as fractions of the field."""
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
    # each parameter the correction applies, in the samples' principal axes, over the field
    E = _principal_axes(m)
    p0 = _corrections(v, E)
    J = np.empty((p0.size, 9))
    step = 1e-6 * np.maximum(np.abs(v), 1e-3)
    for k in range(9):
        dv = np.zeros(9)
        dv[k] = step[k]
        try:
            J[:, k] = (_corrections(v + dv, E) - _corrections(v - dv, E)) / (2 * step[k])
        except np.linalg.LinAlgError:
            J[:, k] = np.inf
    bound = _bounds(D, D @ v - 1.0, J)
    # the hard iron component by component; the soft iron as a whole, by its largest departure
    # from the identity (its eigenvalues': their bounds against the largest of them)
    ok = np.append(
        _judge(p0[:3], bound[:3]), _judge(np.array([np.abs(p0[3:]).max()]), np.array([bound[3:].max()]))
    )
    names = [f"hard iron along {_axis_text(E[:, j])}" for j in range(3)]
    left_out = tuple(
        f"{names[k]}: {100 * p0[k]:.2g} % of the field, known to {100 * bound[k]:.2g} % only"
        for k in np.flatnonzero(~ok[:3])
    ) + (
        ()
        if ok[3]
        else (
            f"soft iron: {100 * np.abs(p0[3:]).max():.2g} % from the identity at most, known to "
            f"{100 * bound[3:].max():.2g} % only",
        )
    )
    b = (m - hard) @ soft.T
    u = b / np.linalg.norm(b, axis=1, keepdims=True)
    coverage = np.sqrt(np.sort(np.linalg.eigvalsh(np.cov(u.T)))[::-1].clip(min=0.0))
    return MagnetometerCalibration(
        hard_iron=hard,
        soft_iron=soft,
        field_strength=strength * scale,
        axes=axes * scale,
        axis_error=axis_error,
        determined=bool(ok.all()),
        coverage=coverage,
        spread_before=_spread(np.linalg.norm(m, axis=1)),
        spread_after=_spread(np.linalg.norm(b, axis=1)),
        n_samples=int(m.shape[0]),
        left_out=left_out,
    ), np.column_stack([p0[:3], bound[:3]])


def _corrections(v: np.ndarray, E: np.ndarray) -> np.ndarray:
    """``(6,)`` the ellipsoid's corrections as fractions of the field: the hard iron's three
    components in the principal axes ``E``, and the soft iron's departures from the identity
    (its eigenvalues less one, ascending), of the quadric's coefficients ``v`` (normalised
    samples)."""
    h, A = _ellipsoid(v)
    w = np.linalg.eigvalsh(A)
    if not np.all(w > 0):
        raise np.linalg.LinAlgError("not an ellipsoid")
    strength = float(np.prod(w) ** (-1.0 / 6.0))
    return np.concatenate([E.T @ h / strength, strength * np.sqrt(w) - 1.0])


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
