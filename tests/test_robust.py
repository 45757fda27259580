"""Robust joint fits by IRLS on the residual norm (calibration.robust), on exact synthetic data.

The sessions are built here, without the simulator: a parent sensor with smooth random rotations
and translations (sums of sines of the rotation vector and position), a child joined to it at a
known ``joint_in_parent`` / ``joint_in_child`` whose relative rotation sweeps a cone (the child's
axis tilts up to about 54 degrees from the parent's, 21 degrees median, 46 degrees at the 95th
percentile) and twists, 3000 frames at 120 Hz, 1 mm Gaussian noise per axis on the child position.
Corruptions hit 5 % of the frames in contiguous blocks, as the real events do:

- ``slip``: the child sensor slides on the skin -- its position is off by a constant 2-5 cm
  vector fixed in the sensor's frame for the block;
- ``field-position``: a field-distortion burst -- the child position is off by ``g (p - s)``
  for a distortion source ``s`` about half a metre away, 3-8 cm on average over the burst;
- ``field-rotation``: the burst turns the child's measured rotation by 5-10 degrees;
- ``mixed``: half the corrupted frames slip, half get both field errors.

The issue's target: with 5 % corrupted frames the robust joint-centre error stays within 1.2x of
the clean session's, while least squares is off by more than 3x. Errors are aggregated as the rms
over seeded sessions of ``|x_hat - x_true|`` (``x = [joint_in_parent; joint_in_child]``), so that
no single lucky draw decides.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy import stats

from calibration import (
    CalibrationError,
    CalibrationInputError,
    calibrate,
    fit_joint,
    joint_residual_vectors,
    spanning_tree,
)
from calibration.robust import (
    CHI3_MEDIAN,
    HUBER_C,
    INLIER_C,
    MIN_FRAMES,
    MIN_SUPPORT,
    TUKEY_C,
    asymptotic_efficiency,
    loss_weights,
    robust_fit_joint,
    robust_pair_misfits,
    supported_rank,
)
from calibration.rotations import rotvec_to_matrix

RATE_HZ = 120.0
N_FRAMES = 3000
NOISE_M = 1e-3
SEEDS = range(6)
KINDS = ("slip", "field-position", "field-rotation", "mixed")
LP = np.array([0.03, -0.02, 0.12])
LC = np.array([-0.01, 0.04, -0.18])
X_TRUE = np.concatenate([LP, LC])


def smooth(rng: np.random.Generator, n: int, amplitude: np.ndarray) -> np.ndarray:
    """``(n, d)`` sums of three sines of 0.1-0.8 Hz per column, each column within +-amplitude."""
    t = np.arange(n)[:, None, None] / RATE_HZ
    amplitude = np.asarray(amplitude, dtype=float)
    freq = rng.uniform(0.1, 0.8, (1, amplitude.size, 3))
    phase = rng.uniform(0.0, 2.0 * np.pi, (1, amplitude.size, 3))
    return np.sin(2.0 * np.pi * freq * t + phase).mean(axis=2) * amplitude


def chain(
    rng: np.random.Generator,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    *,
    n: int = N_FRAMES,
    hinge_axis: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact poses of a chain of sensors, joint ``k`` between sensors ``k`` and ``k + 1``.

    Each relative rotation's vector has x and y within +-0.84 rad and z (twist) within +-0.42 rad,
    so the child's axis sweeps a cone of up to about 54 degrees from the parent's; with
    ``hinge_axis`` every joint turns about that axis (in the parent frame) only. Returns ``R``
    ``(n, J+1, 3, 3)`` and ``p`` ``(n, J+1, 3)``, metres.
    """
    R = [rotvec_to_matrix(smooth(rng, n, [0.8, 0.8, 1.5]))]
    p = [smooth(rng, n, [0.5, 0.5, 0.3]) + np.array([0.0, 0.0, 1.0])]
    for lp, lc in zip(np.reshape(joint_in_parent, (-1, 3)), np.reshape(joint_in_child, (-1, 3)), strict=True):
        if hinge_axis is None:
            rotvec = smooth(rng, n, np.deg2rad([48.0, 48.0, 24.0]))
        else:
            rotvec = smooth(rng, n, [1.0]) * hinge_axis
        R_child = R[-1] @ rotvec_to_matrix(rotvec)
        p.append(np.einsum("fij,j->fi", R[-1], lp) + p[-1] - np.einsum("fij,j->fi", R_child, lc))
        R.append(R_child)
    return np.stack(R, axis=1), np.stack(p, axis=1)


