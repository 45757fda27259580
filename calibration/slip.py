"""Detection of sensor slip from jumps in a joint's residual (O'Brien section 5).

When a sensor moves on the body, the joint centre it was fitted with is no longer fixed in its
frame: from that moment the joint residual carries a new constant offset *in the frame of the
sensor that moved* (``r[f] = R_w_s[f] @ delta`` for a shift ``delta``). The residual's norm is a
poor detector -- a fit over the whole recording splits the shift between before and after -- but
the residual vector expressed in the moved sensor's frame jumps by the full ``|delta|``.

**Statistic.** The residual is expressed in the parent's and in the child's frame
(``e = R_w_s^T r``). At every frame ``t``, ``d[t]`` is the mean of ``e`` over the ``w`` frames
from ``t`` on minus the mean over the ``w`` frames before (:func:`~calibration.slip_stats.
window_difference`); ``D[t] = |d[t]|`` in the data's length unit.

**Noise model, from the same recording.** On real and skin-mounted data ``e`` is dominated by
slow, motion-correlated soft-tissue error, not by white noise, so the noise is taken from the
distribution of ``d`` itself over the recording, which holds every such part: each component is
divided by its robust scale (``1.4826 * MAD`` of ``d`` over the recording) and
``z[t] = |d[t] / scale|``. The tail of ``z`` above its upper quartile is modelled as exponential
(extreme-value law of the Gumbel domain) with its scale from the mean excess; values of ``d``
a correlation time ``tau`` apart (the integrated autocorrelation time of ``d``) count as
independent, so ``2 * 3600 * rate_hz / tau`` tests are made per hour of joint time (2: the
parent's and the child's frame). The threshold is the level of ``z`` expected to be exceeded
``false_alarms_per_hour`` times an hour (:func:`~calibration.slip_stats.tail_threshold`, with
an upper confidence bound on the tail's scale: a recording of a few seconds holds few independent
values and gets a higher threshold). ``d`` is smooth over the window, so a long recording's noise
model is estimated from every ``w / 16``-th frame (:data:`NOISE_SAMPLES_PER_WINDOW`; at least
:data:`NOISE_MIN_SAMPLES` samples, so a recording of fewer than 8,192 frames uses every one): on
a two-minute recording its threshold and scale are within 0.3 % of every frame's; a chunk of
:data:`CHUNK_FRAMES` takes every eighth frame at 120 Hz.

**Leave the candidate out, refit around it.** A slip's own jump would inflate the noise
estimate, and so would the misfit it causes (a joint fitted across a slip is wrong on both sides,
which adds motion-correlated error to the whole recording). The candidate (the largest ``z`` not
yet explained, either frame) is therefore tested against a noise model estimated from the
residual with the joint *refitted on each side of it* (and of every event already found), over
the frames farther than ``w`` from them. A candidate above its threshold becomes an event; its
frame is refined to the least-squares single change of mean of ``e`` within ``w`` of it; it is
attributed to the frame where the jump is largest (the moved sensor's frame holds the step
steady, the other frame turns it); the search repeats with the events as cuts. A slip undone
later (the sensor put back) hides behind its partner, so a failed candidate is retried once with
the next peak as a cut, and kept if the two pass together (each tested with the other as a
cut).

**A slip and its return are at least a window apart.** On skin the residual moves away and
back while one joint after another moves (a few millimetres for a second or two), which window
means see as a step out and a step back, and which the pair retry above would report as a slip
and its return. Window means cannot resolve two steps closer than ``w``, so the pair stands only
if the two least-squares change points are at least ``w`` apart (:func:`_closer_than_window`).
Tried and measured on the humanoid's exercise sessions, and left out: regressing ``e`` on the
pair's relative rotation per piece, or weighting ``d`` by the tracker's local white noise (at
most a quarter fewer false alarms than without the rule, no better detection), and also
requiring an event to pass at twice the window (fewer false alarms, but 2 of 10 2 cm slips lost).

**An event is at least the smallest detectable jump.** Each event found takes frames out of the
next candidate's noise model, and on skin those are the heaviest part of the tail (the limb
exercising), so later candidates meet lower thresholds. An event whose jump is below ``min_jump``
(below; from the residual refitted between all the events, over every frame: the refit absorbs
each event's step) is therefore dropped, and the noise model is re-estimated without it, until
every event left is at least ``min_jump``. On 20 clean humanoid exercise sessions
(``skin-paper-human``, 30 s) this took 14 alarms to 6, at the cost of one of ten 1 cm slips
(a 9.9 mm jump where ``min_jump`` was 10.8 mm) and one of ten 3 cm slips (its jump in the moved
frame 20.0 mm, ``min_jump`` 21.8 mm). Counting frames near the events out of ``min_jump``
instead kept that 3 cm slip but made ``min_jump`` of a short recording meaningless (211 mm for
a 3 cm slip found in 12 s), and re-testing each event with the others as cuts (backward
elimination) removed only one of four excursions of one such session.

**A slip is at least a window from either end.** A recording often starts or ends in another
motion than its middle: a person stands, then walks. Soft tissue sits differently standing than
walking (its offset follows the posture of several joints, not only the pair's), so the residual's
mean steps where the walk begins, once, and nothing in the rest of the recording is like it. On
60 s ``skin-markers`` gait sessions (the gait fades in over its first second) every session had
such a step on most of its joints, 0.3 to 1.4 s in: 33 alarms per joint-hour against the one the
threshold is set for. Window means compare whole windows of motion, so a step whose change point
is within ``w`` of an end cannot be told from the motion starting or stopping there: it is not
reported (nor is a slip in the first or last ``w`` of a recording), and the noise model is
re-estimated without it, as for a jump below ``min_jump``.

Every quantity is a ratio of lengths or a quantile of such ratios, so scaling positions by any
factor leaves the decision unchanged.

**Why not ``ruptures``.** Its penalised segmentation (PELT, binary segmentation) needs a penalty
per change that has no stated false-alarm rate on autocorrelated, heavy-tailed residuals; the one
thing it would add here, a single change point's least-squares location, is a few lines of
numpy (:func:`~calibration.slip_stats.change_point`).

The recording is cut at the events; every piece whose mean offset differs from the first piece's
(the sensors as placed) by more than ``min_jump`` -- the threshold times the noise scale, the
smallest jump the test detects, in the data's unit -- is reported as a slipped interval.

Frames where a pose is missing are left out of the window means.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from calibration.defaults import FALSE_ALARMS_PER_HOUR  # the detector's defaults
from calibration.defaults import SLIP_WINDOW_S as SLIP_WINDOW_S
from calibration.errors import CalibrationInputError
from calibration.hinge import block_edges
from calibration.joint import MIN_FRAMES, check_pair
from calibration.pairs import solve_pairs, statistics_of_stacked
from calibration.slip_stats import (
    change_point,
    correlation_times,
    robust_scale,
    tail_threshold,
    whitened_norm,
    window_difference_rows,
)

_FRAMES = ("parent", "child")

#: Units in the last place of the largest position below which a jump is rounding, not a jump
#: (:func:`_resolution`): 1e3 of them, 2e-13 m at 1 m, far below any tracker's noise.
RESOLUTION_ULPS = 1e3

#: Frames of a joint's series :func:`detect_slip` holds at once: a longer recording is taken a
#: chunk at a time (2^15: 4.5 min at 120 Hz, about 300 independent values of the statistic for a
#: noise model; about 0.45 KB a frame while a chunk is searched, 15 MiB: 2^18 made calibrate's
#: peak 558 MiB on 1,000,000 x 32 frames, 2^16 308 MiB, against 296 MiB without slip detection,
#: whose freed memory the search reuses).
CHUNK_FRAMES = 1 << 15

#: Frames of poses read at once while a chunk's products are formed (:class:`_Pair`): the poses
#: (24 numbers a frame) are not held for a whole chunk, only the products (17 a frame).
READ_FRAMES = 1 << 14

#: Samples of ``d`` per window a noise model is estimated from (:func:`_noise_model`): ``d`` is a
#: difference of window means, correlated over about two thirds of a window (its correlation time),
#: so samples closer than a sixteenth of a window add almost nothing to its robust scale, its tail
#: or its correlation time, while every frame of a long recording would cost up to 15 times as
#: much (a 2 s window at 120 Hz).
NOISE_SAMPLES_PER_WINDOW = 16

#: Fewest samples of ``d`` a noise model is estimated from (a recording of fewer than twice this
#: many frames uses every frame: a short one holds few independent values, and its cost does not
#: matter).
NOISE_MIN_SAMPLES = 4096

#: Windows of overlap each side between consecutive chunks (the search ignores a step within a
#: window of a chunk's ends: every frame is at least this far inside one chunk's core).
OVERLAP_WINDOWS = 4


@dataclass(frozen=True)
class SlipEvent:
    """A jump of a joint's residual offset.

    Attributes:
        frame: the first frame after the jump.
        jump: ``D`` at ``frame``: size of the change of the mean residual vector, the data's
            length unit.
        sensor_frame: ``"parent"`` or ``"child"``: the frame in which the jump is largest (the
            sensor that most likely moved: its frame holds the step steady).
        z: the whitened jump ``z`` (module docstring) at the candidate, in the frame where it
            is most significant.
        threshold: the threshold ``z`` was tested against (its leave-out noise model).
    """

    frame: int
    jump: float
    sensor_frame: str
    z: float
    threshold: float = float("nan")


@dataclass(frozen=True)
class SlipReport:
    """Slip events of one joint and the intervals where its sensors sat elsewhere.

    Attributes:
        events: the detected jumps, in time order.
        intervals: ``[start, stop)`` frame ranges whose residual offset differs from the
            start of the recording's.
        jump: ``(frames,)`` ``D[t]`` in the frame of the largest event (else the child's), the
            data's length unit (NaN within ``w`` of the ends).
        noise: the robust scale of ``d`` (norm of its per-component scales) over the
            recording, the data's length unit.
        window: ``w``, frames.
        threshold: the threshold on ``z`` over the whole recording (no frames left out).
        min_jump: ``threshold * noise / sqrt(3)``: about the smallest jump the test detects,
            the data's length unit; every event is at least this large.
        false_alarms_per_hour: the rate the threshold was set for.
        tests_per_hour: effectively independent tests per hour of joint time.
    """

    events: tuple[SlipEvent, ...]
    intervals: tuple[tuple[int, int], ...]
    jump: np.ndarray
    noise: float
    window: int
    threshold: float = float("nan")
    min_jump: float = float("nan")
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR
    tests_per_hour: float = float("nan")


def _check_options(n: int, window: int, rate_hz: float, false_alarms_per_hour: float) -> None:
    if not 2 <= window <= n // 2:
        raise CalibrationInputError(f"window must be between 2 and frames/2 = {n // 2}, got {window}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise CalibrationInputError(f"rate_hz must be a positive finite number, got {rate_hz}")
    if not (np.isfinite(false_alarms_per_hour) and false_alarms_per_hour > 0):
        raise CalibrationInputError(
            f"false_alarms_per_hour must be a positive finite number, got {false_alarms_per_hour}"
        )


@dataclass(frozen=True)
class _Pair:
    """One joint's frames as the search needs them: the pose products the window differences
    are affine in, and the joint as fitted.

    Per frame, with ``M = R_p^T R_c``, ``u_p = R_p^T (p_c - p_p)`` and ``u_c = R_c^T (p_c - p_p)``,
    the residual of a joint ``(l_p, l_c)`` in the two frames is ``e_p = l_p - u_p - M l_c`` and
    ``e_c = M^T l_p - u_c - l_c``. Window means are linear, so away from the cuts (both windows in
    one piece) ``d_p = -D(u_p) - D(M) l_c`` and ``d_c = D(M)^T l_p - D(u_c)`` with ``D`` the window
    difference of those products, taken once (``coupling``); only the ``2 w`` rows around each cut
    are recomputed from their residuals. The refits come from the same products' sums (O'Brien's
    normal equations, :func:`_refit`). The search asks for the same refits and window differences
    many times; each piece's joint is computed once, and the last few sets of cuts' window
    differences are kept (``_joints``, ``_diffs``).
    """

    terms: np.ndarray  # (17, frames): M (9, row-major), u_p, u_c, |p_c - p_p|^2, 1; zeros where not ok
    coupling: np.ndarray  # (15, frames): the window differences of terms[:15]
    ok: np.ndarray
    joint: tuple[np.ndarray, np.ndarray]
    window: int
    rate_hz: float
    rate: float
    resolution: float = 0.0  # m: the residuals' floating-point resolution: no jump is smaller
    _joints: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False, compare=False
    )
    _diffs: dict[tuple[int, ...], np.ndarray] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def of(
        cls,
        sources: tuple[Any, Any, Any, Any],
        a: int,
        b: int,
        joint: tuple[np.ndarray, np.ndarray],
        *,
        window: int,
        rate_hz: float,
        rate: float,
    ) -> _Pair:
        """Frames ``a:b`` of the poses (``R_w_p``, ``p_w_p``, ``R_w_c``, ``p_w_c`` of
        :func:`detect_slip`, read :data:`READ_FRAMES` at a time) and the joint as fitted (``(3,)``
        each)."""
        jp, jc = (np.asarray(x, dtype=float) for x in joint)
        n = b - a
        terms = np.empty((17, n))  # a row per product: sums and window sums run along rows
        ok = np.zeros(n, dtype=bool)
        top = 0.0
        for s in range(a, b, READ_FRAMES):
            t = min(b, s + READ_FRAMES)
            R_p, p_p, R_c, p_c = check_pair(*(x[s:t] for x in sources))
            rel = p_c - p_p
            cols = terms[:, s - a : t - a]
            cols[:9] = np.matmul(R_p.transpose(0, 2, 1), R_c).reshape(t - s, 9).T
            cols[9:12] = np.einsum("fji,fj->if", R_p, rel)
            cols[12:15] = np.einsum("fji,fj->if", R_c, rel)
            cols[15] = np.einsum("fi,fi->f", rel, rel)
            cols[16] = 1.0
            # every product finite: the rotations and p_c - p_p are, hence both positions
            good = np.isfinite(cols).all(axis=0)
            good &= bool(np.isfinite(jp).all() and np.isfinite(jc).all())
            ok[s - a : t - a] = good
            for x in (p_p, p_c):
                x = x if good.all() else x[good]
                if x.size:
                    top = max(top, float(x.max()), -float(x.min()))
        if not ok.all():
            terms[:, ~ok] = 0.0
        coupling = window_difference_rows(terms[:15], ok, window)
        resolution = RESOLUTION_ULPS * float(np.spacing(max(top, 1.0)))
        return cls(terms, coupling, ok, (jp, jc), window, rate_hz, rate, resolution)

    @property
    def stride(self) -> int:
        """Frames between the samples of ``d`` its noise models take (:func:`_noise_stride`)."""
        return _noise_stride(self.window, self.ok.size)

    def residual_frames(self, a: int = 0, b: int | None = None, joint: Any = None) -> list[np.ndarray]:
        """``[e_p, e_c]``, ``(b - a, 3)`` each: the residual of ``joint`` (default: as fitted) in the
        parent's and the child's frame over frames ``a:b`` (zeros where not ok)."""
        jp, jc = self.joint if joint is None else joint
        e_p, e_c = _affine(self.terms[:15, a:b], jp, jc)
        e_p += jp[:, None]
        e_c -= jc[:, None]
        ok = self.ok[a:b]
        return [np.where(ok, e_p, 0.0).T, np.where(ok, e_c, 0.0).T]

    def fitted_diff(self, rows: int | slice, i: int) -> np.ndarray:
        """``d`` of the joint as fitted (no refit) in sensor frame ``i`` at ``rows``: ``(3,)`` or
        ``(rows, 3)``."""
        C = self.coupling[:, rows]
        d = _affine_frame(C if C.ndim == 2 else C[:, None], *self.joint, i).T
        return d if C.ndim == 2 else d[0]

    def diffs(self, cuts: list[int]) -> list[np.ndarray]:
        """``d``, ``(frames, 3)``, of each sensor frame with the joint refitted between ``cuts``
        (the caller must not change them)."""
        return [self.diff(cuts, 0), self.diff(cuts, 1)]

    def diff(self, cuts: list[int], i: int, stride: int = 1) -> np.ndarray:
        """``d``, ``(frames, 3)``, of sensor frame ``i`` with the joint refitted between ``cuts``, at
        every ``stride``-th frame (``(ceil(frames / stride), 3)``; the caller must not change it)."""
        key = (*sorted(cuts), -1 - i, stride)
        if key in self._diffs:
            return self._diffs[key]
        n, w = self.ok.size, self.window
        cut = key[:-2]
        edges = [0, *cut, n]
        joints = [self._piece_joint(a, b) for a, b in pairwise(edges)]
        out = np.empty((3, -(-n // stride)))

        def rows(a: int, b: int) -> slice:  # the output rows of frames a:b
            return slice(-(-a // stride), -(-b // stride))

        for (a, b), joint in zip(pairwise(edges), joints, strict=True):
            r = rows(a, b)
            out[:, r] = _affine_frame(self.coupling[:, r.start * stride : b : stride], *joint, i)
        for lo, hi in _near(cut, w, n):  # rows whose windows hold two pieces: from their residuals
            r = rows(lo, hi)
            if r.start >= r.stop:
                continue
            s, t = max(0, lo - w), min(n, hi + w)
            e = np.zeros((3, t - s))
            for (a, b), joint in zip(pairwise(edges), joints, strict=True):
                if a < t and b > s:
                    e[:, max(a, s) - s : min(b, t) - s] = self.residual_frames(max(a, s), min(b, t), joint)[
                        i
                    ].T
            out[:, r] = window_difference_rows(e, self.ok[s:t], w)[:, r.start * stride - s : hi - s : stride]
        view = out.T  # (rows, 3)
        view.flags.writeable = False
        if len(self._diffs) >= 3:  # the search asks again only for the last few sets of cuts
            del self._diffs[next(iter(self._diffs))]
        self._diffs[key] = view
        return view

    def _piece_joint(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """The joint refitted on frames ``a:b``; the whole fit's when the piece is shorter than
        the window or cannot be fitted."""
        if (a, b) not in self._joints:
            fit = _refit(self.terms[:, a:b]) if b - a >= self.window else None
            self._joints[(a, b)] = self.joint if fit is None else fit
        return self._joints[(a, b)]


def _affine(x: np.ndarray, jp: np.ndarray, jc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(-x_p - X_M l_c, X_M^T l_p - x_c)``, ``(3, m)`` each, of rows ``x`` ``(15, m)`` laid out as
    :class:`_Pair`'s ``terms`` (``X_M`` the 3 x 3 of the first nine, ``x_p``, ``x_c`` the next
    three each): the window differences of the residual from those of the products (module of
    :class:`_Pair`), or the residual less its constants ``(l_p, -l_c)`` from the products."""
    return _affine_frame(x, jp, jc, 0), _affine_frame(x, jp, jc, 1)


