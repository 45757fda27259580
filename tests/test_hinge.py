"""The statistical single-axis verdict (calibration.hinge) on realistic hinges and ball joints."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import fit_joint
from calibration.hinge import N_BLOCKS, block_edges, block_frames, critical_t, hinge_verdict, score_variance
from calibration.pairs import pair_statistics, solve_pairs
from calibration.rotations import rotvec_to_matrix
from simbench.sim.synthetic import messy_joint

HINGE_WOBBLE = (0.04, 0.04, 0.8)  # about 2 degrees rms off the axis, like the real rig
BALL_2_AXES = (0.04, 0.8, 0.8)
BALL_3_AXES = (0.8, 0.8, 0.8)


def _capture(amp, seed, n_frames=3000):
    return messy_joint(amp, n_frames=n_frames, rate_hz=100.0, rng=np.random.default_rng(seed))


def _fit(cap, scale=1.0, valid=None):
    R, p = cap.R_w_s, scale * cap.p_w_s
    return fit_joint(R[:, 0], p[:, 0], R[:, 1], p[:, 1], valid=valid)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_messy_hinge_is_single_axis_where_the_ratio_rule_was_not(seed):
    cap = _capture(HINGE_WOBBLE, seed)
    fit = _fit(cap)
    # the old fixed rule (s_min/s_max < 0.01) would call this a ball joint, as on the real rig
    assert 0.012 < fit.weak_ratio < 0.03
    assert fit.single_axis and fit.rank == 5
    assert fit.weakest_t < 3.0  # the centre along the axis is not significant at all
    # the hinge axis is the parent body's z axis; in the parent sensor's frame R_b_s^T z
    R_b_s = rotvec_to_matrix(np.array(cap.skeleton.segments[0].sensor_rotvec))
    truth = R_b_s.T @ np.asarray(cap.skeleton.segments[1].axis, dtype=float)
    # recovered to within the wobble (about 2 degrees rms)
    assert abs(fit.axis_in_parent @ truth) > np.cos(np.radians(5.0))


@pytest.mark.parametrize("amp", [BALL_2_AXES, BALL_3_AXES])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ball_joints_moved_in_two_or_three_axes_are_not_single_axis(amp, seed):
    fit = _fit(_capture(amp, seed))
    assert not fit.single_axis and fit.rank == 6


@pytest.mark.parametrize("amp", [HINGE_WOBBLE, BALL_2_AXES])
def test_verdict_is_the_same_in_m_mm_and_inches(amp):
    cap = _capture(amp, 5)
    fits = [_fit(cap, scale) for scale in (1.0, 1000.0, 1.0 / 0.0254)]
    assert len({f.single_axis for f in fits}) == 1 and len({f.rank for f in fits}) == 1
    t = [
        solve_pairs(pair_statistics(cap.R_w_s, scale * cap.p_w_s), [0], [1]).t_statistic[0]
        for scale in (1.0, 1000.0, 1.0 / 0.0254)
    ]
    assert_allclose(t[1], t[0], rtol=1e-6)
    assert_allclose(t[2], t[0], rtol=1e-6)


@pytest.mark.parametrize("amp", [HINGE_WOBBLE, BALL_2_AXES, BALL_3_AXES])
def test_all_pairs_path_agrees_with_fit_joint(amp):
    cap = _capture(amp, 7, n_frames=2000)
    valid = np.ones((2000, 2), dtype=bool)
    valid[300:420, 1] = False  # a gap: blocks with fewer frames
    valid[1990:, 0] = False
    fit = _fit(cap, valid=valid[:, 0] & valid[:, 1])
    stats = pair_statistics(cap.R_w_s, cap.p_w_s, valid=valid, chunk_frames=333)
    sol = solve_pairs(stats, [0], [1])
    assert int(sol.keep[0].sum()) == fit.rank
    # the test statistic itself, from per-block normal equations vs per-frame residuals
    assert sol.t_statistic[0, 5] == pytest.approx(fit.weakest_t, rel=1e-6)
    assert_allclose(sol.singular_values[0], fit.singular_values, rtol=1e-9)
    assert_allclose(sol.joint_in_parent[0], fit.joint_in_parent, atol=1e-9)
    assert_allclose(sol.joint_in_child[0], fit.joint_in_child, atol=1e-9)


def test_block_sums_are_the_statistics_of_each_block():
    cap = _capture(BALL_3_AXES, 3, n_frames=500)
    stats = pair_statistics(cap.R_w_s, cap.p_w_s, chunk_frames=64)
    edges = block_edges(500)  # 16 frames a block: 31 full blocks and one of 4 frames
    assert len(edges) == 33 and edges[0] == 0 and edges[-1] == 500 and edges[-2] == 496
    for k in (0, 7, 31):
        part = pair_statistics(cap.R_w_s[edges[k] : edges[k + 1]], cap.p_w_s[edges[k] : edges[k + 1]])
        assert_allclose(stats.block_gram[k], part.gram, atol=1e-9)
        assert_allclose(stats.block_count[k], part.count)
        # cross terms use positions centred per frame: their differences are what the fit uses
        diff = stats.block_cross[k] - stats.block_self_cross[k]
        assert_allclose(diff, part.cross - part.self_cross, atol=1e-9)
    assert_allclose(stats.block_gram.sum(axis=0), stats.gram, atol=1e-9)


def test_exact_near_hinge_is_a_ball_joint():
    """Noise-free data locate the centre along the axis even with 0.3 degrees of wobble."""
    cap = messy_joint(
        (0.005, 0.005, 0.8),
        n_frames=2000,
        rate_hz=100.0,
        rng=np.random.default_rng(0),
        play_m=0.0,
        skin_m=0.0,
        position_noise_m=0.0,
        rotation_noise_rad=0.0,
    )
    fit = _fit(cap)
    assert fit.weak_ratio < 0.01 and not fit.single_axis
    lp, _ = cap.skeleton.joint_in_sensor_frames()["child"]
    assert_allclose(fit.joint_in_parent, lp, atol=1e-6)


def test_verdict_drops_weakest_directions_while_not_significant():
    floor = np.array([[True] * 6, [True] * 6, [True] * 5 + [False]])
    t = np.array([[50, 50, 50, 20, 30, 1.0], [50, 50, 50, 1.0, 30, 1.0], [50, 50, 50, 1.0, 1.0, np.nan]])
    testable = np.array([[False] * 3 + [True] * 3] * 3)
    precise = np.zeros((3, 6), dtype=bool)
    keep = hinge_verdict(floor, t, np.full(3, 4.0), testable, precise)
    assert keep.sum(axis=1).tolist() == [5, 5, 3]  # row 1: direction 4 kept, 5 significant
    precise[0, 5] = True  # a centre placed within its scatter is measured, even at 0
    assert hinge_verdict(floor, t, np.full(3, 4.0), testable, precise)[0].all()


@pytest.mark.parametrize("n", [0, 1, 2, 31, 32, 33, 64, 65, 500, 6000, 7201, 2**20 + 1])
def test_blocks_are_powers_of_two_long_and_at_most_n_blocks(n):
    edges = block_edges(n)
    length = block_frames(n)
    assert edges[0] == 0 and edges[-1] == n
    assert length & (length - 1) == 0  # a power of two
    assert len(edges) - 1 <= N_BLOCKS
    if n:
        assert np.all(np.diff(edges)[:-1] == length) and 0 < edges[-1] - edges[-2] <= length
    if length > 1:  # the smallest such power: half of it would need more blocks
        assert -(-n // (length // 2)) > N_BLOCKS


def test_blocks_of_a_prefix_are_merged_blocks_of_the_whole():
    # the streaming calibration's premise: every block of a longer recording is a union of
    # consecutive blocks of any shorter prefix (cut where the prefix's blocks are cut)
    for n_short, n_long in ((40, 41), (100, 1000), (1000, 1_000_000), (5000, 5001)):
        short, long = set(block_edges(n_short)[:-1].tolist()), block_edges(n_long)[:-1]
        assert set(long[long < n_short].tolist()) <= short


def test_score_variance_weighs_a_partial_block_by_its_length():
    rng = np.random.default_rng(3)
    g = rng.normal(size=(5, 6))
    g -= g.mean(axis=0)  # block scores sum to zero, as the normal equations make them
    equal = score_variance(g, np.full(5, 100))
    assert_allclose(equal, 5 / 4 * np.sum(g**2, axis=0), rtol=1e-12)  # the textbook B/(B-1)
    counts = np.array([100, 100, 100, 100, 10])
    n, s2 = counts.sum(), np.sum(counts**2)
    assert_allclose(score_variance(g, counts), n * np.sum(g**2, axis=0) / (n - s2 / n), rtol=1e-12)
    assert np.isnan(score_variance(g[:1], counts[:1])).all()  # one block: no variance
    # white noise: the estimate is unbiased for the whole score's variance with unequal blocks
    counts = np.array([64] * 9 + [7])
    frames = rng.normal(size=(20000, counts.sum()))
    frames -= frames.mean(axis=1, keepdims=True)  # the zero-sum constraint of the fit
    blocks = np.add.reduceat(frames, np.r_[0, np.cumsum(counts)[:-1]], axis=1)
    est = score_variance(blocks[:, :, None], counts)[:, 0]
    # the true variance of a single score before centring is counts.sum(); 20000 draws: 2 % tolerance
    assert_allclose(np.mean(est), counts.sum(), rtol=0.02)
    # effective number of blocks: B for equal blocks, less for a partial one
    assert critical_t(np.full(5, 100)) == pytest.approx(critical_t(np.full(5, 7)))
    assert critical_t(np.full(10, 64)) < critical_t(counts) < critical_t(np.full(9, 64))