def corrupt_blocks(rng: np.random.Generator, n: int, fraction: float, n_blocks: int = 3) -> list[slice]:
    """``n_blocks`` disjoint contiguous blocks covering ``fraction`` of ``n`` frames."""
    total = round(fraction * n)
    zone = n // n_blocks
    out = []
    for k in range(n_blocks):
        size = total // n_blocks + (k < total % n_blocks)
        start = int(rng.integers(k * zone, (k + 1) * zone - size))
        out.append(slice(start, start + size))
    return out


def slip(rng: np.random.Generator, R: np.ndarray, p: np.ndarray, blocks: list[slice]) -> None:
    """In place: the sensor slides 2-5 cm on the skin (an offset fixed in its frame) per block."""
    for b in blocks:
        d = rng.normal(size=3)
        d *= rng.uniform(0.02, 0.05) / np.linalg.norm(d)
        p[b] += np.einsum("fij,j->fi", R[b], d)


def field_burst(
    rng: np.random.Generator,
    R: np.ndarray,
    p: np.ndarray,
    blocks: list[slice],
    *,
    position: bool,
    rotation: bool,
) -> None:
    """In place: a field-distortion burst per block -- a position error ``g (p - s)`` growing with
    the distance to a source ``s`` (3-8 cm on average over the burst) and/or a 5-10 degree
    rotation error about a random axis."""
    for b in blocks:
        if position:
            away = p[b] - (p[b.start] + rng.normal(size=3) * 0.5)
            p[b] += rng.uniform(0.03, 0.08) / np.mean(np.linalg.norm(away, axis=1)) * away
        if rotation:
            axis = rng.normal(size=3)
            R[b] = rotvec_to_matrix(axis * np.deg2rad(rng.uniform(5.0, 10.0)) / np.linalg.norm(axis)) @ R[b]


def corrupt(rng: np.random.Generator, R: np.ndarray, p: np.ndarray, kind: str, fraction: float = 0.05):
    """Corrupted copies of one sensor's ``R`` ``(n, 3, 3)`` and ``p`` ``(n, 3)``, and the ``(n,)``
    mask of the corrupted frames."""
    R, p = R.copy(), p.copy()
    if kind == "mixed":
        blocks = corrupt_blocks(rng, len(p), fraction, 4)
        slip(rng, R, p, blocks[::2])
        field_burst(rng, R, p, blocks[1::2], position=True, rotation=True)
    else:
        blocks = corrupt_blocks(rng, len(p), fraction)
        if kind == "slip":
            slip(rng, R, p, blocks)
        else:
            field_burst(
                rng, R, p, blocks, position=kind == "field-position", rotation=kind == "field-rotation"
            )
    mask = np.zeros(len(p), dtype=bool)
    for b in blocks:
        mask[b] = True
    return R, p, mask


