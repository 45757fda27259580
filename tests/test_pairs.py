"""The all-pairs normal-equation path agrees with the per-pair SVD (issue: 1e-6 m)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import (
    CalibrationInputError,
    fit_joint,
    frame_residuals,
    pair_residual_matrix,
    pair_statistics,
    solve_pairs,
)
from simbench.sim.synthetic import random_tree, simulate_motion
from tests.helpers import pair_arrays


def svd_residual_matrix(cap, valid=None):
    n = len(cap.names)
    out = np.full((n, n), np.inf)
    for i in range(n):
        for j in range(i + 1, n):
            v = None if valid is None else valid[:, i] & valid[:, j]
            fit = fit_joint(*pair_arrays(cap, cap.names[i], cap.names[j]), valid=v)
            out[i, j] = out[j, i] = fit.rms_residual
    return out


@pytest.fixture(scope="module")
def tree_noisy():
    return simulate_motion(
        random_tree(9, np.random.default_rng(8)),
        n_frames=1500,
        rate_hz=100.0,
        rng=np.random.default_rng(9),
        position_noise_m=0.004,
        rotation_noise_rad=0.01,
    )


def test_all_pairs_agree_with_svd_on_noisy_data(linkage_noisy, tree_noisy):
    for cap in (linkage_noisy, tree_noisy):
        fast = pair_residual_matrix(pair_statistics(cap.R_w_s, cap.p_w_s))
        ref = svd_residual_matrix(cap)
        # the bound; the two differ by rounding only, far below it
        assert_allclose(fast, ref, atol=1e-6, rtol=0)
        assert_allclose(fast, ref, atol=1e-10, rtol=0)


def test_joint_locations_agree_with_svd(tree_noisy):
    cap = tree_noisy
    stats = pair_statistics(cap.R_w_s, cap.p_w_s)
    n = len(cap.names)
    i, j = np.triu_indices(n, k=1)
    sol = solve_pairs(stats, i, j)
    for k in range(len(i)):
        ref = fit_joint(*pair_arrays(cap, cap.names[i[k]], cap.names[j[k]]))
        assert_allclose(sol.joint_in_parent[k], ref.joint_in_parent, atol=1e-6)
        assert_allclose(sol.joint_in_child[k], ref.joint_in_child, atol=1e-6)
        assert_allclose(sol.singular_values[k], ref.singular_values, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("offset_m", [0.0, 1000.0])
def test_noise_free_residuals_stay_tiny(linkage_exact, offset_m):
    """Cancellation guard: exact joints give ~0 even when the body is 1 km from the origin."""
    cap = linkage_exact
    res = pair_residual_matrix(pair_statistics(cap.R_w_s, cap.p_w_s + offset_m))
    for child, parent in cap.skeleton.parent_of.items():
        # sqrt(eps * |b|^2) with |b| ~ 0.5 m is ~1e-8 m: the floor of the normal equations
        assert res[cap.names.index(parent), cap.names.index(child)] < 3e-8
    joints = {frozenset((cap.names.index(c), cap.names.index(p))) for c, p in cap.skeleton.parent_of.items()}
    others = [res[a, b] for a in range(6) for b in range(a + 1, 6) if frozenset((a, b)) not in joints]
    assert min(others) > 0.01


def test_missing_poses_use_common_frames(linkage_noisy):
    cap = linkage_noisy
    rng = np.random.default_rng(3)
    valid = rng.random(cap.p_w_s.shape[:2]) > 0.1
    p = cap.p_w_s.copy()
    p[~valid] = np.nan  # missing poses also arrive as NaN
    fast = pair_residual_matrix(pair_statistics(cap.R_w_s, p, valid=valid))
    assert_allclose(fast, svd_residual_matrix(cap, valid), atol=1e-10, rtol=0)
    stats = pair_statistics(cap.R_w_s, p)
    assert stats.count[0, 1] == np.sum(valid[:, 0] & valid[:, 1])


def test_chunking_does_not_change_the_result(linkage_noisy, tmp_path):
    cap = linkage_noisy
    whole = pair_statistics(cap.R_w_s, cap.p_w_s, chunk_frames=100_000)
    small = pair_statistics(cap.R_w_s, cap.p_w_s, chunk_frames=7)
    for name in ("gram", "cross", "self_cross", "sq_dist"):
        assert_allclose(getattr(small, name), getattr(whole, name), rtol=1e-10, atol=1e-9)
    path = tmp_path / "poses.h5"
    with h5py.File(path, "w") as fh:
        fh["R"] = cap.R_w_s
        fh["p"] = cap.p_w_s
    with h5py.File(path, "r") as fh:
        from_file = pair_statistics(fh["R"], fh["p"], chunk_frames=500)
    assert_allclose(from_file.gram, whole.gram, rtol=1e-10, atol=1e-9)


def test_frame_residuals_match_the_svd(linkage_noisy):
    cap = linkage_noisy
    fit = fit_joint(*pair_arrays(cap, "chest", "head"))
    p, c = cap.names.index("chest"), cap.names.index("head")
    rms, per_frame = frame_residuals(
        cap.R_w_s, cap.p_w_s, [p], [c], fit.joint_in_parent[None], fit.joint_in_child[None], chunk_frames=333
    )
    assert_allclose(per_frame[:, 0], fit.frame_residual, atol=1e-13)
    assert rms[0] == pytest.approx(fit.rms_residual, rel=1e-12)


def test_input_not_modified(linkage_noisy):
    p = linkage_noisy.p_w_s.copy()
    p[3, 2] = np.nan
    before = p.copy()
    pair_statistics(linkage_noisy.R_w_s, p)
    assert np.array_equal(p, before, equal_nan=True)


def test_shapes_checked():
    with pytest.raises(CalibrationInputError, match=r"Expected p_w_s to have shape \(4, 2, 3\)"):
        pair_statistics(np.zeros((4, 2, 3, 3)), np.zeros((4, 3, 3)))
