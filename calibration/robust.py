"""Robust joint fits: O'Brien's joint fit by iteratively reweighted least squares (IRLS).

The least-squares fit of :func:`calibration.joint.fit_joint` (O'Brien et al. 2000, eqs. 9-13)
gives every frame the same say. A sensor that slides on the skin for a second, or a burst of
magnetic-field distortion, puts a few percent of frames centimetres off, and a squared loss lets
those frames pull the joint centre by millimetres. Here each frame ``f`` gets a weight ``w_f``
from the norm of its 3-D residual ``r_f = |A_f x - b_f|`` (one weight per frame: the three rows
of a frame are one measurement), and the weighted problem ``min_x sum_f w_f |A_f x - b_f|^2`` is
solved again with new weights until the solution settles (IRLS for an M-estimator on the norm).

**Scale.** For a joint that fits up to Gaussian noise of ``sigma`` per axis, ``r_f / sigma``
follows the chi distribution with 3 degrees of freedom, whose median is not 1 (nor the 0.6745
of the one-dimensional MAD) but ``sqrt(chi2.ppf(0.5, 3)) = 1.5382`` (:data:`CHI3_MEDIAN`). The
robust scale is therefore ``sigma = median_f(r_f) / 1.5382`` -- the median absolute deviation of
the residual norms about their model centre, zero -- re-estimated at every iteration. It is a
per-axis standard deviation in metres (:attr:`RobustJointFit.scale_m`). A floor of
:data:`SCALE_FLOOR` times the rms of ``|b_f|`` (the sensors' separation) keeps exact data from
weighting rounding errors.

**Losses and tuning** (``u = r_f / sigma``, a multiple of the per-axis noise):

- ``"huber"``: ``w = min(1, c / u)``, convex, a unique minimum; every frame keeps some pull, at
  most ``c sigma``.
- ``"tukey"`` (biweight): ``w = (1 - (u / c)^2)^2`` for ``u < c``, else 0: frames beyond ``c``
  have no pull at all. Its objective is not convex, so it starts from the converged Huber fit
  (with :data:`HUBER_C`), not from least squares (which gross outliers may have pulled into a
  wrong basin).

**Which loss.** Tukey's is the default. Huber's bounded pull is still a pull: 5 % of frames each
pulling ``c sigma`` in a consistent direction (a slip block is one offset) bias the centre by
about as much as the noise itself. Measured in ``tests/test_robust.py`` (3000 frames, 1 mm noise,
5 % of frames slipping 2-5 cm or in field-distortion bursts of 3-8 cm or 5-10 degrees, rms over
six seeds): least squares 13-36 times the clean session's joint-centre error, Huber 1.6-2.0
times, Tukey 1.00-1.05 times; on clean sessions both are within 1.03 times least squares.

The default constants give 95 % asymptotic efficiency under Gaussian noise *for the norm of a
3-D residual*, not the familiar one-dimensional 1.345 and 4.685. For weights on the norm, the
M-estimator's covariance is ``V (A^T A)^-1 sigma^2`` with
``V = 3 E[psi(u)^2] / E[2 psi(u) / u + psi'(u)]^2`` and ``u ~ chi_3`` (the sandwich formula with
the isotropic Jacobian ``E[w] I + E[u w'] / 3 I``; ``V = 1`` for least squares), whatever the
rotations in ``A``. Solving ``1 / V = 0.95`` by quadrature (:func:`asymptotic_efficiency`)
gives ``c = 1.628`` for Huber (:data:`HUBER_C`) and ``c = 5.490`` for Tukey (:data:`TUKEY_C`).
Huber's ``c`` lies near the median of ``chi_3``, so about 45 % of clean frames are slightly
down-weighted: in three dimensions clipping the norm costs little (the spatial median, ``c -> 0``,
keeps 85 % efficiency). Tukey rejects a clean frame with probability ``1.3e-6``.

**Single-axis joints.** The least-squares fit, with its single-axis verdict, comes from
:func:`calibration.joint.fit_joint`; the weighted problems are solved only in the directions it
determines (the leading right singular vectors of ``A``), so a hinge keeps the minimum-norm
point along its axis. Corrupted frames mislead that verdict both ways: rotation errors turn the
relative rotation off a hinge's axis (a ball joint, or a tilted axis), and slip blocks inflate
the residual's variance until well-determined directions of a ball joint look undetermined
(measured: rank 4 and 5 for a ball joint swept through a 60 degree cone). So the verdict is asked
again of the inlier frames alone and the fit redone in the leading directions of the inliers'
``A``, until the inliers no longer change (at most :data:`MAX_REFITS` rounds). One guard: a
residual cannot reveal a corrupted frame along a direction only that frame informs, so a few
corrupted frames that happen to fit would pin a hinge's centre somewhere along its axis. A
direction is therefore kept only when its information is spread over at least
:data:`MIN_SUPPORT` of the inlier frames (:func:`supported_rank`).

**Inliers** are the frames whose residual norm is at most :data:`INLIER_C` ``sigma``, the
99.9 % point of ``chi_3``; :attr:`RobustJointFit.rms_residual` is their rms, comparable to the
least-squares ``rms_residual`` of a clean session.

:func:`robust_pair_misfits` fits every pair of sensors this way and returns the edge weights of
:func:`calibration.hierarchy.spanning_tree` (both of :data:`calibration.hierarchy.HIERARCHY_METHODS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration.defaults import LOSSES  # the losses robust_fit_joint knows, the default first
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hierarchy import HIERARCHY_METHODS, misfit_weights
from calibration.joint import (
    SINGLE_AXIS_RATIO,
    JointFit,
    Spectrum,
    check_pair,
    finite_frames,
    fit_joint,
    read_spectrum,
)
from calibration.pair_noise import THIRD_DIFFERENCE_GAIN
from calibration.poses import check_poses
from calibration.quantiles import chi2_ppf

#: Median of the chi distribution with 3 degrees of freedom, ``sqrt(chi2.ppf(0.5, 3))``: the
#: median residual norm of 3-D Gaussian noise with unit standard deviation per axis.
CHI3_MEDIAN = float(np.sqrt(chi2_ppf(0.5, 3)))

#: Huber's ``c`` for 95 % efficiency on the norm of a 3-D Gaussian residual (module docstring;
#: the root of ``asymptotic_efficiency("huber", c) = 0.95`` is 1.62799).
HUBER_C = 1.628

#: Tukey's ``c`` for 95 % efficiency on the norm of a 3-D Gaussian residual (root 5.49025).
TUKEY_C = 5.490

#: Default tuning constant of each loss, in units of the per-axis noise ``sigma``.
TUNING = {"huber": HUBER_C, "tukey": TUKEY_C}

#: Frames with residual norm up to this many ``sigma`` are inliers: ``sqrt(chi2.ppf(0.999, 3))``,
#: so one clean frame in a thousand is left out of :attr:`RobustJointFit.rms_residual`.
INLIER_C = float(np.sqrt(chi2_ppf(0.999, 3)))

#: The robust scale is at least this times the rms of ``|b_f|`` (the sensors' separation): on
#: exact data the residuals are rounding errors (~1e-16 of the separation), which must not be
#: weighted as if they were noise. 1e-9 of a 0.3 m separation is 0.3 nm, far below any tracker.
SCALE_FLOOR = 1e-9

#: Most rounds of asking the single-axis verdict again of the inliers and refitting (module
#: docstring); each round stops early once the inlier frames no longer change.
MAX_REFITS = 5

#: Least support (effective share of the inlier frames, :func:`supported_rank`) a direction the
#: rotation alone determines needs to be kept: 2 %, about a second of a one-minute recording.
MIN_SUPPORT = 0.02

#: Fewest frames a robust fit accepts: 6 unknowns and 3 equations per frame, so with fewer than
#: about 10 frames the fit absorbs a fifth or more of the noise and the median residual no longer
#: measures it.
MIN_FRAMES = 10


@dataclass(frozen=True)
class RobustJointFit:
    """The rotary joint between a parent and a child sensor, fitted by IRLS.

    Attributes:
        joint_in_parent: ``(3,)`` joint centre in the parent sensor's frame, metres.
        joint_in_child: ``(3,)`` joint centre in the child sensor's frame, metres.
        weights: ``(frames,)`` final IRLS weight of each input frame, in [0, 1]; NaN where the
            frame was dropped (non-finite pose or marked invalid).
        frame_residual: ``(frames,)`` residual norm ``|A_f x - b_f|`` per input frame, metres;
            NaN where dropped.
        inlier: ``(frames,)`` bool, residual norm at most :data:`INLIER_C` ``* scale_m``.
        scale_m: robust noise standard deviation per axis, ``median(r_f) / CHI3_MEDIAN``,
            metres (floored, see :data:`SCALE_FLOOR`).
        rms_residual: rms residual norm over the inlier frames, metres.
        n_iter: weighted solves made (Huber's and, for Tukey, the biweight's, summed).
        converged: the solution's change fell below ``tol`` before ``max_iter`` in every stage.
        loss: ``"huber"`` or ``"tukey"``.
        tuning: the loss's ``c``, in units of ``scale_m``.
        rank: directions the fit determines (6 ball joint, 5 single-axis).
        single_axis: the relative motion of the inlier frames is about one axis.
        axis_in_parent: ``(3,)`` unit axis in the parent frame when ``single_axis``, else None.
        axis_in_child: ``(3,)`` unit axis in the child frame when ``single_axis``, else None.
        ols: the least-squares fit of all usable frames, for comparison.
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    weights: np.ndarray
    frame_residual: np.ndarray
    inlier: np.ndarray
    scale_m: float
    rms_residual: float
    n_iter: int
    converged: bool
    loss: str
    tuning: float
    rank: int
    single_axis: bool
    axis_in_parent: np.ndarray | None
    axis_in_child: np.ndarray | None
    ols: JointFit

    @property
    def n_inliers(self) -> int:
        """Number of inlier frames."""
        return int(np.count_nonzero(self.inlier))

    @property
    def inlier_fraction(self) -> float:
        """Inlier frames over the frames used."""
        return self.n_inliers / max(self.ols.n_frames, 1)


