"""How well a joint fit places the joint centre: covariances and 95 % regions that keep their word.

A joint fit (:func:`calibration.joint.fit_joint`, O'Brien et al. 2000 eqs. 9-13) solves
``A x = b`` with ``A[f] = [R_w_p[f], -R_w_c[f]]`` (3 x 6), ``b[f] = p_w_c[f] - p_w_p[f]`` and
``x = [joint_in_parent; joint_in_child]``. With ``e[f] = b[f] - A[f] x`` the noise of frame ``f``,
the estimate moves by ``x_hat - x = G A^T e = G sum_f s_f`` where ``G = (A^T A)^+`` and
``s_f = A[f]^T e[f]`` is frame ``f``'s *score* (6,). The covariance of ``x_hat`` is therefore
``G Var(sum_f s_f) G`` and everything below is about estimating ``Var(sum_f s_f)`` from the
residual, in metres squared.

**Determined directions only.** ``G`` is the pseudo-inverse in the subspace the fit kept (its
``rank`` strongest right singular vectors ``V_k``: ``G = V_k S_k^-2 V_k^T``). A single-axis joint
(hinge) leaves its weakest direction out of the solution, where the centre is put at the
minimum-norm point, not measured; that direction gets *no* variance here (``cov @ v_6 = 0``).
The covariance describes the error of ``V_k V_k^T x``, the part of the centre the data determine:
a region that covers is one that contains the truth's projection ``V_k V_k^T x_true``, not any
point on the hinge axis.

**Noise on the rotations.** ``A`` is measured too, and the plain fit is biased by it
(:mod:`calibration.eiv`): its regions hold the truth less often the less a joint turned against
that noise (in the study's small-range sessions, 42 % instead of 95 %). A fit corrected for it
(:func:`calibration.joint.fit_joint` with ``orientation_noise_rad2``) solves ``N x = A^T b`` with
``N = A^T A - 2 F D``; its covariance is the same sandwich with ``N`` in place of ``A^T A``
(``gram_root`` whitens ``N`` in the determined directions, every block's information is
``A_b^T A_b - 2 F_b D``) and frame scores ``A[f]^T r[f] + 2 D x``, which sum to zero at the
corrected estimate (to ``sigma^2`` of it, after the shrink ``S`` is undone).

**Methods** (``method=``):

- ``"iid"`` -- frames independent: ``cov = G (sum_f A[f]^T Sigma_e A[f]) G`` with ``Sigma_e`` the
  3 x 3 world-frame covariance of the residual, pooled over frames (per axis and across axes,
  divided by ``n - rank / 3`` so that its trace is unbiased). For isotropic noise this is
  O'Brien's ``sigma^2 (A^T A)^+``. Degrees of freedom ``3 n - rank`` (normal quantiles, in
  effect). Residuals of real joints (soft tissue, play, tracker distortion) follow the motion and
  are correlated over tenths of a second: then these intervals are far too narrow (the tests
  measure 22-26 % per axis and 1-4 % for the 3-D regions, for a nominal 95 %, with noise
  correlated over 0.3 s), and a warning says so when the residual's
  integrated autocorrelation time exceeds :data:`IID_TAU_WARNING` frames.
- ``"batch-means"`` (the default) -- the sandwich with non-overlapping blocks of consecutive
  frames (batch means, as :mod:`calibration.hinge` already uses for its test):
  ``cov = G [sum_b g~_b g~_b^T] G`` with ``g_b = sum_{f in b} A[f]^T r[f]`` the block's summed
  score from the residual ``r``. The residual is the noise less the fit, which takes a share of
  each block's noise with it; the share is the block's *leverage*, ``M_b = T^T A_b^T A_b T``
  (whitened, ``G = T T^T``, summing to the identity over the blocks), and every block's score is
  corrected for it, ``T^T g~_b = (I - M_b)^(-1/2) T^T g_b`` (the CR2 correction of clustered
  sandwiches, Bell & McCaffrey 2002). For blocks of equal information, ``M_b = I / B``, this is
  the familiar ``B / (B - 1)``; blocks that carry unequal information (short blocks, in which the
  sensors barely turn, or motion that explores a direction only now and then) need more, and
  without it the variance came out 5 % low on white noise in 50 blocks. The degrees of freedom
  follow Satterthwaite (:func:`effective_dof`): ``B - 1`` for equal blocks, fewer for unequal
  ones (about 40 % as many in 50 short blocks of white noise, 80-90 % in 8-10 long ones). It is
  the default because it is right whether or not the residual is correlated (as long as the
  blocks are long against the correlation), needs no random numbers and is cheap.
- ``"block-bootstrap"`` -- a moving-block bootstrap (Kunsch 1989) of the estimating equations:
  ``n_boot`` replicates of ``floor(n / L)`` blocks of ``L`` consecutive used frames (starting every
  ``L / 8`` frames, :data:`MOVING_STEPS`) drawn with replacement, their leverage-corrected scores
  summed, each giving ``x* = x_hat + G (T* - E* T*)`` (linearised, ``A`` fixed), and the
  replicates' covariance (scaled from ``k L`` to ``n`` frames). It needs ``rng``. Its quantiles use
  1.5 times the batch-means degrees of freedom (:data:`OBM_DOF_FACTOR`: the overlapping batch
  means it approximates, Meketon & Schmeiser 1984); with the non-overlapping count alone its
  3-D regions covered 98-99 % in the tests, with 1.5 times it 95-96 %. It offers nothing the
  default lacks for the covariance; it is here to cross-check it.

**Block length.** The blocks must be long against the correlation of the scores, or the variance
is underestimated (by about ``tau / (2 L)`` for an AR(1) series). The rule: the integrated
autocorrelation time ``tau`` (frames) of the scores along the kept directions (Sokal's automatic
window, ``M >= 5 tau(M)``; the largest over the directions, :func:`integrated_autocorrelation_time`)
gives blocks of ``L = ceil(BLOCK_FACTOR tau)`` frames (:data:`BLOCK_FACTOR` = 10, so the bias is
about 5 % of the variance), and ``B = floor(n_total / L)`` nearly equal blocks on the recording's
time line (:func:`block_edges`). When the recording is too short for that (``B < MIN_BLOCKS``),
:data:`MIN_BLOCKS` shorter blocks are used and a warning says the intervals may be too narrow.
``n_blocks=`` overrides the rule. (The hinge test of :mod:`calibration.hinge` has blocks of its own,
``2^k`` frames long, that a calibration fed frame by frame can keep.)

**Quantiles.** The number of blocks is small, so the estimated covariance is uncertain itself:
per-axis intervals use Student's ``t`` with the degrees of freedom of the centre's own three
coordinates (:attr:`JointUncertainty.dof_in_parent`, :attr:`JointUncertainty.dof_in_child`).
A batch-means 3-D region is bounded by the 95 % quantile of its own statistic under the working
model (:func:`working_model_null`: independent Gaussian block scores with covariance proportional
to each block's information, put through the fit, the leverage correction and the region's
Mahalanobis distance exactly as the real scores are; 2,000 seeded draws, so the same fit always
gets the same region). Hotelling's ``T^2`` with Satterthwaite's degrees of freedom,
``p dof / (dof - p + 1) F_{p, dof - p + 1}(level)`` (``chi2_3`` as ``dof -> inf``; unbounded when
``dof < p``), is exact only for blocks of equal information; with unequal ones (a joint turned one
way now and another later) its one averaged count of degrees of freedom set the threshold too
high, a median 1.2 times the simulated one in the study's Polhemus sessions, and the regions held
the truth 97-98 % of the time. It is kept for ``"iid"``, for ``"block-bootstrap"`` and for batch
means whose blocks had to be shorter than the rule asks (the warned case: the blocks are then
correlated, the working model does not hold, and its quantile would be too small; on the study's
soft-tissue sessions it held the truth in 39 % of cases).

**Limb lengths.** A length is ``|c1 - c2|`` for two joint centres in one sensor frame; its
variance by the delta method is ``u^T (S1 + S2 - C - C^T) u`` with ``u`` the unit vector between
them (:func:`length_uncertainty`). Two centres from *different* joint fits of the same sensor (the
thigh's hip and knee) share that sensor's data over the same frames: noise on the thigh sensor
enters both fits, so their cross-covariance ``C`` is not zero in general.
:func:`length_uncertainty` takes ``C`` (``None`` assumes zero: only right for fits over disjoint
data or independent noise); :func:`segment_length_uncertainty` estimates it from both fits' scores
over common blocks (those of the fit with the longer blocks), which is what the calibration should
use. For that each :class:`JointUncertainty` keeps its fit's per-frame scores and relative
rotations (``15 x frames`` floats, about as much as the poses of one sensor).

**JSON.** :func:`to_json` gives a dict for the calibration JSON (lengths in metres):

- ``"method"``: ``"batch-means"``, ``"iid"`` or ``"block-bootstrap"``;
- ``"level"``: 0.95;
- ``"n_frames"``: frames used; ``"n_blocks"``: blocks ``B`` (frames for ``"iid"``);
  ``"block_frames"``: frames per block ``L`` (1 for ``"iid"``);
  ``"tau_int_frames"``: the scores' integrated autocorrelation time, frames (``null`` if unknown);
- ``"dof"``: degrees of freedom of the covariance estimate (at most ``B - 1``, or ``3 n - rank``);
  ``"dof_in_parent"``, ``"dof_in_child"``: those of each 3-D centre, which its intervals and
  ellipsoid use;
- ``"rank"``: determined directions (6 ball, 5 hinge);
- ``"cov_in_parent_m2"``, ``"cov_in_child_m2"``: 3 x 3 covariance of ``joint_in_parent`` /
  ``joint_in_child``, m^2; ``"cov_parent_child_m2"``: their 3 x 3 cross-covariance
  (rows parent, columns child);
- ``"ci95_in_parent_m"``, ``"ci95_in_child_m"``: ``[[lo, hi]] x 3`` per-axis 95 % intervals, m;
- ``"ellipsoid95_in_parent"``, ``"ellipsoid95_in_child"``: ``{"semi_axes_m": [3],
  "axes": [[3] x 3], "threshold": t, "quantile": q}`` the 95 % ellipsoid's semi-axes
  (descending) and their unit directions (one row per axis, in the sensor frame), its bound
  ``t`` on the squared Mahalanobis distance (``null``: unbounded) and where ``t`` comes from,
  ``"working-model"`` (:func:`working_model_null`) or ``"hotelling"``;
- ``"warnings"``: list of strings.

:func:`length_to_json` gives ``{"length_m", "std_m", "ci95_m": [lo, hi], "dof", "level"}``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as _fft

from calibration.eiv import corrected_normal_matrix, noise_diagonal
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import JointFit, check_pair, finite_frames
from calibration.quantiles import chi2_ppf, f_ppf, norm_ppf, t_ppf

#: The estimators of :func:`joint_covariance`; the first is the default.
METHODS = ("batch-means", "iid", "block-bootstrap")

#: Blocks are this many integrated autocorrelation times long: the batch-means variance of an
#: AR(1) series is low by about ``tau / (2 L)``, 5 % at 10.
BLOCK_FACTOR = 10.0

#: Sokal's automatic window: the autocorrelation is summed to the first lag ``M >= 5 tau(M)``.
WINDOW_FACTOR = 5.0

#: Fewest blocks the automatic rule uses (with ``dof = 7`` the 95 % Hotelling threshold is 2.9
#: times the chi-squared one); a shorter recording gets shorter blocks and a warning.
MIN_BLOCKS = 8

#: The bootstrap's moving blocks start every ``L / MOVING_STEPS`` frames (every frame when
#: ``L <= MOVING_STEPS``): neighbouring starts give nearly the same block, and each block's
#: leverage correction costs a 6 x 6 eigendecomposition.
MOVING_STEPS = 8

#: Overlapping blocks carry about 1.5 times the degrees of freedom of as many non-overlapping
#: ones (the overlapping batch means of Meketon & Schmeiser 1984, which the moving-block
#: bootstrap's variance approximates): the bootstrap's quantiles use 1.5 times the batch-means dof.
OBM_DOF_FACTOR = 1.5

#: Bootstrap replicates by default.
N_BOOT = 999

#: ``"iid"`` warns when the scores' integrated autocorrelation time exceeds this (frames).
IID_TAU_WARNING = 2.0

#: Leverage (a block's share of the information along a direction) above which a block's score is
#: no longer inflated further: ``(1 - 0.99)^(-1/2) = 10`` times at most.
MAX_LEVERAGE = 0.99

#: A warning is given when one block carries more than this share along some direction.
LEVERAGE_WARNING = 0.5

#: The level of the regions and intervals by default (and in :func:`to_json`).
LEVEL = 0.95

#: Draws of the working model that give a batch-means region its threshold
#: (:func:`working_model_null`): the 95 % quantile's coverage is then exact to about
#: ``sqrt(0.05 * 0.95 / 2000)`` = 0.5 % (its Monte Carlo error).
N_NULL_DRAWS = 2000

#: Seed of those draws: the same fit always gets the same threshold.
NULL_SEED = 20000

PARTS = ("parent", "child")


@dataclass(frozen=True)
class Region:
    """A joint centre's confidence region in one sensor frame.

    Attributes:
        centre: ``(3,)`` the estimate, metres.
        cov: ``(3, 3)`` its covariance, m^2.
        level: coverage probability, e.g. 0.95.
        dof: degrees of freedom of the covariance estimate (``inf``: known).
        threshold: the squared Mahalanobis distance bounding the ellipsoid: the ``level``
            quantile of the working model's null draws where the fit has them
            (:func:`working_model_null`), else Hotelling's ``T^2`` with ``p`` = the covariance's
            rank (``inf`` when ``dof < p``).
        semi_axes_m: ``(3,)`` the ellipsoid's semi-axes, descending, metres.
        axes: ``(3, 3)`` their unit directions as rows, in the sensor frame.
        intervals_m: ``(3, 2)`` per-axis ``[lo, hi]`` (Student's ``t``), metres.
    """

    centre: np.ndarray
    cov: np.ndarray
    level: float
    dof: float
    threshold: float
    semi_axes_m: np.ndarray
    axes: np.ndarray
    intervals_m: np.ndarray


@dataclass(frozen=True)
class JointUncertainty:
    """The covariance of one joint fit's centre, and what it was estimated from.

    Attributes:
        joint_in_parent: ``(3,)`` the fit's joint centre in the parent sensor frame, metres.
        joint_in_child: ``(3,)`` in the child sensor frame, metres.
        cov: ``(6, 6)`` covariance of ``[joint_in_parent; joint_in_child]``, m^2; zero along the
            directions the fit left undetermined.
        method: one of :data:`METHODS`.
        dof: degrees of freedom of ``cov`` (:func:`effective_dof`: ``B - 1`` for blocks of equal
            information, fewer for unequal ones; ``3 n - rank`` for ``"iid"``).
        dof_in_parent, dof_in_child: the same for the 3-D centre in each frame alone (what its
            region and intervals use).
        n_frames: frames used by the fit.
        n_blocks: blocks ``B`` (frames used, for ``"iid"``).
        block_frames: frames per block ``L`` (1 for ``"iid"``).
        tau_int_frames: integrated autocorrelation time of the scores, frames (NaN: exact data).
        basis: ``(6, rank)`` orthonormal basis of the determined directions (``V_k``).
        gram_root: ``(6, rank)`` ``T = V_k S_k^-1`` with ``T T^T = (A^T A)^+`` in the determined
            directions (dimensionless): the whitening of the scores.
        frame_scores: ``(frames, 6)`` per input frame ``A[f]^T r[f]``, metres; zero where a frame
            was not used. Kept for cross-covariances between fits (:func:`cross_covariance`).
        relative_rotation: ``(frames, 3, 3)`` ``R_w_p^T R_w_c`` per input frame (zero where not
            used), from which every block's ``A_b^T A_b`` follows (for the leverage correction).
        used: ``(frames,)`` bool, the frames the fit used.
        block_edges: ``(B + 1,)`` frame indices of the blocks on the recording's time line (every
            frame for ``"iid"``; for ``"block-bootstrap"`` the non-overlapping blocks of the same
            count): the blocks :func:`cross_covariance` uses.
        warnings: plain-language notes on what the intervals may get wrong.
        orientation_noise_rad2: the rotation-noise variances the fit was corrected for
            (:mod:`calibration.eiv`), rad^2; then ``gram_root`` whitens the corrected normal
            matrix and every frame's score carries the correction's ``2 D x``.
        null_in_parent, null_in_child: ``(N_NULL_DRAWS,)`` sorted draws of the region statistic
            (squared Mahalanobis distance) under the working model, whose ``level`` quantile
            bounds each frame's region (:func:`working_model_null`); ``None`` where Hotelling's
            ``T^2`` is used instead (``"iid"``, ``"block-bootstrap"``, and batch means whose
            blocks had to be shorter than the rule asks).
        bias_bound_m: the most an error of the residual's systematic size that moves with the
            joint can shift the centre, metres (:func:`calibration.diagnostics.motion_bias_bounds`:
            noise over range of motion), which the variance-based regions do not hold; NaN where
            not computed (``calibrate`` sets it).
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    cov: np.ndarray
    method: str
    dof: float
    dof_in_parent: float
    dof_in_child: float
    n_frames: int
    n_blocks: int
    block_frames: int
    tau_int_frames: float
    basis: np.ndarray
    gram_root: np.ndarray
    frame_scores: np.ndarray
    relative_rotation: np.ndarray
    used: np.ndarray
    block_edges: np.ndarray
    warnings: tuple[str, ...] = ()
    orientation_noise_rad2: tuple[float, float] = (0.0, 0.0)
    null_in_parent: np.ndarray | None = None
    null_in_child: np.ndarray | None = None
    bias_bound_m: float = float("nan")

    @property
    def rank(self) -> int:
        """Number of determined directions (6 for a ball joint, 5 for a hinge)."""
        return int(self.basis.shape[1])

    @property
    def gram_pinv(self) -> np.ndarray:
        """``(6, 6)`` ``(A^T A)^+`` in the determined directions (dimensionless)."""
        return self.gram_root @ self.gram_root.T

    @property
    def cov_in_parent(self) -> np.ndarray:
        """``(3, 3)`` covariance of ``joint_in_parent``, m^2."""
        return self.cov[:3, :3]

    @property
    def cov_in_child(self) -> np.ndarray:
        """``(3, 3)`` covariance of ``joint_in_child``, m^2."""
        return self.cov[3:, 3:]

    @property
    def cov_parent_child(self) -> np.ndarray:
        """``(3, 3)`` cross-covariance, rows ``joint_in_parent``, columns ``joint_in_child``, m^2."""
        return self.cov[:3, 3:]

    def region(self, part: str, level: float = LEVEL) -> Region:
        """The confidence region of the centre in the ``"parent"`` or ``"child"`` sensor frame."""
        sl = _part_slice(part)
        centre = self.joint_in_parent if part == "parent" else self.joint_in_child
        dof = self.dof_in_parent if part == "parent" else self.dof_in_child
        null = self.null_in_parent if part == "parent" else self.null_in_child
        threshold = None if null is None else _null_quantile(null, level)
        return confidence_region(centre, self.cov[sl, sl], dof=dof, level=level, threshold=threshold)