def session(seed: int, kind: str | None = None, *, hinge_axis: np.ndarray | None = None):
    """``(Rp, pp, Rc, pc, shift)``: one seeded pair session, noisy child position, optionally
    corrupted; ``shift`` ``(frames,)`` is how far the corruption moved each frame's joint
    residual at the true joint (zero on clean frames), metres."""
    rng = np.random.default_rng(seed)
    R, p = chain(rng, LP, LC, hinge_axis=hinge_axis)
    Rp, pp = R[:, 0], p[:, 0]
    Rc, pc = R[:, 1], p[:, 1] + rng.normal(0.0, NOISE_M, (N_FRAMES, 3))
    shift = np.zeros(N_FRAMES)
    if kind is not None:
        Rk, pk, _ = corrupt(np.random.default_rng(1000 + seed), Rc, pc, kind)
        moved = joint_residual_vectors(Rp, pp, Rk, pk, LP, LC) - joint_residual_vectors(
            Rp, pp, Rc, pc, LP, LC
        )
        Rc, pc, shift = Rk, pk, np.linalg.norm(moved, axis=1)
    return Rp, pp, Rc, pc, shift


def x_of(fit) -> np.ndarray:
    return np.concatenate([fit.joint_in_parent, fit.joint_in_child])


def rms_error(xs: list[np.ndarray], x_true: np.ndarray = X_TRUE) -> float:
    """rms over sessions of ``|x_hat - x_true|``, metres."""
    return float(np.sqrt(np.mean([np.sum((x - x_true) ** 2) for x in xs])))


@pytest.fixture(scope="module")
def clean_errors():
    """Per loss, rms errors over the seeded clean sessions: least squares and robust."""
    ols, rob = [], {"tukey": [], "huber": []}
    for seed in SEEDS:
        args = session(seed)[:4]
        ols.append(x_of(fit_joint(*args)))
        for loss in rob:
            rob[loss].append(x_of(robust_fit_joint(*args, loss=loss)))
    return rms_error(ols), {loss: rms_error(xs) for loss, xs in rob.items()}


def test_chi3_consistency_constant():
    # the median of a 3-D standard normal vector's norm is the chi_3 median, not 1 nor 0.6745
    assert CHI3_MEDIAN == pytest.approx(stats.chi(3).median(), rel=1e-12)
    assert CHI3_MEDIAN == pytest.approx(1.5381722544550522, rel=1e-12)
    norms = np.linalg.norm(np.random.default_rng(0).normal(0.0, 0.002, (200_000, 3)), axis=1)
    # median / CHI3_MEDIAN recovers sigma; 2e5 samples: the median's relative sd is ~0.2 %
    assert np.median(norms) / CHI3_MEDIAN == pytest.approx(0.002, rel=0.01)
    assert INLIER_C == pytest.approx(np.sqrt(stats.chi2.ppf(0.999, 3)), rel=1e-12)


def test_tuning_constants_give_95_percent_efficiency():
    # the constants are rounded to 3 decimals: efficiency within 1e-3 of 0.95
    assert asymptotic_efficiency("huber", HUBER_C) == pytest.approx(0.95, abs=1e-3)
    assert asymptotic_efficiency("tukey", TUKEY_C) == pytest.approx(0.95, abs=1e-3)
    # limits: huge c is least squares; Huber c -> 0 is the spatial median, whose efficiency in 3-D
    # is 4 E[1/u]^2 / 3 with E[1/u] = sqrt(2 / pi) for u ~ chi_3: 8 / (3 pi) = 0.8488
    assert asymptotic_efficiency("huber", 50.0) == pytest.approx(1.0, abs=1e-9)
    assert asymptotic_efficiency("huber", 1e-6) == pytest.approx(8.0 / (3.0 * np.pi), abs=1e-4)
    # the one-dimensional constants are not the 3-D norm's: Tukey's 4.685 is below 95 % here
    assert asymptotic_efficiency("tukey", 4.685) < 0.92