def loss_weights(u: np.ndarray, loss: str, tuning: float) -> np.ndarray:
    """IRLS weights ``psi(u) / u`` of standardised residual norms.

    Args:
        u: ``(...)`` residual norms over the scale (dimensionless, non-negative).
        loss: ``"huber"`` or ``"tukey"``.
        tuning: the loss's ``c``, same units as ``u``.

    Returns:
        ``(...)`` weights in [0, 1].
    """
    u = np.asarray(u, dtype=float)
    if loss == "huber":
        return np.minimum(1.0, tuning / np.maximum(u, np.finfo(float).tiny))
    return np.where(u < tuning, np.square(1.0 - np.square(u / tuning)), 0.0)


def asymptotic_efficiency(loss: str, tuning: float) -> float:
    """Asymptotic efficiency, relative to least squares, of the M-estimator on the residual norm.

    ``1 / V`` with ``V = 3 E[psi^2] / E[2 psi / u + psi']^2`` and ``u ~ chi_3`` (module
    docstring), by quadrature: the noise is Gaussian, isotropic, with known scale.

    Args:
        loss: ``"huber"`` or ``"tukey"``.
        tuning: the loss's ``c`` (positive).
    """
    loss, c = _check_loss(loss, tuning)
    # here, not at the top: scipy.stats and scipy.integrate cost 0.7 s at every start of the command
    # line, for a figure only the tests and studies ask for
    from scipy.integrate import quad
    from scipy.stats import chi

    pdf = chi(3).pdf
    if loss == "huber":
        slope = quad(lambda u: 3.0 * pdf(u), 0.0, c)[0]
        slope += quad(lambda u: 2.0 * c / u * pdf(u), c, np.inf)[0]
        power = quad(lambda u: u * u * pdf(u), 0.0, c)[0] + c * c * chi(3).sf(c)
    else:

        def psi(u: float) -> float:
            return u * (1.0 - (u / c) ** 2) ** 2

        def dpsi(u: float) -> float:
            return (1.0 - (u / c) ** 2) * (1.0 - 5.0 * (u / c) ** 2)

        slope = quad(lambda u: (2.0 * psi(u) / u + dpsi(u)) * pdf(u), 0.0, c, limit=200)[0]
        power = quad(lambda u: psi(u) ** 2 * pdf(u), 0.0, c, limit=200)[0]
    return float(slope * slope / (3.0 * power))