@dataclass(frozen=True)
class LengthUncertainty:
    """A limb length (distance between two joint centres in one sensor frame) and its uncertainty.

    Attributes:
        length_m: the estimated length, metres.
        variance_m2: its delta-method variance, m^2.
        dof: degrees of freedom of the variance (``inf``: known).
        level: the interval's coverage probability.
        interval_m: ``(lo, hi)`` Student's ``t`` interval, metres.
    """

    length_m: float
    variance_m2: float
    dof: float
    level: float
    interval_m: tuple[float, float]

    @property
    def std_m(self) -> float:
        """Standard error, metres."""
        return math.sqrt(self.variance_m2)


# ----------------------------------------------------------------------------------------------
# quantiles and regions


def t_quantile(dof: float, level: float = LEVEL) -> float:
    """Two-sided Student's ``t`` quantile: half-width of a ``level`` interval in standard errors."""
    _check_level(level)
    q = 0.5 + level / 2.0
    return float(norm_ppf(q) if math.isinf(dof) else t_ppf(q, dof))


def region_threshold(p: int | np.ndarray, dof: float | np.ndarray, level: float = LEVEL) -> np.ndarray:
    """Squared Mahalanobis distance bounding a ``level`` region in ``p`` dimensions.

    Hotelling's ``T^2`` with ``dof`` degrees of freedom for the covariance estimate:
    ``p dof / (dof - p + 1) F_{p, dof - p + 1}(level)``; ``chi2_p(level)`` for ``dof = inf``;
    ``inf`` when ``dof < p``; 0 when ``p = 0``. Broadcasts over ``p`` and ``dof``.
    """
    _check_level(level)
    p, dof = np.broadcast_arrays(np.asarray(p, dtype=float), np.asarray(dof, dtype=float))
    d2 = dof - p + 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        hot = p * dof / d2 * f_ppf(level, np.maximum(p, 1.0), np.where(d2 > 0, d2, 1.0))
    out = np.where(np.isinf(dof), chi2_ppf(level, np.maximum(p, 1.0)), hot)
    out = np.where(~np.isinf(dof) & (d2 <= 0), np.inf, out)
    return np.where(p == 0, 0.0, out)


