"""The batch calibration's one pass over the poses (issue 19): the misfit tree's noise and the
jackknife's block sums read off the pair statistics, and the rms residual from the normal
equations where their rounding allows, agree with the passes over the data they replace."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import calibrate, frame_residuals, pair_noise_variance, pair_statistics, solve_pairs
from calibration.diagnostics import block_jackknife, jackknife_block_sums, jackknife_standard_error
from calibration.pairs import rms_needs_data
from simbench.sim.synthetic import random_tree, simulate_motion


def _capture(noise_m: float, *, n: int = 7, n_frames: int = 2500, seed: int = 4):
    skeleton = random_tree(n, np.random.default_rng(seed))
    cap = simulate_motion(
        skeleton,
        n_frames=n_frames,
        rate_hz=120.0,
        rng=np.random.default_rng(seed + 1),
        position_noise_m=noise_m,
    )
    return skeleton, cap


def _gappy(cap, offset_m: float, seed: int = 0):
    """The capture far from the origin, with 3 % of the poses missing and one NaN rotation."""
    rng = np.random.default_rng(seed)
    valid = rng.random(cap.p_w_s.shape[:2]) > 0.03
    R = cap.R_w_s.copy()
    R[10, 1, 0, 0] = np.nan
    return R, cap.p_w_s + offset_m, valid


def _tree_arrays(skeleton):
    par = np.array([skeleton.names.index(skeleton.parent_of[c]) for c in skeleton.parent_of])
    chi = np.array([skeleton.names.index(c) for c in skeleton.parent_of])
    return par, chi


@pytest.mark.parametrize("gaps", ["many", "one", "none"])
@pytest.mark.parametrize("chunk_frames", [1024, 97, 2])
def test_noise_from_third_difference_sums_matches_the_pass_over_the_data(chunk_frames, gaps):
    _, cap = _capture(0.004)
    R, p, valid = _gappy(cap, 300.0)
    if gaps != "many":  # chunks laid out, the third differences joined across them (but one)
        R, valid = cap.R_w_s.copy(), None
        if gaps == "one":
            R[1000, 3] = np.nan
    stats = pair_statistics(R, p, valid=valid, chunk_frames=chunk_frames, third_differences=True)
    n = len(cap.names)
    i, j = np.triu_indices(n, k=1)
    sol = solve_pairs(stats, i, j)
    fast = stats.third_differences.noise_variance(i, j, sol.joint_in_parent, sol.joint_in_child)
    slow = pair_noise_variance(R, p, i, j, sol.joint_in_parent, sol.joint_in_child, valid=valid)
    assert_allclose(fast, slow, rtol=1e-9, atol=0)
    assert fast.min() > 0.0


@pytest.mark.parametrize("chunk_frames", [1024, 61])
def test_jackknife_from_the_statistics_matches_its_own_pass(chunk_frames):
    skeleton, cap = _capture(0.004, n_frames=1999)
    R, p, valid = _gappy(cap, 50.0)
    par, chi = _tree_arrays(skeleton)
    rank = np.full(par.size, 6)
    stats = pair_statistics(R, p, valid=valid, chunk_frames=chunk_frames, jackknife_blocks=20)
    fast = jackknife_standard_error(jackknife_block_sums(stats, par, chi), rank)
    slow = block_jackknife(R, p, par, chi, rank, valid=valid)
    assert_allclose(fast, slow, rtol=1e-9, atol=0)


def test_statistics_with_jackknife_blocks_keep_the_hinge_blocks():
    _, cap = _capture(0.004, n_frames=1999)
    R, p, valid = _gappy(cap, 0.0)
    plain = pair_statistics(R, p, valid=valid)
    both = pair_statistics(R, p, valid=valid, jackknife_blocks=20, third_differences=True)
    for name in ("gram", "cross", "self_cross", "sq_dist", "block_gram", "block_cross", "block_self_cross"):
        assert_allclose(getattr(both, name), getattr(plain, name), rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(both.block_count, plain.block_count)
    assert both.jackknife_count.sum(axis=0).tolist() == plain.count.tolist()


@pytest.mark.parametrize(
    ("noise_m", "offset_m"), [(0.004, 0.0), (0.004, 1e4), (0.0, 0.0), (0.0, 1e3), (1e-4, 1e3)]
)
def test_rms_without_frame_residuals_is_the_exact_one_to_a_nanometre(noise_m, offset_m):
    """Noisy data take the normal equations' rms, noise-free data (at their rounding floor) the
    exact pass; both agree with the exact per-frame pass to 1e-9 m, far from the origin too."""
    skeleton, cap = _capture(noise_m)
    R, p, valid = _gappy(cap, offset_m)
    exact = calibrate(R, p, cap.names, valid=valid, parent_of=skeleton.parent_of)
    quick = calibrate(R, p, cap.names, valid=valid, parent_of=skeleton.parent_of, keep_frame_residuals=False)
    for a, b in zip(exact.joints, quick.joints, strict=True):
        assert b.fit.frame_residual is None
        assert b.fit.rms_residual == pytest.approx(a.fit.rms_residual, rel=0, abs=1e-9)
        assert_allclose(b.fit.joint_in_parent, a.fit.joint_in_parent, rtol=0, atol=1e-9)
    # the noisy joints are certified from the normal equations alone, the noise-free ones are not
    stats = pair_statistics(R, p, valid=valid)
    par, chi = _tree_arrays(skeleton)
    needs = rms_needs_data(stats, solve_pairs(stats, par, chi))
    assert needs.all() if noise_m == 0.0 else not needs.any()


def test_default_tree_and_verdicts_do_not_depend_on_the_chunks():
    _, cap = _capture(0.004, n=9, n_frames=3000)
    R, p, valid = _gappy(cap, 100.0)
    whole = calibrate(R, p, cap.names, valid=valid, chunk_frames=5000)
    for chunk in (1000, 37):
        cut = calibrate(R, p, cap.names, valid=valid, chunk_frames=chunk)
        assert cut.parent_of == whole.parent_of and cut.warnings == whole.warnings
        rms, _ = frame_residuals(R, p, *_tree_arrays_of(cut), valid=valid)
        assert_allclose([j.fit.rms_residual for j in cut.joints], rms, rtol=0, atol=1e-12)


def _tree_arrays_of(cal):
    names = list(cal.names)
    par = np.array([names.index(j.parent) for j in cal.joints])
    chi = np.array([names.index(j.child) for j in cal.joints])
    lp = np.array([j.fit.joint_in_parent for j in cal.joints])
    lc = np.array([j.fit.joint_in_child for j in cal.joints])
    return par, chi, lp, lc


def test_large_out_of_core_input_keeps_no_frame_residuals_by_default(tmp_path, monkeypatch):
    """The default on an h5py dataset: per-frame residuals up to FRAME_RESIDUAL_BYTES, beyond it
    none (memory that does not grow with the frames), with the same joints and rms."""
    import h5py

    from calibration import pipeline

    _, cap = _capture(0.004, n=5, n_frames=1500)
    path = tmp_path / "poses.h5"
    with h5py.File(path, "w") as fh:
        fh["R"], fh["p"] = cap.R_w_s, cap.p_w_s
    memory = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    with h5py.File(path, "r") as fh:
        small = calibrate(fh["R"], fh["p"], cap.names)
        monkeypatch.setattr(pipeline, "FRAME_RESIDUAL_BYTES", 8 * 1500 * 4 - 1)
        large = calibrate(fh["R"], fh["p"], cap.names)
        in_memory_still = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    assert all(j.fit.frame_residual is not None for j in small.joints + in_memory_still.joints)
    assert all(j.fit.frame_residual is None for j in large.joints)
    assert large.parent_of == memory.parent_of
    assert large.warnings == memory.warnings
    for a, b in zip(memory.joints, large.joints, strict=True):
        assert_allclose(b.fit.joint_in_parent, a.fit.joint_in_parent, rtol=0, atol=1e-12)
        assert b.fit.rms_residual == pytest.approx(a.fit.rms_residual, rel=0, abs=1e-9)
