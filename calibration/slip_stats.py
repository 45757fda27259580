"""The statistics behind slip detection: window means, a robust noise scale, a tail threshold.

Everything here is unit-free in the sense the detector needs: scaling the input series by any
factor scales :func:`window_difference` and :func:`robust_scale` by that factor and leaves
:func:`whitened_norm`, :func:`correlation_frames` and :func:`tail_threshold` unchanged.
"""

from __future__ import annotations

import numpy as np
from scipy.fft import next_fast_len

from calibration.quantiles import MAD_TO_SIGMA, chi2_ppf

#: :func:`correlation_times` first computes the lags up to ``samples / LAG_FRACTION``.
LAG_FRACTION = 8

#: Quantile of the statistic above which its tail is modelled (the exponential tail's origin).
TAIL_QUANTILE = 0.75

#: Confidence of the upper bound on the tail's scale used for the threshold (short recordings hold
#: few independent exceedances; the bound keeps the stated rate with this confidence).
TAIL_CONFIDENCE = 0.75


def window_sums(x: np.ndarray, w: int) -> np.ndarray:
    """``(k, samples - w + 1)`` sums of each row of ``x`` (``(k, samples)``) over the ``w`` samples
    from each sample ``t``.

    Each sum is a block's total less a prefix of it plus a prefix of the next block (blocks of
    ``w`` samples), so its rounding error is that of sums of ``w`` samples, not of a running sum
    over the whole series (whose differences lose the digits the series' magnitude takes: the
    window difference of terms of 1 m that cancel to micrometres, :mod:`calibration.slip`).
    """
    k, n = x.shape
    if n < w:
        return np.empty((k, 0))
    nb = -(-n // w)
    blocks = np.zeros((k, (nb + 1) * w))
    blocks[:, :n] = x
    blocks = blocks.reshape(k, nb + 1, w)
    inclusive = np.cumsum(blocks, axis=2)
    before = np.subtract(inclusive, blocks, out=blocks)  # the block's samples before each one
    out = inclusive[:, :-1, -1:] - before[:, :-1]
    out += before[:, 1:]
    return out.reshape(k, nb * w)[:, : n - w + 1]


def window_difference(e: np.ndarray, ok: np.ndarray, w: int) -> np.ndarray:
    """``(frames, k)`` mean of ``e`` over the ``w`` frames from ``t`` minus over the ``w`` before.

    Args:
        e: ``(frames, k)`` a series (any unit; ``k`` columns, 3 for a residual vector); rows
            where ``ok`` is false are ignored.
        ok: ``(frames,)`` valid rows.
        w: window, frames.

    Returns NaN within ``w`` of the ends and where fewer than ``w / 2`` valid rows fall in
    either window.
    """
    return window_difference_rows(np.asarray(e, dtype=float).T, ok, w).T.copy()


def window_difference_rows(
    x: np.ndarray, ok: np.ndarray, w: int, out: np.ndarray | None = None
) -> np.ndarray:
    """:func:`window_difference` of series laid out as rows: ``x`` ``(k, frames)`` to ``(k, frames)``
    (into ``out`` when given). The rows are taken one at a time (the window sums' scratch is one
    row's), the windows' counts of valid rows once."""
    k, n = x.shape
    if out is None:
        out = np.empty((k, n))
    out.fill(np.nan)
    if n < 2 * w:
        return out
    cn = np.zeros(n + 1, dtype=np.int64)
    cn[1:] = np.cumsum(ok)
    count = cn[w:] - cn[:-w]
    na, nb = count[w:], count[: n - 2 * w + 1]
    enough = (nb >= w / 2) & (na >= w / 2)
    every = bool(cn[-1] == n)
    rows = out[:, w : n - w + 1]
    for r in range(k):
        sums = window_sums(x[r : r + 1] if every else np.where(ok, x[r : r + 1], 0.0), w)[0]
        row = rows[r]
        if every:  # both windows hold w rows
            np.subtract(sums[w:], sums[: n - 2 * w + 1], out=row)
            row /= w
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            np.divide(sums[w:], na, out=row)
            row -= sums[: n - 2 * w + 1] / nb
    rows[:, ~enough] = np.nan
    return out


def robust_scale(d: np.ndarray, use: np.ndarray) -> np.ndarray:
    """``(3,)`` per-component robust standard deviation of ``d[use]`` (``1.4826 * MAD``).

    A component with no spread gets a floor of ``1e-12`` times the largest ``|d|`` (so that an
    exactly constant series yields zeros, not infinities); all zeros when ``d[use]`` is.
    """
    x = d[use].T.copy()  # (3, samples): each component's median over contiguous samples
    if x.shape[1] == 0:
        return np.zeros(3)
    top = float(max(x.max(), -x.min()))
    centre = np.median(x, axis=1, overwrite_input=True)  # reorders x's rows: only their sets matter
    x -= centre[:, None]
    np.abs(x, out=x)
    s = MAD_TO_SIGMA * np.median(x, axis=1, overwrite_input=True)
    return np.maximum(s, 1e-12 * top)


def whitened_norm(d: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """``(frames,)`` ``|d / scale|`` (components divided by their scale); 0 where ``scale`` is 0."""
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(scale > 0, d / np.where(scale > 0, scale, 1.0), 0.0)
    return np.linalg.norm(z, axis=1)


def correlation_frames(x: np.ndarray, use: np.ndarray | None = None) -> float:
    """Integrated autocorrelation time of ``x`` (``(samples,)``) over the samples ``use``, frames.

    ``1 + 2 sum_k rho_k`` up to the first negative ``rho_k`` (the initial-positive-sequence
    truncation), with ``rho_k`` from the pairs of used samples ``k`` apart (gaps are left out,
    not bridged); samples a distance ``tau`` apart count as about independent. At least 1.
    """
    x = np.asarray(x, dtype=float)
    return float(correlation_times(x[:, None], use)[0])


def correlation_times(x: np.ndarray, use: np.ndarray | None = None) -> np.ndarray:
    """``(k,)`` :func:`correlation_frames` of each column of ``x`` (``(samples, k)``), in one batch
    of FFTs (the pairs' counts transformed once when every column uses the same samples).

    The sum stops at the first lag that is not positive, which for a window difference comes
    within a few windows; the FFTs are first zero-padded only to the first length of factors 2,
    3 and 5 from ``samples + samples / 8`` (:data:`LAG_FRACTION`), which gives every lag up to the
    padding exactly (a circular correlation wraps only beyond it), and again to ``2 samples - 1``
    (every lag) for a column whose autocorrelation is still positive there.
    """
    x = np.asarray(x, dtype=float)
    n, k = x.shape
    m = np.isfinite(x)
    if use is not None:
        m &= np.asarray(use, dtype=bool)[:, None]
    out = np.ones(k)
    count = m.sum(axis=0)
    cols = np.flatnonzero(count >= 3)
    if cols.size == 0:
        return out
    m = np.ascontiguousarray(m[:, cols].T)  # (columns, samples): each FFT over contiguous samples
    xs = np.where(m, x[:, cols].T, 0.0)
    xc = np.where(m, xs - (xs.sum(axis=1) / count[cols])[:, None], 0.0)
    same = bool((m == m[:1]).all())
    full = next_fast_len(2 * n - 1, real=True)
    for size in dict.fromkeys((min(next_fast_len(n + max(n // LAG_FRACTION, 1), real=True), full), full)):
        lags = min(n, size - n + 1)  # lags 0 .. size - n are exact
        num = np.empty((cols.size, lags))
        for c in range(cols.size):  # a column at a time: the transforms' scratch stays small
            fx = np.fft.rfft(xc[c], size)
            num[c] = np.fft.irfft(fx * np.conj(fx), size)[:lags]
        # the sums stop at the first lag whose covariance is not positive: the pairs' counts are
        # needed only up to there, and are counted from the runs of used samples when few
        stop = ~(num[:, 1:] > 0)
        used = num[:, 0] > 0
        need = (
            int((np.argmax(stop, axis=1)[used] + 2).max(initial=1)) if stop.any(axis=1)[used].all() else lags
        )
        pairs = _pair_counts(m[0], need) if same else None
        if pairs is None:
            fm = np.fft.rfft((m[:1] if same else m).astype(float), size)
            pairs = np.round(np.fft.irfft(fm * np.conj(fm), size)[:, :need])
        pairs = np.broadcast_to(pairs, (num.shape[0], need))
        with np.errstate(invalid="ignore", divide="ignore"):
            cov = np.where(pairs > 0, num[:, :need] / np.maximum(pairs, 1.0), np.nan)
        if lags == n or bool((~(cov[:, 1:] > 0)).any(axis=1)[used].all()):
            break
    for c, col in enumerate(cols):
        if num[c, 0] > 0:
            out[col] = initial_positive_time(cov[c] / cov[c, 0])
    return out


def _pair_counts(m: np.ndarray, lags: int, most_runs: int = 4) -> np.ndarray | None:
    """``(lags,)`` the number of samples ``t`` with ``m[t]`` and ``m[t + k]`` at each lag ``k``,
    counted from the runs of ``m`` (``(samples,)`` bool); ``None`` when it has more than
    ``most_runs`` runs (then a transform is faster)."""
    edges = np.flatnonzero(np.diff(m.astype(np.int8), prepend=0, append=0))
    starts, stops = edges[::2], edges[1::2]
    if starts.size > most_runs:
        return None
    k = np.arange(lags)
    out = np.zeros(lags, dtype=np.int64)
    for a, b in zip(starts, stops, strict=True):
        for c, d in zip(starts, stops, strict=True):  # t in [a, b) and t + k in [c, d)
            out += np.maximum(0, np.minimum(b, d - k) - np.maximum(a, c - k))
    return out.astype(float)


def initial_positive_time(rho: np.ndarray) -> float:
    """``1 + 2 sum_k rho_k`` of an autocorrelation ``rho`` (``(lags,)``, ``rho[0] = 1``) up to its
    first lag that is not positive (NaN counts as not positive); at least 1."""
    stop = np.flatnonzero(~(rho > 0))
    k = int(stop[0]) if stop.size else rho.size
    return max(1.0, float(1.0 + 2.0 * rho[1:k].sum()))


def tail_threshold(
    z: np.ndarray,
    tests_per_hour: float,
    false_alarms_per_hour: float,
    correlation: float = 1.0,
    confidence: float = TAIL_CONFIDENCE,
) -> float:
    """The level of ``z`` exceeded ``false_alarms_per_hour`` times an hour under an exponential tail.

    The tail above ``u``, the :data:`TAIL_QUANTILE` quantile of ``z``, is modelled as
    exponential (the generalized Pareto tail with shape 0, the extreme-value law of the Gumbel
    domain, which holds Gaussian, chi and exponential-like statistics), with the maximum
    likelihood scale ``beta = mean(z - u | z > u)``: ``P(z > u + x) = (1 - q) exp(-x / beta)``.
    The exceedances hold about ``m = count / correlation`` independent values, so ``2 m beta /
    beta_true`` is chi-square with ``2 m`` degrees of freedom; ``beta`` is replaced by its upper
    confidence bound ``2 m beta / chi2_{2m}^{-1}(1 - confidence)`` (a recording of a few seconds
    gets a high threshold rather than a confident false alarm).
    With ``tests_per_hour`` effectively independent tests, the level with the expected
    ``false_alarms_per_hour`` exceedances is ``u + beta ln((1 - q) tests_per_hour / rate)``.

    Args:
        z: ``(samples,)`` the statistic under no change (NaN ignored).
        tests_per_hour: effectively independent values of ``z`` per hour.
        false_alarms_per_hour: the rate, > 0.
        correlation: the correlation time of ``z``, samples (at least 1).
        confidence: of the upper bound on ``beta`` (0.5: about the point estimate).
    """
    z = z[np.isfinite(z)]
    if z.size < 4:
        return float("inf")
    u = float(np.quantile(z, TAIL_QUANTILE))
    above = z[z > u] - u
    beta = float(above.mean()) if above.size else 0.0
    m = max(above.size / max(correlation, 1.0), 0.5)
    beta *= 2.0 * m / float(chi2_ppf(1.0 - confidence, 2.0 * m))
    expected = (1.0 - TAIL_QUANTILE) * tests_per_hour / false_alarms_per_hour
    return u + beta * max(0.0, float(np.log(expected)))


def change_point(e: np.ndarray, ok: np.ndarray, lo: int, hi: int) -> int:
    """The least-squares single change of mean of ``e[lo:hi]`` (``(frames, 3)``): its first frame.

    Minimises the sum of squared deviations from a two-piece constant fit, i.e. maximises
    ``j (m - j) / m |mean(e[:j]) - mean(e[j:])|^2`` over splits ``j`` of the ``m`` valid rows.
    """
    idx = np.arange(lo, hi)[ok[lo:hi]]
    m = idx.size
    if m < 2:
        return (lo + hi) // 2
    x = e[idx]
    cs = np.cumsum(x, axis=0)
    j = np.arange(1, m)
    left = cs[:-1] / j[:, None]
    right = (cs[-1] - cs[:-1]) / (m - j)[:, None]
    gain = j * (m - j) / m * np.sum((left - right) ** 2, axis=1)
    return int(idx[int(np.argmax(gain)) + 1])
