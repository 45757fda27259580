"""The single-axis (hinge) verdict: does the data determine the joint centre along the weakest axis?

A joint fit (O'Brien eqs. 9-13, ``A x = b``) has six directions, the right singular vectors
``v_j`` of ``A``. Along the weakest one, ``v_6``, a hinge leaves the centre undetermined: the
hinge model puts it at the minimum-norm point (``v_6 . x = 0``), the ball model fits it. The
residual rises by ``(u_6 . b)^2`` when the hinge model is imposed, and the verdict asks whether
that rise stands out from the residual's own noise (O'Brien section 3.2 made statistical).

**The test.** The fitted coefficient along ``v_j`` is ``c_j = (v_j . A^T b) / s_j^2`` and its
t statistic against ``c_j = 0`` is ``t_j = (v_j . A^T b) / sqrt(var)``, where ``var`` is the
variance of the score ``v_j . A^T e`` (``e`` the residual). Residuals of real joints are
strongly autocorrelated (soft tissue, play, tracker distortion that follow the motion), so the
variance is not ``sigma^2 s_j^2`` but is estimated by batch means: the recording is cut into
consecutive blocks of frames, each block's score
``g_b = sum_{f in b} (A_f v_j) . r_f`` is summed from the full model's residual ``r``, and
``var = B / (B - 1) sum_b g_b^2`` over the ``B`` blocks that hold frames (the scores sum to
zero by the normal equations; :func:`score_variance` weighs a partial block by its length). With
correlation shorter than a block, ``t_j`` follows Student's t with ``B - 1`` degrees of freedom
(the effective number of independent samples is ``B``, not the frame count). A direction is
undetermined when ``|t_j|`` is below the two-sided critical value at :data:`TEST_LEVEL`.

**The blocks** are ``L = 2^k`` frames long, ``k`` the smallest with at most :data:`N_BLOCKS`
(32) blocks, the last one partial (:func:`block_edges`): 17 to 32 blocks for any recording
longer than 32 frames. They depend on the recording's length only through ``L``, so a
calibration fed frame by frame (:mod:`calibration.streaming`) holds the same blocks in constant
memory (merging neighbours when ``L`` doubles) and reaches the same verdict as the batch.
(Until issue 17 the rule was 16 equal blocks over the whole recording, which a stream cannot
keep: the cut points move with every frame.)

Only the three directions along which the relative rotation varies (``s_j^2 < n``, see
:func:`testable_directions`) may be dropped. A direction is also kept when it is *precise*: the
confidence interval of the centre along it is narrower than the joint's own rms residual
(:func:`precise_directions`) -- the centre is then measured to lie at the minimum-norm point,
which happens for a ball joint whose centre lies midway between the sensors along its weakest
direction. Directions are dropped from the weakest up while not significant and not precise; a
fit with exactly one dropped direction is single-axis.

Both numerator and denominator are lengths, so ``t``, the interval and the residual scale
together and the verdict is the same in m, mm or inches.

**Effect size: can the wobble place the centre along the axis at all?** A significance test
alone flips with the recording's length and noise: a hinge wobbling 2 degrees about a centre
that the sensors do not straddle is called a ball joint once enough clean frames accumulate, and
not in a shorter or noisier recording of the same rig. The verdict therefore also asks whether
the off-axis motion is large enough to place the centre along the weakest direction against the
residual's *systematic* part (skin, play and tracker distortion that move with the joint, which
more frames do not average away). An error vector ``e`` of rms ``r_sys`` per frame moves the
coefficient along ``v_j`` by ``(u_j . e) / s_j``, at most ``r_sys sqrt(n) / s_j`` (Cauchy-
Schwarz, ``|u_j| = 1``), i.e. the joint by at most

    B_j = r_sys sqrt(n) / (sqrt(2) s_j) = r_sys / phi_j,   phi_j = sqrt(2) s_j / sqrt(n),

``phi_j`` the rms relative rotation (rad) that direction sees (for a hinge's axis: the rms off-
axis wobble). This is the rule of the functional-joint-centre literature, the centre's error
grows as noise over range of motion (Ehrig et al. 2006, J Biomech 39:2798; Camomilla et al.
2006, J Biomech 39:1096), with the noise measured: ``r_sys^2`` is the ball model's mean square
residual less its white noise, read off the residual's third differences
(:mod:`calibration.pair_noise`) and taken at its upper 97.5 % confidence limit
(:func:`systematic_rms`); white noise averages out and is the test's business. The
weakest direction is undetermined whatever the test says when ``B_6`` exceeds
:data:`UNCERTAIN_FRACTION` of the sensors' rms distance (the limit the motion warnings of
:mod:`calibration.diagnostics` put on a centre's error): the centre could then lie anywhere over
a fifth of the pair's extent along the axis. A shift along the weakest direction larger than
``B_6`` (``|u_6 . b| > r_sys sqrt(n)``: imposing the hinge would more than double the residual's
systematic sum of squares) is no artefact and keeps the direction: a ball joint that turned
little about one axis but whose centre lies well off the minimum-norm point is not made a hinge
with a displaced centre. The question is one of a hinge's axis, so it is asked only when the
next direction is placed (``B_5`` within the limit): a joint that barely moved in every
direction (a hip in a knee trial) is left to the test, and the motion warnings report it as a
ball joint to be moved in two or more directions. Nor is a direction that turned as much as the
literature asks
(:data:`WELL_MOVED_RMS_RAD`, the rms of 20 degrees peak to peak): its bound is large for its
residual -- a slipped sensor, a pair that is no joint -- not for its motion. Both ``B_6`` and
that shift are independent of the recording's length (``s_j^2`` and ``u_6 . b`` grow as ``n``
and ``sqrt(n)``) and are lengths (unit-free). Only the weakest direction is judged so (the
single-axis verdict); stronger directions keep the test alone, and the motion warnings report
their bound. On messy simulated hinges with 2 degrees rms wobble ``B_6`` is 0.6-0.9 of the
distance, on ball joints moved about two or three axes 0.04-0.08 (studies/hinge_verdict.py).
Without the third differences (pair statistics made without them) the rule is not applied.

**Hard floor.** Directions with ``s_j < floor * s_max`` are undetermined whatever the test says
(:func:`calibration.joint.determined_directions`): below :data:`calibration.joint.SINGLE_AXIS_RATIO`
(1e-4: about 0.2 mrad, 0.01 degree, rms off the axis, finer than any tracker resolves) the test
would only compare rounding errors.

**What the verdict cannot tell.** It asks whether the data place the centre along the weakest
direction, not whether the joint is mechanically a hinge: a hinge that wobbles a few degrees
about a fixed centre, with sensors offset along its axis, reveals that centre to the test given
enough clean frames; the effect size above keeps it single-axis as long as the wobble is too
small against the systematic noise (studies/hinge_verdict.py: 20 of 20 at 60 s and at 240 s
with a quarter of the noise). A ball joint that barely moved is called single-axis for the same
reason: the data cannot place its centre along the weakest direction either.
"""

