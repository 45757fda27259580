"""An orientation estimate read the wrong way: quaternions in another convention than stated.

Orientations are exchanged as scalar-first quaternions of ``R_w_s`` (sensor to world) in an ENU
world (``docs/conventions.md``). An estimator written elsewhere may mean another of the common
conventions: scalar last ``(x, y, z, w)``, the inverse rotation (world to sensor), or a world
with z down (NED). Each reading of the same numbers predicts a different direction of gravity in
the sensor frame, ``R^T up``, and the accelerometer measures it (with the motion's own
acceleration on top, which every reading shares).

:func:`better_reading` compares the stated reading with each alternative on the accelerometer:
the angle between ``R^T up`` and the measured direction, its median over blocks of
:data:`BLOCK_S` (about independent: a hand's motion decorrelates within a second), and a
one-sided sign test over the blocks -- the alternative fits better in more blocks than chance
allows at :data:`FALSE_ALARM` (binomial, p = 1/2; tied blocks left out). An estimate right in the
stated convention fits better than any alternative wherever the sensor is tilted or turned away
from the world's axes; where it is not (a sensor level and facing north reads the same every
way), the blocks tie or split and nothing is said. Fewer than ``log2(1 / FALSE_ALARM)`` (10)
blocks cannot reach the rate: a recording shorter than 10 s is not judged.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
from scipy.special import betainc

from calibration.errors import CalibrationInputError
from calibration.rotations import quat_to_matrix

#: Seconds of samples per block of the sign test.
BLOCK_S = 1.0

#: False-alarm rate of the sign test, per sensor and alternative.
FALSE_ALARM = 1e-3

#: ENU to NED (x and y swapped, z negated): a rotation matrix (determinant +1).
_ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

#: The alternatives tested, by the words a warning uses.
ALTERNATIVES = (
    "scalar-last quaternions (x, y, z, w)",
    "the inverse rotation (world to sensor)",
    "a world with z down (NED)",
)


class Reading(NamedTuple):
    """A reading of an estimate that fits the accelerometer better than the stated one.

    Attributes:
        alternative: one of :data:`ALTERNATIVES`.
        stated_deg: median tilt error of the estimate as stated, deg.
        alternative_deg: median tilt error read as ``alternative``, deg.
        blocks_better: blocks in which the alternative fits better.
        blocks: blocks compared (ties left out).
        p_value: one-sided sign test.
    """

    alternative: str
    stated_deg: float
    alternative_deg: float
    blocks_better: int
    blocks: int
    p_value: float


def _gravity_directions(q: np.ndarray) -> dict[str, np.ndarray]:
    """``{reading: (F, 3)}`` the world's up in the sensor frame under the stated reading and each
    alternative of :data:`ALTERNATIVES`."""
    up = np.array([0.0, 0.0, 1.0])
    R = quat_to_matrix(q)
    R_last = quat_to_matrix(q[:, [3, 0, 1, 2]])
    return {
        "stated": np.einsum("fji,j->fi", R, up),
        ALTERNATIVES[0]: np.einsum("fji,j->fi", R_last, up),
        ALTERNATIVES[1]: np.einsum("fij,j->fi", R, up),
        ALTERNATIVES[2]: np.einsum("fji,j->fi", R, _ENU_TO_NED.T @ up),
    }


def better_reading(
    q_w_s: np.ndarray, acc: np.ndarray, rate_hz: float, valid: np.ndarray | None = None
) -> Reading | None:
    """The alternative reading of one sensor's estimate that fits its accelerometer significantly
    better than the stated one (module docstring), or ``None``.

    Args:
        q_w_s: ``(F, 4)`` the estimate as stated: scalar-first, sensor to world, ENU (NaN where
            not estimated).
        acc: ``(F, 3)`` the accelerometer, sensor frame, any unit (its direction is used).
        rate_hz: the sample rate, Hz.
        valid: optional ``(F,)`` bool, False where a sample is not to be used.

    Returns:
        Of the alternatives whose sign test is below :data:`FALSE_ALARM` and whose median error is
        below the stated reading's, the one with the smallest median error; or ``None``.
    """
    q = np.asarray(q_w_s, dtype=float)
    a = np.asarray(acc, dtype=float)
    if q.ndim != 2 or q.shape[1] != 4 or a.shape != (q.shape[0], 3):
        raise CalibrationInputError(f"Expected q_w_s (F, 4) and acc (F, 3), got {q.shape} and {a.shape}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise CalibrationInputError(f"Expected a positive rate_hz, got {rate_hz}")
    norm = np.linalg.norm(a, axis=1)
    use = np.isfinite(q).all(axis=1) & np.isfinite(norm) & (norm > 0)
    use &= np.linalg.norm(np.nan_to_num(q), axis=1) > 0
    if valid is not None:
        use &= np.asarray(valid, dtype=bool)
    per_block = max(1, round(BLOCK_S * rate_hz))
    n_blocks = use.size // per_block
    idx = np.flatnonzero(use[: n_blocks * per_block])
    if idx.size == 0:
        return None
    d = a[idx] / norm[idx, None]
    medians = {}
    for k, g in _gravity_directions(q[idx]).items():
        angle = np.full(n_blocks * per_block, np.nan)  # NaN where a sample is not used
        angle[idx] = np.degrees(np.arccos(np.clip(np.sum(g * d, axis=1), -1.0, 1.0)))
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a block without a used sample: NaN
            medians[k] = np.nanmedian(angle.reshape(n_blocks, per_block), axis=1)
    seen = np.isfinite(medians["stated"])
    medians = {k: v[seen] for k, v in medians.items()}
    stated = medians.pop("stated")
    best: Reading | None = None
    for k, alt in medians.items():
        diff = stated - alt
        better, worse = int(np.sum(diff > 0)), int(np.sum(diff < 0))
        n = better + worse
        if n == 0 or not np.median(alt) < np.median(stated):
            continue
        p = float(betainc(better, n - better + 1, 0.5)) if better > 0 else 1.0  # P(X >= better)
        if p < FALSE_ALARM and (best is None or np.median(alt) < best.alternative_deg):
            best = Reading(k, float(np.median(stated)), float(np.median(alt)), better, n, p)
    return best


__all__ = ["ALTERNATIVES", "BLOCK_S", "FALSE_ALARM", "Reading", "better_reading"]