def robust_fit_joint(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
    loss: str = LOSSES[0],
    tuning: float | None = None,
    max_iter: int = 50,
    tol: float = 1e-10,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
) -> RobustJointFit:
    """Fit the rotary joint between two sensors robustly (IRLS on the residual norm).

    Starts from :func:`calibration.joint.fit_joint` (least squares, with its single-axis
    verdict) and reweights frames by their residual norm (module docstring).

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are dropped, as are frames with
            a non-finite pose.
        loss: ``"tukey"`` (the default) or ``"huber"`` (:data:`LOSSES`).
        tuning: the loss's ``c`` in units of the per-axis noise; ``None`` for the 95 %
            efficiency constant (:data:`TUNING`).
        max_iter: most weighted solves per stage (at least 1).
        tol: convergence: the largest change of ``x`` at most ``tol`` times the larger of
            ``max |x|`` and the scale (dimensionless, so any length unit works).
        single_axis_ratio: the hard floor of :mod:`calibration.joint`.

    Returns:
        The fit, its weights and residuals, and the least-squares fit for comparison.

    Raises:
        CalibrationInputError: malformed arrays, an unknown loss, a tuning constant that is not
            a positive number, ``max_iter < 1`` or ``tol <= 0``.
        CalibrationError: fewer than :data:`MIN_FRAMES` usable frames.
    """
    R_w_p, p_w_p, R_w_c, p_w_c = check_pair(R_w_p, p_w_p, R_w_c, p_w_c)
    loss, c = _check_loss(loss, TUNING.get(loss, 1.0) if tuning is None else tuning)
    if isinstance(max_iter, bool) or not isinstance(max_iter, int | np.integer) or max_iter < 1:
        raise CalibrationInputError(f"max_iter must be an integer of at least 1, got {max_iter!r}")
    if not isinstance(tol, float | int | np.floating | np.integer) or not np.isfinite(tol) or tol <= 0:
        raise CalibrationInputError(f"tol must be a positive number, got {tol!r}")
    n_total = R_w_p.shape[0]
    ok = finite_frames(R_w_p, p_w_p, R_w_c, p_w_c)
    if valid is not None:
        valid = np.asarray(valid)
        if valid.shape != (n_total,) or valid.dtype != bool:
            raise CalibrationInputError(
                f"Expected valid to be a bool array of shape ({n_total},), got {valid.dtype} {valid.shape}"
            )
        ok &= valid
    n_used = int(np.count_nonzero(ok))
    if n_used < MIN_FRAMES:
        raise CalibrationError(
            f"A robust joint fit needs at least {MIN_FRAMES} frames where both poses are valid, got {n_used}"
        )
    A = np.concatenate([R_w_p[ok], -R_w_c[ok]], axis=2)  # (n, 3, 6), O'Brien eq. 12
    b = p_w_c[ok] - p_w_p[ok]  # (n, 3), O'Brien eq. 11
    floor = SCALE_FLOOR * float(np.sqrt(np.mean(np.sum(b * b, axis=1))))
    ols = fit_joint(R_w_p, p_w_p, R_w_c, p_w_c, valid=ok, single_axis_ratio=single_axis_ratio)

    V, spectrum = _determined_basis(A, ols.rank, single_axis_ratio)
    x0 = np.concatenate([ols.joint_in_parent, ols.joint_in_child])
    x, n_iter, converged = _solve(A, b, V, x0, loss, c, floor, max_iter, tol)
    r, scale = _residual_and_scale(A, b, x, floor)
    inlier = r <= INLIER_C * scale
    for _ in range(MAX_REFITS):
        # the verdict and the directions asked again of the inliers (module docstring)
        if not MIN_FRAMES <= np.count_nonzero(inlier) < n_used:
            break
        clean = np.zeros(n_total, dtype=bool)
        clean[np.flatnonzero(ok)[inlier]] = True
        recheck = fit_joint(R_w_p, p_w_p, R_w_c, p_w_c, valid=clean, single_axis_ratio=single_axis_ratio)
        rank = supported_rank(A[inlier], recheck.rank)
        if rank == spectrum.rank == 6:
            break
        grew = rank > spectrum.rank
        V, spectrum = _determined_basis(A[inlier], rank, single_axis_ratio)
        start = V @ (V.T @ x)
        x, more, again = (
            _solve(A, b, V, start, loss, c, floor, max_iter, tol)  # from Huber: a new direction
            if grew
            else _irls(A, b, V, start, loss, c, floor, max_iter, tol)
        )
        n_iter, converged = n_iter + more, converged and again
        r, scale = _residual_and_scale(A, b, x, floor)
        before, inlier = inlier, r <= INLIER_C * scale
        if np.array_equal(before, inlier):
            break

    weights = np.full(n_total, np.nan)
    weights[ok] = loss_weights(r / scale, loss, c)
    frame_residual = np.full(n_total, np.nan)
    frame_residual[ok] = r
    inlier_all = np.zeros(n_total, dtype=bool)
    inlier_all[ok] = inlier
    return RobustJointFit(
        joint_in_parent=x[:3].copy(),
        joint_in_child=x[3:].copy(),
        weights=weights,
        frame_residual=frame_residual,
        inlier=inlier_all,
        scale_m=float(scale),
        rms_residual=float(np.sqrt(np.mean(r[inlier] ** 2))) if inlier.any() else float("nan"),
        n_iter=n_iter,
        converged=converged,
        loss=loss,
        tuning=c,
        rank=spectrum.rank,
        single_axis=spectrum.single_axis,
        axis_in_parent=spectrum.axis_in_parent,
        axis_in_child=spectrum.axis_in_child,
        ols=ols,
    )


