"""The statistics behind slip detection, against analytic cases and plain reference loops."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.slip_stats import (
    change_point,
    correlation_frames,
    robust_scale,
    tail_threshold,
    whitened_norm,
    window_difference,
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
