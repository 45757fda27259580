"""Frames whose pose noise drowns the rest: left out of the fits.

A tracker is not equally noisy everywhere. A magnetic tracker's position noise grows as about the
fourth power of the distance to its transmitter (docs/conventions.md): within its range it is a millimetre,
two metres out centimetres, a walk of five metres away from it metres. A least-squares joint fit
gives every frame the same say, so the far frames, even a minority of them, carry the fit (a
humanoid walking away from a Polhemus source: joint residuals of 4.6 m, every joint of the
hierarchy wrong), and a robust fit cannot help once they are the majority.

**The noise of a frame, from the poses alone.** The third difference of a position series keeps
white noise (variance ``20 s^2`` per axis, lag-one covariance ``-15 s^2``) and nearly removes
the motion, which is smooth at the capture rate and whose third differences are nearly equal from
frame to frame (lag-one covariance about equal to their variance). So over a window of
:data:`WINDOW_FRAMES` frames, ``(mean d^2 - mean d_f . d_f+1) / 35`` estimates the noise variance
``s^2`` (summed over the three axes) about each frame, whatever the motion does.

**Which frames go.** For unweighted least squares the error variance of a fit from ``n`` frames of
noise variances ``s_1^2 <= ... <= s_n^2`` goes as ``sum s_i^2 / n^2``: a frame helps the fit when
its variance is below about twice the mean of the frames already in, and harms it beyond. Each
sensor keeps the ``n`` quietest of its frames that minimise that sum (the rest are left out as if
missing), but only frames whose noise is beyond :data:`QUIET_RATIO` times its quietest tenth (the
window's estimate of a constant noise varies by far less: no frame of a steady tracker goes) and
above :data:`NOISE_FLOOR` of the body's size (noise-free data, whose third differences are the
motion's own, loses nothing). The candidates' third differences, pooled, must also correlate as
white noise does from one frame to the next (:data:`WHITE_RATIO`): heel strikes and other
impacts of an exact walk raise the estimate without being noise. And frames go only where that
makes the expected error at least :data:`MIN_GAIN` times smaller.

**Off by default.** The sum above gives every frame the same leverage; a joint fit does not. The
farthest poses of an exercise in front of a transmitter are its noisiest and also its most
informative, and a field distortion is not white noise: turned on for the validation, the
paper-table linkage's worst length error went from 0.91 to 1.17 cm. On a walk that leaves the
tracker's range it pays: the humanoid's 30 s walk with the Flock of Birds, 16.6 -> 4.2 mm rms
centre error; a gait 5 m from a Polhemus source, 12 -> 2 wrong joints of 15.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from calibration.pair_sums import third_difference
from calibration.poses import CHUNK_FRAMES

#: Frames over which a frame's noise is estimated (0.27 s at 120 Hz).
WINDOW_FRAMES = 32

#: Least share of a window's third differences that must exist (four consecutive valid poses
#: each) for its estimate: a pose missing every seventh frame leaves 3 of 7.
MIN_SHARE = 0.25

#: A frame may go only when its noise (standard deviation) is beyond this many times its
#: sensor's quietest tenth (the window's estimate of a steady noise spreads by about 25 %).
QUIET_RATIO = 3.0

#: The noisiest frames are left out only where that makes the expected error of an unweighted fit
#: at least this many times smaller: below it, which frames carry the fit (the farthest poses of
#: an exercise are its noisiest and its most informative) matters as much as their noise.
MIN_GAIN = 2.0

#: Noise below this fraction of the body's size (the sensors' rms distance from their centroid)
#: harms no joint fit (skin and joint play leave millimetres): such frames always stay (0.1 mm on
#: a body of a metre; noise-free data, whose third differences are the motion's own, loses none).
NOISE_FLOOR = 1e-4

#: The candidates' third differences, pooled, must have a lag-one correlation below this: white
#: noise has -0.75 (``-15 / 20``), motion near +1, a velocity's kink (an impact) -0.5.
WHITE_RATIO = -0.6

#: Fewest frames read at a time (the work per frame is small: short chunks would cost more in
#: their overhead than in it).
MIN_CHUNK_FRAMES = 32768

#: The variance of the third difference of white noise less its lag-one covariance, over the
#: noise's variance: ``(1 + 9 + 9 + 1) - (-3 - 9 - 3)``.
GAIN = 35.0


@dataclass(frozen=True)
class NoisyFrames:
    """The frames left out for their noise.

    Attributes:
        mask: ``(F, N)`` True where a sensor's pose is left out for its noise (it was valid).
        quiet_m: ``(N,)`` each sensor's noise in its quietest tenth of frames, RMS per axis, in the
            positions' unit (NaN for a sensor with too few frames).
        kept_max_m: ``(N,)`` the largest noise among the frames it keeps, same unit.
        dropped_median_m: ``(N,)`` the median noise of the frames it leaves out (NaN if none).
        gain: ``(N,)`` how many times smaller the expected error of an unweighted fit is without
            the noisiest frames than with them (1 when none would go); frames are left out only
            where it reaches :data:`MIN_GAIN`.
    """

    mask: np.ndarray
    quiet_m: np.ndarray
    kept_max_m: np.ndarray
    dropped_median_m: np.ndarray
    gain: np.ndarray

    def warnings(self, names: tuple[str, ...]) -> list[str]:
        """One line per sensor that leaves frames out."""
        out = []
        n_frames = self.mask.shape[0]
        for k, name in enumerate(names):
            count = int(self.mask[:, k].sum())
            if count:
                out.append(
                    f"sensor {name}: {count} of {n_frames} frames left out for their position noise "
                    f"(median {_mm(self.dropped_median_m[k])} against {_mm(self.quiet_m[k])} in its "
                    f"quietest tenth; kept up to {_mm(self.kept_max_m[k])}; they made the fit's "
                    f"expected error {_larger(self.gain[k])}): noise that varies this much is a "
                    "tracker beyond its range (a magnetic tracker far from its transmitter) or a "
                    "disturbed field"
                )
        return out


def _larger(x: float) -> str:
    return "infinitely larger, the other frames being exact" if np.isinf(x) else f"{x:.3g} times larger"


def _mm(x: float) -> str:
    return "?" if not np.isfinite(x) else f"{x * 1000:.3g} mm"


def frame_noise(p: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each frame's local noise variance ``(F, N)`` (summed over the axes, positions' unit
    squared) from positions ``p`` ``(F, N, 3)`` valid where ``ok`` ``(F, N)`` (module docstring),
    NaN where the window holds too few third differences; and about each frame the window's mean
    squared third difference and mean lag-one product ``(F, N)`` (their ratio tells white noise,
    -0.75, from motion)."""
    f, n = ok.shape
    out = np.full((f, n), np.nan)
    if f < 5:
        return out, np.zeros((f, n)), np.zeros((f, n))
    d = third_difference(np.where(ok[..., None], p, 0.0), np.empty((f - 3, n, 3)))
    ok4 = ok[3:] & ok[2:-1] & ok[1:-2] & ok[:-3]
    d[~ok4] = 0.0
    sq = np.einsum("fni,fni->fn", d, d)
    lag = np.zeros_like(sq)
    lag[1:] = np.einsum("fni,fni->fn", d[1:], d[:-1])
    pair = np.zeros(sq.shape)
    pair[1:] = ok4[1:] & ok4[:-1]
    count = uniform_filter1d(ok4.astype(float), WINDOW_FRAMES, axis=0, mode="constant")
    count_pair = uniform_filter1d(pair, WINDOW_FRAMES, axis=0, mode="constant")
    mean_sq = uniform_filter1d(sq, WINDOW_FRAMES, axis=0, mode="constant")
    mean_lag = uniform_filter1d(lag, WINDOW_FRAMES, axis=0, mode="constant")
    enough = (count >= MIN_SHARE) & (count_pair > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        s2 = (mean_sq / count - mean_lag / count_pair) / GAIN
    s2 = np.where(enough, np.maximum(s2, 0.0), np.nan)
    out[1:-2] = s2  # the third difference at f spans frames f..f+3: centre it
    out[0], out[-2:] = out[1], out[-3]  # the first and last frames: their neighbours' windows
    out[~ok] = np.nan
    v, c = np.zeros((f, n)), np.zeros((f, n))
    with np.errstate(invalid="ignore", divide="ignore"):
        v[1:-2] = np.where(enough, mean_sq / count, 0.0)
        c[1:-2] = np.where(enough, mean_lag / count_pair, 0.0)
    return out, v, c


def noisy_frames(p_w_s: Any, valid: np.ndarray, chunk_frames: int = CHUNK_FRAMES) -> NoisyFrames:
    """The frames each sensor leaves out for their noise (module docstring).

    Args:
        p_w_s: ``(F, N, 3)`` positions (anything sliceable along frames), any length unit.
        valid: ``(F, N)`` bool, the usable poses.
        chunk_frames: frames read at a time (with :data:`WINDOW_FRAMES` of overlap).

    Returns:
        The frames left out and the noise levels behind the choice.
    """
    valid = np.asarray(valid, dtype=bool)
    f, n = valid.shape
    s2 = np.full((f, n), np.nan)
    sq, lag = np.zeros((f, n)), np.zeros((f, n))
    size2 = []
    pad = WINDOW_FRAMES + 4
    step = max(int(chunk_frames), MIN_CHUNK_FRAMES)
    for start in range(0, f, step):
        lo, hi = max(0, start - pad), min(f, start + step + pad)
        p = np.asarray(p_w_s[lo:hi], dtype=float)
        ok = valid[lo:hi] & np.isfinite(p).all(axis=-1)
        here = slice(start - lo, start - lo + min(step, f - start))
        s2_, sq_, lag_ = frame_noise(p, ok)
        s2[start : start + min(step, f - start)] = s2_[here]
        sq[start : start + min(step, f - start)] = sq_[here]
        lag[start : start + min(step, f - start)] = lag_[here]
        okc = ok[here]
        pc = np.where(okc[..., None], p[here], 0.0)
        count = np.maximum(okc.sum(axis=1), 1)
        centre = pc.sum(axis=1) / count[:, None]
        dev = np.where(okc, np.sum((pc - centre[:, None]) ** 2, axis=-1), 0.0)
        size2.append(np.where(okc.sum(axis=1) > 1, dev.sum(axis=1) / count, np.nan))
    sizes = np.concatenate(size2) if size2 else np.array([])
    body = float(np.sqrt(np.nanmedian(sizes))) if np.isfinite(sizes).any() else 0.0
    floor2 = (NOISE_FLOOR * body) ** 2 * 3.0
    mask = np.zeros((f, n), dtype=bool)
    quiet = np.full(n, np.nan)
    kept_max = np.full(n, np.nan)
    dropped = np.full(n, np.nan)
    gain = np.ones(n)
    for k in range(n):
        x = s2[:, k]
        have = np.flatnonzero(np.isfinite(x))
        if have.size < 10 * WINDOW_FRAMES:
            continue
        xs = x[have]
        q = float(np.quantile(xs, 0.1))
        quiet[k] = np.sqrt(q / 3.0)
        candidate = (xs > QUIET_RATIO**2 * q) & (xs > floor2)
        cand = have[candidate]
        # the candidates' excess must be white noise, not motion
        if cand.size and not np.sum(lag[cand, k]) < WHITE_RATIO * np.sum(sq[cand, k]):
            cand = cand[:0]
        n0, s0 = int(have.size - cand.size), float(np.sum(xs[~candidate])) if cand.size else float(np.sum(xs))
        order = cand[np.argsort(x[cand], kind="stable")]
        cum = s0 + np.concatenate([[0.0], np.cumsum(x[order])])  # the sums keeping 0..m candidates
        count = n0 + np.arange(order.size + 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            expected = np.where(count > 0, cum / np.maximum(count, 1) ** 2, np.inf)
        keep = int(np.argmin(expected))
        if expected[keep] > 0:
            gain[k] = float(np.sqrt(expected[-1] / expected[keep]))
        elif expected[-1] > 0:  # exact poses but for a few noisy frames: leaving them out is exact
            gain[k] = np.inf
        if keep < order.size and gain[k] >= MIN_GAIN:
            mask[order[keep:], k] = True
            dropped[k] = float(np.sqrt(np.median(x[order[keep:]]) / 3.0))
            kept = np.concatenate([xs[~candidate], x[order[:keep]]])
        else:
            kept = xs
        kept_max[k] = float(np.sqrt(np.max(kept) / 3.0))
    return NoisyFrames(mask=mask, quiet_m=quiet, kept_max_m=kept_max, dropped_median_m=dropped, gain=gain)
