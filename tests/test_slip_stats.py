"""The statistics behind slip detection, against analytic cases and plain reference loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration.slip_stats import (
    _pair_counts,
    change_point,
    correlation_frames,
    correlation_times,
    robust_scale,
    tail_threshold,
    whitened_norm,
    window_difference,
    window_difference_rows,
    window_sums,
)


def test_window_difference_matches_a_loop():
    rng = np.random.default_rng(1)
    e = rng.normal(size=(50, 3))
    ok = rng.random(50) > 0.1
    w = 6
    got = window_difference(e, ok, w)
    for t in range(50):
        if t < w or t > 50 - w:
            assert np.isnan(got[t]).all()
            continue
        b, a = ok[t - w : t], ok[t : t + w]
        if b.sum() < w / 2 or a.sum() < w / 2:
            assert np.isnan(got[t]).all()
            continue
        want = e[t : t + w][a].mean(axis=0) - e[t - w : t][b].mean(axis=0)
        np.testing.assert_allclose(got[t], want, rtol=0, atol=1e-12)  # same sums, rounding only


def test_robust_scale_of_gaussian_and_of_a_constant():
    rng = np.random.default_rng(2)
    d = rng.normal(scale=[1.0, 2.0, 3.0], size=(20000, 3))
    # MAD scale of 20000 normal samples: relative standard error about 1 %
    np.testing.assert_allclose(robust_scale(d, np.ones(20000, bool)), [1.0, 2.0, 3.0], rtol=0.04)
    flat = np.zeros((10, 3))
    s = robust_scale(flat, np.ones(10, bool))
    assert (s == 0).all() and (whitened_norm(flat, s) == 0).all()


def test_correlation_time_of_white_noise_and_ar1():
    rng = np.random.default_rng(3)
    assert correlation_frames(rng.normal(size=20000)) == pytest.approx(1.0, abs=0.1)
    phi = 0.8
    x = np.zeros(50000)
    eps = rng.normal(size=x.size)
    for t in range(1, x.size):
        x[t] = phi * x[t - 1] + eps[t]
    # AR(1): integrated autocorrelation time (1 + phi) / (1 - phi) = 9; sampling error ~ 5 %
    assert correlation_frames(x) == pytest.approx((1 + phi) / (1 - phi), rel=0.15)
    # gaps are left out, not bridged: every other sample of white noise is still white
    use = np.arange(20000) % 2 == 0
    assert correlation_frames(rng.normal(size=20000), use) == pytest.approx(1.0, abs=0.1)


def test_tail_threshold_of_an_exponential():
    """z ~ Exp(1) has P(z > x) = exp(-x): N tests an hour, rate r: threshold ln(N / r)."""
    rng = np.random.default_rng(4)
    z = rng.exponential(size=200000)
    for n, r in ((1000.0, 1.0), (5000.0, 0.1)):
        # 50000 exceedances: the confidence bound and the scale estimate are within 1 %
        assert tail_threshold(z, n, r) == pytest.approx(np.log(n / r), rel=0.03)
    # few independent exceedances: the confidence bound raises the threshold
    assert tail_threshold(z[:40], 1000.0, 1.0) > tail_threshold(z[:40], 1000.0, 1.0, confidence=0.5)
    assert tail_threshold(z[:3], 1000.0, 1.0) == np.inf


def test_change_point_of_a_clean_step():
    e = np.zeros((100, 3))
    e[37:] = [1.0, -2.0, 0.5]
    ok = np.ones(100, bool)
    assert change_point(e, ok, 10, 90) == 37
    ok[35:40] = False
    assert change_point(e, ok, 10, 90) == 40  # the first valid frame after the step


def test_window_sums_match_a_loop_and_keep_the_digits_of_a_large_offset():
    rng = np.random.default_rng(4)
    w = 7
    x = 1e3 + rng.normal(scale=1e-6, size=(2, 5000))  # metres of offset, micrometres of signal
    got = window_sums(x, w)
    assert got.shape == (2, 5000 - w + 1)
    want = np.array([[math.fsum(row[t : t + w]) for t in range(5000 - w + 1)] for row in x])
    # rounding of sums of w values (~1e-13 here); a running sum's differences lose ~1e-9
    np.testing.assert_allclose(got, want, rtol=0, atol=32 * w * np.spacing(1e3))
    assert window_sums(x[:, :5], w).shape == (2, 0)


def test_window_difference_rows_is_the_transposed_window_difference():
    rng = np.random.default_rng(5)
    e = rng.normal(size=(300, 3))
    ok = rng.random(300) > 0.2
    rows = window_difference_rows(e.T.copy(), ok, 9)
    np.testing.assert_array_equal(np.isnan(rows), np.isnan(window_difference(e, ok, 9).T))
    np.testing.assert_allclose(rows, window_difference(e, ok, 9).T, rtol=0, atol=1e-14)


@pytest.mark.parametrize("case", ["same runs", "many gaps", "own masks", "long memory"])
def test_correlation_times_equal_each_column_on_its_own(case):
    rng = np.random.default_rng(6)
    n = 4000
    x = rng.normal(size=(n, 3))
    use = np.ones(n, dtype=bool)
    if case == "same runs":  # a few runs: the pairs are counted from them
        use[1000:1300] = use[2500:2600] = False
    if case == "many gaps":  # many runs: the pairs come from a transform
        use = rng.random(n) > 0.1
    phi = 0.999 if case == "long memory" else 0.9  # positive beyond n / 8 lags: the full-length pass
    for t in range(1, n):
        x[t] += phi * x[t - 1]
    if case == "own masks":  # a column's own gaps: its own pairs
        x[rng.random(n) < 0.05, 1] = np.nan
    got = correlation_times(x, use)
    want = [correlation_frames(x[:, k], use) for k in range(3)]
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert got.min() > 5.0  # AR(1) memory: tau = (1 + phi) / (1 - phi) = 19 at 0.9


def test_pair_counts_from_runs_are_the_products_of_the_mask():
    m = np.zeros(200, dtype=bool)
    m[3:50] = m[60:61] = m[120:190] = True
    got = _pair_counts(m, 200)
    want = [int(np.sum(m[: 200 - k] & m[k:])) for k in range(200)]
    np.testing.assert_array_equal(got, want)
    assert _pair_counts(np.arange(200) % 2 == 0, 10) is None  # 100 runs: a transform is faster