def test_efficiency_constant_checked_by_monte_carlo():
    # location of 3-D Gaussian points with known scale: Huber on the norm at c = HUBER_C should have
    # 1/0.95 the variance of the mean. 2000 replicates of 400 points estimate the ratio to about
    # +-2 % (measured 0.944); the window checks that quadrature and simulation agree, nothing finer
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(2000, 400, 3))
    loc = pts.mean(axis=1)
    for _ in range(30):
        r = np.linalg.norm(pts - loc[:, None], axis=2)
        w = loss_weights(r, "huber", HUBER_C)
        loc = np.einsum("rn,rnk->rk", w, pts) / w.sum(axis=1)[:, None]
    eff = np.mean(np.sum(pts.mean(axis=1) ** 2, axis=1)) / np.mean(np.sum(loc**2, axis=1))
    print(f"\nMonte Carlo efficiency of Huber c={HUBER_C} on the 3-D norm: {eff:.3f}")
    assert 0.90 < eff < 1.0


@pytest.mark.parametrize("loss", ["huber", "tukey"])
def test_noise_free_fit_is_exact(loss):
    rng = np.random.default_rng(3)
    R, p = chain(rng, LP, LC)
    fit = robust_fit_joint(R[:, 0], p[:, 0], R[:, 1], p[:, 1], loss=loss)
    # exact data: only rounding of metre-sized numbers (~1e-16)
    assert_allclose(x_of(fit), X_TRUE, atol=1e-9)
    assert fit.converged and fit.rank == 6 and not fit.single_axis
    assert fit.rms_residual < 1e-12 and fit.inlier.all()
    if loss == "huber":
        assert np.all(fit.weights == 1.0)
    else:
        # residuals ~1e-16 against the scale floor (1e-9 of the separation): 1 - w ~ 1e-13
        assert np.all(fit.weights > 1.0 - 1e-9)


@pytest.mark.parametrize("loss", ["huber", "tukey"])
def test_noise_free_hinge_keeps_the_minimum_norm_point(loss):
    axis = np.array([0.0, 0.0, 1.0])
    v = np.concatenate([axis, axis]) / np.sqrt(2.0)
    R, p = chain(np.random.default_rng(4), LP, LC, hinge_axis=axis)
    fit = robust_fit_joint(R[:, 0], p[:, 0], R[:, 1], p[:, 1], loss=loss)
    assert fit.single_axis and fit.rank == 5
    # exact data: the minimum-norm point on the axis, to rounding
    assert_allclose(x_of(fit), X_TRUE - (X_TRUE @ v) * v, atol=1e-9)
    assert_allclose(x_of(fit), x_of(fit.ols), atol=1e-12)
    assert np.all(fit.weights > 1.0 - 1e-9)


def test_clean_session_efficiency(clean_errors):
    ols, robust = clean_errors
    print(f"\nclean sessions, rms error over {len(SEEDS)} seeds: OLS {ols * 1e3:.4f} mm", end="")
    for loss, err in robust.items():
        print(f", {loss} {err * 1e3:.4f} mm (x{err / ols:.3f})", end="")
    # 95 % asymptotic efficiency is x1.026 in error; the brief's bound is 1.1x
    assert robust["tukey"] <= 1.1 * ols
    assert robust["huber"] <= 1.1 * ols