def confidence_region(
    centre: np.ndarray, cov3: np.ndarray, *, dof: float, level: float = LEVEL, threshold: float | None = None
) -> Region:
    """The ``level`` ellipsoid and per-axis intervals of a 3-D estimate.

    Args:
        centre: ``(3,)`` estimate, metres.
        cov3: ``(3, 3)`` its covariance, m^2.
        dof: degrees of freedom of ``cov3`` (``inf``: known); the per-axis intervals use it.
        level: coverage probability.
        threshold: the ellipsoid's squared Mahalanobis bound when it is known otherwise (the
            working model's quantile, :func:`working_model_null`); ``None``: Hotelling's ``T^2``
            (:func:`region_threshold`).
    """
    centre = np.asarray(centre, dtype=float)
    cov3 = np.asarray(cov3, dtype=float)
    if centre.shape != (3,) or cov3.shape != (3, 3):
        raise CalibrationInputError(
            f"Expected centre (3,) and cov3 (3, 3), got {centre.shape} and {cov3.shape}"
        )
    w, U = np.linalg.eigh(0.5 * (cov3 + cov3.T))
    w, U = np.clip(w[::-1], 0.0, None), U[:, ::-1]
    rank = int(np.count_nonzero(w > _rank_tol(w)))
    threshold = (
        float(region_threshold(rank, dof, level)) if threshold is None or rank == 0 else float(threshold)
    )
    half = t_quantile(dof, level) * np.sqrt(np.clip(np.diag(cov3), 0.0, None))
    return Region(
        centre=centre.copy(),
        cov=cov3.copy(),
        level=level,
        dof=float(dof),
        threshold=threshold,
        semi_axes_m=np.sqrt(threshold * w) if rank else np.zeros(3),
        axes=U.T.copy(),
        intervals_m=np.stack([centre - half, centre + half], axis=1),
    )