def supported_rank(A: np.ndarray, rank: int) -> int:
    """The rank a joint fit keeps once directions resting on a handful of frames are dropped.

    The information along a direction ``v`` is ``sum_f h_f`` with ``h_f = |A_f v|^2``; its
    support is the effective number of frames carrying it, ``(sum h)^2 / sum h^2``, over the
    frame count. Directions are dropped from the weakest up (down to the three translations,
    which every frame supports) while their support is below :data:`MIN_SUPPORT` (module
    docstring: measured 0.4-0.7 for ball joints swept through a cone, 0.0004-0.003 for a hinge
    whose few corrupted inliers alone turn off its axis).

    Args:
        A: ``(n, 3, 6)`` the joint fit's rows per frame (O'Brien eq. 12).
        rank: the rank the single-axis verdict of :mod:`calibration.joint` gave.

    Returns:
        ``rank`` or fewer, at least ``min(rank, 3)``.
    """
    _, _, Vt = np.linalg.svd(np.linalg.qr(A.reshape(-1, 6), mode="r"))
    h = np.sum(np.square(A @ Vt.T), axis=1)  # (n, 6) information per frame and direction
    total = h.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        support = total * total / np.sum(h * h, axis=0) / A.shape[0]
    while rank > 3 and not support[rank - 1] >= MIN_SUPPORT:
        rank -= 1
    return rank


