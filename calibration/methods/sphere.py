"""Sphere fits: the centre about which a segment's points turn, seen from the other segment.

A point fixed on the child (a marker, or the child sensor's origin), expressed in the parent's
frame, stays on a sphere about the joint centre. Two fits of that sphere are given here, for one
point or several points at once (each on its own sphere about the same centre):

**Gamage and Lasenby's closed form.** Reference: S. S. H. U. Gamage, J. Lasenby, "New least
squares solutions for estimating the average centre of rotation and the axis of rotation",
Journal of Biomechanics 35 (2002) 87-93. With points ``v[f, k]`` of marker ``k`` at frame ``f``,
it minimises ``sum_{f,k} (|v[f,k] - c|^2 - r_k^2)^2``; eliminating each ``r_k`` leaves a linear
system for the centre::

    C c = d / 2,   C = sum_k cov_k(v),   d = sum_k mean_f((v[f,k] - vbar_k) |v[f,k]|^2)

with ``cov_k`` the covariance of marker ``k``'s points over the frames and ``vbar_k`` their mean.
The estimate is biased by noise: for isotropic noise of variance ``s2`` per axis,
``E[C] = C_true + M s2' I`` and ``E[d] = d_true + 2 s2' sum_k vbar_k`` (``M`` markers,
``s2' = s2 (1 - 1/frames)``), so the centre is pulled towards the points' mean by about
``s2 C^-1 (vbar - c)`` -- centimetres when the motion is small. The optional **bias correction**
subtracts both expectations, ``c = (C - M s2' I)^-1 (d - 2 s2' sum_k vbar_k) / 2``: written out
here for isotropic white noise, the form of Halvorsen's bias-compensated least squares
(J. Biomech. 36 (2003) 999-1008), which corrects this estimator's bias to first order.
``s2`` is given, or estimated as the smallest noise level at which the corrected centre's radial
rms residual equals it (this module's choice). Soft-tissue motion is not isotropic white noise,
so an estimated ``s2`` can over- or under-correct on real data: prefer a known noise.

**Geometric least squares.** Minimise the orthogonal distances ``sum_{f,k} (|v[f,k] - c| - r_k)^2``
with :func:`scipy.optimize.least_squares`, started from the closed form. Its bias is second order
in the noise; it costs an iterative solve.

**Degenerate motion.** No rotation leaves the points still: :class:`CalibrationError`. A rotation
about one axis leaves every marker on a circle, all in parallel planes: the centre is undetermined
along the axis, also :class:`CalibrationError` (use SARA, :mod:`calibration.methods.sara`). Both are
judged from the points' scatter (:attr:`SphereFit.spread_m`), not from their units. Noise hides the
second: an arc of a few degrees on skin markers has a spread across its plane of millimetres, and
the geometric fit then follows the points towards a plane, its centre kilometres away (a real
walking trial's ankle: 1,150 km). So each fit's centre is also judged from the fit itself
(:func:`centre_standard_error`): the standard error of the centre in its least determined direction,
from the geometric residual's Jacobian at the fitted sphere, the radial residuals' variance, and
their correlation over frames (:func:`calibration.clusters.correlation_frames`: skin moves markers
smoothly, so ``k`` correlated frames carry about one frame's worth of information). A centre whose
standard error exceeds the sphere's smallest radius -- one standard error as large as the sphere --
is not located: :class:`CalibrationError`. On the real trials at hand the located joints' ratio is
0.05-0.71; the two ankles of a walk that turn a few degrees are at 1.4 and 8e6.

:func:`sphere_joint` runs either fit on world-frame points given the parent's pose, and, given the
child's pose too, carries the centre into the child's frame.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares

from calibration.clusters import correlation_frames
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import SINGLE_AXIS_RATIO
from calibration.methods.score import check_finite, check_pair, check_valid, frame_residuals, rms

#: Fewest used frames a sphere fit accepts (four points in general position fix a sphere).
MIN_FRAMES = 4

#: The variants of :func:`fit_sphere`.
VARIANTS = ("gamage-lasenby", "geometric")

#: Points whose rms spread is below this fraction of their distance from the origin do not move
#: (rounding of still points is about 1e-16 of it).
STILL_RATIO = 1e-9

#: Noise levels tried between 0 and the largest the spread allows when the bias correction
#: estimates the noise (the first crossing is then refined by Brent's method).
NOISE_GRID = 64


@dataclass(frozen=True)
class SphereFit:
    """A sphere fitted to one or more markers' points about a common centre.

    Attributes:
        centre: ``(3,)`` the centre, in the frame of the points, metres.
        radii: ``(markers,)`` each marker's radius, metres.
        rms_residual: root mean square of the radial residuals ``|v - c| - r_k``, metres.
        spread_m: ``(3,)`` rms spread of the points (summed over markers) along the principal
            directions of their scatter, descending, metres: the last near 0 for a rotation
            about one axis.
        noise_std_m: the noise standard deviation per axis the bias correction used (given or
            estimated), metres; NaN without the correction.
        method: ``"gamage-lasenby"`` or ``"geometric"``.
        n_frames: frames used.
        n_markers: markers fitted.
        n_iterations: closed-form solves of the noise search (bias correction with estimated
            noise; 0 otherwise) or function evaluations (geometric).
        centre_se_m: the centre's standard error in its least determined direction, metres
            (:func:`centre_standard_error`).
    """

    centre: np.ndarray
    radii: np.ndarray
    rms_residual: float
    spread_m: np.ndarray
    noise_std_m: float
    method: str
    n_frames: int
    n_markers: int
    n_iterations: int
    centre_se_m: float = float("nan")


def _points_array(points: np.ndarray, name: str) -> np.ndarray:
    """``(frames, markers, 3)`` float points, a ``(frames, 3)`` input getting one marker."""
    try:
        v = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise CalibrationInputError(
            f"Expected {name} to be a numeric array, got {type(points).__name__}"
        ) from exc
    if v.ndim == 2 and v.shape[1:] == (3,):
        v = v[:, None, :]
    if v.ndim != 3 or v.shape[2] != 3 or v.shape[1] < 1:
        raise CalibrationInputError(
            f"Expected {name} to have shape (frames, 3) or (frames, markers, 3), got {np.shape(points)}"
        )
    return v


def check_points(points: np.ndarray, name: str, valid: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """``(frames, markers, 3)`` float points (a ``(frames, 3)`` input gets one marker) and the
    ``(frames,)`` used frames, checked (shape, finite where used, enough frames)."""
    v = _points_array(points, name)
    used = check_valid(valid, v.shape[0])
    check_finite(name, v, used)
    n_used = int(np.count_nonzero(used))
    if n_used < MIN_FRAMES:
        raise CalibrationInputError(f"Expected at least {MIN_FRAMES} used frames of {name}, got {n_used}")
    return v, used


def _scatter(v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centred points ``(frames, markers, 3)``, the reference point ``(3,)`` they are centred on
    and the summed covariance ``C`` ``(3, 3)`` of the markers (metres^2)."""
    ref = v.reshape(-1, 3).mean(axis=0)
    w = v - ref
    dv = w - w.mean(axis=0)
    C = np.einsum("fki,fkj->ij", dv, dv) / v.shape[0]
    return w, ref, C