from __future__ import annotations

import numpy as np

from calibration.quantiles import t_ppf

#: Most blocks of frames for the batch-means variance of the scores (:func:`block_edges`): a
#: recording longer than this many frames is cut into between ``N_BLOCKS / 2 + 1`` and
#: ``N_BLOCKS`` blocks.
N_BLOCKS = 32

#: A direction is undetermined when the bound on its centre's bias exceeds this fraction of the
#: sensors' rms distance (module docstring; the motion warnings' limit,
#: :mod:`calibration.diagnostics`).
UNCERTAIN_FRACTION = 0.2

#: The range of motion the functional-joint-centre literature asks of a joint's planes, degrees
#: (Ehrig et al. 2006; Camomilla et al. 2006: "tens of degrees").
LITERATURE_RANGE_DEG = 20.0

#: The rms rotation of a sinusoid spanning :data:`LITERATURE_RANGE_DEG` peak to peak, rad (7.1
#: degrees): a direction that turned this much is not short of motion.
WELL_MOVED_RMS_RAD = float(np.deg2rad(LITERATURE_RANGE_DEG) / (2.0 * np.sqrt(2.0)))

#: Two-sided level of the test: the chance that a true hinge (noise only along its axis) is
#: called a ball joint, when the residual's correlation is shorter than a block.
TEST_LEVEL = 1e-3