def holds_truth(
    unc: JointUncertainty, truth_in_parent: np.ndarray, truth_in_child: np.ndarray
) -> tuple[bool, bool]:
    """Whether the 95 % regions of ``unc`` (in the parent and in the child frame) hold a true centre.

    Only the directions the fit determined are compared (module docstring): for a single-axis
    fit the truth and the estimate are both projected onto ``unc.basis``, so that a true centre
    anywhere on the hinge's axis counts by its determined part.

    Args:
        unc: the fit's uncertainty (:func:`joint_covariance`).
        truth_in_parent: ``(3,)`` the true centre in the parent sensor frame, metres.
        truth_in_child: ``(3,)`` in the child sensor frame, metres.

    Returns:
        ``(parent, child)``: whether each region holds the truth.
    """
    V = unc.basis
    x_hat = np.concatenate([unc.joint_in_parent, unc.joint_in_child])
    x_true = np.concatenate(
        [np.asarray(truth_in_parent, dtype=float), np.asarray(truth_in_child, dtype=float)]
    )
    if x_true.shape != (6,):
        raise CalibrationInputError(
            f"Expected truth_in_parent and truth_in_child of shape (3,), got {np.shape(truth_in_parent)} "
            f"and {np.shape(truth_in_child)}"
        )
    e, t = V @ (V.T @ x_hat), V @ (V.T @ x_true)
    held = []
    for part in PARTS:
        sl, region = _part_slice(part), unc.region(part)
        held.append(bool(covers(e[sl], t[sl], region.cov, LEVEL, dof=region.dof, threshold=region.threshold)))
    return held[0], held[1]


def covers(
    estimate: np.ndarray,
    truth: np.ndarray,
    cov3: np.ndarray,
    level: float = LEVEL,
    *,
    dof: float = math.inf,
    threshold: float | None = None,
) -> bool | np.ndarray:
    """Whether ``truth`` lies in the ``level`` confidence region of ``estimate`` (Mahalanobis test).

    The squared Mahalanobis distance ``d^T cov^+ d`` (``d = truth - estimate``) is compared with
    :func:`region_threshold` for ``p`` = the covariance's rank. A rank-deficient covariance is a
    flat region: a truth off its plane (by more than rounding) is not covered.

    Args:
        estimate: ``(..., 3)`` estimated points, metres (or any one unit).
        truth: ``(..., 3)`` true points, the same unit.
        cov3: ``(..., 3, 3)`` covariance of ``estimate``, the unit squared.
        level: coverage probability.
        dof: degrees of freedom of ``cov3`` (scalar or broadcasting over ``...``).
        threshold: the squared Mahalanobis bound of a full-rank region when it is known
            otherwise (a :class:`Region`'s ``threshold``); ``None``: :func:`region_threshold`.

    Returns:
        bool for single points, else ``(...)`` bool array.
    """
    est, tru = np.asarray(estimate, dtype=float), np.asarray(truth, dtype=float)
    cov = np.asarray(cov3, dtype=float)
    if est.shape[-1:] != (3,) or tru.shape[-1:] != (3,) or cov.shape[-2:] != (3, 3):
        raise CalibrationInputError(
            f"Expected estimate and truth (..., 3) and cov3 (..., 3, 3), got {est.shape}, {tru.shape}, "
            f"{cov.shape}"
        )
    try:
        shape = np.broadcast_shapes(est.shape[:-1], tru.shape[:-1], cov.shape[:-2], np.shape(dof))
    except ValueError as err:
        raise CalibrationInputError(
            f"estimate {est.shape}, truth {tru.shape}, cov3 {cov.shape} and dof {np.shape(dof)} do not "
            "broadcast"
        ) from err
    w, U = np.linalg.eigh(0.5 * (cov + np.swapaxes(cov, -1, -2)))
    y = np.einsum("...ji,...j->...i", U, tru - est)  # d in the eigenbasis
    tol = _rank_tol(w)
    inside = w > tol
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = np.sum(np.where(inside, y * y / np.where(inside, w, 1.0), 0.0), axis=-1)
    scale = 1e-9 * (1.0 + np.maximum(np.abs(est).max(axis=-1), np.abs(tru).max(axis=-1)))
    off_plane = np.any(~inside & (np.abs(y) > scale[..., None]), axis=-1)
    if threshold is None:
        threshold = region_threshold(np.count_nonzero(inside, axis=-1), dof, level)
    out = np.broadcast_to((d2 <= threshold) & ~off_plane, shape)
    return bool(out) if out.ndim == 0 else out.copy()


# ----------------------------------------------------------------------------------------------
# the joint's covariance