@pytest.mark.parametrize("kind", KINDS)
def test_corrupted_session_meets_target(kind, clean_errors):
    clean_ols, _ = clean_errors
    ols, tukey, huber, small, ols_rank = [], [], [], [], []
    for seed in SEEDS:
        Rp, pp, Rc, pc, shift = session(seed, kind)
        fit = robust_fit_joint(Rp, pp, Rc, pc)  # the default loss, Tukey's biweight
        ols.append(x_of(fit.ols))
        tukey.append(x_of(fit))
        huber.append(x_of(robust_fit_joint(Rp, pp, Rc, pc, loss="huber")))
        # frames the corruption moved by 1 cm or more (10 sigma; the noise's norm exceeds 4.5 mm
        # once in 2000 frames) get no weight; clean frames are inliers but for the 0.1 % tail
        assert np.all(fit.weights[shift > 0.01] == 0.0)
        assert np.mean(fit.inlier[shift == 0.0]) > 0.99
        small.append(np.mean(shift[shift > 0] < 0.01))
        # a ball joint swept through a 60 degree cone: the robust verdict sees it whatever the
        # least-squares one (fooled by the corrupted frames' variance) says
        assert fit.rank == 6
        ols_rank.append(fit.ols.rank)
    e_ols, e_tukey, e_huber = rms_error(ols), rms_error(tukey), rms_error(huber)
    print(
        f"\n{kind}: clean OLS {clean_ols * 1e3:.4f} mm; corrupted OLS {e_ols * 1e3:.3f} mm "
        f"(x{e_ols / clean_ols:.1f}), tukey {e_tukey * 1e3:.4f} mm (x{e_tukey / clean_ols:.3f}), "
        f"huber {e_huber * 1e3:.4f} mm (x{e_huber / clean_ols:.2f}); corrupted frames moved "
        f"< 1 cm: {np.mean(small):.1%}; least-squares ranks {ols_rank}"
    )
    # the target, met by the default (Tukey) loss
    assert e_ols > 3.0 * clean_ols
    assert e_tukey <= 1.2 * clean_ols
    # Huber's bounded but non-zero pull (c sigma per corrupted frame) leaves a bias: measured
    # x1.7-x2.9 of the clean error, so it misses the target; it still removes most of the damage
    assert e_huber <= 0.2 * e_ols


def test_hinge_stays_on_axis_with_corruption():
    axis = np.array([1.0, 0.0, 0.0])
    v = np.concatenate([axis, axis]) / np.sqrt(2.0)  # A's null direction for an exact hinge
    x_star = X_TRUE - (X_TRUE @ v) * v  # the minimum-norm point on the true axis
    fooled, tilts = 0, []
    for seed in range(4):
        Rp, pp, Rc, pc, _ = session(seed, hinge_axis=axis)
        clean = fit_joint(Rp, pp, Rc, pc)
        assert clean.single_axis
        for kind in ("slip", "field-rotation"):
            Rk, pk, _ = corrupt(np.random.default_rng(2000 + seed), Rc, pc, kind)
            fit = robust_fit_joint(Rp, pp, Rk, pk)
            fooled += fit.ols.rank == 6
            assert fit.single_axis and fit.rank == 5
            sign = np.sign(fit.axis_in_parent @ axis)
            tilt = np.degrees(np.arccos(np.clip(sign * fit.axis_in_parent @ axis, -1.0, 1.0)))
            tilts.append(tilt)
            if kind == "slip":
                # positions only: the rotations are exact, so is the axis, to rounding
                assert_allclose(sign * fit.axis_in_parent, axis, atol=1e-9)
                assert_allclose(sign * fit.axis_in_child, axis, atol=1e-9)
            else:
                # a few corrupted frames whose rotation error happens to fit stay inliers and
                # tilt the axis (measured: up to 0.05 degree, least squares: up to 0.5 degree)
                assert tilt < 0.1
            x = x_of(fit)
            # minimum norm along the fitted axis: no component along its null direction
            v_fit = np.concatenate([fit.axis_in_parent, fit.axis_in_child]) / np.sqrt(2.0)
            assert abs(x @ v_fit) < 1e-12
            # and the point is where the clean fit puts it, within its noise (clean error ~0.1 mm)
            assert np.linalg.norm(x - x_star) <= max(3.0 * np.linalg.norm(x_of(clean) - x_star), 3e-4)
    # rotation errors made least squares call 1 of these 8 hinges a ball joint on the test alone;
    # the effect size of the verdict (issue 42: the bias bound along the axis, calibration.hinge)
    # keeps all 8 single-axis (measured)
    print(
        f"\nhinge: least squares called {fooled} of 8 corrupted hinges ball joints, robust 0 of 8; "
        f"robust axis tilt up to {max(tilts):.3f} deg"
    )
    assert fooled == 0


