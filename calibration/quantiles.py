"""Quantiles of the chi-square, Student's t, F and normal distributions.

The functions :mod:`scipy.stats`' ``ppf`` methods evaluate for these distributions
(``scipy.special``), called directly: the values are the same to the bit, and importing the
calibration does not pay for :mod:`scipy.stats` (about 0.6 s, half of ``import calibration``,
on every start of the command line). Arguments are those of a valid distribution: probabilities
in ``(0, 1)``, positive degrees of freedom; they broadcast. And the normal distribution's
robust standard deviation of a sample (:func:`mad_std`).
"""

from __future__ import annotations

import numpy as np
from scipy import special

#: ``1 / Phi^-1(3/4)``: a normal variable's standard deviation over its median absolute deviation.
MAD_TO_SIGMA = 1.4826


def mad_std(x: np.ndarray) -> float:
    """Robust standard deviation of a sample ``(n,)``: :data:`MAD_TO_SIGMA` times its median
    absolute deviation about its median (NaN for an empty sample)."""
    x = np.asarray(x, dtype=float)
    return MAD_TO_SIGMA * float(np.median(np.abs(x - np.median(x))))


def chi2_ppf(q: float | np.ndarray, df: float | np.ndarray) -> np.ndarray:
    """``scipy.stats.chi2.ppf(q, df)``: the ``q`` quantile of chi-square with ``df`` degrees of freedom."""
    return 2.0 * special.gammaincinv(np.asarray(df, dtype=float) / 2.0, q)


def t_ppf(q: float | np.ndarray, df: float | np.ndarray) -> np.ndarray:
    """``scipy.stats.t.ppf(q, df)``: the ``q`` quantile of Student's t with ``df`` degrees of freedom."""
    return special.stdtrit(df, q)


def f_ppf(q: float | np.ndarray, dfn: float | np.ndarray, dfd: float | np.ndarray) -> np.ndarray:
    """``scipy.stats.f.ppf(q, dfn, dfd)``: the ``q`` quantile of F with ``(dfn, dfd)`` degrees of freedom."""
    return special.fdtri(dfn, dfd, q)


def norm_ppf(q: float | np.ndarray) -> np.ndarray:
    """``scipy.stats.norm.ppf(q)``: the ``q`` quantile of the standard normal distribution."""
    return special.ndtri(q)