def _check_loss(loss: str, tuning: float) -> tuple[str, float]:
    """The loss name and its tuning constant as a float, or an input error."""
    if loss not in LOSSES:
        raise CalibrationInputError(f"loss must be one of {list(LOSSES)}, got {loss!r}")
    try:
        c = float(tuning)
    except (TypeError, ValueError):
        raise CalibrationInputError(f"tuning must be a positive number, got {tuning!r}") from None
    if not np.isfinite(c) or c <= 0.0:
        raise CalibrationInputError(f"tuning must be a positive number, got {tuning!r}")
    return loss, c


def _determined_basis(A: np.ndarray, rank: int, single_axis_ratio: float) -> tuple[np.ndarray, Spectrum]:
    """``(6, rank)`` the leading right singular vectors of ``A`` (``(n, 3, 6)``) -- the directions
    :func:`calibration.joint.fit_joint` determines (it drops directions from the weakest up) --
    and the spectrum read from them (rank, single-axis verdict, axis)."""
    _, s, Vt = np.linalg.svd(np.linalg.qr(A.reshape(-1, 6), mode="r"))  # A's spectrum, from its triangle
    keep = np.arange(6) < rank
    return Vt[:rank].T, read_spectrum(s, Vt.T, single_axis_ratio, keep)


def _residual_and_scale(
    A: np.ndarray, b: np.ndarray, x: np.ndarray, floor: float
) -> tuple[np.ndarray, float]:
    """``(n,)`` residual norms of ``x`` (metres) and the floored robust scale (module docstring)."""
    r = np.linalg.norm(A @ x - b, axis=1)
    return r, max(float(np.median(r)) / CHI3_MEDIAN, floor)


