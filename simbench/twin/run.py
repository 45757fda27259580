"""The digital twin of a real IMU recording: simulate its readings from the optical pose, identify
what the real sensor adds, compare sample by sample, and score the orientation methods on both.

For a BROAD-layout trial (:func:`simbench.io.imu.read_broad`, with ``opt_pos`` and ``opt_quat``):

1. **Ideal readings** of the housing's optical pose through the one seam
   (:func:`simbench.twin.simulate.ideal_readings`; orientation smoothed below
   :data:`DEFAULT_CUTOFF_HZ`, positions below :data:`DEFAULT_POSITION_CUTOFF_HZ`); gaps in the
   optical data filled, and the samples within the smoothing's half-window of a gap left out of
   every comparison (:func:`simbench.twin.simulate.near_gaps`).
2. **Identification** (:mod:`simbench.twin.identify`), each step on what the earlier found: the
   gyroscope's time offset (cross-correlation), the still phases, the gyroscope's bias and noise,
   the axis misalignment ``C`` (Kabsch of the gyroscope vectors; applied to all three sensors),
   the accelerometer's time offset, bias, noise and lever arm, the magnetometer's time offset,
   hard and soft iron, local field and its gradient (robust: the disturbed samples left out) and
   noise.
3. **The twin's readings**: the ideal ones with the identified deterministic errors (time offsets,
   misalignment, lever arm, biases, hard and soft iron, the field and its gradient). Each kind is
   compared with the real one over the motion phase (BROAD's ``movement``, less the samples near
   an optical gap): R^2, rms and the difference's spectrum (:mod:`simbench.twin.compare`). Random
   noise cannot match sample by sample, so the comparison is of this deterministic twin; the
   difference's spectrum shows what is left (noise is flat; motion the smoothing removed, marker
   jitter differentiated, a latency left over sit in their bands).
4. **Orientation**: each method of :data:`METHODS` (TRIAD, the default gyro-free estimator, VQF)
   through the estimator registry on the real recording and on the twin *with* white noise of the
   identified densities (a ``numpy.random.Generator`` seeded from ``seed``), scored by BROAD's
   total error (:func:`simbench.score.score_orientation`, RMSE in degrees against ``opt_quat`` in
   ENU, the frames matching as the estimators estimate in ENU) over the same samples.

:data:`EFFECTS` can each be left out (``without``) to measure what it explains.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from calibration.rotations import matrix_to_rotvec
from simbench.errors import InputError
from simbench.estimators import DEFAULT_ORIENTATION, resolve, run_orientation
from simbench.io.imu import ImuRecording, read_broad, read_broad_pose
from simbench.orient import calibrate_magnetometers
from simbench.score import score_orientation
from simbench.twin import compare, identify
from simbench.twin.simulate import fill_gaps, ideal_readings, near_gaps, smoothing_window
from simbench.versions import software_versions

#: The orientation's smoothing cutoff, Hz: the gyroscope's R^2 over BROAD's undisturbed trials is
#: highest at 20-30 Hz (hand motion has content above the simulator's 6 Hz for BVH clips).
DEFAULT_CUTOFF_HZ = 20.0
#: The positions' cutoff, Hz: an acceleration is the position differentiated twice, and above
#: 12-15 Hz the markers' jitter outweighs the motion (BROAD's undisturbed trials).
DEFAULT_POSITION_CUTOFF_HZ = 12.0
#: The per-sample two-vector baseline of the twin's comparison ...
BASELINE = "triad"
#: ... and its gyro-aided reference.
REFERENCE = "vqf"
#: The orientation methods scored on the real recording and on the twin (issue 41): TRIAD, the
#: default gyro-free estimator, VQF.
METHODS = (BASELINE, DEFAULT_ORIENTATION, REFERENCE)
#: The sensor kinds, as the JSON names them.
KINDS = ("acc", "gyro", "mag")
#: The deterministic effects the twin identifies, each of which can be left out.
EFFECTS = ("time_offset", "misalignment", "lever_arm", "bias", "mag_time_offset", "gradient")
#: The twin predicts a method's real error when twin / real lies within this factor (issue 41).
RATIO_FACTOR = 1.5
#: Issue 41's targets for BROAD's undisturbed trials, motion phase: the twin's R^2 per kind.
R2_TARGETS = {"acc": 0.90, "gyro": 0.95, "mag": 0.95}
#: Length of the report's default window of traces, s.
WINDOW_S = 10.0


@dataclass(frozen=True)
class Identified:
    """What the recording shows about its sensor (:mod:`simbench.twin.identify`).

    Attributes:
        still: the still phases.
        time_offset_s: ``{kind: offset}``, s: the IMU's delay behind the optical pose.
        gyro_peak: the gyroscope cross-correlation's peak (unit-free).
        gyro, acc, mag: bias and noise per axis (``mag``'s bias is the still phases' mean
            residual of the field model, not applied).
        misalignment: ``(3, 3)`` ``C``, ``v_imu = C v_opt``.
        lever_arm_m: ``(3,)`` the accelerometer's position from the tracked point, IMU frame, m.
        magnetometer: the field model.
    """

    still: identify.StillPhases
    time_offset_s: dict[str, float]
    gyro_peak: float
    gyro: identify.BiasNoise
    acc: identify.BiasNoise
    mag: identify.BiasNoise
    misalignment: np.ndarray
    lever_arm_m: np.ndarray
    magnetometer: identify.MagnetometerFit

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, units in the key names."""
        fit = self.magnetometer
        return {
            "still": {
                "fraction": float(self.still.mask.mean()),
                "phases": len(self.still.runs),
                "threshold_rad_s": self.still.threshold_rad_s,
                "rule": (
                    f"the gyroscope's moving standard deviation over {identify.STILL_WINDOW_S:g} s below "
                    f"{identify.STILL_FACTOR:g} x its 5th percentile for at least {identify.STILL_MIN_S:g} s"
                ),
            },
            "time_offset_ms": {k: 1e3 * v for k, v in self.time_offset_s.items()},
            "gyro_correlation_peak": self.gyro_peak,
            "gyro_bias_rad_s": self.gyro.bias.tolist(),
            "gyro_noise_density_rad_s_per_sqrt_hz": self.gyro.noise_density.tolist(),
            "acc_bias_m_s2": self.acc.bias.tolist(),
            "acc_noise_density_m_s2_per_sqrt_hz": self.acc.noise_density.tolist(),
            "mag_noise_ut": self.mag.noise_std.tolist(),
            "misalignment_deg": identify.rotation_angle_deg(self.misalignment),
            "misalignment_rotvec_deg": np.rad2deg(matrix_to_rotvec(self.misalignment)).tolist(),
            "lever_arm_mm": (1e3 * self.lever_arm_m).tolist(),
            "hard_iron_ut": fit.hard_iron_ut.tolist(),
            "soft_iron": fit.soft_iron.tolist(),
            "field_w_ut": fit.field_w_ut.tolist(),
            "field_strength_ut": fit.strength_ut,
            "field_inclination_deg": fit.inclination_deg,
            "field_declination_deg": fit.declination_deg,
            "field_gradient_ut_per_m": fit.gradient_ut_per_m.tolist(),
            "mag_fit_rms_ut": fit.rms_ut,
            "mag_disturbed_fraction": fit.excluded_fraction,
            "mag_rank1_ratio": fit.rank1_ratio,
            "mag_direction_spread": fit.direction_spread.tolist(),
            "mag_field_determined": fit.determined,
        }