def test_support_drops_directions_resting_on_a_few_frames():
    rng = np.random.default_rng(8)
    R, _ = chain(rng, LP, LC)
    ball = np.concatenate([R[:, 0], -R[:, 1]], axis=2)
    assert supported_rank(ball, 6) == 6
    axis = np.array([0.0, 1.0, 0.0])
    R, _ = chain(rng, LP, LC, hinge_axis=axis)
    R_off = R[:, 1].copy()
    R_off[:20] = rotvec_to_matrix(np.array([0.1, 0.0, 0.05])) @ R_off[:20]  # 20 frames off the axis
    hinge = np.concatenate([R[:, 0], -R_off], axis=2)
    # 20 of 3000 frames carry the axis direction: support 0.7 % < MIN_SUPPORT
    assert MIN_SUPPORT > 20 / N_FRAMES
    assert supported_rank(hinge, 6) == 5
    # a second of off-axis motion in every half minute (4 % of frames) is kept
    R_off[: int(0.04 * N_FRAMES)] = (
        rotvec_to_matrix(np.array([0.1, 0.0, 0.05])) @ R[: int(0.04 * N_FRAMES), 1]
    )
    assert supported_rank(np.concatenate([R[:, 0], -R_off], axis=2), 6) == 6
    assert supported_rank(ball, 4) == 4  # never raises a rank


# five sensors in a chain: two long segments, a medium one and a short one (a hand or foot)
CHAIN_LP = np.array([[0.02, 0.05, -0.10], [0.0, 0.04, -0.20], [0.01, 0.03, -0.15], [0.0, 0.02, -0.05]])
CHAIN_LC = np.array([[0.03, -0.02, 0.12], [0.01, 0.03, 0.10], [-0.02, 0.0, 0.09], [0.0, 0.02, 0.04]])
CHAIN_EDGES = [(0, 1), (1, 2), (2, 3), (3, 4)]


@pytest.mark.parametrize("kind", ["slip", "mixed"])
def test_hierarchy_from_robust_costs(kind):
    rng = np.random.default_rng(21)
    R, p = chain(rng, CHAIN_LP, CHAIN_LC)
    p = p + rng.normal(0.0, NOISE_M, p.shape)
    R[:, 4], p[:, 4], _ = corrupt(rng, R[:, 4], p[:, 4], kind)  # the leaf: the pair (3, 4)
    names = [f"s{k}" for k in range(5)]

    def edges(tree):
        return sorted(tuple(sorted(e)) for e in tree.joints)

    robust = robust_pair_misfits(R, p)
    assert_allclose(robust.residual, robust.residual.T, rtol=0)
    assert np.isinf(np.diag(robust.residual)).all()
    for method in ("misfit", "mst"):
        assert edges(spanning_tree(robust.weights(method))) == CHAIN_EDGES
    ols = {m: calibrate(R, p, names, hierarchy_method=m) for m in ("misfit", "mst")}
    ols_right = {m: edges(cal.hierarchy) == CHAIN_EDGES for m, cal in ols.items()}
    res = ols["mst"].residual_matrix
    joints = [robust.residual[e] for e in CHAIN_EDGES]
    non_joint = min(res[i, j] for i in range(5) for j in range(i + 1, 5) if (i, j) not in CHAIN_EDGES)
    print(
        f"\nhierarchy ({kind} on s3-s4): OLS trees right {ols_right}; OLS rms of the corrupted joint "
        f"{res[3, 4] * 1e3:.2f} mm vs clean joints {res[0, 1] * 1e3:.2f} mm, nearest non-joint "
        f"{non_joint * 1e3:.1f} mm; robust {[round(float(j) * 1e3, 2) for j in joints]} mm"
    )
    # the robust cost of the corrupted joint is that of a clean one (same noise): within 10 %
    assert robust.residual[3, 4] <= 1.1 * max(joints[:3])
    # least squares inflates it: its margin to the non-joints shrinks (here it still holds)
    assert res[3, 4] > 2.0 * res[0, 1]
    assert robust.inlier_fraction[3, 4] == pytest.approx(0.95, abs=0.01)
    # the robust noise variance is the white noise of both sensors: 3 (sqrt(2) mm)^2 = 6 mm^2
    assert_allclose(robust.noise_variance[np.triu_indices(5, 1)], 6e-6, rtol=0.1)