def _solve(  # positional: private
    A: np.ndarray,
    b: np.ndarray,
    V: np.ndarray,
    x0: np.ndarray,
    loss: str,
    c: float,
    floor: float,
    max_iter: int,
    tol: float,
) -> tuple[np.ndarray, int, bool]:
    """IRLS from ``x0`` in the span of ``V``: Huber, then (for Tukey) the biweight from Huber's
    solution. Returns ``(x, weighted solves, converged)``."""
    huber_c = c if loss == "huber" else HUBER_C
    x, n_iter, converged = _irls(A, b, V, x0, "huber", huber_c, floor, max_iter, tol)
    if loss == "tukey":
        x, more, again = _irls(A, b, V, x, "tukey", c, floor, max_iter, tol)
        n_iter, converged = n_iter + more, converged and again
    return x, n_iter, converged


def _irls(  # positional: private
    A: np.ndarray,
    b: np.ndarray,
    V: np.ndarray,
    x: np.ndarray,
    loss: str,
    c: float,
    floor: float,
    max_iter: int,
    tol: float,
) -> tuple[np.ndarray, int, bool]:
    """One loss's IRLS: reweight by the residual norms, solve the weighted problem in the span of
    ``V`` (``(6, k)``), repeat until ``x`` settles. ``A`` is ``(n, 3, 6)``, ``b`` ``(n, 3)``.

    Each weighted solve is an increment from the current ``x``: with ``e = b - A x`` (which the
    weights need anyway), ``dy = (sum_f w_f M_f)^-1 sum_f w_f (A_f V)^T e_f`` and
    ``M_f = (A_f V)^T (A_f V)`` formed once, so an iteration costs a weighted sum over the frames
    instead of a QR factorisation of the ``3 n x k`` weighted system, and the increment form keeps
    the accuracy of the residual (iterative refinement) where the normal matrix alone would square
    the condition number.
    """
    n, k = A.shape[0], V.shape[1]
    rows = A.reshape(3 * n, 6)
    AV = rows @ V  # (3 n, k)
    gram = np.einsum("fai,faj->fij", AV.reshape(n, 3, k), AV.reshape(n, 3, k)).reshape(n, k * k)  # M_f
    for it in range(1, max_iter + 1):
        e = b - (rows @ x).reshape(n, 3)
        r = np.sqrt(np.einsum("fa,fa->f", e, e))
        scale = max(float(np.median(r)) / CHI3_MEDIAN, floor)
        w = loss_weights(r / scale, loss, c)
        rhs = AV.T @ (e * w[:, None]).reshape(3 * n)  # sum_f w_f (A_f V)^T e_f
        step_y, *_ = np.linalg.lstsq((w @ gram).reshape(k, k), rhs, rcond=None)
        x_new = V @ (V.T @ x + step_y)
        step = float(np.max(np.abs(x_new - x)))
        x = x_new
        if step <= tol * max(float(np.max(np.abs(x))), scale):
            return x, it, True
    return x, max_iter, False