def joint_covariance(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    fit: JointFit,
    *,
    valid: np.ndarray | None = None,
    method: str = METHODS[0],
    n_blocks: int | None = None,
    rng: np.random.Generator | None = None,
    n_boot: int = N_BOOT,
) -> JointUncertainty:
    """The covariance of a joint fit's centre (module docstring: methods, blocks, quantiles).

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        fit: the fit of exactly these arrays (and ``valid``) by :func:`calibration.joint.fit_joint`.
        valid: the ``valid`` given to the fit, ``(frames,)`` bool or ``None``.
        method: one of :data:`METHODS`.
        n_blocks: blocks for ``"batch-means"`` (>= 2), overriding the automatic rule; for
            ``"block-bootstrap"`` it sets the block length ``frames // n_blocks``.
        rng: random generator, required by ``"block-bootstrap"`` (unused otherwise).
        n_boot: bootstrap replicates.

    Returns:
        The covariance (metres squared), with the frames' scores for cross-covariances.

    Raises:
        CalibrationInputError: malformed arrays, a fit that does not belong to them, an unknown
            method, bad options.
        CalibrationError: fewer than two blocks hold frames.
    """
    if method not in METHODS:
        raise CalibrationInputError(f"method must be one of {list(METHODS)}, got {method!r}")
    if not isinstance(fit, JointFit):
        raise CalibrationInputError(f"fit must be a JointFit, got {type(fit).__name__}")
    if method == "block-bootstrap" and not isinstance(rng, np.random.Generator):
        raise CalibrationInputError("method='block-bootstrap' needs rng, a numpy.random.Generator")
    if n_blocks is not None and (isinstance(n_blocks, bool) or not isinstance(n_blocks, int | np.integer)):
        raise CalibrationInputError(f"n_blocks must be an int or None, got {n_blocks!r}")
    if n_blocks is not None and n_blocks < 2:
        raise CalibrationInputError(f"n_blocks must be at least 2, got {n_blocks}")
    if isinstance(n_boot, bool) or not isinstance(n_boot, int | np.integer) or n_boot < 2:
        raise CalibrationInputError(f"n_boot must be an int >= 2, got {n_boot!r}")
    R_w_p, p_w_p, R_w_c, p_w_c = check_pair(R_w_p, p_w_p, R_w_c, p_w_c)
    n_total = R_w_p.shape[0]
    ok = _used_frames(R_w_p, p_w_p, R_w_c, p_w_c, valid)
    n = int(np.count_nonzero(ok))
    if n_total != fit.n_frames + fit.n_dropped or n != fit.n_frames:
        raise CalibrationInputError(
            f"The fit used {fit.n_frames} of {fit.n_frames + fit.n_dropped} frames, but these poses give "
            f"{n} usable of {n_total}: pass the arrays and valid mask the fit was made from"
        )
    if n_blocks is not None and n_blocks > n:
        raise CalibrationInputError(f"n_blocks must be at most the {n} frames used, got {n_blocks}")

    Rp, Rc = R_w_p[ok], R_w_c[ok]
    A = np.concatenate([Rp, -Rc], axis=2).reshape(3 * n, 6)  # O'Brien eqs. 12-13
    b = (p_w_c[ok] - p_w_p[ok]).reshape(3 * n)  # O'Brien eq. 11
    tri = np.linalg.qr(A, mode="r")  # A^T A = tri^T tri
    _, s, Vt = np.linalg.svd(tri)  # A's spectrum, from its 6 x 6 triangle
    x = np.concatenate([fit.joint_in_parent, fit.joint_in_child])
    r = (b - A @ x).reshape(n, 3)
    _check_fit_matches(fit, s, r, ok)
    k = fit.rank  # directions are dropped from the weakest up (calibration.hinge)
    basis = Vt[:k].T.copy()
    noise = tuple(float(v) for v in fit.orientation_noise_rad2)
    scores = np.concatenate(
        [np.einsum("fji,fj->fi", Rp, r), -np.einsum("fji,fj->fi", Rc, r)], axis=1
    )  # (n, 6) A[f]^T r[f]
    if max(noise) > 0.0:  # corrected least squares (calibration.eiv): its normal matrix and scores
        w_n, U_n = np.linalg.eigh(basis.T @ corrected_normal_matrix(tri.T @ tri, n, noise) @ basis)
        root = basis @ (U_n / np.sqrt(np.clip(w_n, 1e-300, None)))  # (6, k): root root^T = V N_k^-1 V^T
        scores = scores + 2.0 * (noise_diagonal(noise) @ x)
    else:
        root = basis / s[:k]  # (6, k): G = root root^T
    frame_scores = np.zeros((n_total, 6))
    frame_scores[ok] = scores
    relative = np.zeros((n_total, 3, 3))
    relative[ok] = np.einsum("fji,fjk->fik", Rp, Rc)  # R_w_p^T R_w_c: A[f]^T A[f] = [[I, -Q], [-Q^T, I]]

    warnings: list[str] = []
    if k < 6:
        warnings.append(
            f"{6 - k} direction(s) of the centre are undetermined by the motion (rank {k}): they get no "
            "variance; along them the centre is the minimum-norm point, not a measurement"
        )
    tau = integrated_autocorrelation_time(frame_scores @ basis, valid=ok) if k else float("nan")
    leverage = 0.0
    null: tuple[np.ndarray | None, ...] = (None, None)
    if method == "iid":
        sigma_e = r.T @ r / max(n - k / 3.0, 1.0)  # per axis and across, pooled over frames
        meat = A.T @ np.einsum("kl,flj->fkj", sigma_e, A.reshape(n, 3, 6)).reshape(3 * n, 6)
        cov = root @ (root.T @ meat @ root) @ root.T
        dof, n_used_blocks, length = float(3 * n - k), n, 1
        dof_parts = (dof, dof)
        edges = np.arange(n_total + 1)  # every frame its own block (for cross-covariances)
        if tau > IID_TAU_WARNING:
            warnings.append(
                f"The residual is correlated over about {tau:.0f} frames: iid intervals are too narrow "
                "by about a factor sqrt(tau); use method='batch-means'"
            )
    else:
        n_series = n_total if method == "batch-means" else n  # the bootstrap joins the used frames
        length, n_want, short = _block_length(tau, n_series, n_blocks)
        if short and np.isfinite(tau):
            warnings.append(
                f"The residual is correlated over about {tau:.0f} frames: blocks of "
                f"{math.ceil(BLOCK_FACTOR * tau)} frames are wanted but {n_series} frames give fewer "
                f"than {MIN_BLOCKS}; {n_want} shorter blocks are used and the intervals may be too "
                "narrow (record longer)"
            )
        edges = block_edges(n_total, n_want)
        z, M, leverage = _adjusted_block_scores(frame_scores, relative, ok, root, edges, noise=noise)
        n_used_blocks, dof = z.shape[0], effective_dof(M)
        dof_parts = tuple(effective_dof(M, root[_part_slice(part)]) for part in PARTS)
        if method == "batch-means":
            meat_w = z.T @ z
            length = int(np.max(np.diff(edges)))
            if not short:  # blocks long against the correlation: the working model's own quantile
                null = working_model_null(M, tuple(root[_part_slice(part)] for part in PARTS))
        else:
            meat_w, leverage = _moving_block_bootstrap(scores, relative[ok], root, length, rng, n_boot, noise)
            dof, dof_parts = OBM_DOF_FACTOR * dof, tuple(OBM_DOF_FACTOR * d for d in dof_parts)
        cov = root @ meat_w @ root.T
    if leverage > LEVERAGE_WARNING:
        warnings.append(
            f"One block of frames carries {leverage:.0%} of the information along some direction: the "
            "covariance rests on few frames there (the motion explored that direction only briefly)"
        )
    return JointUncertainty(
        joint_in_parent=np.asarray(fit.joint_in_parent, dtype=float).copy(),
        joint_in_child=np.asarray(fit.joint_in_child, dtype=float).copy(),
        cov=0.5 * (cov + cov.T),
        method=method,
        dof=dof,
        dof_in_parent=dof_parts[0],
        dof_in_child=dof_parts[1],
        n_frames=n,
        n_blocks=int(n_used_blocks),
        block_frames=int(length),
        tau_int_frames=float(tau),
        basis=basis,
        gram_root=root,
        frame_scores=frame_scores,
        relative_rotation=relative,
        used=ok,
        block_edges=edges,
        warnings=tuple(warnings),
        orientation_noise_rad2=noise,
        null_in_parent=null[0],
        null_in_child=null[1],
    )