def _affine_frame(x: np.ndarray, jp: np.ndarray, jc: np.ndarray, i: int) -> np.ndarray:
    """Sensor frame ``i``'s half of :func:`_affine`, ``(3, m)``: one product of a ``(3, 15)``
    matrix with the rows."""
    A = np.zeros((3, 15))
    rows = np.arange(3)
    if i == 0:  # -x_p[r] - sum_j M[r, j] l_c[j]
        A[:, 9:12] = -np.eye(3)
        A[rows[:, None], 3 * rows[:, None] + rows] = -jc
    else:  # -x_c[r] + sum_j l_p[j] M[j, r]
        A[:, 12:15] = -np.eye(3)
        A[rows[:, None], 3 * rows + rows[:, None]] = jp
    return A @ x[:15]


def _near(cuts: tuple[int, ...], w: int, n: int) -> list[tuple[int, int]]:
    """``[lo, hi)`` row ranges within ``w`` of a cut (``|t - cut| < w``), merged, inside ``[0, n)``."""
    out: list[tuple[int, int]] = []
    for c in cuts:
        lo, hi = max(0, c - w + 1), min(n, c + w)
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        elif lo < hi:
            out.append((lo, hi))
    return out


def _refit(terms: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(joint_in_parent, joint_in_child)`` of the joint refitted on these frames (``terms`` of
    :class:`_Pair`, ``(17, frames)``), or ``None`` with fewer than
    :data:`~calibration.joint.MIN_FRAMES` usable: :func:`calibration.joint.fit_joint`'s answer with
    ``effect_size=False`` (the single-axis verdict's test, not its effect size) from the normal
    equations of the all-pairs path (:func:`calibration.pairs.solve_pairs`), their sums over each
    block of the verdict's test (:func:`calibration.hinge.block_edges`) taken from the products
    the search holds. Positions centred on the pair's mean as :func:`calibration.pairs.pair_statistics`
    centres them: ``p_c - centre = (p_c - p_p) / 2``."""
    edges = block_edges(terms.shape[1])
    sums = np.add.reduceat(terms, edges[:-1], axis=1).T  # (B, 17)
    nb = sums.shape[0]
    cnt = sums[:, 16]
    eye = cnt[:, None, None] * np.eye(3)
    M = sums[:, :9].reshape(nb, 3, 3)
    gram = np.empty((nb, 2, 2, 3, 3))
    gram[:, 0, 0], gram[:, 0, 1], gram[:, 1, 0], gram[:, 1, 1] = eye, M, M.transpose(0, 2, 1), eye
    half_p, half_c = 0.5 * sums[:, 9:12], 0.5 * sums[:, 12:15]
    cross = np.stack([np.stack([-half_p, half_p], 1), np.stack([-half_c, half_c], 1)], 1)
    self_cross = np.stack([np.stack([-half_p, -half_p], 1), np.stack([half_c, half_c], 1)], 1)
    sq = np.zeros((nb, 2, 2))
    sq[:, 0, 1] = sq[:, 1, 0] = sums[:, 15]
    count = np.broadcast_to(np.rint(cnt).astype(np.int64)[:, None, None], (nb, 2, 2))
    stats = statistics_of_stacked((gram, cross, self_cross, sq, count), terms.shape[1])
    sol = solve_pairs(stats, np.array([0]), np.array([1]))
    if sol.n_frames[0] < MIN_FRAMES:
        return None
    return sol.joint_in_parent[0], sol.joint_in_child[0]


def _noise_stride(window: int, frames: int) -> int:
    """Frames between the samples of ``d`` a noise model is estimated from: at most
    :data:`NOISE_SAMPLES_PER_WINDOW` a window, at least :data:`NOISE_MIN_SAMPLES` in all."""
    return max(1, min(window // NOISE_SAMPLES_PER_WINDOW, frames // NOISE_MIN_SAMPLES))


def _noise_model(pair: _Pair, d: np.ndarray, use: np.ndarray, stride: int) -> tuple[np.ndarray, float, float]:
    """``(scale, threshold, tests per hour)`` of one sensor frame's ``d`` at every ``stride``-th
    frame (:func:`_noise_stride`), from the samples ``use``."""
    scale = robust_scale(d, use)
    z = whitened_norm(d[use], scale)
    tau_samples = float(correlation_times(d, use).max())
    tests_per_hour = len(_FRAMES) * 3600.0 * pair.rate_hz / (stride * tau_samples)
    return scale, tail_threshold(z, tests_per_hour, pair.rate, tau_samples), tests_per_hour


def _test(
    pair: _Pair, free: np.ndarray, cuts: list[int], k: int, i: int, d_now: np.ndarray | None = None
) -> tuple[float, float]:
    """``(z, threshold)`` of a jump at frame ``k`` in sensor frame ``i``.

    ``cuts`` are the events already found (and a tentative one, see :func:`_search`). The jump is
    measured on the residual with the joint refitted between the ``cuts``; its noise model comes
    from the residual refitted on each side of ``k`` too (a slip's misfit spreads
    motion-correlated error over the whole recording), over the frames of ``free`` farther than
    the window from ``k`` and from the ``cuts``. ``d_now``: ``pair.diffs(cuts)[i]`` when the
    caller has it already (saves the refit).
    """
    w = pair.window
    stride = pair.stride
    frames = np.arange(0, free.size, stride)
    d_k = (pair.diff(cuts, i) if d_now is None else d_now)[k : k + 1]
    d = pair.diff([*cuts, k], i, stride)
    rest = free[::stride] & np.isfinite(d).all(axis=1) & (np.abs(frames - k) > w)
    for c in cuts:
        rest &= np.abs(frames - c) > w
    if rest.sum() < 4 or not np.isfinite(d_k).all():
        return 0.0, float("inf")
    scale, thr, _ = _noise_model(pair, d, rest, stride)
    return float(whitened_norm(d_k, scale)[0]), thr


def _excess(z: float, threshold: float) -> float:
    """``z / threshold``, how far a candidate stands above its threshold (ranks candidates).

    A threshold of 0 comes from a residual with no noise at all (every ``z`` of the noise model
    0, e.g. a recording that never moves): there a ``z`` of 0 is no evidence (0) and any larger
    ``z`` is beyond every noise (``inf``); an infinite threshold (too few frames to test) gives 0.
    """
    if threshold > 0.0:
        return z / threshold
    return float("inf") if z > 0.0 else 0.0


def _check_sources(sources: tuple[Any, Any, Any, Any], n: int) -> None:
    """Shapes of :func:`detect_slip`'s poses: ``(frames, 3, 3)``, ``(frames, 3)``, ``(frames, 3, 3)``,
    ``(frames, 3)``, ``n`` frames each."""
    names = ("R_w_p", "p_w_p", "R_w_c", "p_w_c")
    for name, x, tail in zip(names, sources, ((3, 3), (3,), (3, 3), (3,)), strict=True):
        shape = tuple(np.shape(x))
        if len(shape) != 1 + len(tail) or shape[1:] != tail:
            raise CalibrationInputError(
                f"Expected {name} to have shape (frames, {', '.join(map(str, tail))}), got {shape}"
            )
        if shape[0] != n:
            raise CalibrationInputError(f"Expected {name} to have {n} frames like R_w_p, got {shape[0]}")


def _peak(d: np.ndarray, free: np.ndarray, stride: int = 1) -> int | None:
    """The frame of ``free`` with the largest whitened ``d`` (its scale from every ``stride``-th frame);
    ``None`` when there is none."""
    zc = np.where(free, whitened_norm(d, robust_scale(d[::stride], free[::stride])), -np.inf)
    k = int(np.argmax(zc))
    return k if np.isfinite(zc[k]) else None


def _closer_than_window(pair: _Pair, i: int, k: int, k2: int) -> bool:
    """Whether the steps near ``k`` and ``k2`` (least-squares change points) are closer than ``w``."""
    w = pair.window
    n = pair.ok.size
    at = []
    for c in (k, k2):
        lo, hi = max(0, c - w), min(n, c + w)
        at.append(lo + change_point(pair.residual_frames(lo, hi)[i], pair.ok[lo:hi], 0, hi - lo))
    return abs(at[0] - at[1]) < w


def _search(pair: _Pair, free: np.ndarray) -> tuple[list[tuple[int, int, float, float]], np.ndarray]:
    """``(frame, sensor frame index, z, threshold)`` of the events, strongest first; frames left.

    Forward selection: the strongest remaining peak of either sensor frame is tested
    (:func:`_test`) with the events found so far as cuts. A slip that is undone later (the sensor
    put back) hides behind its partner, which spreads error over the other's noise model, so a
    candidate that fails is tested once more with the next strongest peak as a cut, and is kept
    only if that peak passes its own test with the candidate as a cut as well (the pair stands
    together) and the two are at least ``w`` apart.
    """
    w = pair.window
    free = free.copy()
    frames = np.arange(free.size)
    found: list[tuple[int, int, float, float]] = []
    for _ in range(free.size // (2 * w) + 1):
        cuts = [f[0] for f in found]
        ds = pair.diffs(cuts)
        best = None
        for i, d in enumerate(ds):
            k = _peak(d, free, pair.stride)
            if k is None:
                continue
            z, thr = _test(pair, free, cuts, k, i, d)
            if best is None or _excess(z, thr) > _excess(best[2], best[3]):
                best = (k, i, z, thr)
        if best is None:
            break
        if not best[2] > best[3]:
            k, i = best[0], best[1]
            k2 = _peak(ds[i], free & (np.abs(frames - k) > w), pair.stride)
            if k2 is None:
                break
            z, thr = _test(pair, free & (np.abs(frames - k2) > w), [*cuts, k2], k, i)
            if not z > thr:  # the pair cannot stand: its partner's test is not needed
                break
            z2, thr2 = _test(pair, free & (np.abs(frames - k) > w), [*cuts, k], k2, i)
            if not z2 > thr2 or _closer_than_window(pair, i, k, k2):
                break
            best = (k, i, z, thr)
        # attribution: the moved sensor's frame holds the step steady, the other's turns it
        k = best[0]
        i_moved = int(np.argmax([np.nan_to_num(np.linalg.norm(d[k])) for d in ds]))
        found.append((k, i_moved, best[2], best[3]))
        free &= np.abs(frames - k) > w
    return found, free


def detect_slip(
    R_w_p: Any,
    p_w_p: Any,
    R_w_c: Any,
    p_w_c: Any,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    *,
    window: int,
    rate_hz: float,
    false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR,
    chunk_frames: int = CHUNK_FRAMES,
    series: bool = True,
) -> SlipReport:
    """Find the frames where a joint's residual offset jumps (a sensor moved on the body).

    A recording of more than ``chunk_frames`` frames is taken a chunk at a time (memory bounded
    by the chunk, not the recording): chunks of at most ``chunk_frames`` frames that overlap by
    :data:`OVERLAP_WINDOWS` windows each side, each searched as a recording of its own (its own
    noise model and threshold, set for the same rate per hour), an event kept by the chunk whose
    core (the chunk less its overlaps, the cores tiling the recording) holds its frame. Then
    ``intervals`` are judged against the first chunk's first piece as in one search, and
    ``noise``, ``threshold``, ``min_jump`` and ``tests_per_hour`` are the chunks' medians.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent rotations, sensor to world (an array, or anything
            that gives one for a slice of frames, e.g. an h5py dataset's view).
        R_w_c: ``(frames, 3, 3)`` child rotations, likewise.
        p_w_p: ``(frames, 3)`` parent positions in world, any length unit.
        p_w_c: ``(frames, 3)`` child positions in world, the same unit.
        joint_in_parent: ``(3,)`` the fitted joint in the parent frame, the same unit.
        joint_in_child: ``(3,)`` the fitted joint in the child frame, the same unit.
        window: ``w`` of the module docstring, frames (at least 2, at most half the frames).
        rate_hz: frames per second (turns the rate per hour into a rate per frame).
        false_alarms_per_hour: expected false alarms per hour of this joint's recording when
            no sensor moves (module docstring).
        chunk_frames: the most frames held at once (at least ``8 * window`` more than twice the
            overlap).
        series: keep ``jump`` (``False``: an empty array; the events and figures are the same).

    Raises:
        CalibrationInputError: shapes that do not match, a window out of range, a rate or a
            false-alarm rate that is not positive and finite.
    """
    options = {"window": window, "rate_hz": float(rate_hz), "rate": float(false_alarms_per_hour)}
    try:
        n = len(R_w_p)
    except TypeError:
        raise CalibrationInputError(
            f"Expected R_w_p of shape (frames, 3, 3), got {np.shape(R_w_p)}"
        ) from None
    _check_sources((R_w_p, p_w_p, R_w_c, p_w_c), n)
    _check_options(n, window, rate_hz, false_alarms_per_hour)
    overlap = OVERLAP_WINDOWS * window
    if n > chunk_frames and chunk_frames < 2 * overlap + 8 * window:
        raise CalibrationInputError(
            f"chunk_frames must be at least {2 * overlap + 8 * window} for a window of {window}, got "
            f"{chunk_frames}"
        )
    pieces = _chunks(n, chunk_frames, overlap)
    reports = []
    reference = None  # the first chunk's first piece: every chunk's intervals are judged against it
    for a, b, core_a, core_b in pieces:
        pair = _Pair.of((R_w_p, p_w_p, R_w_c, p_w_c), a, b, (joint_in_parent, joint_in_child), **options)
        rep, reference = _detect_chunk(pair, reference=reference, series=series)
        del pair
        reports.append((a, core_a, core_b, rep))
    events, intervals, jumps = [], [], []
    for a, core_a, core_b, rep in reports:
        events += [
            dataclasses.replace(ev, frame=ev.frame + a)
            for ev in rep.events
            if core_a <= ev.frame + a < core_b
        ]
        intervals += [
            (max(lo + a, core_a), min(hi + a, core_b))
            for lo, hi in rep.intervals
            if lo + a < core_b and hi + a > core_a
        ]
        if series:
            jumps.append(rep.jump[core_a - a : core_b - a])
    return SlipReport(
        events=tuple(events),
        intervals=tuple(_merged(intervals, {core_a for _, core_a, _, _ in reports})),
        jump=np.concatenate(jumps) if series else np.empty(0),
        noise=float(np.median([r.noise for *_, r in reports])),
        window=window,
        threshold=float(np.median([r.threshold for *_, r in reports])),
        min_jump=float(np.median([r.min_jump for *_, r in reports])),
        false_alarms_per_hour=false_alarms_per_hour,
        tests_per_hour=float(np.median([r.tests_per_hour for *_, r in reports])),
    )


def _chunks(n: int, chunk: int, overlap: int) -> list[tuple[int, int, int, int]]:
    """``(start, stop, core start, core stop)`` of each chunk of ``n`` frames: at most ``chunk``
    frames, cores of equal length tiling ``[0, n)``, each chunk its core and ``overlap`` each side."""
    if n <= chunk:
        return [(0, n, 0, n)]
    k = -(-n // (chunk - 2 * overlap))
    edges = np.linspace(0, n, k + 1).round().astype(int)
    return [
        (max(0, int(lo) - overlap), min(n, int(hi) + overlap), int(lo), int(hi)) for lo, hi in pairwise(edges)
    ]


def _merged(intervals: list[tuple[int, int]], seams: set[int]) -> list[tuple[int, int]]:
    """Intervals sorted, those that overlap or meet at a seam between chunk cores joined (one
    interval cut by the chunks); those that meet at an event stay apart, as in one search."""
    out: list[tuple[int, int]] = []
    for lo, hi in sorted(intervals):
        if out and (lo < out[-1][1] or (lo == out[-1][1] and lo in seams)):
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _detect_chunk(
    pair: _Pair, reference: list[np.ndarray | None] | None = None, series: bool = True
) -> tuple[SlipReport, list[np.ndarray | None]]:
    """:func:`detect_slip` on frames held at once (the whole recording, or one chunk), and the
    mean offsets its intervals were judged against (``reference``: a later chunk's, the first
    chunk's; :func:`_intervals`). ``series``: compute the report's ``jump`` (else empty)."""
    n, window, ok = pair.ok.size, pair.window, pair.ok
    valid = np.isfinite(pair.coupling[0])  # both windows hold enough frames (d is finite)
    found, _ = _search(pair, valid)
    while True:
        events = []
        for k, i, z, thr in found:
            lo, hi = max(0, k - window), min(n, k + window)
            frame = lo + change_point(pair.residual_frames(lo, hi)[i], ok[lo:hi], 0, hi - lo)
            d_at = pair.fitted_diff(frame, i)
            jump = float(np.linalg.norm(d_at if np.isfinite(d_at).all() else pair.fitted_diff(k, i)))
            events.append(SlipEvent(frame=frame, jump=jump, sensor_frame=_FRAMES[i], z=z, threshold=thr))
        shown = found[0][1] if found else 1
        stride = pair.stride
        d_clean = pair.diff([f[0] for f in found], shown, stride)
        # the joint refitted on each side of every event absorbs its step: every frame counts
        rest = valid[::stride] & np.isfinite(d_clean).all(axis=1)
        scale, thr_all, tests_per_hour = _noise_model(pair, d_clean, rest, stride)
        noise = float(np.linalg.norm(scale))
        min_jump = thr_all * noise / np.sqrt(3.0)
        # an event smaller than the recording's smallest detectable jump passed only because
        # the events found before it took the heaviest part of the tail out of its noise model
        # and a jump within the numbers' resolution is rounding, not a jump; and a step within a
        # window of either end is the motion starting or stopping, as far as window means can tell
        kept = [
            f
            for f, ev in zip(found, events, strict=True)
            if ev.jump >= max(min_jump, pair.resolution) and window <= ev.frame <= n - window
        ]
        if len(kept) == len(found):
            break
        found = kept
    events.sort(key=lambda ev: ev.frame)
    intervals, reference = _intervals(pair, events, min_jump, reference)
    report = SlipReport(
        events=tuple(events),
        intervals=intervals,
        jump=np.linalg.norm(pair.fitted_diff(slice(None), shown), axis=-1) if series else np.empty(0),
        noise=noise,
        window=window,
        threshold=thr_all,
        min_jump=min_jump,
        false_alarms_per_hour=pair.rate,
        tests_per_hour=tests_per_hour,
    )
    return report, reference


def _intervals(
    pair: _Pair,
    events: list[SlipEvent],
    min_jump: float,
    reference: list[np.ndarray | None] | None = None,
) -> tuple[tuple[tuple[int, int], ...], list[np.ndarray | None]]:
    """Pieces between events whose mean offset (in each sensor frame) differs from the reference
    by more than ``min_jump``, and the reference: the first piece's mean offsets, or those given
    (a later chunk of a recording is judged against the recording's first piece)."""
    ok, n = pair.ok, pair.ok.size
    cuts = [0, *(ev.frame for ev in events), n]
    pieces = list(pairwise(cuts))
    if reference is None:
        a, b = pieces.pop(0)
        first = ok[a:b]
        reference = [np.mean(e[first], axis=0) if first.any() else None for e in pair.residual_frames(a, b)]
    out = []
    for a, b in pieces:
        seg = ok[a:b]
        moved = seg.any() and any(
            ref is not None and np.linalg.norm(np.mean(e[seg], axis=0) - ref) > min_jump
            for e, ref in zip(pair.residual_frames(a, b), reference, strict=True)
        )
        if moved:
            out.append((a, b))
    return tuple(out), reference