def block_frames(n_frames: int) -> int:
    """``L = 2^k`` frames per block, ``k`` the smallest integer with ``ceil(n_frames / L) <= N_BLOCKS``.

    The blocks depend on the frames seen so far only through ``L``, which doubles as a recording
    grows: a calibration that receives frames one at a time (:mod:`calibration.streaming`) keeps
    at most :data:`N_BLOCKS` blocks and merges neighbours in pairs when the next frame would open
    one more, and so holds exactly the blocks the whole recording gets here, in constant memory.
    """
    n = max(int(n_frames), 0)
    length = 1
    while -(-n // length) > N_BLOCKS:
        length *= 2
    return length


def block_edges(n_frames: int) -> np.ndarray:
    """``(B + 1,)`` frame indices cutting ``n_frames`` frames into ``B = ceil(n_frames / L)``
    consecutive blocks of ``L`` frames (:func:`block_frames`), the last one partial.

    ``B`` is ``n_frames`` up to :data:`N_BLOCKS` frames (one frame a block), then between
    ``N_BLOCKS / 2 + 1`` and ``N_BLOCKS``; a recording of no frames is one empty block.
    """
    n = max(int(n_frames), 0)
    length = block_frames(n)
    edges = np.arange(0, n, length, dtype=np.int64)
    return np.append(edges, n) if n else np.array([0, 0], dtype=np.int64)


def block_of_frame(n_frames: int) -> np.ndarray:
    """``(n_frames,)`` the block index of every frame (see :func:`block_edges`)."""
    edges = block_edges(n_frames)
    return np.searchsorted(edges, np.arange(n_frames), side="right") - 1


def score_variance(block_scores: np.ndarray, block_counts: np.ndarray) -> np.ndarray:
    """Batch-means variance of every direction's score, for blocks of any lengths.

    With ``n_b`` frames in block ``b`` and ``n = sum n_b``, a score whose per-frame long-run
    variance is ``sigma^2`` has block sums of variance ``n_b sigma^2`` that add up to zero (the
    normal equations), so ``E sum_b g_b^2 = sigma^2 (n - sum_b n_b^2 / n)``; the variance of the
    whole score, ``n sigma^2``, is estimated by ``n sum_b g_b^2 / (n - sum_b n_b^2 / n)``. For
    ``B`` equal blocks this is the textbook ``B / (B - 1) sum_b g_b^2``; the last, partial block
    of :func:`block_edges` (and blocks thinned by missing frames) enter with their true weight.

    Args:
        block_scores: ``(..., B, 6)`` ``sum_{f in b} (A_f v_j) . r_f`` per block and direction,
            with ``r`` the full model's residual (length units).
        block_counts: ``(..., B)`` frames in each block.

    Returns:
        ``(..., 6)`` the variance (length squared); NaN where fewer than two blocks hold frames.
    """
    counts = np.asarray(block_counts, dtype=float)
    n_blocks = np.count_nonzero(counts > 0, axis=-1)[..., None]
    n = np.sum(counts, axis=-1)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = n - np.sum(counts * counts, axis=-1)[..., None] / n
        var = np.sum(np.square(block_scores), axis=-2) * n / spread
    return np.where(n_blocks >= 2, var, np.nan)


def score_t(proj: np.ndarray, var: np.ndarray) -> np.ndarray:
    """``(..., 6)`` ``|t_j| = |v_j . A^T b| / sqrt(var_j)`` (dimensionless).

    ``proj`` is ``(..., 6)`` ``v_j . A^T b``, ``var`` from :func:`score_variance`. ``inf`` where
    the variance is zero (exact data); NaN where it is NaN (no test possible).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.abs(proj) / np.sqrt(var)
    return np.where(var == 0.0, np.inf, t)


def precise_directions(
    var: np.ndarray, eigval: np.ndarray, t_crit: np.ndarray, rms_residual: np.ndarray
) -> np.ndarray:
    """``(..., 6)`` bool: directions along which the data place the centre within its own scatter.

    A centre moved by ``d`` along a hinge axis moves ``x`` by ``d [a_p; a_c]``, i.e. by
    ``sqrt(2) d`` along the unit direction ``v_6``. The coefficient ``c_j`` has standard error
    ``sqrt(var_j) / s_j^2``; the direction is *precise* when the half-width of its confidence
    interval, as a move of the joint, ``t_crit sqrt(var_j) / (sqrt(2) s_j^2)``, is below the rms
    residual (the joint's own scatter). A precise direction is determined even when its
    coefficient is not significant: the centre then is measured to lie at the minimum-norm point.

    Args:
        var: ``(..., 6)`` from :func:`score_variance`.
        eigval: ``(..., 6)`` ``s_j^2``.
        t_crit: ``(...,)`` from :func:`critical_t`.
        rms_residual: ``(...,)`` rms residual of the full (ball) model, same length unit.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        half_width = t_crit[..., None] * np.sqrt(var) / (np.sqrt(2.0) * eigval)
    return half_width < np.asarray(rms_residual)[..., None]


def critical_t(block_counts: np.ndarray) -> np.ndarray:
    """``(...,)`` two-sided critical ``|t|`` at :data:`TEST_LEVEL` with ``B_eff - 1`` degrees of
    freedom, ``B_eff = n^2 / sum_b n_b^2`` the effective number of blocks (``B`` for equal blocks,
    less when the last block is partial or gaps thin some blocks); at least 1."""
    counts = np.asarray(block_counts, dtype=float)
    n = np.sum(counts, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        n_eff = np.where(n > 0, n * n / np.sum(counts * counts, axis=-1), 0.0)
    dof = np.maximum(n_eff - 1.0, 1.0)
    return t_ppf(1.0 - TEST_LEVEL / 2.0, dof)


def testable_directions(singular_values: np.ndarray, n_frames: np.ndarray) -> np.ndarray:
    """``(..., 6)`` bool: the directions the test may drop, ``s_j^2 < n_frames``.

    The Gram matrix ``A^T A`` has ``n I`` on its diagonal blocks, so its eigenvalues are
    ``n (1 +- sigma_k(M))`` (:mod:`calibration.joint`): the three below ``n`` are the directions
    along which the relative rotation varies, the ones a hinge or a still pair leaves weak. The
    three others are fixed by any motion and are never dropped, even when the centre's component
    along them happens to be zero.
    """
    s = np.asarray(singular_values, dtype=float)
    return np.square(s) < np.asarray(n_frames, dtype=float)[..., None]


#: Relative variance of the white-noise estimate from third differences, times the frames:
#: ``var(nu_hat) / nu^2 = WHITE_ESTIMATE_VARIANCE / n`` for Gaussian white noise (each component's
#: squared third difference has variance ``2 (20 sigma^2)^2`` and correlations ``rho_k^2`` with
#: ``rho = -15/20, 6/20, -1/20`` at lags 1-3; three components: ``2 (1 + 2 sum rho_k^2) / 3``).
WHITE_ESTIMATE_VARIANCE = 2.0 * (1.0 + 2.0 * (0.75**2 + 0.3**2 + 0.05**2)) / 3.0

#: One-sided normal quantile of the white noise's upper confidence limit (97.5 %).
WHITE_UPPER_Z = 1.959963984540054


def systematic_rms(rms_residual: np.ndarray, white_variance: np.ndarray, n_frames: np.ndarray) -> np.ndarray:
    """``sqrt(max(r^2 - nu_up, 0))``: the part of an rms residual ``r`` that is not white noise.

    ``nu`` (:mod:`calibration.pair_noise`, from ``n_frames`` frames) is taken at its upper 97.5 %
    confidence limit, ``nu (1 + 1.96 sqrt(WHITE_ESTIMATE_VARIANCE / n))``: where white noise
    makes nearly all of the residual, the difference of two close numbers would otherwise call
    its estimation error systematic. Same length unit as ``r``; ``r`` where ``nu`` is NaN.
    """
    r2 = np.square(np.asarray(rms_residual, dtype=float))
    nu = np.nan_to_num(np.asarray(white_variance, dtype=float), nan=0.0)
    n = np.maximum(np.asarray(n_frames, dtype=float), 1.0)
    upper = nu * (1.0 + WHITE_UPPER_Z * np.sqrt(WHITE_ESTIMATE_VARIANCE / n))
    return np.sqrt(np.clip(r2 - upper, 0.0, None))


def bias_bounds(rms_systematic: np.ndarray, singular_values: np.ndarray, n_frames: np.ndarray) -> np.ndarray:
    """``(..., 6)`` ``B_j = r_sys sqrt(n) / (sqrt(2) s_j)``: the most a systematic error of rms
    ``r_sys`` per frame moves the joint centre along each direction ``v_j`` (module docstring),
    in ``r_sys``'s unit; ``inf`` where ``s_j = 0`` and ``r_sys > 0``, 0 where ``r_sys = 0``.

    Args:
        rms_systematic: ``(...,)`` from :func:`systematic_rms`.
        singular_values: ``(..., 6)`` ``s_j`` of ``A``, descending.
        n_frames: ``(...,)`` frames of the fit.
    """
    s = np.asarray(singular_values, dtype=float)
    r = np.asarray(rms_systematic, dtype=float)[..., None]
    n = np.asarray(n_frames, dtype=float)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = r * np.sqrt(n) / (np.sqrt(2.0) * s)
    return np.where(r == 0.0, 0.0, out)


def biased_directions(
    rms_systematic: np.ndarray,
    singular_values: np.ndarray,
    n_frames: np.ndarray,
    separation: np.ndarray,
    proj: np.ndarray,
) -> np.ndarray:
    """``(..., 6)`` bool: True for the weakest direction when the data cannot place the centre
    along it for the systematic noise (module docstring): its bias bound (:func:`bias_bounds`)
    exceeds :data:`UNCERTAIN_FRACTION` of the sensors' rms distance ``separation`` (same unit),
    and the shift the data show along it, ``|v_j . A^T b| / (sqrt(2) s_j^2)``, is within that bound
    (``|u_j . b| <= r_sys sqrt(n)``: the systematic error alone could have made it). The other
    directions are False (only the single-axis verdict rests on it). Only an axis is judged so:
    the next direction's bound must be within the limit (the centre placed across the weakest
    direction); a joint that barely moved in every direction is left to the test and the motion
    warnings. A weakest direction that
    turned :data:`WELL_MOVED_RMS_RAD` or more is not short of motion: its bound is large for its
    residual (a slip, a pair that is no joint), which the motion warnings report, and the test
    alone decides.

    Args:
        rms_systematic: ``(...,)`` from :func:`systematic_rms`.
        singular_values: ``(..., 6)`` ``s_j``, descending.
        n_frames: ``(...,)`` frames of the fit.
        separation: ``(...,)`` the sensors' rms distance.
        proj: ``(..., 6)`` ``v_j . A^T b = s_j (u_j . b)``.
    """
    bound = bias_bounds(rms_systematic, singular_values, n_frames)
    s = np.asarray(singular_values, dtype=float)
    r = np.asarray(rms_systematic, dtype=float)
    n = np.asarray(n_frames, dtype=float)
    out = np.zeros(bound.shape, dtype=bool)
    sep = np.asarray(separation, dtype=float)
    within = np.abs(np.asarray(proj, dtype=float)[..., -1]) <= s[..., -1] * r * np.sqrt(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        short = np.sqrt(2.0) * s[..., -1] / np.sqrt(n) < WELL_MOVED_RMS_RAD
    limit = UNCERTAIN_FRACTION * sep
    axis = bound[..., -2] <= limit  # placed across the weakest direction: it is an axis
    out[..., -1] = (bound[..., -1] > limit) & axis & within & short  # NaN: False
    return out


def hinge_verdict(
    floor_keep: np.ndarray,
    t: np.ndarray,
    t_crit: np.ndarray,
    testable: np.ndarray,
    precise: np.ndarray,
    biased: np.ndarray | None = None,
) -> np.ndarray:
    """Directions the data determine: the floor's, minus the weakest ones whose test fails.

    Args:
        floor_keep: ``(..., 6)`` bool, directions above the hard floor (descending order).
        t: ``(..., 6)`` ``|t_j|`` from :func:`score_t` (NaN: no test possible, keep).
        t_crit: ``(...,)`` critical values from :func:`critical_t`.
        testable: ``(..., 6)`` bool, from :func:`testable_directions`.
        precise: ``(..., 6)`` bool, from :func:`precise_directions`.
        biased: ``(..., 6)`` bool, from :func:`biased_directions` (``None``: none): undetermined
            whatever the test says (the effect size of the module docstring).

    Returns:
        ``(..., 6)`` bool: directions dropped from the weakest kept one upward while they are
        testable and either biased, or not precise and their test is not significant
        (stopping at the first kept).
    """
    failed = ~precise & (t < t_crit[..., None])  # NaN: kept
    if biased is not None:
        failed = failed | biased
    insignificant = floor_keep & testable & failed
    # a kept direction survives when it, or a weaker kept direction, is significant
    significant = floor_keep & ~insignificant
    weaker_or_self = np.flip(np.cumsum(np.flip(significant, axis=-1), axis=-1), axis=-1) > 0
    return floor_keep & weaker_or_self