@dataclass(frozen=True)
class TwinResult:
    """A recording and its twin (module docstring).

    Attributes:
        source: the file.
        rate_hz: Hz.
        time_s: ``(F,)`` s.
        real, sim: ``{kind: (F, 3)}`` the real readings and the deterministic twin's.
        compared: ``(F,)`` the samples compared (motion, not near a gap).
        identified: what was identified.
        readings: ``{kind: {"r2", "rms", "spectrum"}}``.
        orientation: ``{method: {"real_deg", "twin_deg", "ratio"}}``.
        window_s: ``(start, end)`` of the report's traces, s.
        seed: the noise's seed.
        settings: cutoffs, effects left out.
        coverage: fractions of samples: gaps, excluded, motion, compared.
        notes: what the run noticed.
        run_time_s: s.
    """

    source: str
    rate_hz: float
    time_s: np.ndarray
    real: dict[str, np.ndarray]
    sim: dict[str, np.ndarray]
    compared: np.ndarray
    identified: Identified
    readings: dict[str, dict[str, Any]]
    orientation: dict[str, dict[str, float]]
    window_s: tuple[float, float]
    seed: int
    settings: dict[str, Any]
    coverage: dict[str, float]
    notes: tuple[str, ...] = ()
    run_time_s: float = math.nan
    versions: dict[str, str] = field(default_factory=software_versions)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN as ``None`` is left to the writer)."""
        return {
            "file": self.source,
            "rate_hz": self.rate_hz,
            "samples": int(self.time_s.size),
            "seed": self.seed,
            "window_s": list(self.window_s),
            "settings": self.settings,
            "coverage": self.coverage,
            "identified": self.identified.as_dict(),
            "readings": self.readings,
            "orientation": self.orientation,
            "notes": list(self.notes),
            "run_time_s": self.run_time_s,
            "versions": self.versions,
        }


def _shift(x: np.ndarray, time_s: np.ndarray, offset_s: float) -> np.ndarray:
    """``x`` ``(F, ...)`` at ``time_s - offset_s`` (a cubic spline through the samples; held at
    the ends): the readings of a sensor ``offset_s`` behind."""
    if offset_s == 0:
        return x
    at = np.clip(time_s - offset_s, time_s[0], time_s[-1])
    return CubicSpline(time_s, x, axis=0)(at)


def parse_window(text: str) -> tuple[float, float]:
    """``"START:END"`` (s) as two floats.

    Raises:
        InputError: not two numbers with START < END.
    """
    parts = str(text).split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start, end = float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"--window: expected START:END in seconds (e.g. 20:30), got {text!r}") from None
    if not (math.isfinite(start) and math.isfinite(end) and 0 <= start < end):
        raise InputError(f"--window: expected 0 <= START < END, got {text!r}")
    return start, end


def _window(
    time_s: np.ndarray, motion: np.ndarray, given: tuple[float, float] | None, source: str
) -> tuple[float, float]:
    last = float(time_s[-1])
    if given is not None:
        start, end = (float(x) for x in given)
        if not (0 <= start < end) or start >= last:
            raise InputError(
                f"{source}: window {start:g}:{end:g} s: expected 0 <= start < end with start within the "
                f"recording (0-{last:.1f} s)"
            )
        return start, min(end, last)
    idx = np.flatnonzero(motion)
    centre = float(time_s[idx[idx.size // 2]]) if idx.size else last / 2
    start = max(0.0, min(centre - WINDOW_S / 2, last - WINDOW_S))
    return start, min(start + WINDOW_S, last)


def _noisy(x: np.ndarray, std: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return x + std * rng.normal(size=x.shape)


def _orientation_error(
    rec: ImuRecording, method: str, evaluate: np.ndarray, calibrated: ImuRecording | None = None
) -> float:
    """The method's total error on ``rec`` over ``evaluate``, degrees. ``calibrated``: ``rec`` with
    its magnetometers calibrated already (:func:`simbench.orient.calibrate_magnetometers`), for an
    estimator that would calibrate them itself (its ``calibrate_mag``, on by default): the same
    input, the fit made once per recording rather than once per method."""
    est = resolve(method, "orientation")
    if calibrated is not None and est.defaults.get("calibrate_mag") is True:
        got = run_orientation(est, calibrated, params={"calibrate_mag": False})
    else:
        got = run_orientation(est, rec)
    scored = score_orientation(got.q_enu, rec.q_true, rec.names, evaluate)
    return scored.per_sensor[rec.names[0]]["total_deg"]


def twin(
    path: str | os.PathLike[str],
    *,
    seed: int = 0,
    window: tuple[float, float] | None = None,
    cutoff_hz: float = DEFAULT_CUTOFF_HZ,
    position_cutoff_hz: float = DEFAULT_POSITION_CUTOFF_HZ,
    without: Collection[str] = (),
    methods: Collection[str] = METHODS,
) -> TwinResult:
    """The digital twin of a BROAD-layout trial (module docstring).

    Args:
        path: the trial (HDF5: ``imu_acc``, ``imu_gyr``, ``imu_mag``, ``opt_pos``, ``opt_quat``,
            ``movement``, attribute ``sampling_rate``).
        seed: the seed of the twin's noise (``numpy.random.default_rng``).
        window: ``(start, end)`` s of the report's traces (default: :data:`WINDOW_S` about the
            middle of the motion phase).
        cutoff_hz, position_cutoff_hz: the smoothing cutoffs of orientation and position, Hz.
        without: effects of :data:`EFFECTS` left out (not identified, not applied).
        methods: the orientation methods to score (``()``: none).

    Raises:
        InputError: a file that is not such a trial (naming it and what is missing), an unknown
            effect, a window outside the recording, no still phase.
    """
    t0 = time.perf_counter()
    unknown = sorted(set(without) - set(EFFECTS))
    if unknown:
        raise InputError(f"twin: unknown effect(s) {unknown}; expected some of {list(EFFECTS)}")
    if not (isinstance(seed, int | np.integer) and not isinstance(seed, bool) and seed >= 0):
        raise InputError(f"twin: expected a seed as an integer >= 0, got {seed!r}")
    rec = read_broad(path)
    n, rate = rec.time_s.size, rec.rate_hz
    pose = read_broad_pose(path, n, rate)
    src = str(path)
    t = rec.time_s
    real = {"acc": rec.acc[:, 0], "gyro": rec.gyro[:, 0], "mag": rec.mag[:, 0]}
    notes = list(rec.notes)
    try:
        p, q, gap = fill_gaps(pose.p_w, pose.q_w)
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None
    try:
        w = max(smoothing_window(rate, cutoff_hz, n, src), smoothing_window(rate, position_cutoff_hz, n, src))
    except InputError as exc:
        raise InputError(f"{exc} (twin cutoffs)") from None
    excluded = near_gaps(gap, w // 2)
    finite = rec.valid[:, 0] & np.isfinite(real["gyro"]).all(axis=1)
    usable = ~excluded & finite
    if rec.evaluate is not None:
        motion = np.asarray(rec.evaluate, dtype=bool)
    else:
        motion = None
    # the ideal readings on the optical clock, and what a unit field or lever arm adds: one
    # playback, an accelerometer at the tracked point and one a metre along each axis
    ideal = ideal_readings(
        t,
        p,
        q,
        cutoff_hz,
        position_cutoff_hz=position_cutoff_hz,
        lever_arms_m=np.vstack([np.zeros(3), np.eye(3)]),
    )
    acc0, gyro0 = ideal.acc[:, 0], ideal.gyro
    lever0 = np.swapaxes(ideal.acc[:, 1:] - acc0[:, None], 1, 2)  # (F, axis, arm)
    unit0 = np.swapaxes(ideal.R_w_s, 1, 2)  # column j: R^T e_j, the reading of a unit field along j
    still = identify.still_phases(real["gyro"], rate, usable)
    if motion is None:
        motion = ~still.mask
        notes.append(
            "no movement mask in the file: the motion phase is every sample outside the still phases"
        )
    use = motion & usable
    if use.sum() < 2:
        raise InputError(f"{src}: no sample in motion with an optical pose to compare")
    # gyroscope: time offset, bias and noise, misalignment
    if "time_offset" in without:
        tau_g, peak = 0.0, math.nan
    else:
        tau_g, peak = identify.time_offset(real["gyro"], gyro0, rate, use)
    gyro1 = _shift(gyro0, t, tau_g)
    gyro_bn = identify.bias_and_noise(real["gyro"], gyro1, still, rate)
    gyro_bias = np.zeros(3) if "bias" in without else gyro_bn.bias
    C = (
        np.eye(3)
        if "misalignment" in without
        else identify.misalignment(real["gyro"] - gyro_bias, gyro1, use)
    )
    if "time_offset" not in without and "misalignment" not in without:
        # once more with the axes aligned (a misalignment leaks between the axes' correlations)
        tau_g, peak = identify.time_offset(real["gyro"], gyro0 @ C.T, rate, use)
        gyro1 = _shift(gyro0, t, tau_g)
        C = identify.misalignment(real["gyro"] - gyro_bias, gyro1, use)
    sim_gyro = gyro1 @ C.T + gyro_bias
    # accelerometer: time offset, bias and noise, lever arm
    tau_a = 0.0 if "time_offset" in without else identify.time_offset(real["acc"], acc0 @ C.T, rate, use)[0]
    acc1 = _shift(acc0, t, tau_a) @ C.T
    lever1 = np.einsum("ij,fjk->fik", C, _shift(lever0, t, tau_a))
    acc_bn = identify.bias_and_noise(real["acc"], acc1, still, rate)
    acc_bias = np.zeros(3) if "bias" in without else acc_bn.bias
    r = (
        np.zeros(3)
        if "lever_arm" in without
        else identify.lever_arm(real["acc"] - acc_bias - acc1, lever1, use)
    )
    sim_acc = acc1 + lever1 @ r + acc_bias
    # magnetometer: the field model at the gyroscope's offset, then at the magnetometer's own
    unit_imu = np.einsum("ij,fjk->fik", C, unit0)
    p_fit = None if "gradient" in without else p
    tau_m = tau_g
    fit = identify.magnetometer(real["mag"], _shift(unit_imu, t, tau_m), usable, p_fit)
    if "mag_time_offset" not in without and "time_offset" not in without:
        for _ in range(2):
            ideal_m = fit.predict(unit_imu, p_fit)
            tau_m = identify.time_offset(real["mag"], ideal_m, rate, use)[0]
            fit = identify.magnetometer(real["mag"], _shift(unit_imu, t, tau_m), usable, p_fit)
    sim_mag = fit.predict(_shift(unit_imu, t, tau_m), p_fit)
    mag_bn = identify.bias_and_noise(real["mag"], sim_mag, still, rate)
    ident = Identified(
        still,
        {"acc": tau_a, "gyro": tau_g, "mag": tau_m},
        peak,
        dataclasses.replace(gyro_bn, bias=gyro_bias),
        dataclasses.replace(acc_bn, bias=acc_bias),
        mag_bn,
        C,
        C @ r,
        fit,
    )
    sim = {"acc": sim_acc, "gyro": sim_gyro, "mag": sim_mag}
    noise = {"acc": acc_bn, "gyro": gyro_bn, "mag": mag_bn}
    readings: dict[str, dict[str, Any]] = {}
    for kind in KINDS:
        readings[kind] = {
            "r2": compare.r2(real[kind], sim[kind], use),
            "r2_noise_ceiling": compare.r2_ceiling(real[kind], noise[kind].noise_std, use),
            "rms": compare.rms(real[kind], sim[kind], use),
            "unit": {"acc": "m/s^2", "gyro": "rad/s", "mag": "uT"}[kind],
            "spectrum": compare.spectrum_summary(real[kind] - sim[kind], rate, use),
        }
    undisturbed = use & fit.inliers
    readings["mag"]["r2_undisturbed"] = compare.r2(real["mag"], sim["mag"], undisturbed)
    readings["mag"]["undisturbed_fraction"] = float(undisturbed.sum() / use.sum())
    # orientation: the real recording and the noisy twin, scored over the same samples
    rng = np.random.default_rng(seed)
    noisy = {
        "acc": _noisy(sim_acc, acc_bn.noise_std, rng),
        "gyro": _noisy(sim_gyro, gyro_bn.noise_std, rng),
        "mag": _noisy(sim_mag, mag_bn.noise_std, rng),
    }
    twin_rec = dataclasses.replace(
        rec,
        acc=noisy["acc"][:, None],
        gyro=noisy["gyro"][:, None],
        mag=noisy["mag"][:, None],
        valid=np.ones_like(rec.valid),
        source=f"twin of {src}",
        notes=(),
    )
    orientation = {}
    # each recording's magnetometers calibrated once, for every method that calibrates them
    real_cal, twin_cal = (calibrate_magnetometers(r)[0] if methods else None for r in (rec, twin_rec))
    for method in methods:
        real_deg = _orientation_error(rec, method, use, real_cal)
        twin_deg = _orientation_error(twin_rec, method, use, twin_cal)
        orientation[method] = {"real_deg": real_deg, "twin_deg": twin_deg, "ratio": twin_deg / real_deg}
    coverage = {
        "optical_gap_fraction": float(gap.mean()),
        "excluded_fraction": float(excluded.mean()),
        "motion_fraction": float(motion.mean()),
        "motion_excluded_fraction": float((motion & ~usable).sum() / max(int(motion.sum()), 1)),
        "compared_fraction": float(use.mean()),
    }
    settings = {
        "cutoff_hz": cutoff_hz,
        "position_cutoff_hz": position_cutoff_hz,
        "smoothing_window_frames": w,
        "gravity_m_s2": 9.81,
        "without": sorted(without),
        "methods": list(methods),
        "r2": "1 - sum |real - sim|^2 / sum |real - mean(real)|^2 over the compared samples, axes pooled",
    }
    return TwinResult(
        source=src,
        rate_hz=rate,
        time_s=t,
        real=real,
        sim=sim,
        compared=use,
        identified=ident,
        readings=readings,
        orientation=orientation,
        window_s=_window(t, use, window, src),
        seed=int(seed),
        settings=settings,
        coverage=coverage,
        notes=tuple(notes),
        run_time_s=time.perf_counter() - t0,
    )


#: Why a kind's R^2 can miss its target, by what the measurements of BROAD's trials showed: the
#: effects the twin does not model.
LEFT_OUT = {
    "acc": "marker jitter differentiated twice (the positions' cutoff trades it against motion the "
    "smoothing removes), and accelerations the optical pose does not see (taps, vibration)",
    "gyro": "marker jitter differentiated (the orientation's cutoff trades it against fast motion the "
    "smoothing removes)",
    "mag": "a field disturbance that moves with the sensor or is not linear in position (a magnet near "
    "the path or attached), the optical orientation's own error (0.5 deg is 0.4 uT of a 44 uT field), "
    "and the magnetometer's sample-and-hold (29 % of BROAD's magnetometer samples repeat the previous one)",
}


#: A twin further than this below its noise ceiling leaves more than the noise unexplained.
NOISE_GAP = 0.01


def targets(result: TwinResult) -> dict[str, dict[str, Any]]:
    """Each kind's R^2 against :data:`R2_TARGETS`: ``{kind: {"target", "r2", "met", "why"}}``,
    ``why`` for a miss: the white noise when the noise ceiling itself is below the target (the
    motion moves the reading little), otherwise the effects :data:`LEFT_OUT`."""
    out = {}
    for kind, target in R2_TARGETS.items():
        r = result.readings[kind]
        met = bool(r["r2"] >= target)
        if met:
            why = None
        elif r["r2_noise_ceiling"] < target:
            why = (
                f"the sensor's white noise: a twin exact but for it reaches R^2 {r['r2_noise_ceiling']:.3f} "
                "(the motion moves this reading little)"
            )
            if r["r2"] < r["r2_noise_ceiling"] - NOISE_GAP:
                why += f"; the {r['r2_noise_ceiling'] - r['r2']:.3f} below that is {LEFT_OUT[kind]}"
        else:
            why = f"left out: {LEFT_OUT[kind]}"
        out[kind] = {"target": target, "r2": r["r2"], "met": met, "why": why}
    return out


def summary(result: TwinResult) -> dict[str, Any]:
    """The figures of a twin the validation report shows (JSON-ready)."""
    d = result.as_dict()
    ident = d["identified"]
    keep = (
        "time_offset_ms",
        "misalignment_deg",
        "lever_arm_mm",
        "gyro_bias_rad_s",
        "gyro_noise_density_rad_s_per_sqrt_hz",
        "acc_bias_m_s2",
        "acc_noise_density_m_s2_per_sqrt_hz",
        "mag_noise_ut",
        "hard_iron_ut",
        "field_strength_ut",
        "field_inclination_deg",
        "mag_disturbed_fraction",
        "mag_field_determined",
    )
    return {
        "file": Path(d["file"]).name,
        "readings": {
            k: {x: v[x] for x in ("r2", "r2_noise_ceiling", "rms", "unit")} for k, v in d["readings"].items()
        },
        "targets": targets(result),
        "identified": {k: ident[k] for k in keep},
        "orientation": d["orientation"],
        "coverage": d["coverage"],
        "seed": d["seed"],
        "run_time_s": d["run_time_s"],
    }