@dataclass(frozen=True)
class RobustPairMisfits:
    """Robust joint fits of every pair of sensors, as hierarchy edge weights.

    Attributes:
        residual: ``(N, N)`` symmetric rms residual over each pair's inlier frames
            (:attr:`RobustJointFit.rms_residual`), metres; ``inf`` on the diagonal and where a
            pair has fewer than :data:`MIN_FRAMES` common frames.
        noise_variance: ``(N, N)`` robust white-noise variance of each pair's residual (mean
            square norm, square metres): ``3 (median |d3 e| / (sqrt(20) CHI3_MEDIAN))^2`` from the
            third differences of the robust fit's residual vectors (as in
            :mod:`calibration.pair_noise`, with the median in place of the mean so that the edges
            of slip and distortion blocks do not count); ``inf`` where ``residual`` is.
        scale_m: ``(N, N)`` robust per-axis scale of each pair's fit, metres.
        inlier_fraction: ``(N, N)`` fraction of each pair's frames that are inliers (0 where not
            fitted).
    """

    residual: np.ndarray
    noise_variance: np.ndarray
    scale_m: np.ndarray
    inlier_fraction: np.ndarray

    def weights(self, method: str = HIERARCHY_METHODS[0]) -> np.ndarray:
        """``(N, N)`` edge weights for :func:`calibration.hierarchy.spanning_tree`.

        Args:
            method: ``"misfit"`` (inlier mean square residual less the robust noise variance,
                :func:`calibration.hierarchy.misfit_weights`) or ``"mst"`` (the inlier rms
                residual, O'Brien's weighting made robust).
        """
        if method not in HIERARCHY_METHODS:
            raise CalibrationInputError(f"method must be one of {list(HIERARCHY_METHODS)}, got {method!r}")
        if method == "mst":
            return self.residual
        return misfit_weights(
            self.residual, np.where(np.isfinite(self.noise_variance), self.noise_variance, 0)
        )