def _check_spread(w: np.ndarray, ref: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``(3,)`` rms spread along the principal directions; raises on still or planar points."""
    lam = np.clip(np.linalg.eigvalsh(C)[::-1], 0.0, None)
    spread = np.sqrt(lam)
    scale = max(float(np.linalg.norm(ref)), float(np.sqrt(np.mean(np.sum(w * w, axis=-1)))))
    if spread[0] <= STILL_RATIO * scale:
        raise CalibrationError(
            f"The points do not move (rms spread {spread[0]:.3g} m): a sphere fit needs the child to "
            "rotate relative to the parent"
        )
    if spread[2] < SINGLE_AXIS_RATIO * spread[0]:
        raise CalibrationError(
            f"The points lie in parallel planes (spread {spread[2]:.3g} m across them, {spread[0]:.3g} m "
            "along them): the rotation is about one axis and the centre is undetermined along it; "
            "use SARA for a hinge"
        )
    return spread


def _closed_form(w: np.ndarray, C: np.ndarray, s2: float) -> np.ndarray:
    """Gamage and Lasenby's centre of centred points ``w``, bias-corrected for noise variance
    ``s2`` (0: uncorrected); metres, in the centred coordinates."""
    n, m = w.shape[:2]
    wbar = w.mean(axis=0)  # (markers, 3)
    sq = np.sum(w * w, axis=2)  # (frames, markers)
    d = np.einsum("fki,fk->i", w - wbar, sq) / n
    s2_eff = s2 * (1.0 - 1.0 / n)
    C_bc = C - m * s2_eff * np.eye(3)
    d_bc = d - 2.0 * s2_eff * wbar.sum(axis=0)
    if s2 > 0.0 and np.linalg.eigvalsh(C_bc)[0] <= 0.0:
        raise CalibrationError(
            f"The bias correction for noise {np.sqrt(s2):.3g} m exceeds the points' spread "
            f"({np.sqrt(np.linalg.eigvalsh(C)[0]):.3g} m in the narrowest direction): the motion is too small"
        )
    return 0.5 * np.linalg.solve(C_bc, d_bc)


def _radial(w: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Radii ``(markers,)`` (mean distance from ``c``) and radial residuals ``(frames, markers)``."""
    dist = np.linalg.norm(w - c, axis=2)
    radii = dist.mean(axis=0)
    return radii, dist - radii


def centre_standard_error(w: np.ndarray, c: np.ndarray, radii: np.ndarray) -> float:
    """The standard error of a sphere's centre in its least determined direction, metres.

    From the Jacobian ``J`` of the radial residuals ``|w - c| - r_k`` in ``(c, r_1..r_m)`` at the
    fitted sphere (its SVD, so that a centre the points do not fix gets an infinite error rather
    than a cut-off one): ``cov = s2 k (J^T J)^-1``, ``s2`` the residuals' variance with the
    parameters' degrees of freedom counted, ``k`` their correlation over frames
    (:func:`calibration.clusters.correlation_frames` of the frame's mean residual).

    Args:
        w: ``(frames, markers, 3)`` points, metres.
        c: ``(3,)`` the fitted centre, in the points' coordinates, metres.
        radii: ``(markers,)`` the fitted radii, metres.
    """
    n, m = w.shape[:2]
    d = w - c
    dist = np.maximum(np.linalg.norm(d, axis=2), np.finfo(float).tiny)
    e = dist - radii
    J = np.zeros((n * m, 3 + m))
    J[:, :3] = -(d / dist[..., None]).reshape(-1, 3)
    J[np.arange(n * m), 3 + np.tile(np.arange(m), n)] = -1.0
    s2 = float(np.sum(e * e)) / max(n * m - 3 - m, 1)
    k = correlation_frames(e.mean(axis=1))
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    if sv[-1] <= 0.0:
        return float("inf")
    cov = (Vt.T / sv**2) @ Vt
    return float(np.sqrt(max(np.linalg.eigvalsh(cov[:3, :3] * s2 * k)[-1], 0.0)))


def _located(fit: SphereFit, w: np.ndarray, ref: np.ndarray) -> SphereFit:
    """``fit`` with its centre's standard error; :class:`CalibrationError` where it exceeds the
    smallest radius (module docstring)."""
    se = centre_standard_error(w, fit.centre - ref, fit.radii)
    radius = float(np.min(fit.radii))
    if not se <= radius:
        raise CalibrationError(
            f"The sphere is not located: its centre's standard error ({se:.3g} m) exceeds its radius "
            f"({radius:.3g} m), the points barely curve (a rotation about one axis, or too small for the "
            "noise): use SARA for a hinge, or move the joint through more of its range"
        )
    return dataclasses.replace(fit, centre_se_m=se)


def _estimate_noise(w: np.ndarray, C: np.ndarray) -> tuple[float, int]:
    """The noise variance per axis for the bias correction, estimated from the data, and the
    closed-form solves it took.

    The smallest ``s`` at which the corrected centre's radial rms residual (degrees of freedom
    counted) equals ``s``: at the true centre the radial residual is the noise along the radius.
    A plain fixed-point iteration ``s <- residual(s)`` overshoots from the biased start when the
    motion is small, hence the scan over ``[0, s_max)`` (``s_max`` where the corrected ``C``
    loses definiteness) and Brent's method on the first crossing.
    """
    n, m = w.shape[:2]
    dof_scale = np.sqrt(n * m / max(n * m - 3 - m, 1))
    s_max = np.sqrt(max(float(np.linalg.eigvalsh(C)[0]), 0.0) / (m * (1.0 - 1.0 / n)))
    evaluations = 0

    def excess(s: float) -> float:
        nonlocal evaluations
        evaluations += 1
        _, e = _radial(w, _closed_form(w, C, s * s))
        return float(dof_scale * np.sqrt(np.mean(e * e))) - s

    grid = s_max * np.arange(NOISE_GRID) / NOISE_GRID
    previous = excess(0.0)
    if previous <= 0.0:  # noise-free: the uncorrected centre fits to rounding
        return 0.0, evaluations
    for lo, hi in itertools.pairwise(grid):
        current = excess(hi)
        if current <= 0.0:
            s = brentq(excess, lo, hi, xtol=1e-6 * s_max)
            return float(s) ** 2, evaluations
        previous = current
    raise CalibrationError(
        f"The bias correction cannot estimate the noise: the radial residual stays above every noise "
        f"level the points' spread allows (up to {s_max:.3g} m, last residual excess {previous:.3g} m); "
        "the motion is too small for the noise, give noise_std_m or use the geometric fit"
    )


def gamage_lasenby(
    points: np.ndarray,
    *,
    bias_correction: bool = False,
    noise_std_m: float | None = None,
    valid: np.ndarray | None = None,
) -> SphereFit:
    """Gamage and Lasenby's (2002) closed-form centre of rotation, optionally bias-corrected.

    Args:
        points: ``(frames, 3)`` or ``(frames, markers, 3)`` points fixed on the moving segment,
            expressed in the frame of the segment the centre is fixed in (e.g. the parent's),
            metres.
        bias_correction: subtract the first-order noise bias (module docstring).
        noise_std_m: noise standard deviation per axis of the points, metres; with
            ``bias_correction`` and ``None`` it is estimated from the radial residuals.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre and radii in the points' frame, the radial rms residual and the spread.

    Raises:
        CalibrationInputError: malformed points, NaN in a used frame, fewer than
            :data:`MIN_FRAMES` used frames, a negative or non-finite ``noise_std_m``, or
            ``noise_std_m`` without ``bias_correction``.
        CalibrationError: the points do not move, lie in parallel planes (one-axis rotation),
            their spread is smaller than the noise to be corrected, or the centre is not located
            (its standard error exceeds the radius).
    """
    if noise_std_m is not None:
        if not bias_correction:
            raise CalibrationInputError("Expected noise_std_m only with bias_correction=True, got it without")
        if not np.isfinite(noise_std_m) or noise_std_m < 0.0:
            raise CalibrationInputError(f"Expected noise_std_m to be finite and >= 0, got {noise_std_m}")
    v, used = check_points(points, "points", valid)
    w, ref, C = _scatter(v[used])
    spread = _check_spread(w, ref, C)
    s2, evaluations = 0.0, 0
    if bias_correction and noise_std_m is not None:
        s2 = float(noise_std_m) ** 2
    elif bias_correction:
        s2, evaluations = _estimate_noise(w, C)
    c = _closed_form(w, C, s2)
    radii, e = _radial(w, c)
    fit = SphereFit(
        centre=c + ref,
        radii=radii,
        rms_residual=float(np.sqrt(np.mean(e * e))),
        spread_m=spread,
        noise_std_m=float(np.sqrt(s2)) if bias_correction else float("nan"),
        method="gamage-lasenby",
        n_frames=int(w.shape[0]),
        n_markers=int(w.shape[1]),
        n_iterations=evaluations,
    )
    return _located(fit, w, ref)


def geometric_sphere(
    points: np.ndarray,
    *,
    start: np.ndarray | None = None,
    valid: np.ndarray | None = None,
) -> SphereFit:
    """The geometric least-squares sphere: minimise ``sum (|v - c| - r_k)^2`` over ``c`` and each
    marker's ``r_k`` (:func:`scipy.optimize.least_squares`, Levenberg-Marquardt).

    Args:
        points: ``(frames, 3)`` or ``(frames, markers, 3)`` points fixed on the moving segment,
            in the frame the centre is fixed in, metres.
        start: optional ``(3,)`` starting centre, metres; default Gamage and Lasenby's closed form.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre and radii in the points' frame, the radial rms residual and the spread.

    Raises:
        CalibrationInputError: malformed points or ``start``, NaN in a used frame, too few frames.
        CalibrationError: the points do not move or lie in parallel planes; the solver failed; the
            centre is not located (its standard error exceeds the radius).
    """
    v, used = check_points(points, "points", valid)
    w, ref, C = _scatter(v[used])
    spread = _check_spread(w, ref, C)
    if start is None:
        c0 = _closed_form(w, C, 0.0)
    else:
        c0 = np.asarray(start, dtype=float)
        if c0.shape != (3,) or not np.isfinite(c0).all():
            raise CalibrationInputError(f"Expected start to be a finite (3,) centre, got shape {c0.shape}")
        c0 = c0 - ref
    m = w.shape[1]
    r0, _ = _radial(w, c0)
    flat = w.reshape(-1, 3)
    marker = np.tile(np.arange(m), w.shape[0])

    def residual(x: np.ndarray) -> np.ndarray:
        return np.linalg.norm(flat - x[:3], axis=1) - x[3:][marker]

    def jacobian(x: np.ndarray) -> np.ndarray:
        diff = flat - x[:3]
        dist = np.maximum(np.linalg.norm(diff, axis=1), np.finfo(float).tiny)
        J = np.zeros((flat.shape[0], 3 + m))
        J[:, :3] = -diff / dist[:, None]
        J[np.arange(flat.shape[0]), 3 + marker] = -1.0
        return J

    sol = least_squares(
        residual, np.concatenate([c0, r0]), jac=jacobian, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14
    )
    if sol.status <= 0 or not np.isfinite(sol.x).all():
        raise CalibrationError(f"The geometric sphere fit did not converge: {sol.message}")
    c = sol.x[:3]
    radii, e = _radial(w, c)
    fit = SphereFit(
        centre=c + ref,
        radii=radii,
        rms_residual=float(np.sqrt(np.mean(e * e))),
        spread_m=spread,
        noise_std_m=float("nan"),
        method="geometric",
        n_frames=int(w.shape[0]),
        n_markers=int(m),
        n_iterations=int(sol.nfev),
    )
    return _located(fit, w, ref)


def fit_sphere(
    points: np.ndarray,
    *,
    variant: str = "gamage-lasenby",
    bias_correction: bool = False,
    noise_std_m: float | None = None,
    valid: np.ndarray | None = None,
) -> SphereFit:
    """Either sphere fit by name (:data:`VARIANTS`); arguments as :func:`gamage_lasenby`.

    ``bias_correction`` and ``noise_std_m`` belong to the closed form: given with
    ``variant="geometric"`` they raise :class:`CalibrationInputError`.
    """
    if variant == "gamage-lasenby":
        return gamage_lasenby(points, bias_correction=bias_correction, noise_std_m=noise_std_m, valid=valid)
    if variant == "geometric":
        if bias_correction or noise_std_m is not None:
            raise CalibrationInputError(
                "Expected bias_correction and noise_std_m only with variant='gamage-lasenby', got them "
                "with 'geometric'"
            )
        return geometric_sphere(points, valid=valid)
    raise CalibrationInputError(f"Expected variant to be one of {', '.join(VARIANTS)}, got {variant!r}")


def points_in_parent(R_w_p: np.ndarray, p_w_p: np.ndarray, points_w: np.ndarray) -> np.ndarray:
    """World points expressed in the parent sensor's frame: ``R_w_p^T (x_w - p_w_p)``.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        points_w: ``(frames, 3)`` or ``(frames, markers, 3)`` points in world, metres.

    Returns:
        The points in the parent frame, the shape of ``points_w``, metres. No checks (see
        :func:`sphere_joint` for the checked path).
    """
    x = np.asarray(points_w, dtype=float)
    if x.ndim == 2:
        return np.einsum("fji,fj->fi", R_w_p, x - p_w_p)
    return np.einsum("fji,fkj->fki", R_w_p, x - p_w_p[:, None, :])


def centre_in_child(
    R_w_p: np.ndarray, p_w_p: np.ndarray, R_w_c: np.ndarray, p_w_c: np.ndarray, joint_in_parent: np.ndarray
) -> np.ndarray:
    """The child-frame point that best follows a parent-frame centre, by least squares.

    Minimises ``sum_f |R_w_c[f] c_c + p_w_c[f] - (R_w_p[f] c_p + p_w_p[f])|^2`` over ``c_c``:
    the mean over frames of ``R_w_c[f]^T (R_w_p[f] c_p + p_w_p[f] - p_w_c[f])``.

    Args:
        R_w_p, R_w_c: ``(frames, 3, 3)`` used frames' rotations, sensor to world.
        p_w_p, p_w_c: ``(frames, 3)`` used frames' positions in world, metres.
        joint_in_parent: ``(3,)`` the centre in the parent frame, metres.

    Returns:
        ``(3,)`` the centre in the child frame, metres.
    """
    at_w = np.einsum("fij,j->fi", R_w_p, joint_in_parent) + p_w_p
    return np.einsum("fji,fj->i", R_w_c, at_w - p_w_c) / R_w_p.shape[0]


@dataclass(frozen=True)
class SphereJoint:
    """A joint centre from a sphere fit of child points seen from the parent.

    Attributes:
        joint_in_parent: ``(3,)`` centre in the parent sensor's frame, metres.
        joint_in_child: ``(3,)`` centre in the child sensor's frame (:func:`centre_in_child`),
            metres; ``None`` when the child's pose was not given.
        rms_residual: root mean square over used frames of the joint constraint's residual norm
            (O'Brien eq. 8) at both centres, metres; NaN without the child's pose.
        frame_residual: ``(frames,)`` that residual per frame, NaN where unused; ``None`` without
            the child's pose.
        sphere: the sphere fit in the parent frame.
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray | None
    rms_residual: float
    frame_residual: np.ndarray | None
    sphere: SphereFit


def sphere_joint(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    points_w: np.ndarray,
    *,
    R_w_c: np.ndarray | None = None,
    p_w_c: np.ndarray | None = None,
    variant: str = "gamage-lasenby",
    bias_correction: bool = False,
    noise_std_m: float | None = None,
    valid: np.ndarray | None = None,
) -> SphereJoint:
    """Joint centre from a sphere fit of world points carried into the parent's frame.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        points_w: ``(frames, 3)`` or ``(frames, markers, 3)`` points fixed on the child, in world,
            metres (markers, or the child sensor's origin ``p_w_c``).
        R_w_c: optional ``(frames, 3, 3)`` child sensor rotations; with ``p_w_c`` gives the
            centre in the child's frame too.
        p_w_c: optional ``(frames, 3)`` child sensor positions in world, metres.
        variant: as :func:`fit_sphere`.
        bias_correction: as :func:`fit_sphere`.
        noise_std_m: as :func:`fit_sphere`.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre in the parent frame (and the child frame), the residual and the sphere fit.

    Raises:
        CalibrationInputError: malformed arrays, only one of ``R_w_c``/``p_w_c``, NaN in a used
            frame, too few frames, a bad option.
        CalibrationError: the points do not move or lie in parallel planes.
    """
    if (R_w_c is None) != (p_w_c is None):
        raise CalibrationInputError("Expected both R_w_c and p_w_c or neither, got only one")
    child_given = R_w_c is not None and p_w_c is not None
    if child_given:
        pair = check_pair(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid, min_frames=MIN_FRAMES)
    else:  # the parent's pose stands in for the child's: checked once, never used
        pair = check_pair(R_w_p, p_w_p, R_w_p, p_w_p, valid=valid, min_frames=MIN_FRAMES)
    u = pair.used
    x = _points_array(points_w, "points_w")
    if x.shape[0] != u.shape[0]:
        raise CalibrationInputError(
            f"Expected points_w to have {u.shape[0]} frames like R_w_p, got {x.shape[0]}"
        )
    x, _ = check_points(x, "points_w", u)
    v = np.full(x.shape, np.nan)
    v[u] = points_in_parent(pair.R_w_p[u], pair.p_w_p[u], x[u])
    fit = fit_sphere(v, variant=variant, bias_correction=bias_correction, noise_std_m=noise_std_m, valid=u)
    if not child_given:
        return SphereJoint(fit.centre.copy(), None, float("nan"), None, fit)
    c_c = centre_in_child(pair.R_w_p[u], pair.p_w_p[u], pair.R_w_c[u], pair.p_w_c[u], fit.centre)
    residual = frame_residuals(pair, fit.centre, c_c)
    return SphereJoint(fit.centre.copy(), c_c, rms(residual), residual, fit)
