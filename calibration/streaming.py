"""Calibration while the subject is still suited: frames pushed one at a time (issue 17).

O'Brien et al. (section 5) note that the calibration is fast enough to run during the capture, so
that a bad session or a slipped sensor can be re-taken on the spot. Every fit of
:func:`calibration.pipeline.calibrate` is a sum over frames (:mod:`calibration.pairs`), so
:class:`StreamingCalibrator` keeps the same sufficient statistics and answers at any time with
what the batch calibration would answer on the frames pushed so far:

- **Pair statistics** (:class:`calibration.pair_sums.PairSums`, positions centred per frame as in
  the batch) per block of the single-axis test: blocks of ``L = 2^k`` frames, at most
  :data:`calibration.hinge.N_BLOCKS`; when the next frame would open one block more, neighbours
  are merged in pairs and ``L`` doubles. These are exactly the blocks
  :func:`calibration.hinge.block_edges` gives the whole recording, so the joints, residuals,
  hierarchy and single-axis verdicts are those of the batch (equal to rounding: the sums are
  added in another order; measured below 1e-12 m on the joint centres).
- **Third-difference statistics** for the misfit hierarchy's noise
  (:mod:`calibration.pair_noise`): the residual's third difference is linear in the joint,
  ``D3 e = D3 A x - D3 b``, so ``sum |D3 e|^2`` is a quadratic form in ``x`` whose matrices are
  sums over frames too (the pair statistics of the third-differenced poses, plus each sensor's
  own ``sum D3R_i^T D3R_i`` weighted by the pair's validity). Three frames carry over between
  pushes.

Memory does not grow with the session: the statistics are ``O(N_BLOCKS * sensors^2)``, the slip
monitor keeps :data:`SLIP_HISTORY_S` seconds of its window differences per joint, and frames are held
only until the next flush (:data:`FLUSH_S`).

**Residuals.** The rms residuals come from the normal equations (as the batch's
``keep_frame_residuals=False`` takes them for noisy joints); the batch's default recomputes them
from the data in a second pass, which a stream cannot make. Both agree to 1e-9 m unless the
residual itself is at the rounding floor of the normal equations (about 1e-8 m on noise-free data,
:mod:`calibration.pairs`).

**Slip alerts** (:class:`SlipAlert`) are the detector of :mod:`calibration.slip` made causal: per
joint of the current tree, the residual (with the joint as fitted so far) in the parent's and in
the child's frame; ``d`` the mean over the last ``w`` frames minus the mean over the ``w`` frames
before (default :data:`LIVE_SLIP_WINDOW_S`); an alert when ``|d / scale|`` crosses the threshold,
set for ``false_alarms_per_hour`` per joint (default :data:`calibration.slip.FALSE_ALARMS_PER_HOUR`,
the batch's). The noise model is the data's own, as the batch's, from the last
:data:`SLIP_HISTORY_S` seconds of ``d`` (frames near an alert left out):

- *With the joint as fitted now.* ``d`` is affine in the joint: ``d_p = dv_p - dM l_c`` and
  ``d_c = dv_c + dM^T l_p`` with ``dM``, ``dv_p``, ``dv_c`` the window differences of
  ``M = R_p^T R_c``, ``v_p = R_p^T (p_p - p_c)`` and ``v_c = R_c^T (p_p - p_c)``. The history keeps
  those (every ``w / 8``-th frame: ``d`` is a mean over ``w`` frames), and each refit
  (:data:`REFIT_S`) recomputes the whole history's ``d`` with the new joint. Nothing restarts
  when the fit moves (an earlier version restarted when it moved by 10 times the white noise, so
  that on skin, whose residual is not white, a joint never armed).
- *Motion.* Soft tissue that follows the joint, and the fit's own error, grow with the joint's
  rotation between the two windows: ``d`` is divided by ``sqrt(1 + r^2)``, ``r = |dM| / m0``,
  ``m0`` the history's median ``|dM|`` (the history so divided gives the noise model), so a fast
  movement is judged against fast movements. The skin under each sensor also follows the other
  joints of its segment (a pelvis cluster moves with the hips, which the pelvis-abdomen joint does
  not see turn): the test divides by ``sqrt(1 + r^2)`` with ``r`` the largest of the joint's own
  and its neighbours' (the joints sharing a sensor with it): a neighbour's ``|dM|`` in excess of
  its own ``m0``, over the larger of the two joints' ``m0`` (one without a noise model yet: its
  ``|dM|`` over the joint's ``m0``). A neighbour moving as it usually does adds nothing, and one
  that barely moves (its ``m0`` its noise) does not count; a joint still for seconds whose
  neighbour then moves fast is judged against that movement, not against its quiet history.
- *Scale* per joint and frame: :func:`calibration.slip_stats.robust_scale`, raised to its upper
  confidence bound (:data:`LIVE_TAIL_CONFIDENCE`, chi-square with the history's independent values,
  its length over the correlation time): a joint seconds old has few. (The pooled tail below is
  fitted to the history whitened by this raised scale, so the bound cancels in the threshold:
  measured with it in force in ``docs/live-slip.md``, fifth round.)
- *Tail* pooled over the joints: the exponential tail of the whitened ``z`` above its upper
  quartile (:func:`calibration.slip_stats.tail_threshold`, at :data:`LIVE_TAIL_CONFIDENCE`) is
  fitted to every armed joint's ``z`` together: in units of each joint's own scale the tail's
  shape is the recording's, and one joint's first seconds hold too few independent values for it.

*Arming.* A joint arms (has a threshold) once its history holds :data:`SLIP_WARMUP_S` seconds,
from ``2 w`` after its pair's first frames (3 s at the default window), as its pair is seen rather
than when the whole tree has settled (:meth:`StreamingCalibrator._monitor_joints`): the monitor
follows the tree of the pairs seen together for ``2 w`` frames (a cluster out of view at first does
not rearrange the others' joints); the poses of the last ``2 w`` frames and a warm-up are held, so
that a joint new to the tree gets the history it would have had; a joint leaving the tree keeps its
history for when it returns; and only a joint the tree kept over one refit raises alerts (a joint
in it for a single refit is a tie of the tree's weights). A jump of ``X`` times the threshold is seen
``w / X`` frames after it happens (at most ``w``). The alert names the sensor whose other joints
repeat the jump in its frame (a slip of a sensor moves every one of its joints' residuals by the
same vector in its frame; a leaf sensor when its neighbour's other joints do not; failing both,
the sensor whose frame holds the jump more significantly), the least-squares change point within
the last ``2 w`` frames as the time, and the change of mean across it as the size. One slip moves
every joint of its sensor: alerts on joints sharing a sensor within ``2 w`` frames of an alert are
folded into it, and a sensor once alerted on raises no more alerts (its joints' fits now mix
two placements; re-fix the sensor and start a new calibration). A crossing must also be a step
that the joint's own fit error does not explain (:meth:`_SlipMonitor._steady`). Unlike the batch
detector, the joint is not refitted around a candidate (that needs the frames after it).

Measured (``studies/live_slip_real.py``, ``studies/results/live_slip_real.json``): on 7 real
recordings (marker clusters of hip, knee, wheelchair racing and propulsion, arm), 2 cm slips
injected, and on the skin-artefact presets; the figures are in ``docs/live-slip.md``.

**Operator guidance** (:class:`Coverage`): the three weak singular values of a joint's normal
matrix, ``s_k^2 = n (1 - sigma_k(M))`` with ``M`` the mean relative rotation
(:mod:`calibration.joint`), give for small rotations the relative rotation's variance about
three principal axes (parent sensor frame): ``c_k = sum_l w_l - 2 w_k`` with ``w_k = s_k^2 / n``.
A joint is "moved enough" when its second-largest rms rotation reaches
:data:`MIN_ROTATION_DEG` (two axes turned: all six directions determined); otherwise the advice
names that axis ("move more about axis X"). A joint the fit finds single-axis (a hinge) cannot
turn across its axis, so for it the largest rms rotation decides and the advice names the hinge's
axis (its centre along that axis stays unmeasured, as in the batch fit).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import connected_components

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hierarchy import (
    HIERARCHY_METHODS,
    LOOP_FACTOR,
    hierarchy_from_parents,
    loop_candidates,
    misfit_weights,
    spanning_tree,
)
from calibration.hinge import N_BLOCKS
from calibration.joint import MIN_FRAMES, SINGLE_AXIS_RATIO
from calibration.pair_sums import PairSums, ThirdDifferenceSums
from calibration.pairs import PairSolutions, PairStatistics, solve_pairs, statistics_of_blocks
from calibration.pipeline import Calibration, Joint, checked_names, fit_warnings, solved_joint
from calibration.quantiles import chi2_ppf
from calibration.skeleton import segment_lengths, sensor_placements
from calibration.slip import FALSE_ALARMS_PER_HOUR
from calibration.slip_stats import (
    change_point,
    initial_positive_time,
    robust_scale,
    tail_threshold,
    whitened_norm,
)

#: Seconds of frames held before they are added to the statistics (and the slip monitor runs).
FLUSH_S = 0.1

#: Seconds between refits of the tree and joints the slip monitor uses.
REFIT_S = 2.0

#: Default window ``w`` of the live slip monitor, seconds: an alert comes at most this late after
#: a clear jump (the batch detector's is :data:`calibration.slip.SLIP_WINDOW_S`, looking both ways).
LIVE_SLIP_WINDOW_S = 0.5

#: Seconds of the slip statistic each joint keeps for its noise model.
SLIP_HISTORY_S = 60.0

#: Seconds of a joint's slip history (its window differences, from ``2 w`` after it joins the tree)
#: before it may raise an alert: it arms ``2 w + SLIP_WARMUP_S`` (3 s at the default window) after
#: it joins. A short history gets a high threshold (the confidence bounds on its scale and on the
#: pooled tail), not none. Measured: 1 s (armed at 2 s) alerted 22 of 34 slips on the right sensor
#: in the real recordings (studies/live_slip_real.py) and 6 of 8 in the Polhemus humanoid sessions
#: of benchmarks/bench_live.py with 7 false alarms per joint-hour, one of them early in the session
#: of tests/test_live.py; 2 s, 21 of 34 and 6 of 8 with 8, none there.
SLIP_WARMUP_S = 2.0

#: Confidence of the upper bound on the tail's scale behind the live threshold
#: (:func:`calibration.slip_stats.tail_threshold`; the batch detector's is
#: :data:`calibration.slip_stats.TAIL_CONFIDENCE`, 0.75). The live threshold is estimated again at
#: every refit from a history seconds long at first, so each refit is one more chance to draw a low
#: bound. Measured (studies/live_slip_real.py, 7 real recordings, 34 injected 2 cm slips, before
#: the scale's bound was added): 0.75 gave 5 false alarms in 7.4 joint-minutes and 25 slips alerted
#: within 0.5 s; 0.95 gave 2 and 24.
LIVE_TAIL_CONFIDENCE = 0.95

#: Per-frame products held per joint (``M`` 9, ``v_p`` 3, ``v_c`` 3, valid 1: :class:`_SlipMonitor`).
_Q = 16

#: A joint has moved enough when its second-largest rms rotation reaches this, degrees (a sinusoid
#: of +-7 degrees; a joint moved less than about 10 degrees gets a centre decimetres off: DESIGN.md).
MIN_ROTATION_DEG = 5.0

_FRAME_NAMES = ("parent", "child")

_FOREVER = 2**62  # a frame no session reaches


@dataclass(frozen=True)
class SlipAlert:
    """A sensor that may have moved on the body, found causally (module docstring).

    Attributes:
        sensor: the sensor that probably moved.
        joint: ``"parent-child"`` the joint whose residual jumped first.
        frame: the estimated first frame after the jump (index since the first push).
        time_s: ``frame / rate_hz`` plus the calibrator's ``start_time_s``, seconds.
        raised_frame: the frame at which the alert was raised (frames pushed so far, minus one).
        size_m: the jump of the residual's mean in the sensor's frame, metres.
        z: the whitened jump when the alert was raised (dimensionless).
        threshold: the threshold it crossed.
        false_alarms_per_hour: the rate the threshold was set for, per joint.
    """

    sensor: str
    joint: str
    frame: int
    time_s: float
    raised_frame: int
    size_m: float
    z: float
    threshold: float
    false_alarms_per_hour: float

    @property
    def message(self) -> str:
        """``"sensor S may have slipped at t s, size X cm"``."""
        return (
            f"sensor {self.sensor} may have slipped at {self.time_s:.2f} s, size {self.size_m * 100:.1f} cm"
        )


@dataclass(frozen=True)
class Coverage:
    """How well a joint's motion so far determines its centre (module docstring).

    Attributes:
        joint: ``"parent-child"``.
        rotation_rms_deg: ``(3,)`` rms relative rotation about each principal axis, degrees,
            largest first (small-angle reading of the fit's singular values).
        axes_in_parent: ``(3, 3)`` the principal axes as rows, unit vectors in the parent
            sensor's frame, in the order of ``rotation_rms_deg``.
        condition: ``s_max / s_min`` of the fit's ``A`` (``inf`` if a direction is exactly free).
        moved_enough: the second-largest rms rotation is at least :data:`MIN_ROTATION_DEG`; for
            a joint the fit finds single-axis (a hinge, which cannot turn across its axis), the
            largest.
        advice: ``"moved enough"`` or ``"move more about axis [x, y, z] (parent frame)"``; for a
            single-axis joint, ``"single-axis joint, axis [x, y, z] (parent frame): moved enough
            (...)"`` or ``"single-axis joint: move more about its axis [x, y, z] (parent frame)"``.
    """

    joint: str
    rotation_rms_deg: np.ndarray
    axes_in_parent: np.ndarray
    condition: float
    moved_enough: bool
    advice: str


@dataclass(frozen=True)
class LiveState:
    """What the streaming calibration knows after the frames pushed so far.

    Attributes:
        calibration: the batch calibration's result on the same frames (joints in both frames,
            residual matrix, hierarchy, single-axis verdicts, limb lengths, placements); joints
            carry no per-frame residuals, and the warnings are those of the statistics (no
            jackknife diagnostics).
        coverage: one per joint of ``calibration``, in its order.
        alerts: every slip alert raised so far, in time order.
        n_frames: frames pushed.
        time_s: time of the last frame pushed, seconds.
        false_alarms_per_hour: expected false slip alerts per hour over all current joints.
    """

    calibration: Calibration
    coverage: tuple[Coverage, ...]
    alerts: tuple[SlipAlert, ...]
    n_frames: int
    time_s: float
    false_alarms_per_hour: float


class StreamingCalibrator:
    """Incremental calibration: push frames, read the batch calibration of all frames so far.

    Example::

        cal = StreamingCalibrator(names, rate_hz=120.0)
        for R, p, ok in source:          # (S, 3, 3), (S, 3), (S,) per frame, or blocks of frames
            cal.push(R, p, ok)
            for alert in cal.new_alerts():
                print(alert.message)
        state = cal.state()              # joints, hierarchy, residuals, coverage, alerts

    Args:
        names: ``S`` unique sensor names.
        rate_hz: frames per second (slip windows and times), > 0.
        parent_of: a known hierarchy ``{child: parent}``; inferred when ``None``.
        root: root sensor name (see :func:`calibration.pipeline.calibrate`).
        hierarchy_method: ``"misfit"`` or ``"mst"`` (:mod:`calibration.hierarchy`).
        single_axis_ratio: see :mod:`calibration.joint`.
        loop_factor: see :func:`calibration.hierarchy.loop_candidates`.
        slip: run the causal slip monitor.
        slip_window_s: ``w`` of the monitor, seconds.
        false_alarms_per_hour: per joint, the rate the alert threshold is set for.
        start_time_s: time of the first frame, seconds.
    """

    def __init__(
        self,
        names: Sequence[str],
        *,
        rate_hz: float,
        parent_of: Mapping[str, str] | None = None,
        root: str | None = None,
        hierarchy_method: str = HIERARCHY_METHODS[0],
        single_axis_ratio: float = SINGLE_AXIS_RATIO,
        loop_factor: float = LOOP_FACTOR,
        slip: bool = True,
        slip_window_s: float = LIVE_SLIP_WINDOW_S,
        false_alarms_per_hour: float = FALSE_ALARMS_PER_HOUR,
        start_time_s: float = 0.0,
    ) -> None:
        names = tuple(str(x) for x in names)
        if len(names) < 2:
            raise CalibrationInputError(
                f"calibration needs at least 2 sensors, got {len(names)} ({list(names)})"
            )
        self.names = checked_names(names, len(names))
        n = len(self.names)
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise CalibrationInputError(f"rate_hz must be a positive finite number, got {rate_hz}")
        if hierarchy_method not in HIERARCHY_METHODS:
            raise CalibrationInputError(
                f"hierarchy_method must be one of {list(HIERARCHY_METHODS)}, got {hierarchy_method!r}"
            )
        if not 0.0 < single_axis_ratio < 1.0:
            raise CalibrationInputError(f"single_axis_ratio must be in (0, 1), got {single_axis_ratio}")
        if root is not None and root not in self.names:
            raise CalibrationInputError(f"root {root!r} is not a sensor; sensors are {list(self.names)}")
        if not (np.isfinite(false_alarms_per_hour) and false_alarms_per_hour > 0):
            raise CalibrationInputError(
                f"false_alarms_per_hour must be a positive finite number, got {false_alarms_per_hour}"
            )
        window = round(slip_window_s * rate_hz)
        if slip and window < 2:
            raise CalibrationInputError(
                f"the slip window of {slip_window_s:g} s holds {slip_window_s * rate_hz:.3g} frames at "
                f"{rate_hz:g} Hz; slip detection needs at least 2 (a longer window or no slip detection; "
                "at so low a rate, are the times in seconds?)"
            )
        # a known hierarchy is checked now, not at the first read
        self._tree_given = (
            None if parent_of is None else hierarchy_from_parents(parent_of, self.names, root=root)
        )
        self.rate_hz = float(rate_hz)
        self.start_time_s = float(start_time_s)
        self.parent_of = None if parent_of is None else dict(parent_of)
        self.root = root
        self.hierarchy_method = hierarchy_method
        self.single_axis_ratio = float(single_axis_ratio)
        self.loop_factor = float(loop_factor)
        self.false_alarms_per_hour = float(false_alarms_per_hour)
        self.n_frames = 0  # frames pushed
        self._n_summed = 0  # frames added to the statistics
        self._block_len = 1
        self._blocks: list[PairSums] = []
        self._d3 = ThirdDifferenceSums(n)
        self._flush = max(1, round(FLUSH_S * rate_hz))
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._n_pending = 0
        self._refit_every = max(1, round(REFIT_S * rate_hz))
        self._refit_at = 0  # frames summed at the last refit of the slip monitor's joints
        self._monitor = _SlipMonitor(self, window) if slip else None

    # ---------------------------------------------------------------- input
    def push(self, R_w_s: np.ndarray, p_w_s: np.ndarray, valid: np.ndarray | None = None) -> None:
        """Add one frame or a block of frames.

        Args:
            R_w_s: ``(S, 3, 3)`` or ``(F, S, 3, 3)`` rotations, sensor to world.
            p_w_s: ``(S, 3)`` or ``(F, S, 3)`` sensor positions in world, metres.
            valid: optional ``(S,)`` or ``(F, S)`` bool, False where a pose is missing;
                non-finite poses are always missing.

        Raises:
            CalibrationInputError: shapes that do not match the sensors or each other.
        """
        R, p, ok = self._checked(R_w_s, p_w_s, valid)
        if R.shape[0] == 0:
            return
        self._pending.append((R, p, ok))
        self._n_pending += R.shape[0]
        self.n_frames += R.shape[0]
        if self._n_pending >= self._flush:
            self._drain()

    def _checked(
        self, R_w_s: np.ndarray, p_w_s: np.ndarray, valid: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = len(self.names)
        R = np.asarray(R_w_s, dtype=float)
        p = np.asarray(p_w_s, dtype=float)
        single = R.ndim == 3
        if R.shape[-3:] != (n, 3, 3) or R.ndim not in (3, 4):
            raise CalibrationInputError(
                f"Expected R_w_s to have shape ({n}, 3, 3) or (frames, {n}, 3, 3), got {R.shape}"
            )
        want = (n, 3) if single else (R.shape[0], n, 3)
        if p.shape != want:
            raise CalibrationInputError(f"Expected p_w_s to have shape {want} to match R_w_s, got {p.shape}")
        if single:
            R, p = R[None], p[None]
        f = R.shape[0]
        ok = np.isfinite(R.reshape(f, n, 9)).all(axis=2) & np.isfinite(p).all(axis=2)
        if valid is not None:
            v = np.asarray(valid)
            if v.shape != want[:-1]:
                raise CalibrationInputError(f"Expected valid to have shape {want[:-1]}, got {v.shape}")
            ok &= v.reshape(f, n).astype(bool)
        if not ok.all():  # as calibration.poses.iter_chunks: no NaN reaches a product
            R = np.where(ok[:, :, None, None], R, 0.0)
            p = np.where(ok[:, :, None], p, 0.0)
        else:  # own copies: the caller may reuse its buffers
            R, p = R.copy(), p.copy()
        return R, p, ok

    def _drain(self) -> None:
        """Add the pending frames to the statistics and run the slip monitor on them."""
        if not self._pending:
            return
        if len(self._pending) == 1:
            R, p, ok = self._pending[0]
        else:
            R, p, ok = (np.concatenate(x) for x in zip(*self._pending, strict=True))
        self._pending, self._n_pending = [], 0
        self._add_to_blocks(R, p, ok)
        self._d3.add(R, p, ok)
        start = self._n_summed
        self._n_summed += R.shape[0]
        if self._monitor is not None:
            if self._n_summed - self._refit_at >= self._refit_every or not self._monitor.ready:
                self._refit_monitor()
            self._monitor.update(R, p, ok, start)

    def _add_to_blocks(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray) -> None:
        """Add frames to their blocks of :func:`calibration.hinge.block_edges`, merging when full."""
        n = len(self.names)
        buf = np.empty((R.shape[0], 3, 4 * n))
        lo, frame = 0, self._n_summed
        while lo < R.shape[0]:
            k = frame // self._block_len
            if k >= N_BLOCKS:  # one block more than allowed: merge neighbours, L doubles
                pairs = zip(self._blocks[::2], self._blocks[1::2], strict=True)  # N_BLOCKS full blocks
                self._blocks = [a.merge(b) for a, b in pairs]
                self._block_len *= 2
                continue
            while len(self._blocks) <= k:
                self._blocks.append(PairSums(n))
            hi = min(R.shape[0], lo + (k + 1) * self._block_len - frame)
            self._blocks[k].add(R[lo:hi], p[lo:hi], ok[lo:hi], buf[: hi - lo])
            frame += hi - lo
            lo = hi

    # ---------------------------------------------------------------- output
    def statistics(self) -> PairStatistics:
        """The pair statistics of every frame pushed (those of :func:`calibration.pairs.pair_statistics`)."""
        self._drain()
        n = len(self.names)
        blocks = [b.result() for b in self._blocks] or [PairSums(n).result()]
        # with the third differences, as the batch keeps them (the single-axis verdict's effect size)
        return dataclasses.replace(statistics_of_blocks(blocks, self.n_frames), third_differences=self._d3)

    def calibration(self) -> Calibration:
        """The calibration of every frame pushed, as :func:`calibration.pipeline.calibrate` gives it
        with ``keep_frame_residuals=False`` (module docstring).

        Raises:
            CalibrationError: too few frames yet, or sensors that share no usable frames.
        """
        stats = self.statistics()
        cal, _ = self._solve(stats)
        return cal

    def state(self) -> LiveState:
        """The calibration, each joint's coverage and the slip alerts so far.

        Raises:
            CalibrationError: too few frames yet, or sensors that share no usable frames.
        """
        stats = self.statistics()
        cal, sol = self._solve(stats)
        coverage = tuple(_coverage(j, sol, k) for k, j in enumerate(cal.joints))
        return LiveState(
            calibration=cal,
            coverage=coverage,
            alerts=self.alerts,
            n_frames=self.n_frames,
            time_s=self.start_time_s + (self.n_frames - 1) / self.rate_hz,
            false_alarms_per_hour=self.false_alarms_per_hour * len(cal.joints),
        )

    @property
    def nbytes(self) -> int:
        """Bytes of numpy arrays the calibrator holds (statistics, pending frames, slip monitor):
        bounded by the sensors, the rate and the options, not by the frames pushed."""
        arrays: list[np.ndarray] = []
        for sums in [*self._blocks, self._d3.sums]:
            arrays += [x for x in vars(sums).values() if isinstance(x, np.ndarray)]
        arrays.append(self._d3.self_gram)
        arrays += [x for block in self._pending for x in block]
        arrays += [x for x in self._d3.carry or ()]
        if self._monitor is not None:
            arrays += self._monitor.arrays()
        return int(sum(x.nbytes for x in arrays))

    @property
    def alerts(self) -> tuple[SlipAlert, ...]:
        """Every slip alert raised so far (frames still pending are not yet examined)."""
        return () if self._monitor is None else tuple(self._monitor.alerts)

    def slip_armed_s(self) -> dict[str, float]:
        """``{"parent-child": seconds}``: when each joint's slip monitor first had a noise model
        (could raise an alert), seconds after the first frame; joints never armed are absent."""
        if self._monitor is None:
            return {}
        names = self.names
        return {
            f"{names[a]}-{names[b]}": frame / self.rate_hz for (a, b), frame in self._monitor.armed_at.items()
        }

    def new_alerts(self) -> list[SlipAlert]:
        """The alerts raised since the last call."""
        return [] if self._monitor is None else self._monitor.take_new()

    def _solve(self, stats: PairStatistics) -> tuple[Calibration, PairSolutions]:
        """The batch pipeline's steps 2-5 on the statistics (:mod:`calibration.pipeline`)."""
        names, n = self.names, len(self.names)
        if self.n_frames < MIN_FRAMES:
            raise CalibrationError(f"calibration needs at least {MIN_FRAMES} frames, got {self.n_frames}")
        per_sensor = np.diagonal(stats.count)
        if np.max(stats.count - np.diag(per_sensor)) < MIN_FRAMES:
            raise CalibrationError(
                f"no pair of sensors has {MIN_FRAMES} frames where both poses are valid "
                f"(frames: {stats.n_frames}, most valid frames of one sensor: {int(np.max(per_sensor))})"
            )
        residual, weights = self._tree_weights(stats, *np.triu_indices(n, k=1))
        if self._tree_given is not None:
            tree = self._tree_given
        else:
            root = None if self.root is None else names.index(self.root)
            tree = spanning_tree(weights, root=root, names=names)
        par = np.array([p for p, _ in tree.joints], dtype=np.int64)
        chi = np.array([c for _, c in tree.joints], dtype=np.int64)
        sol = solve_pairs(stats, par, chi, single_axis_ratio=self.single_axis_ratio)
        too_few = [
            f"{names[p]}-{names[c]}" for k, (p, c) in enumerate(tree.joints) if sol.n_frames[k] < MIN_FRAMES
        ]
        if too_few:
            raise CalibrationError(
                f"joints with fewer than {MIN_FRAMES} frames where both sensors are valid: {too_few}"
            )
        joints = tuple(
            solved_joint(names, sol, k, sol.rms_residual, None, self.n_frames, self.single_axis_ratio)
            for k in range(len(par))
        )
        missing = stats.n_frames - per_sensor.astype(np.int64)
        loops = tuple(
            (names[a], names[b], r)
            for a, b, r in loop_candidates(residual, tree, loop_factor=self.loop_factor)
        )
        lp, lc = sol.joint_in_parent, sol.joint_in_child
        cal = Calibration(
            names=names,
            hierarchy=tree,
            hierarchy_given=self._tree_given is not None,
            joints=joints,
            residual_matrix=residual,
            loop_candidates=loops,
            lengths=tuple(segment_lengths(names, tree.joints, lp, lc)),
            placements=tuple(sensor_placements(names, tree.joints, lp, lc)),
            warnings=tuple(fit_warnings(joints, names, missing, loops, self.n_frames)),
            n_frames=self.n_frames,
            missing=missing,
            hierarchy_method=self.hierarchy_method,
        )
        return cal, sol

    def _tree_weights(
        self, stats: PairStatistics, i: np.ndarray, j: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The pairs ``(i, j)`` solved: ``(N, N)`` their rms residuals and the spanning tree's
        weights (the residuals, or the misfit's), ``inf`` for the pairs not given."""
        n = len(self.names)
        pairs = solve_pairs(stats, i, j, single_axis_ratio=self.single_axis_ratio)
        residual = np.full((n, n), np.inf)
        residual[i, j] = residual[j, i] = pairs.rms_residual
        if self.hierarchy_method != "misfit":
            return residual, residual
        noise = np.zeros((n, n))
        noise[i, j] = noise[j, i] = self._d3.noise_variance(i, j, pairs.joint_in_parent, pairs.joint_in_child)
        return residual, misfit_weights(residual, noise)

    def _refit_monitor(self) -> None:
        """Give the slip monitor the joints it follows, as fitted now (nothing while too few frames)."""
        assert self._monitor is not None
        try:
            keys, lp, lc = self._monitor_joints(self.statistics())  # called from _drain: nothing pending
        except CalibrationError:  # as the calibration's: sensors the fit cannot yet join
            return
        if not keys:
            return
        self._refit_at = self._n_summed - self._n_summed % self._refit_every  # every REFIT_S of the stream
        self._monitor.set_joints(keys, lp, lc)

    def _monitor_joints(self, stats: PairStatistics) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
        """The joints the slip monitor follows: ``[(parent, child)]`` sensor indices and their
        centres ``(J, 3)`` in the parent's and the child's frame, metres.

        The tree of :meth:`calibration` restricted to the pairs seen together for at least one
        window pair (``2 w`` frames: before that no window difference exists, so no joint could be
        tested): the spanning tree of each group of sensors those pairs connect, with the
        calibration's weights, and of a given hierarchy its joints between such pairs. A sensor
        seen for a few frames only (a marker cluster hidden at the start) has pair fits that are
        noise; in the whole tree they rearrange the joints of the sensors seen all along at every
        refit, each rearrangement restarting those joints' histories (measured on the sprint
        recording of ``studies/live_slip_real.py``: its joints armed 7.7-15.7 s after the start).
        """
        assert self._monitor is not None
        names = self.names
        known = stats.count >= 2 * self._monitor.w
        np.fill_diagonal(known, False)
        if self._tree_given is not None:
            keys = [(p, c) for p, c in self._tree_given.joints if known[p, c]]
        else:
            i, j = np.nonzero(np.triu(known))
            if not i.size:
                return [], np.zeros((0, 3)), np.zeros((0, 3))
            _, weights = self._tree_weights(stats, i, j)
            _, group = connected_components(known, directed=False)
            keys = []
            for g in np.unique(group):
                members = np.flatnonzero(group == g)
                if members.size < 2:
                    continue
                root = None
                if self.root is not None and names.index(self.root) in members:
                    root = int(np.flatnonzero(members == names.index(self.root))[0])
                sub = spanning_tree(weights[np.ix_(members, members)], root=root)
                keys += [(int(members[p]), int(members[c])) for p, c in sub.joints]
        if not keys:
            return [], np.zeros((0, 3)), np.zeros((0, 3))
        par = np.array([k[0] for k in keys], dtype=np.int64)
        chi = np.array([k[1] for k in keys], dtype=np.int64)
        sol = solve_pairs(stats, par, chi, single_axis_ratio=self.single_axis_ratio)
        return keys, sol.joint_in_parent.reshape(-1, 3), sol.joint_in_child.reshape(-1, 3)


def _coverage(joint: Joint, sol: PairSolutions, k: int) -> Coverage:
    """The rotation a joint has seen about its principal axes, and what to do (module docstring)."""
    n = float(sol.n_frames[k])
    s = sol.singular_values[k]
    v = sol.right_vectors[k]
    weak = np.square(s[3:]) / max(n, 1.0)  # w_k = 1 - sigma_k(M), ascending rotation coverage
    c = np.clip(np.sum(weak) - 2.0 * weak, 0.0, None)  # variance about each principal axis, rad^2
    axes = v[:3, 3:].T  # parent-frame halves of the weak directions
    axes = axes / np.maximum(np.linalg.norm(axes, axis=1, keepdims=True), 1e-300)
    order = np.argsort(-c, kind="stable")
    rms = np.degrees(np.sqrt(c[order]))
    axes = axes[order]

    def named(axis: np.ndarray) -> str:
        a = axis * (1.0 if axis[np.argmax(np.abs(axis))] >= 0 else -1.0)
        return f"{np.round(a, 2).tolist()} ({joint.parent} frame)"

    if joint.fit.single_axis:  # a hinge cannot turn across its axis: ask only for what it can do
        enough = bool(rms[0] >= MIN_ROTATION_DEG)
        advice = (
            f"single-axis joint, axis {named(axes[0])}: moved enough "
            "(its centre along the axis is not measured)"
            if enough
            else f"single-axis joint: move more about its axis {named(axes[0])}"
        )
    else:
        enough = bool(rms[1] >= MIN_ROTATION_DEG)
        advice = "moved enough" if enough else f"move more about axis {named(axes[1])}"
    return Coverage(
        joint=joint.name,
        rotation_rms_deg=rms,
        axes_in_parent=axes,
        condition=joint.fit.condition,
        moved_enough=enough,
        advice=advice,
    )


def _flipped(delta: np.ndarray) -> np.ndarray:
    """The window differences of the pose products (``(..., 15)``, :class:`_SlipMonitor`) of a joint
    with its parent and child swapped: ``M' = M^T``, ``v_p' = -v_c``, ``v_c' = -v_p``."""
    out = np.empty_like(delta)
    out[..., :9] = np.swapaxes(delta[..., :9].reshape(*delta.shape[:-1], 3, 3), -1, -2).reshape(
        *delta.shape[:-1], 9
    )
    out[..., 9:12] = -delta[..., 12:15]
    out[..., 12:15] = -delta[..., 9:12]
    return out


def _correlation_frames(x: np.ndarray) -> np.ndarray:
    """``(k,)`` :func:`calibration.slip_stats.correlation_frames` of each column of ``x``
    (``(n, k)``, no gaps), in one batch of FFTs."""
    n = x.shape[0]
    xc = x - x.mean(axis=0)
    fx = np.fft.rfft(xc, 2 * n, axis=0)
    num = np.fft.irfft(fx * np.conj(fx), axis=0)[:n]
    cov = num / (n - np.arange(n))[:, None]
    out = np.ones(x.shape[1])
    for k in np.flatnonzero(cov[0] > 0):
        out[k] = initial_positive_time(cov[:, k] / cov[0, k])
    return out


class _SlipMonitor:
    """The causal slip detector over the joints of the current tree (module docstring).

    Per joint and frame it keeps the pose products the window difference is affine in
    (``M = R_p^T R_c``, ``v_p = R_p^T (p_p - p_c)``, ``v_c = R_c^T (p_p - p_c)``): the last ``2 w``
    frames' values for the windows, and every :attr:`stride`-th frame's window difference of them
    for :data:`SLIP_HISTORY_S` seconds, so that the noise model is that of ``d`` with the joint as
    fitted now, whenever it was recorded. Each joint's row of the ``(J, ...)`` arrays holds its fit,
    its history and its noise model.
    """

    def __init__(self, owner: StreamingCalibrator, window: int) -> None:
        self.owner = owner
        self.w = window
        self.rate = owner.rate_hz
        # d is a mean over w frames: samples w / 8 apart hold nearly all its distribution
        self.stride = max(1, window // 8)
        self.history = max(4 * window, round(SLIP_HISTORY_S * self.rate)) // self.stride
        self.warmup = max(2, round(SLIP_WARMUP_S * self.rate) // self.stride)
        n = len(owner.names)
        # the poses of the last 2 w frames and a warm-up's history (a ring): a joint that joins the
        # tree gets its history from them, so that it arms as soon as its pair has been seen as long
        # as a joint needs to arm, not a warm-up after the tree settles (_backfill)
        self.back = 2 * window + self.warmup * self.stride
        self.ring_R = np.zeros((self.back, n, 3, 3))
        self.ring_p = np.zeros((self.back, n, 3))
        self.ring_ok = np.zeros((self.back, n), dtype=bool)
        self.ring_n = 0  # frames written to the ring since the stream's start (or a gap)
        self.R = np.zeros((0, n, 3, 3))  # held poses, the last 2 w frames up to frame end
        self.p = np.zeros((0, n, 3))
        self.ok = np.zeros((0, n), dtype=bool)
        self.end = 0  # frames examined
        self.keys: list[tuple[int, int]] = []
        self.slipped: set[int] = set()  # sensors alerted on
        self.alerts: list[SlipAlert] = []
        self.armed_at: dict[tuple[int, int], int] = {}  # joint -> first frame with a noise model
        # joints that left the tree: (hist, n_hist, quiet_until) rows, oldest first (set_joints)
        self.shelf: dict[tuple[int, int], tuple[np.ndarray, int, int]] = {}
        self.confirmed: set[frozenset[int]] = set()
        self._taken = 0
        self.ready = False
        self._rows(0)
        self._latest: tuple[np.ndarray, np.ndarray] | None = None

    def _rows(self, j: int) -> None:
        """Fresh per-joint arrays for ``j`` joints."""
        self.par = np.zeros(j, dtype=np.int64)
        self.chi = np.zeros(j, dtype=np.int64)
        self.lp = np.zeros((j, 3))
        self.lc = np.zeros((j, 3))
        self.q = np.zeros((self.R.shape[0], j, _Q))  # the held frames' products (_products)
        self.cs = np.zeros((self.R.shape[0] + 1, j, _Q))  # their running sums, from 0
        self.hist = np.zeros((j, self.history, _Q - 1))  # rings of the products' window difference
        self.nbr = np.zeros((j, j), dtype=bool)  # joints sharing a sensor
        self.n_hist = np.zeros(j, dtype=np.int64)
        self.scale = np.zeros((j, 2, 3))
        self.threshold = np.full((j, 2), np.inf)
        self.motion0 = np.full(j, np.inf)  # typical |dM| of the history (_models)
        self.quiet_until = np.full(j, -1, dtype=np.int64)  # no alert, no history, up to this frame

    def arrays(self) -> list[np.ndarray]:
        """Every array held (for :attr:`StreamingCalibrator.nbytes`)."""
        names = (
            "R",
            "p",
            "ok",
            "par",
            "chi",
            "lp",
            "lc",
            "q",
            "cs",
            "hist",
            "nbr",
            "n_hist",
            "scale",
            "threshold",
            "ring_R",
            "ring_p",
            "ring_ok",
        )
        shelved = [hist for hist, _, _ in self.shelf.values()]
        return [getattr(self, k) for k in (*names, "motion0", "quiet_until")] + shelved

    def take_new(self) -> list[SlipAlert]:
        out = self.alerts[self._taken :]
        self._taken = len(self.alerts)
        return out

    def _products(
        self,
        R: np.ndarray,
        p: np.ndarray,
        ok: np.ndarray,
        par: np.ndarray | None = None,
        chi: np.ndarray | None = None,
    ) -> np.ndarray:
        """``(F, J, 16)`` per frame and joint (the tree's, or ``par``, ``chi``): ``M`` (9), ``v_p``
        (3), ``v_c`` (3), valid (1); zero where either pose is missing."""
        par = self.par if par is None else par
        chi = self.chi if chi is None else chi
        Rp, Rc = R[:, par], R[:, chi]  # (F, J, 3, 3)
        dp = p[:, par] - p[:, chi]
        out = np.empty((R.shape[0], par.size, _Q))
        out[..., :9] = np.matmul(np.swapaxes(Rp, 2, 3), Rc).reshape(R.shape[0], par.size, 9)
        out[..., 9:12] = np.einsum("fjba,fjb->fja", Rp, dp)
        out[..., 12:15] = np.einsum("fjba,fjb->fja", Rc, dp)
        okj = ok[:, par] & ok[:, chi]
        out[..., :15] *= okj[..., None]
        out[..., 15] = okj
        return out

    def _d(self, delta: np.ndarray, lp: np.ndarray, lc: np.ndarray) -> np.ndarray:
        """``(..., J, 2, 3)`` the window difference of the residual in the parent's and the child's
        frame from that of the products (``(..., J, 15)``) and the joints (``(J, 3)`` each)."""
        dM = delta[..., :9].reshape(*delta.shape[:-1], 3, 3)
        d = np.empty((*delta.shape[:-1], 2, 3))
        # e_p = l_p + v_p - M l_c and e_c = M^T l_p + v_c - l_c: the constants drop out of d
        d[..., 0, :] = delta[..., 9:12] - np.einsum(
            "...ab,...b->...a", dM, np.broadcast_to(lc, dM.shape[:-1])
        )
        d[..., 1, :] = delta[..., 12:15] + np.einsum(
            "...ba,...b->...a", dM, np.broadcast_to(lp, dM.shape[:-1])
        )
        return d

    def set_joints(self, keys: list[tuple[int, int]], lp: np.ndarray, lc: np.ndarray) -> None:
        """Follow the joints ``keys`` (``(parent, child)`` sensor indices; a joint new to them
        starts afresh, one whose parent and child swapped, as a new root turns them, keeps its
        history), fitted at ``lp``, ``lc`` (``(J, 3)``, metres, in the parent's and the child's
        frame), and refresh every noise model with them."""
        before = {frozenset(k) for k in self.keys}
        self.confirmed |= {frozenset(k) for k in keys} & before
        if keys != self.keys:  # the tree changed: rows move, new joints start afresh
            old = {k: i for i, k in enumerate(self.keys)}
            kept = {name: getattr(self, name) for name in ("hist", "n_hist", "quiet_until")}
            self._rows(len(keys))
            # joints leaving the tree go on the shelf, with their histories, for when they return
            # (a tree whose weights are close swaps joints back and forth at refits)
            for k, key in enumerate(self.keys):
                if key not in keys and key[::-1] not in keys:
                    self.shelf.pop(key, None)
                    self.shelf[key] = (
                        kept["hist"][k].copy(),
                        int(kept["n_hist"][k]),
                        int(kept["quiet_until"][k]),
                    )
            while len(self.shelf) > max(len(keys), 1):  # the oldest first
                del self.shelf[next(iter(self.shelf))]
            fresh = []  # joints new to the tree: their history from the ring
            for i, key in enumerate(keys):
                flipped = key[::-1]
                if key in old:
                    for name, arr in kept.items():
                        getattr(self, name)[i] = arr[old[key]]
                    continue
                if flipped in old:
                    k, source = old[flipped], flipped
                    hist, n_hist, quiet = kept["hist"][k], kept["n_hist"][k], kept["quiet_until"][k]
                elif key in self.shelf or flipped in self.shelf:
                    source = key if key in self.shelf else flipped
                    hist, n_hist, quiet = self.shelf.pop(source)
                else:
                    fresh.append(i)
                    continue
                self.hist[i] = hist if source == key else _flipped(hist)
                self.n_hist[i], self.quiet_until[i] = n_hist, quiet
                if source in self.armed_at:
                    self.armed_at.setdefault(key, self.armed_at[source])
            self.keys = keys
            self.par = np.array([k[0] for k in keys], dtype=np.int64)
            self.chi = np.array([k[1] for k in keys], dtype=np.int64)
            ends = np.stack([self.par, self.chi], axis=1)  # (J, 2)
            self.nbr = (ends[:, None, :, None] == ends[None, :, None, :]).any(axis=(2, 3))
            np.fill_diagonal(self.nbr, False)
            self.q = self._products(self.R, self.p, self.ok)
            self.cs = np.concatenate([np.zeros((1, *self.q.shape[1:])), np.cumsum(self.q, axis=0)])
            self._backfill(np.array(fresh, dtype=np.int64))
        self.lp = np.asarray(lp, dtype=float).reshape(-1, 3)
        self.lc = np.asarray(lc, dtype=float).reshape(-1, 3)
        for i, key in enumerate(keys):
            if self.slipped & set(key):
                self.quiet_until[i] = _FOREVER
        self.ready = True
        self._models()

    def _backfill(self, rows: np.ndarray) -> None:
        """The histories of joints ``rows`` (new to the tree, none yet) from the poses in the ring:
        the window differences :meth:`_examine` would have kept had they been joints all along."""
        w, m = self.w, min(self.ring_n, self.back)
        if not rows.size or m < 2 * w:
            return
        at = (self.ring_n - m + np.arange(m)) % self.back
        q = self._products(self.ring_R[at], self.ring_p[at], self.ring_ok[at], self.par[rows], self.chi[rows])
        cs = np.concatenate([np.zeros((1, *q.shape[1:])), np.cumsum(q, axis=0)])
        ends = np.arange(2 * w - 1, m)
        ends = ends[(self.end - m + ends) % self.stride == 0]  # the frames the history samples
        hi, mid, lo = ends + 1, ends + 1 - w, ends + 1 - 2 * w
        after, before = cs[hi] - cs[mid], cs[mid] - cs[lo]  # (c, r, 16)
        na, nb = after[..., 15], before[..., 15]
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = after[..., :15] / na[..., None] - before[..., :15] / nb[..., None]  # (c, r, 15)
        good = (na >= w / 2) & (nb >= w / 2) & np.isfinite(delta).all(axis=2)
        for k, row in enumerate(rows):
            samples = delta[good[:, k], k][-self.history :]
            self.hist[row, : samples.shape[0]] = samples
            self.n_hist[row] = samples.shape[0]

    def update(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray, start: int) -> None:
        """Examine frames ``start .. start + len(R)`` (already validated, invalid poses zeroed)."""
        w = self.w
        if self.ok.shape[0] and self.end != start:  # a gap in the stream
            self.R, self.p, self.ok = self.R[:0], self.p[:0], self.ok[:0]
            self.q, self.cs = self.q[:0], self.cs[:1] * 0.0
            self.ring_n = 0
        at = (self.ring_n + np.arange(R.shape[0])[-self.back :]) % self.back
        self.ring_R[at], self.ring_p[at], self.ring_ok[at] = (
            R[-self.back :],
            p[-self.back :],
            ok[-self.back :],
        )
        self.ring_n += R.shape[0]
        held = self.ok.shape[0]
        new = self._products(R, p, ok)
        q = np.concatenate([self.q, new])
        # running sums of the held and the new frames' products (cs[i]: frames before q[i])
        cs = np.concatenate([self.cs, self.cs[-1] + np.cumsum(new, axis=0)])
        e0 = start - held  # frame of q[0]
        keep = 2 * w
        self.R = np.concatenate([self.R, R])[-keep:]
        self.p = np.concatenate([self.p, p])[-keep:]
        self.ok = np.concatenate([self.ok, ok])[-keep:]
        self.q = q[-keep:]
        tail = cs[-keep - 1 :]
        self.cs = tail - tail[0]  # from the first frame held on: no growth
        self.end = start + R.shape[0]
        m = q.shape[0]
        ends = np.arange(max(held, 2 * w - 1), m)  # windows ending at each new frame
        if not self.keys or not ends.size:
            return
        hi, mid, lo = ends + 1, ends + 1 - w, ends + 1 - 2 * w
        after, before = cs[hi] - cs[mid], cs[mid] - cs[lo]  # (c, J, 16)
        na, nb = after[..., 15], before[..., 15]
        with np.errstate(invalid="ignore", divide="ignore"):
            delta = after[..., :15] / na[..., None] - before[..., :15] / nb[..., None]  # (c, J, 15)
        delta[~((na >= w / 2) & (nb >= w / 2))] = np.nan
        d = self._d(delta, self.lp, self.lc)  # (c, J, 2, 3)
        frames = e0 + ends
        self._latest = (d, frames)
        # each joint's own rotation between the windows against its typical one, and the largest
        # of its neighbours' (the joints sharing a sensor with it; _motion_factor)
        turn = np.nan_to_num(np.linalg.norm(delta[..., :9], axis=2))  # (c, J) |dM|
        m0 = self.motion0
        known = np.where(np.isfinite(m0), m0, 0.0)  # a neighbour without a noise model: 0
        typical = np.fmax(m0[:, None], known[None, :])  # (J, J): the larger of j's and k's
        excess = np.maximum(turn[:, None, :] - known[None, None, :], 0.0) / typical  # (c, J, J)
        near = np.where(self.nbr, excess, 0.0).max(axis=2, initial=0.0)
        factor = self._motion_factor(np.fmax(turn / m0, near))
        self._examine(d / factor[..., None, None], factor, delta, frames, q, e0)

    def _examine(
        self, d: np.ndarray, factor: np.ndarray, delta: np.ndarray, frames: np.ndarray, q: np.ndarray, e0: int
    ) -> None:
        """Test the new ``d`` of every joint (``(c, J, 2, 3)`` at ``frames``, divided by the motion
        ``factor``, ``(c, J)``), then add the quiet ones' product differences (``(c, J, 15)``) to the
        histories."""
        ready = np.isfinite(self.threshold).all(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            z = np.linalg.norm(d / np.where(self.scale > 0, self.scale, np.inf), axis=3)  # (c, J, 2)
            over = ((z > self.threshold).any(axis=2) & ready) & (frames[:, None] > self.quiet_until)
        if over.any():
            for j in np.flatnonzero(over.any(axis=0)):
                # an alert just raised silences its sensor's joints (and quiets its neighbours)
                still = np.flatnonzero(over[:, j] & (frames > self.quiet_until[j]))
                if not still.size:
                    continue
                at = int(still[0])
                frame = int(frames[at])
                e, okj, M = self._residual(q[:, j], j)
                if self._steady(j, frame, e, okj, M, e0, float(factor[at, j])):
                    self._alert(j, z[at, j], frame, e, okj, e0)
                else:  # the joint's misfit following the motion: look again a little later
                    self.quiet_until[j] = max(self.quiet_until[j], frame + self.w // 4)
        use = (frames[:, None] > self.quiet_until) & np.isfinite(delta).all(axis=2)
        use &= (frames % self.stride == 0)[:, None]
        ci, ji = np.nonzero(use)
        if ci.size:
            rank = np.cumsum(use, axis=0)[ci, ji] - 1  # order of each sample within its joint
            self.hist[ji, (self.n_hist[ji] + rank) % self.history] = delta[ci, ji]
            counts = use.sum(axis=0)
            before = self.n_hist.copy()
            self.n_hist += counts
            if ((before < self.warmup) & (self.n_hist >= self.warmup)).any():
                self._models()

    @staticmethod
    def _motion_factor(r: np.ndarray) -> np.ndarray:
        """``sqrt(1 + r^2)``: what ``d`` is divided by (module docstring), ``r`` a window
        difference ``|dM|`` of ``R_p^T R_c`` over the joint's typical one (the median over its
        history; ``inf`` before it has a noise model: ``r = 0``)."""
        return np.sqrt(1.0 + r**2)

    def _residual(self, q: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``e`` ``(m, 2, 3)`` (the residual in the parent's and the child's frame, joint ``j`` as
        fitted now), valid ``(m,)`` and ``M`` ``(m, 3, 3)`` from the held products ``q`` (``(m, 16)``)."""
        M = q[:, :9].reshape(-1, 3, 3)
        ok = q[:, 15] > 0.5
        lp, lc = self.lp[j], self.lc[j]
        e = np.empty((q.shape[0], 2, 3))
        e[:, 0] = lp + q[:, 9:12] - M @ lc
        e[:, 1] = np.einsum("fba,b->fa", M, lp) + q[:, 12:15] - lc
        return e * ok[:, None, None], ok, M

    def _models(self) -> None:
        """Every joint's noise model from its history with the joints as fitted now.

        Each side's scale is its own (:func:`calibration.slip_stats.robust_scale` of its ``d``); the
        tail of the whitened ``z`` above its upper quartile (:func:`calibration.slip_stats.
        tail_threshold`) is pooled over every joint with its warm-up's history: in units of each
        joint's own scale the tail's shape is the recording's, and a few seconds of one joint hold
        too few independent values to bound it (module docstring).
        """
        ready = np.flatnonzero(self.n_hist >= self.warmup)
        if not ready.size:
            return
        zs, taus = [], []
        for j in ready:
            n_hist = int(self.n_hist[j])
            filled = min(n_hist, self.history)
            # the ring in time order, so that the correlation time sees neighbours as neighbours
            start = n_hist % self.history if n_hist > self.history else 0
            hist = self.hist[j, (start + np.arange(filled)) % self.history]  # (filled, 15)
            d = self._d(hist, self.lp[j], self.lc[j])  # (filled, 2, 3)
            own = np.linalg.norm(hist[:, :9], axis=1)
            self.motion0[j] = max(float(np.median(own)), 1e-12)
            d = d / self._motion_factor(own / self.motion0[j])[:, None, None]
            tau = _correlation_frames(d.reshape(filled, 6)).reshape(2, 3).max(axis=1)  # samples
            use = np.ones(filled, dtype=bool)
            for i in range(2):
                # the scale's upper confidence bound from the history's independent values: a joint
                # seconds old has few (a chi-square bound, as the tail's in tail_threshold)
                n_eff = max(filled / tau[i], 1.0)
                bound = np.sqrt(n_eff / float(chi2_ppf(1.0 - LIVE_TAIL_CONFIDENCE, n_eff)))
                self.scale[j, i] = robust_scale(d[:, i], use) * bound
                zs.append(whitened_norm(d[:, i], self.scale[j, i]))
                taus.append(tau[i])
        tau_all = float(np.median(taus))
        tests_per_hour = len(_FRAME_NAMES) * 3600.0 * self.rate / (tau_all * self.stride)
        threshold = tail_threshold(
            np.concatenate(zs),
            tests_per_hour,
            self.owner.false_alarms_per_hour,
            tau_all,
            confidence=LIVE_TAIL_CONFIDENCE,
        )
        # only a joint the tree kept over a refit raises alerts (a joint in it for one refit only is
        # a tie of its weights: a hand against a foot while neither has moved, a head against a
        # wheelchair's wheel), though its history and noise model go into the pooled tail
        ready = ready[[frozenset(self.keys[j]) in self.confirmed for j in ready]]
        self.threshold[ready] = threshold
        if np.isfinite(threshold):
            for j in ready:
                self.armed_at.setdefault(self.keys[j], self.end - 1)

    def _steady(
        self, j: int, frame: int, e: np.ndarray, ok: np.ndarray, M: np.ndarray, e0: int, factor: float
    ) -> bool:
        """Whether a jump up to ``frame`` is a step of the residual's mean that the joint's own fit
        error does not explain.

        A joint fitted from the frames so far is off by some ``dx``, and its residual then carries
        ``R_i^T A_f dx`` (O'Brien eq. 12's ``A``), which a fast movement turns into a jump of the
        window means. Over the last ``2 w`` frames, each sensor frame's residual is regressed on a
        step at its least-squares change point, a constant and those six columns; the jump stands
        when the fitted step, divided by the crossing's motion ``factor`` and whitened by the noise
        model of ``d`` (the step a window difference sees at the change point), still crosses the
        threshold, and also crosses it whitened by the white noise of the last ``2 w`` frames
        alone (a tracker whose noise grows with the distance from its source, as a magnetic one's,
        is noisier now than in the history the model was fitted to). ``e`` is ``(m, 2, 3)`` from
        frame ``e0``, ``M`` ``(m, 3, 3)`` the relative rotation ``R_p^T R_c``.
        """
        end = frame - e0 + 1
        lo = max(0, end - 2 * self.w)
        ok_w = ok[lo:end]
        m = int(ok_w.sum())
        if m < 12:
            return True  # nothing to regress on: the window test alone decides
        Mw = M[lo:end][ok_w]
        eye = np.broadcast_to(np.eye(3), Mw.shape)
        for i in range(2):
            e_i = e[lo:end, i][ok_w]
            cp = change_point(e_i, np.ones(m, dtype=bool), 0, m)
            X = np.zeros((m, 3, 12))
            X[cp:, :, 0:3] = np.eye(3)
            X[:, :, 3:6] = np.eye(3)
            # R_i^T R_p and -R_i^T R_c: (I, -M) in the parent's frame, (M^T, -I) in the child's
            X[:, :, 6:9] = eye if i == 0 else np.swapaxes(Mw, 1, 2)
            X[:, :, 9:12] = -Mw if i == 0 else -eye
            theta = np.linalg.lstsq(X.reshape(3 * m, 12), e_i.reshape(3 * m), rcond=None)[0]
            if whitened_norm(theta[None, :3] / factor, self.scale[j, i])[0] <= self.threshold[j, i]:
                continue
            # the step's own white noise now: sigma from the median second difference (robust to
            # the step, blind to smooth skin motion), over the frames either side of the change
            sigma = 1.4826 * np.median(np.abs(np.diff(e_i, n=2, axis=0)), axis=0) / np.sqrt(6.0)
            white = sigma * np.sqrt(1.0 / max(cp, 1) + 1.0 / max(m - cp, 1))
            if whitened_norm(theta[None, :3], white)[0] > self.threshold[j, i]:
                return True
        return False

    def _moved_side(self, j: int, z: np.ndarray, frame: int) -> int:
        """0 (parent) or 1 (child): which sensor of the jumping joint ``j`` moved.

        A sensor that moves by ``delta`` shifts the residual of every one of its joints by
        ``delta`` in its own frame, over the same frames: the window difference of each of its other
        joints, in its frame and at the crossing's frame, repeats joint ``j``'s; those of the other
        sensor's joints do not. Each side's evidence is the largest share of ``j``'s jump one of its
        other joints repeats (``d_k . d_j / |d_j|^2``, unit-free; the shift enters a joint's
        residual with ``+`` where the sensor is the parent, ``-`` where it is the child). A side
        without other joints (a leaf) is the moved one when the other side's evidence is below one
        half; two sides with other joints, the larger. Where that does not decide (two sensors
        only, or no valid window), the side whose frame holds the jump more significantly
        (:mod:`calibration.slip`'s rule, weak over a short window).
        """
        assert self._latest is not None
        d, frames = self._latest
        at = np.flatnonzero(frames == frame)
        evidence: list[float | None] = [None, None]
        if at.size:
            d_at = d[int(at[0])]  # (J, 2, 3)
            for side, sensor in enumerate((self.par[j], self.chi[j])):
                own = d_at[j, side]
                norm2 = float(own @ own)
                shares = []
                for k, key in enumerate(self.keys):
                    if k == j or sensor not in key:
                        continue
                    # joint k's d in this sensor's frame; the sensor's shift enters a joint's
                    # residual with + as its parent, - as its child
                    k_side = 0 if key[0] == sensor else 1
                    other = d_at[k, k_side] * (1.0 if k_side == side else -1.0)
                    if np.isfinite(other).all() and norm2 > 0:
                        shares.append(float(other @ own) / norm2)
                evidence[side] = max(shares) if shares else None
        a, b = evidence
        if a is None and b is not None and b < 0.5:
            return 0
        if b is None and a is not None and a < 0.5:
            return 1
        if a is not None and b is not None and max(a, b) >= 0.5 and a != b:
            return 0 if a > b else 1
        if a is not None and a >= 0.5 and b is None:
            return 0
        if b is not None and b >= 0.5 and a is None:
            return 1
        return int(np.argmax(np.nan_to_num(z / self.threshold[j], nan=0.0, posinf=0.0)))

    def _alert(self, j: int, z: np.ndarray, frame: int, e: np.ndarray, ok: np.ndarray, e0: int) -> None:
        names = self.owner.names
        w = self.w
        i = self._moved_side(j, z, frame)
        moved = int(self.par[j] if i == 0 else self.chi[j])
        # the change of mean within the last 2 w frames up to the crossing, in the sensor's frame
        end = frame - e0 + 1
        lo = max(0, end - 2 * w)
        e_i, ok_i = e[lo:end, i], ok[lo:end]
        cp = change_point(e_i, ok_i, 0, e_i.shape[0])
        before, after = ok_i.copy(), ok_i.copy()
        before[cp:], after[:cp] = False, False
        size = float("nan")
        if before.any() and after.any():
            size = float(np.linalg.norm(e_i[after].mean(axis=0) - e_i[before].mean(axis=0)))
        slip_frame = e0 + lo + cp
        # one slip moves every joint of its sensor, and from then on those joints' fits mix the
        # sensor's two placements (misfit that follows the motion): the sensor's joints, and the
        # joint that jumped, raise no more alerts (until the sensor is re-fixed and a new
        # calibration started); the other joints of the jumping joint's sensors stay quiet, and keep
        # the jump out of their noise models, for 2 w frames
        self.slipped.add(moved)
        for k, key in enumerate(self.keys):
            if k == j or moved in key:
                self.quiet_until[k] = _FOREVER
            elif set(key) & {int(self.par[j]), int(self.chi[j])}:
                self.quiet_until[k] = max(self.quiet_until[k], frame + 2 * w)
        self.alerts.append(
            SlipAlert(
                sensor=names[moved],
                joint=f"{names[self.par[j]]}-{names[self.chi[j]]}",
                frame=int(slip_frame),
                time_s=self.owner.start_time_s + slip_frame / self.rate,
                raised_frame=frame,
                size_m=size,
                z=float(z[i]),
                threshold=float(self.threshold[j, i]),
                false_alarms_per_hour=self.owner.false_alarms_per_hour,
            )
        )