def integrated_autocorrelation_time(series: np.ndarray, *, valid: np.ndarray | None = None) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum_k rho(k)`` of a series, in frames.

    ``rho`` is estimated through the FFT about zero (the scores have mean zero by the normal
    equations), normalised per lag by the number of valid pairs (gaps allowed), and summed up to
    Sokal's automatic window, the first lag ``M >= 5 tau(M)`` (at most a quarter of the series).
    A multi-column series gives the largest ``tau`` over its columns (the blocks must serve the
    slowest one). ``tau = 1`` for white noise; ``(1 + phi) / (1 - phi)`` for AR(1).

    Args:
        series: ``(frames,)`` or ``(frames, k)``.
        valid: optional ``(frames,)`` bool; invalid frames are left out of every product.

    Returns:
        ``tau`` in frames (at least 1); NaN when the series is all zero (exact data) or empty.
    """
    z = np.asarray(series, dtype=float)
    z = z[:, None] if z.ndim == 1 else z
    if z.ndim != 2:
        raise CalibrationInputError(f"Expected series of shape (frames,) or (frames, k), got {z.shape}")
    n = z.shape[0]
    mask = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if mask.shape != (n,):
        raise CalibrationInputError(f"Expected valid to have shape ({n},), got {mask.shape}")
    z = np.where(mask[:, None] & np.isfinite(z), z, 0.0)
    if n < 2 or not np.any(z):
        return float("nan")
    n_fft = _fft.next_fast_len(2 * n)
    spec = _fft.rfft(z, n_fft, axis=0)
    acov = _fft.irfft(np.abs(spec) ** 2, n_fft, axis=0)[:n]
    pairs = np.rint(_fft.irfft(np.abs(_fft.rfft(mask.astype(float), n_fft)) ** 2, n_fft)[:n])
    max_lag = max(1, n // 4)
    acov, pairs = acov[: max_lag + 1], pairs[: max_lag + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = (acov / np.maximum(pairs, 1.0)[:, None]) / (acov[0] / pairs[0])
    rho = np.where(np.isfinite(rho), rho, 0.0)[:, acov[0] > 0]
    taus = 1.0 + 2.0 * np.cumsum(rho[1:], axis=0)  # tau(M) for M = 1 .. max_lag
    lags = np.arange(1, taus.shape[0] + 1)[:, None]
    stop = lags >= WINDOW_FACTOR * taus
    at = np.where(stop.any(axis=0), np.argmax(stop, axis=0), taus.shape[0] - 1)
    tau = taus[at, np.arange(taus.shape[1])]
    return float(max(1.0, np.max(tau)))


def block_edges(n_frames: int, n_blocks: int) -> np.ndarray:
    """``(n_blocks + 1,)`` frame indices cutting ``n_frames`` into consecutive, nearly equal blocks."""
    n_blocks = max(1, min(int(n_blocks), int(n_frames)))
    return np.rint(np.linspace(0, n_frames, n_blocks + 1)).astype(np.int64)


def cross_covariance(a: JointUncertainty, b: JointUncertainty) -> tuple[np.ndarray, float]:
    """Cross-covariance of two joint fits' centres over the same recording, by batch means.

    Both fits' scores are summed over the blocks of the fit with the longer blocks
    (:attr:`JointUncertainty.block_edges`; see :func:`segment_length_uncertainty` for why it
    matters) and leverage-corrected as in batch means (module docstring). Frames a fit did not
    use contribute zero to its scores. ``cross_covariance(u, u)`` is ``u.cov`` for
    ``"batch-means"``; for ``"iid"`` fits every frame is a block (the heteroscedasticity-robust
    sandwich, frames independent).

    Returns:
        ``(6, 6)`` covariance of ``x_a`` with ``x_b`` (rows ``a``), m^2, and its degrees of freedom
        (the smaller of the two fits' :func:`effective_dof` over those blocks).
    """
    _check_same_recording(a, b)
    za, zb, Ma, Mb = _common_block_scores(a, b)
    return a.gram_root @ (za.T @ zb) @ b.gram_root.T, min(effective_dof(Ma), effective_dof(Mb))


# ----------------------------------------------------------------------------------------------
# limb lengths


def length_uncertainty(
    c1: np.ndarray,
    c2: np.ndarray,
    cov1: np.ndarray,
    cov2: np.ndarray,
    *,
    cov12: np.ndarray | None = None,
    dof: float = math.inf,
    level: float = LEVEL,
) -> LengthUncertainty:
    """Delta-method uncertainty of ``|c1 - c2|`` for two joint centres in one sensor frame.

    ``var = u^T (cov1 + cov2 - cov12 - cov12^T) u`` with ``u = (c1 - c2) / |c1 - c2|`` (the
    length's bias, ``tr(cov_d (I - u u^T)) / (2 |d|)``, is of second order and ignored).

    Args:
        c1: ``(3,)`` first centre, metres.
        c2: ``(3,)`` second centre, metres, in the same sensor frame.
        cov1: ``(3, 3)`` covariance of ``c1``, m^2.
        cov2: ``(3, 3)`` covariance of ``c2``, m^2.
        cov12: ``(3, 3)`` ``Cov(c1, c2)``, m^2; ``None`` assumes zero (independent fits: no
            shared sensor noise, or disjoint data). Two fits of the same sensor over the same
            frames share its noise: use :func:`segment_length_uncertainty`.
        dof: degrees of freedom of the covariances (``inf``: known).
        level: coverage probability.
    """
    arrays = [np.asarray(a, dtype=float) for a in (c1, c2, cov1, cov2)]
    cov12 = np.zeros((3, 3)) if cov12 is None else np.asarray(cov12, dtype=float)
    for name, a, shape in zip(
        ("c1", "c2", "cov1", "cov2", "cov12"),
        [*arrays, cov12],
        [(3,), (3,), (3, 3), (3, 3), (3, 3)],
        strict=True,
    ):
        if a.shape != shape:
            raise CalibrationInputError(f"Expected {name} to have shape {shape}, got {a.shape}")
    d = arrays[0] - arrays[1]
    length = float(np.linalg.norm(d))
    if length == 0.0:
        raise CalibrationInputError("The two centres coincide: the length's direction is undefined")
    u = d / length
    var = float(u @ (arrays[2] + arrays[3] - cov12 - cov12.T) @ u)
    return _length_result(length, max(var, 0.0), dof, level)


def segment_length_uncertainty(
    a: JointUncertainty, part_a: str, b: JointUncertainty, part_b: str, *, level: float = LEVEL
) -> LengthUncertainty:
    """Uncertainty of a limb length from two joint fits of the same sensor, their correlation included.

    The length is ``|c_a - c_b|``, ``c_a`` the ``part_a`` (``"parent"`` or ``"child"``) centre of
    fit ``a`` and ``c_b`` likewise; both must be in the same sensor's frame (the thigh is the child
    of the hip fit and the parent of the knee fit: ``part_a="child", part_b="parent"``). Its
    linearised error ``u^T (S_a G_a sum_f s_a,f - S_b G_b sum_f s_b,f)`` is one series summed over
    frames; its variance is estimated by batch means over the blocks of the fit with the longer
    blocks (as :func:`cross_covariance`), with Satterthwaite's degrees of freedom along this one
    direction (:func:`effective_dof`, the two fits' shares of each block added as if independent).
    This includes the cross-covariance from the noise both fits share, and its variance equals
    :func:`length_uncertainty`'s given :func:`cross_covariance` and both covariances over those
    blocks.
    """
    _check_same_recording(a, b)
    sa, sb = _part_slice(part_a), _part_slice(part_b)
    c_a = a.joint_in_parent if part_a == "parent" else a.joint_in_child
    c_b = b.joint_in_parent if part_b == "parent" else b.joint_in_child
    d = c_a - c_b
    length = float(np.linalg.norm(d))
    if length == 0.0:
        raise CalibrationInputError("The two centres coincide: the length's direction is undefined")
    u = d / length
    za, zb, Ma, Mb = _common_block_scores(a, b)
    wa, wb = a.gram_root[sa].T @ u, b.gram_root[sb].T @ u  # the length in each fit's whitened scores
    h = za @ wa - zb @ wb  # (B,) each block's share of the length's error
    # Satterthwaite along this one direction (effective_dof), the fits taken as independent
    share = np.einsum("i,bij,j->b", wa, Ma, wa) + np.einsum("i,bij,j->b", wb, Mb, wb)
    n_blocks = h.shape[0]
    dof = np.sum(share) ** 2 / np.sum(share**2) * (n_blocks - 1) / n_blocks if np.any(share) else n_blocks - 1
    return _length_result(length, float(h @ h), float(dof), level)


# ----------------------------------------------------------------------------------------------
# JSON


def to_json(unc: JointUncertainty) -> dict:
    """A JSON-ready dict of a joint's uncertainty at 95 % (fields in the module docstring)."""
    out: dict = {
        "method": unc.method,
        "level": LEVEL,
        "n_frames": int(unc.n_frames),
        "n_blocks": int(unc.n_blocks),
        "block_frames": int(unc.block_frames),
        "tau_int_frames": _json_float(unc.tau_int_frames),
        "dof": _json_float(unc.dof),
        "dof_in_parent": _json_float(unc.dof_in_parent),
        "dof_in_child": _json_float(unc.dof_in_child),
        "rank": unc.rank,
        "cov_in_parent_m2": _json_list(unc.cov_in_parent),
        "cov_in_child_m2": _json_list(unc.cov_in_child),
        "cov_parent_child_m2": _json_list(unc.cov_parent_child),
    }
    for part in PARTS:
        region = unc.region(part, LEVEL)
        out[f"ci95_in_{part}_m"] = _json_list(region.intervals_m)
        null = unc.null_in_parent if part == "parent" else unc.null_in_child
        out[f"ellipsoid95_in_{part}"] = {
            "semi_axes_m": _json_list(region.semi_axes_m),
            "axes": _json_list(region.axes),
            "threshold": _json_float(region.threshold),
            "quantile": "hotelling" if null is None else "working-model",
        }
    out["bias_bound_m"] = _json_float(unc.bias_bound_m)
    out["warnings"] = list(unc.warnings)
    return out


def length_to_json(length: LengthUncertainty) -> dict:
    """``{"length_m", "std_m", "ci95_m": [lo, hi], "dof", "level"}`` of a limb length."""
    return {
        "length_m": float(length.length_m),
        "std_m": float(length.std_m),
        "ci95_m": _json_list(np.asarray(length.interval_m)),
        "dof": _json_float(length.dof),
        "level": float(length.level),
    }


# ----------------------------------------------------------------------------------------------
# helpers


def _check_level(level: float) -> None:
    if not (isinstance(level, float | int) and 0.0 < float(level) < 1.0):
        raise CalibrationInputError(f"level must be in (0, 1), got {level!r}")


def _part_slice(part: str) -> slice:
    if part not in PARTS:
        raise CalibrationInputError(f"part must be one of {list(PARTS)}, got {part!r}")
    return slice(0, 3) if part == "parent" else slice(3, 6)


def _rank_tol(w: np.ndarray) -> np.ndarray:
    """Eigenvalues at or below this are zero (relative to the largest), ``(...)`` -> ``(..., 1)``."""
    return 1e-10 * np.max(np.abs(w), axis=-1, keepdims=True)


def _used_frames(
    R_w_p: np.ndarray, p_w_p: np.ndarray, R_w_c: np.ndarray, p_w_c: np.ndarray, valid: np.ndarray | None
) -> np.ndarray:
    """``(frames,)`` bool, the frames :func:`calibration.joint.fit_joint` uses."""
    n_total = R_w_p.shape[0]
    ok = finite_frames(R_w_p, p_w_p, R_w_c, p_w_c)
    if valid is not None:
        valid = np.asarray(valid)
        if valid.shape != (n_total,):
            raise CalibrationInputError(f"Expected valid to have shape ({n_total},), got {valid.shape}")
        ok &= valid.astype(bool)
    return ok


def _check_fit_matches(fit: JointFit, s: np.ndarray, r: np.ndarray, ok: np.ndarray) -> None:
    """Raise when ``fit`` was not made from these frames (its spectrum or residuals differ)."""
    fit_s = np.asarray(fit.singular_values, dtype=float)
    # 1e-6 of s_max: the normal-equation path (calibration.pairs) resolves small singular values
    # only to about sqrt(eps) s_max; other data differ by far more
    if fit_s.shape != (6,) or not np.allclose(fit_s, s, rtol=1e-6, atol=1e-6 * s[0]):
        raise CalibrationInputError(
            "The fit's singular values differ from these poses' (the fit was made from other data): "
            f"{np.round(fit_s, 6).tolist()} vs {np.round(s, 6).tolist()}"
        )
    if not 0 <= fit.rank <= 6:
        raise CalibrationInputError(f"The fit's rank must be in 0..6, got {fit.rank}")
    if fit.frame_residual is not None:
        fr = np.asarray(fit.frame_residual, dtype=float)
        mine = np.linalg.norm(r, axis=1)
        tol = 1e-9 + 1e-6 * float(np.sqrt(np.mean(mine**2)))
        if fr.shape != ok.shape or not np.allclose(fr[ok], mine, rtol=0.0, atol=tol):
            raise CalibrationInputError(
                "The fit's per-frame residuals differ from these poses' (the fit was made from other data)"
            )


def _block_length(tau: float, n_frames: int, n_blocks: int | None) -> tuple[int, int, bool]:
    """``(L, B, too_short)``: frames per block and blocks, by the rule or as given."""
    if n_blocks is not None:
        return max(1, n_frames // n_blocks), int(n_blocks), False
    t = 1.0 if not np.isfinite(tau) else tau
    length = max(1, math.ceil(BLOCK_FACTOR * t))
    want = n_frames // length
    if want >= MIN_BLOCKS:
        return length, want, False
    n_b = min(MIN_BLOCKS, n_frames)
    return max(1, n_frames // n_b), n_b, True


def _block_sums(values: np.ndarray, used: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """``(B, ...)`` per-block sums of ``(frames, ...)`` values over the blocks that hold used frames.

    Raises:
        CalibrationError: fewer than two blocks hold frames.
    """
    counts = np.add.reduceat(used.astype(np.int64), edges[:-1])
    keep = (counts > 0) & (np.diff(edges) > 0)
    if np.count_nonzero(keep) < 2:
        raise CalibrationError(
            f"Batch means need at least 2 blocks holding frames, got {np.count_nonzero(keep)}"
        )
    return np.add.reduceat(values, edges[:-1], axis=0)[keep]


def _gram(
    counts: np.ndarray, relative_sums: np.ndarray, noise: tuple[float, float] = (0.0, 0.0)
) -> np.ndarray:
    """``(B, 6, 6)`` ``sum_{f in b} A[f]^T A[f]`` from the used frames per block ``(B,)`` and their
    summed relative rotations ``(B, 3, 3)``; less ``2 F_b D`` for a fit corrected for rotation noise
    ``noise`` (:mod:`calibration.eiv`)."""
    W = np.zeros((counts.shape[0], 6, 6))
    W[:, :3, :3] = counts[:, None, None] * (1.0 - 2.0 * noise[0]) * np.eye(3)
    W[:, 3:, 3:] = counts[:, None, None] * (1.0 - 2.0 * noise[1]) * np.eye(3)
    W[:, :3, 3:] = -relative_sums
    W[:, 3:, :3] = -np.swapaxes(relative_sums, 1, 2)
    return W


def effective_dof(shares: np.ndarray, rows: np.ndarray | None = None) -> float:
    """Degrees of freedom of a batch-means covariance whose blocks carry unequal information.

    ``shares`` is ``(B, k, k)``: each block's share ``M_b = T^T A_b^T A_b T`` of the whitened
    information (they sum to the identity). Under the working model (block scores independent,
    ``Var(z_b) ~ M_b``) Satterthwaite's approximation gives ``1 / sum_b (c^T M_b c)^2`` degrees of
    freedom along a unit direction ``c``; averaged over the ``r`` directions of the quantity of
    interest it is the participation ratio ``B_eff = r / sum_b tr(N_b^2)``, with ``N_b`` the
    shares whitened in that quantity's own coordinates (``B_eff = B`` for equal blocks). Less the
    mean's share: ``B_eff (B - 1) / B`` (``B - 1`` for equal blocks, as in :mod:`calibration.hinge`).

    Args:
        shares: ``(B, k, k)`` the blocks' shares ``M_b``.
        rows: ``(m, k)`` the quantity of interest ``rows @ z`` in whitened scores (``S T`` for the
            parent or child centre, ``S`` selecting its rows of ``x``); ``None``: all of ``z``.
    """
    M = np.asarray(shares, dtype=float)
    n_blocks = M.shape[0]
    if rows is not None:
        M = rows @ M @ rows.T  # (B, m, m) each block's share of the quantity's covariance
        w, U = np.linalg.eigh(M.sum(axis=0))
        keep = w > _rank_tol(w)[0]
        whiten = U[:, keep] / np.sqrt(w[keep])
        M = whiten.T @ M @ whiten
    r = M.shape[-1]
    total = float(np.einsum("bij,bji->", M, M))
    if r == 0 or total <= 0.0:
        return float(n_blocks - 1)
    return r / total * (n_blocks - 1) / n_blocks


def working_model_null(
    shares: np.ndarray,
    parts: tuple[np.ndarray, ...],
    *,
    n_draws: int = N_NULL_DRAWS,
    seed: int = NULL_SEED,
) -> tuple[np.ndarray | None, ...]:
    """Draws of a batch-means region's statistic under the working model, for its threshold.

    The working model of the batch-means covariance: the blocks' whitened scores are independent
    Gaussians with covariance proportional to their shares of the information,
    ``g_b ~ N(0, M_b)``. Each draw goes through what the estimator does to real scores: the fit
    takes its share of the total, ``g~_b = g_b - M_b sum_c g_c``, every block is leverage-corrected
    (CR2, as :func:`_leverage_adjusted`), and the quantity ``q = P z`` of every part gives
    ``d^2 = (P sum_b g_b)^T (sum_b q_b q_b^T)^-1 (P sum_b g_b)``. The noise scale cancels, so the
    draws' quantile is the region's threshold for any noise level.

    Why not Hotelling's ``T^2`` with Satterthwaite's degrees of freedom (:func:`effective_dof`):
    when the blocks carry unequal information (motion that turns a joint one way now and another
    way later), the directions of a 3-D centre have different degrees of freedom, and one averaged
    count for all three puts the threshold too high: in the study's Polhemus sessions the
    simulated quantile was a median 0.83 of the Hotelling one, and the regions held the truth in
    97.4 % of cases instead of 95 % (95.5 % with the simulated quantile).

    Args:
        shares: ``(B, k, k)`` the blocks' shares of the whitened information ``M_b`` (summing
            to the identity).
        parts: per quantity, ``(m, k)`` its rows in whitened scores (``S T`` for a centre).
        n_draws: draws of the working model.
        seed: seed of the draws (the same shares always give the same draws).

    Returns:
        Per part, the ``(n_draws,)`` sorted draws of ``d^2``; ``None`` for a part of rank 0 or
        where a draw's covariance is singular.
    """
    M = 0.5 * (shares + np.swapaxes(shares, 1, 2))
    n_blocks, k, _ = M.shape
    w, U = np.linalg.eigh(M)
    w = np.clip(w, 0.0, None)
    root_b = U * np.sqrt(w)[:, None, :]  # M_b = root_b root_b^T
    adjust = (U / np.sqrt(1.0 - np.minimum(w, MAX_LEVERAGE))[:, None, :]) @ np.swapaxes(U, 1, 2)
    reduced = []
    for P in parts:
        Up, sp, _ = np.linalg.svd(np.asarray(P, dtype=float), full_matrices=False)
        keep = sp > _rank_tol(sp)[0] if sp.size else np.zeros(0, dtype=bool)
        reduced.append(Up[:, keep].T @ P if np.any(keep) else None)
    # every part's rows of the corrected block scores at once: with Q_b = P adjust_b,
    # P z_b = Q_b root_b x_b - Q_b M_b total, total = sum_b root_b x_b (x: the standard draws)
    live = [i for i, P in enumerate(reduced) if P is not None]
    rows = np.cumsum([0] + [reduced[i].shape[0] for i in live])
    Q = np.concatenate([reduced[i] for i in live]) @ adjust if live else np.zeros((n_blocks, 0, k))
    QR, QM = Q @ root_b, (Q @ M).reshape(-1, k)  # (B, m, k), (B m, k)
    root_all = np.swapaxes(root_b, 0, 1).reshape(k, n_blocks * k)  # total = root_all @ x
    rng = np.random.default_rng(seed)
    draws: list[list[np.ndarray]] = [[] for _ in parts]
    chunk = max(1, min(n_draws, (1 << 21) // max(1, n_blocks * k)))
    for start in range(0, n_draws, chunk):
        n = min(chunk, n_draws - start)
        x = rng.standard_normal((n_blocks, k, n))
        total = root_all @ x.reshape(n_blocks * k, n)  # (k, n)
        Pz = QR @ x - (QM @ total).reshape(n_blocks, -1, n)  # (B, m, n)
        for j, i in enumerate(live):
            if reduced[i] is None:
                continue
            q = Pz[:, rows[j] : rows[j + 1]]  # (B, m_i, n)
            m_i = q.shape[1]
            C = np.empty((n, m_i, m_i))
            for a in range(m_i):
                for b in range(a + 1):
                    C[:, a, b] = C[:, b, a] = np.einsum("bn,bn->n", q[:, a], q[:, b])
            e = (reduced[i] @ total).T  # (n, m_i)
            try:
                d2 = np.einsum("ni,ni->n", e, np.linalg.solve(C, e[..., None])[..., 0])
            except np.linalg.LinAlgError:
                reduced[i] = None
                continue
            draws[i].append(d2)
    return tuple(
        None if P is None else np.sort(np.concatenate(d)) for P, d in zip(reduced, draws, strict=True)
    )


def _null_quantile(null: np.ndarray, level: float) -> float:
    """The ``level`` quantile of sorted null draws (:func:`working_model_null`)."""
    _check_level(level)
    return float(np.quantile(null, level))


def _leverage_adjusted(z: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, float]:
    """``(B, k)`` whitened block scores ``(I - M_b)^(-1/2) z_b`` (CR2) and the largest leverage.

    ``M_b = T^T W_b T`` (``(B, k, k)``, summing to the identity over all blocks) is block ``b``'s
    share of the information; eigenvalues are clipped at :data:`MAX_LEVERAGE`.
    """
    w, U = np.linalg.eigh(0.5 * (M + np.swapaxes(M, 1, 2)))
    w = np.clip(w, 0.0, MAX_LEVERAGE)
    y = np.einsum("bji,bj->bi", U, z) / np.sqrt(1.0 - w)
    return np.einsum("bij,bj->bi", U, y), float(w.max(initial=0.0))


def _adjusted_block_scores(
    frame_scores: np.ndarray,
    relative: np.ndarray,
    used: np.ndarray,
    root: np.ndarray,
    edges: np.ndarray,
    present: np.ndarray | None = None,
    *,
    noise: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(B, k)`` leverage-adjusted whitened block scores, ``(B, k, k)`` the blocks' shares of the
    information ``M_b`` and the largest leverage (see :func:`_leverage_adjusted`), over the blocks
    holding frames of ``present`` (default ``used``, the fit's own frames)."""
    present = used if present is None else present
    values = np.concatenate([frame_scores, relative.reshape(-1, 9), used[:, None].astype(float)], axis=1)
    sums = _block_sums(values, present, edges)
    counts = sums[:, 15]
    M = root.T @ _gram(counts, sums[:, 6:15].reshape(-1, 3, 3), noise) @ root  # (B, k, k)
    z, leverage = _leverage_adjusted(sums[:, :6] @ root, M)
    return z, M, leverage


def _moving_block_bootstrap(
    scores: np.ndarray,
    relative: np.ndarray,
    root: np.ndarray,
    length: int,
    rng: np.random.Generator,
    n_boot: int,
    noise: tuple[float, float] = (0.0, 0.0),
) -> tuple[np.ndarray, float]:
    """``(k, k)`` moving-block bootstrap covariance of the whitened score sum ``T^T sum_f s_f`` and
    the largest leverage.

    Every moving block's summed score is leverage-adjusted as in batch means before resampling.
    """
    n = scores.shape[0]
    length = min(length, n)
    k = max(1, n // length)

    starts = np.arange(0, n - length + 1, max(1, length // MOVING_STEPS))

    def moving(values: np.ndarray) -> np.ndarray:
        csum = np.concatenate([np.zeros((1, *values.shape[1:])), np.cumsum(values, axis=0)])
        return csum[starts + length] - csum[starts]

    M = root.T @ _gram(np.full(starts.shape[0], float(length)), moving(relative), noise) @ root
    z, leverage = _leverage_adjusted(moving(scores) @ root, M)  # (starts, k)
    centre = k * z.mean(axis=0)
    meat = np.zeros((z.shape[1], z.shape[1]))
    chunk = max(1, (1 << 22) // (k * max(z.shape[1], 1)))
    for start in range(0, n_boot, chunk):
        m = min(chunk, n_boot - start)
        dev = z[rng.integers(0, z.shape[0], size=(m, k))].sum(axis=1) - centre
        meat += dev.T @ dev
    return meat / n_boot * (n / (k * length)), leverage  # from the replicates' k L frames to n


def _check_same_recording(a: JointUncertainty, b: JointUncertainty) -> None:
    for name, u in (("a", a), ("b", b)):
        if not isinstance(u, JointUncertainty):
            raise CalibrationInputError(f"{name} must be a JointUncertainty, got {type(u).__name__}")
    if a.frame_scores.shape != b.frame_scores.shape:
        raise CalibrationInputError(
            f"Both fits must come from the same recording: {a.frame_scores.shape[0]} vs "
            f"{b.frame_scores.shape[0]} frames"
        )


def _common_block_scores(
    a: JointUncertainty, b: JointUncertainty
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Both fits' leverage-adjusted whitened block scores over the coarser fit's blocks,
    ``(B, k_a)`` and ``(B, k_b)``, and their information shares ``(B, k_a, k_a)``, ``(B, k_b, k_b)``."""
    edges = a.block_edges if a.block_frames >= b.block_frames else b.block_edges
    present = a.used | b.used
    za, Ma, _ = _adjusted_block_scores(
        a.frame_scores,
        a.relative_rotation,
        a.used,
        a.gram_root,
        edges,
        present,
        noise=a.orientation_noise_rad2,
    )
    zb, Mb, _ = _adjusted_block_scores(
        b.frame_scores,
        b.relative_rotation,
        b.used,
        b.gram_root,
        edges,
        present,
        noise=b.orientation_noise_rad2,
    )
    return za, zb, Ma, Mb


def _length_result(length: float, var: float, dof: float, level: float) -> LengthUncertainty:
    half = t_quantile(dof, level) * math.sqrt(var)
    return LengthUncertainty(length, var, float(dof), float(level), (length - half, length + half))


def _json_float(v: float) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _json_list(a: np.ndarray) -> list:
    """Nested lists of floats, ``None`` where a value is not finite (JSON has no NaN)."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 0:
        return _json_float(a)  # type: ignore[return-value]
    return [_json_list(row) if a.ndim > 1 else _json_float(row) for row in a]