def test_dropped_frames_are_nan_and_match_the_cut_fit():
    Rp, pp, Rc, pc, _ = session(0, "slip")
    Rp, pc = Rp.copy(), pc.copy()
    Rp[7, 1, 1] = np.nan
    pc[100] = np.inf
    valid = np.ones(N_FRAMES, dtype=bool)
    valid[200:210] = False
    fit = robust_fit_joint(Rp, pp, Rc, pc, valid=valid)
    drop = ~valid
    drop[[7, 100]] = True
    assert np.isnan(fit.weights[drop]).all() and np.isnan(fit.frame_residual[drop]).all()
    assert not fit.inlier[drop].any()
    keep = ~drop
    ref = robust_fit_joint(Rp[keep], pp[keep], Rc[keep], pc[keep])
    # the same frames give the same arithmetic up to the order of sums
    assert_allclose(x_of(fit), x_of(ref), atol=1e-12)
    assert_allclose(fit.weights[keep], ref.weights, atol=1e-9)
    assert fit.ols.n_dropped == 12


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    rotvec=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
    shift=st.tuples(*[st.floats(-100.0, 100.0)] * 3),
    unit=st.sampled_from([1e-3, 1.0, 100.0, 1000.0 / 25.4]),
)
def test_fit_is_equivariant_under_world_motion_and_units(seed, rotvec, shift, unit):
    rng = np.random.default_rng(seed)
    R, p = chain(rng, LP, LC, n=240)
    Rc, pc, _ = corrupt(rng, R[:, 1], p[:, 1] + rng.normal(0.0, NOISE_M, (240, 3)), "mixed")
    Rp, pp = R[:, 0], p[:, 0]
    base = robust_fit_joint(Rp, pp, Rc, pc)
    Q = rotvec_to_matrix(np.array(rotvec))
    t = np.array(shift)
    moved = robust_fit_joint(Q @ Rp, unit * (pp @ Q.T + t), Q @ Rc, unit * (pc @ Q.T + t))
    # joints live in the sensor frames: a world motion leaves them, a unit scales them. Rounding
    # of coordinates up to ~100 m: 1e-13 relative, amplified by the fit's conditioning
    assert_allclose(x_of(moved), unit * x_of(base), rtol=0, atol=unit * 1e-8)
    assert_allclose(moved.weights, base.weights, atol=1e-6)
    assert moved.scale_m == pytest.approx(unit * base.scale_m, rel=1e-6)
    assert np.all((base.weights >= 0.0) & (base.weights <= 1.0))
    assert np.array_equal(base.inlier, base.frame_residual <= INLIER_C * base.scale_m)


