"""Detection of sensor slip from jumps in a joint's residual (O'Brien section 5).

When a sensor moves on the body, the joint centre it was fitted with is no longer fixed in its
frame: from that moment the joint residual carries a new constant offset *in the frame of the
sensor that moved* (``r[f] = R_w_s[f] @ delta`` for a shift ``delta``). The residual's norm is a
poor detector -- a fit over the whole recording splits the shift between before and after, so
the norm may not change at all -- but the residual vector expressed in the moved sensor's frame
jumps by the full ``|delta|``.

**Detector** (sliding window of ``w`` frames): the residual vector of the fitted joint is
expressed in the parent's and in the child's frame (``e = R_w_s^T r``); at every frame ``t`` the
mean of ``e`` over the ``w`` frames before ``t`` is compared with the mean over the ``w`` frames
from ``t`` on, ``D[t] = |mean_after - mean_before|`` (metres), in whichever sensor frame gives
the larger jump. The noise ``sigma`` of ``e`` per component is estimated robustly from its
first differences (``1.4826 * MAD / sqrt(2)``); a difference of two ``w``-frame means then has
standard deviation ``sigma * sqrt(2 / w)`` per component, and ``z[t] = D[t] / (sigma sqrt(2/w))``.
Frames with ``z > z_threshold`` *and* ``D > min_jump`` are candidates; candidate runs closer
than ``w`` frames are merged and each run gives one slip event, at its largest ``D``. The
recording is cut at the events; every piece whose mean residual offset differs from the first
piece's (the sensors as placed) by more than ``min_jump`` is reported as a slipped interval.

Frames where a pose is missing are left out of the window means.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from calibration.errors import CalibrationInputError
from calibration.joint import check_pair, joint_residual_vectors

#: Default z threshold: far in the tail of the chi distribution with 3 degrees of freedom.
Z_THRESHOLD = 8.0

#: Default smallest offset change reported as slip, metres (below a real sensor's shift).
MIN_JUMP = 0.01


@dataclass(frozen=True)
class SlipEvent:
    """A jump of a joint's residual offset.

    Attributes:
        frame: the first frame after the jump.
        jump: size of the change of the mean residual vector, metres.
        sensor_frame: ``"parent"`` or ``"child"``: the frame in which the jump is largest (the
            sensor that most likely moved).
        z: the jump over its noise standard deviation.
    """

    frame: int
    jump: float
    sensor_frame: str
    z: float


@dataclass(frozen=True)
class SlipReport:
    """Slip events of one joint and the intervals where its sensors sat elsewhere.

    Attributes:
        events: the detected jumps, in time order.
        intervals: ``[start, stop)`` frame ranges whose residual offset differs from the
            start of the recording's.
        jump: ``(frames,)`` ``D[t]`` of the module docstring, metres (NaN within ``w`` of the
            ends).
        noise: ``sigma``, metres.
        window: ``w``, frames.
    """

    events: tuple[SlipEvent, ...]
    intervals: tuple[tuple[int, int], ...]
    jump: np.ndarray
    noise: float
    window: int


def _window_means(e: np.ndarray, ok: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Means of ``e`` over the ``w`` valid-weighted frames before and from each frame."""
    n = e.shape[0]
    cs = np.zeros((n + 1, 3))
    cs[1:] = np.cumsum(np.where(ok[:, None], e, 0.0), axis=0)
    cn = np.zeros(n + 1)
    cn[1:] = np.cumsum(ok)
    before = np.full((n, 3), np.nan)
    after = np.full((n, 3), np.nan)
    t = np.arange(w, n - w + 1)
    nb = cn[t] - cn[t - w]
    na = cn[t + w] - cn[t]
    enough = (nb >= w / 2) & (na >= w / 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        before[t] = np.where(enough[:, None], (cs[t] - cs[t - w]) / nb[:, None], np.nan)
        after[t] = np.where(enough[:, None], (cs[t + w] - cs[t]) / na[:, None], np.nan)
    return before, after


def _robust_sigma(e: np.ndarray, ok: np.ndarray) -> float:
    both = ok[1:] & ok[:-1]
    d = (e[1:] - e[:-1])[both]
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d, axis=0))) / np.sqrt(2.0))


def detect_slip(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    *,
    window: int,
    z_threshold: float = Z_THRESHOLD,
    min_jump: float = MIN_JUMP,
) -> SlipReport:
    """Find the frames where a joint's residual offset jumps (a sensor moved on the body).

    Args:
        R_w_p, R_w_c: ``(frames, 3, 3)`` parent and child rotations, sensor to world.
        p_w_p, p_w_c: ``(frames, 3)`` parent and child positions in world, metres.
        joint_in_parent, joint_in_child: ``(3,)`` the fitted joint, metres.
        window: ``w`` of the module docstring, frames (at least 2, at most half the frames).
        z_threshold: see the module docstring.
        min_jump: see the module docstring, metres.
    """
    R_w_p, p_w_p, R_w_c, p_w_c = check_pair(R_w_p, p_w_p, R_w_c, p_w_c)
    n = R_w_p.shape[0]
    if not 2 <= window <= n // 2:
        raise CalibrationInputError(f"window must be between 2 and frames/2 = {n // 2}, got {window}")
    r = joint_residual_vectors(R_w_p, p_w_p, R_w_c, p_w_c, joint_in_parent, joint_in_child)
    ok = np.isfinite(r).all(axis=1)
    best = None
    for label, R in (("parent", R_w_p), ("child", R_w_c)):
        e = np.einsum("fji,fj->fi", np.where(ok[:, None, None], R, 0.0), np.where(ok[:, None], r, 0.0))
        before, after = _window_means(e, ok, window)
        d = np.linalg.norm(after - before, axis=1)
        peak = np.nanmax(d) if np.isfinite(d).any() else -np.inf
        if best is None or peak > best[0]:
            best = (peak, label, e, d)
    assert best is not None
    _, label, e, d = best
    sigma = _robust_sigma(e, ok)
    scale = sigma * np.sqrt(2.0 / window)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(scale > 0, d / scale, np.where(d > 0, np.inf, 0.0))
    cand = np.flatnonzero(np.nan_to_num(z) > z_threshold)
    cand = cand[d[cand] > min_jump]
    events: list[SlipEvent] = []
    if cand.size:
        breaks = np.flatnonzero(np.diff(cand) >= window) + 1
        for run in np.split(cand, breaks):
            k = int(run[np.argmax(d[run])])
            events.append(SlipEvent(frame=k, jump=float(d[k]), sensor_frame=label, z=float(z[k])))
    cuts = [0, *(ev.frame for ev in events), n]
    pieces = list(pairwise(cuts))
    first_ok = ok[: pieces[0][1]]
    ref = np.mean(e[: pieces[0][1]][first_ok], axis=0) if first_ok.any() else np.zeros(3)
    intervals = []
    for a, b in pieces[1:]:
        seg_ok = ok[a:b]
        if seg_ok.any() and np.linalg.norm(np.mean(e[a:b][seg_ok], axis=0) - ref) > min_jump:
            intervals.append((a, b))
    return SlipReport(events=tuple(events), intervals=tuple(intervals), jump=d, noise=sigma, window=window)