def robust_pair_misfits(
    R_w_s: Any,
    p_w_s: Any,
    *,
    valid: Any = None,
    loss: str = LOSSES[0],
    tuning: float | None = None,
    max_iter: int = 50,
    tol: float = 1e-10,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
) -> RobustPairMisfits:
    """Robust joint fit of every unordered pair of sensors, for a hierarchy built from them.

    One :func:`robust_fit_joint` per pair (``N (N - 1) / 2`` fits, the lower-index sensor as
    parent; the residual does not depend on which is parent), on arrays held in memory (unlike
    :func:`calibration.pairs.pair_statistics`, which reads chunks): fine for up to a few dozen
    sensors (32 sensors: 496 fits, each about 0.1 s for 3000 frames). Give
    :meth:`RobustPairMisfits.weights` to :func:`calibration.hierarchy.spanning_tree`.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` sensor positions in world, metres.
        valid: optional ``(frames, sensors)`` bool, False where a pose is missing.
        loss: as :func:`robust_fit_joint`.
        tuning: as :func:`robust_fit_joint`.
        max_iter: as :func:`robust_fit_joint`.
        tol: as :func:`robust_fit_joint`.
        single_axis_ratio: as :func:`robust_fit_joint`.

    Raises:
        CalibrationInputError: malformed arrays or options.
        CalibrationError: fewer than 2 sensors.
    """
    R_w_s = np.asarray(R_w_s, dtype=float)
    p_w_s = np.asarray(p_w_s, dtype=float)
    valid = None if valid is None else np.asarray(valid)
    _, n = check_poses(R_w_s, p_w_s, valid)
    if valid is not None and valid.dtype != bool:
        raise CalibrationInputError(f"Expected valid to be a bool array, got {valid.dtype}")
    _check_loss(loss, TUNING.get(loss, 1.0) if tuning is None else tuning)
    if n < 2:
        raise CalibrationError(f"robust pair misfits need at least 2 sensors, got {n}")
    ok = np.isfinite(R_w_s).all(axis=(2, 3)) & np.isfinite(p_w_s).all(axis=2)
    if valid is not None:
        ok &= valid
    residual = np.full((n, n), np.inf)
    noise = np.full((n, n), np.inf)
    scale = np.full((n, n), np.nan)
    fraction = np.zeros((n, n))
    for i, j in zip(*np.triu_indices(n, k=1), strict=True):
        both = ok[:, i] & ok[:, j]
        if np.count_nonzero(both) < MIN_FRAMES:
            continue
        fit = robust_fit_joint(
            R_w_s[:, i],
            p_w_s[:, i],
            R_w_s[:, j],
            p_w_s[:, j],
            valid=both,
            loss=loss,
            tuning=tuning,
            max_iter=max_iter,
            tol=tol,
            single_axis_ratio=single_axis_ratio,
        )
        e = _residual_vectors(R_w_s[:, i], p_w_s[:, i], R_w_s[:, j], p_w_s[:, j], fit, both)
        residual[i, j] = residual[j, i] = fit.rms_residual
        noise[i, j] = noise[j, i] = _robust_noise_variance(e)
        scale[i, j] = scale[j, i] = fit.scale_m
        fraction[i, j] = fraction[j, i] = fit.inlier_fraction
    return RobustPairMisfits(residual=residual, noise_variance=noise, scale_m=scale, inlier_fraction=fraction)


def _residual_vectors(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    fit: RobustJointFit,
    ok: np.ndarray,
) -> np.ndarray:
    """``(frames, 3)`` the fit's world residual vector per frame (O'Brien eq. 8), NaN where not
    ``ok``, metres."""
    e = np.full(p_w_p.shape, np.nan)
    e[ok] = (
        np.einsum("fij,j->fi", R_w_p[ok], fit.joint_in_parent)
        + p_w_p[ok]
        - np.einsum("fij,j->fi", R_w_c[ok], fit.joint_in_child)
        - p_w_c[ok]
    )
    return e


def _robust_noise_variance(e: np.ndarray) -> float:
    """Mean square norm of the white noise in residual vectors ``e`` (``(frames, 3)``, NaN where
    missing): the third difference of white noise of ``sigma`` per axis has norm
    ``sqrt(20) sigma chi_3``, so ``sigma = median |d3| / (sqrt(20) CHI3_MEDIAN)`` and the result
    is ``3 sigma^2``. Zero when no four consecutive frames are valid."""
    d3 = e[3:] - 3.0 * e[2:-1] + 3.0 * e[1:-2] - e[:-3]
    norms = np.linalg.norm(d3, axis=1)
    norms = norms[np.isfinite(norms)]
    if norms.size == 0:
        return 0.0
    sigma = float(np.median(norms)) / (np.sqrt(THIRD_DIFFERENCE_GAIN) * CHI3_MEDIAN)
    return 3.0 * sigma * sigma