def test_bad_inputs():
    Rp, pp, Rc, pc, _ = session(0)
    with pytest.raises(CalibrationInputError, match=r"Expected p_w_p to have shape \(frames, 3\)"):
        robust_fit_joint(Rp, pp[:, :2], Rc, pc)
    with pytest.raises(CalibrationInputError, match="Expected R_w_c to have 3000 frames"):
        robust_fit_joint(Rp, pp, Rc[:10], pc)
    with pytest.raises(
        CalibrationInputError, match=r"loss must be one of \['tukey', 'huber'\], got 'cauchy'"
    ):
        robust_fit_joint(Rp, pp, Rc, pc, loss="cauchy")
    for bad in (0.0, -1.0, np.inf, np.nan, "big"):
        with pytest.raises(CalibrationInputError, match="tuning must be a positive number"):
            robust_fit_joint(Rp, pp, Rc, pc, tuning=bad)
    with pytest.raises(CalibrationInputError, match="max_iter must be an integer of at least 1"):
        robust_fit_joint(Rp, pp, Rc, pc, max_iter=0)
    with pytest.raises(CalibrationInputError, match="tol must be a positive number"):
        robust_fit_joint(Rp, pp, Rc, pc, tol=0.0)
    with pytest.raises(CalibrationInputError, match=r"Expected valid to be a bool array of shape \(3000,\)"):
        robust_fit_joint(Rp, pp, Rc, pc, valid=np.ones(3000))
    with pytest.raises(
        CalibrationError, match=f"at least {MIN_FRAMES} frames where both poses are valid, got 9"
    ):
        robust_fit_joint(Rp[:9], pp[:9], Rc[:9], pc[:9])
    valid = np.zeros(3000, dtype=bool)
    valid[:5] = True
    with pytest.raises(CalibrationError, match="got 5"):
        robust_fit_joint(Rp, pp, Rc, pc, valid=valid)
    with pytest.raises(CalibrationInputError, match="loss must be one of"):
        asymptotic_efficiency("l1", 1.0)


def test_pair_misfits_bad_inputs():
    R = np.tile(np.eye(3), (20, 1, 1, 1))
    p = np.zeros((20, 1, 3))
    with pytest.raises(CalibrationError, match="at least 2 sensors, got 1"):
        robust_pair_misfits(R, p)
    with pytest.raises(CalibrationInputError, match=r"Expected p_w_s to have shape \(20, 1, 3\)"):
        robust_pair_misfits(R, np.zeros((20, 2, 3)))
    with pytest.raises(CalibrationInputError, match="tuning must be a positive number"):
        robust_pair_misfits(np.tile(np.eye(3), (20, 2, 1, 1)), np.zeros((20, 2, 3)), tuning=-2.0)
    rng = np.random.default_rng(1)
    R2, p2 = chain(rng, LP, LC, n=200)
    valid = np.ones((200, 2), dtype=bool)
    valid[5:, 1] = False  # the pair shares 5 frames: not fitted, an infinite cost
    out = robust_pair_misfits(R2, p2, valid=valid)
    assert np.isinf(out.residual).all() and out.inlier_fraction[0, 1] == 0.0
    with pytest.raises(CalibrationInputError, match=r"method must be one of \['misfit', 'mst'\]"):
        out.weights("tree")


def test_a_robust_calibration_of_too_few_frames_says_how_many_it_needs():
    rng = np.random.default_rng(2)
    R, p = chain(rng, LP, LC, n=MIN_FRAMES - 1)
    with pytest.raises(CalibrationError, match=f"needs at least {MIN_FRAMES} frames where both poses"):
        calibrate(R, p, ["a", "b"], robust="huber")
    R, p = chain(rng, LP, LC, n=MIN_FRAMES + 40)
    assert calibrate(R, p, ["a", "b"], robust="huber").joints  # enough: it calibrates


def test_calibration_refuses_poses_that_are_not_rotations_or_not_arrays():
    rng = np.random.default_rng(4)
    R, p = chain(rng, LP, LC, n=200)
    names = ["a", "b"]
    for bad in (0 * R, 2 * R, -R):  # zeros, scaled, reflected
        with pytest.raises(CalibrationInputError, match=r"hold rotation matrices .* 128 of 128 sampled"):
            calibrate(bad, p, names)
    noisy = R.copy()
    noisy[:, :, 0, 0] += 1e-7  # a tracker's single-precision matrices: rotations still
    assert calibrate(noisy, p, names).joints
    half = R.copy()
    half[::3] = 0.0  # a third of the frames zero but marked invalid: judged on the valid ones
    valid = np.ones((200, 2), dtype=bool)
    valid[::3] = False
    assert calibrate(half, p, names, valid=valid).joints
    with pytest.raises(CalibrationInputError, match=r"Expected R_w_s as an array .* got a list"):
        calibrate(R.tolist(), p, names)
