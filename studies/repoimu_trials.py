"""The default gyro-free estimator on RepoIMU's T-stick trials, against TRIAD and VQF (issue 43).

    .venv/bin/python studies/repoimu_trials.py --data DIR [--json studies/results/repoimu_trials.json]
        [--only NAME ...] [--pattern 'Pendulum_*.csv']

RepoIMU (Szczesna et al. 2016, "Reference data set for accuracy evaluation of orientation
estimation algorithms for inertial motion capture systems", ICCVG, doi 10.1007/978-3-319-46418-3_45;
github.com/agnieszkaszczesna/RepoIMU): a hand-held T-shaped stick with an Xsens MTi IMU at 100 Hz
and Vicon markers, 28 trials of about 90 s (and a static one, left out). ``--data`` is the folder
of its ``TStick_*.csv`` files: ``;``-separated, two header lines, columns time (s), the Vicon
quaternion W X Y Z (relative to the start: identity at the first sample), the IMU's accelerometer
(m/s^2), gyroscope (rad/s) and magnetometer (normalised, about 1) X Y Z. The files stay outside
the repository; this reader stays here (one dataset's layout, not a format simbench offers).
``--pattern 'Pendulum_*.csv'`` runs the dataset's other part (a three-segment pendulum, an IMU and
markers on each segment, about 36 s a trial, the same layout), each segment on its own.

**Alignment** (the same for every method, from the optical truth and the raw readings only,
never from an estimate, so it favours none): the truth is ``R_enu_imu(t) = A Q(t) B`` with ``Q``
the file's quaternion and two unknown constant rotations.

- ``B`` (Vicon body to IMU axes): the IMU's gyroscope against the body-frame angular velocity of
  ``Q`` (central differences), Kabsch over every sample (:func:`simbench.twin.identify.misalignment`).
- ``A`` (Vicon world to ENU): up is the mean over the trial of the accelerometer rotated into the
  Vicon world by ``Q B`` (the linear acceleration's mean is the change of velocity over the
  trial's length: nil); the field is the least-squares ``f`` of ``m(t) = (Q B)^T f + h`` with a
  constant sensor-frame offset ``h`` (the magnetometer's hard iron) -- linear in ``(f, h)``; north
  is ``f``'s horizontal part.

The clocks agree (the gyroscope against the optical rate, :func:`simbench.twin.identify.time_offset`:
reported per trial, a few ms). Each trial goes through what ``simbench orient`` does (the
magnetometer calibrated from the recording), then each method; the default also without the
calibration, and TRIAD on the raw readings (issue 43's "plain TRIAD", the denominator of the
ratio). Errors with BROAD's definitions over every sample.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.estimators import DEFAULT_ORIENTATION as DEFAULT_METHOD
from simbench.io.imu import ImuRecording
from simbench.orient import calibrate_magnetometers, describe_fit, estimate, input_warnings
from simbench.score import score_orientation
from simbench.twin.identify import misalignment, time_offset

METHODS = (DEFAULT_METHOD, "triad", "vqf")


def read_repoimu(path: Path) -> tuple[ImuRecording, np.ndarray]:
    """One RepoIMU CSV (module docstring): the recording (no reference yet) and ``Q`` ``(F, 4)``."""
    d = np.genfromtxt(path, delimiter=";", skip_header=2)
    if d.ndim != 2 or d.shape[1] < 14:
        raise ValueError(f"{path}: expected 14 ';'-separated columns after 2 header lines, got {d.shape}")
    d = d[:, :14]
    t = d[:, 0]
    rate = 1.0 / float(np.median(np.diff(t)))
    acc, gyro, mag = d[:, 5:8], d[:, 8:11], d[:, 11:14]
    valid = np.isfinite(d[:, 5:14]).all(axis=1) & np.any(acc != 0, axis=1) & np.any(mag != 0, axis=1)
    rec = ImuRecording(
        names=("imu",),
        time_s=t - t[0],
        acc=acc[:, None],
        gyro=gyro[:, None],
        mag=mag[:, None],
        valid=valid[:, None],
        q_true=None,
        evaluate=None,
        rate_hz=rate,
        source=str(path),
    )
    return rec, d[:, 1:5]


def matrices(q: np.ndarray) -> np.ndarray:
    """``(F, 3, 3)`` of quaternions ``(F, 4)``; NaN where a quaternion is missing (NaN or zero:
    the markers lost)."""
    ok = np.isfinite(q).all(axis=1) & (np.linalg.norm(np.nan_to_num(q), axis=1) > 0.5)
    out = np.full((q.shape[0], 3, 3), np.nan)
    out[ok] = quat_to_matrix(q[ok])
    return out


def quats(R: np.ndarray) -> np.ndarray:
    """``(F, 4)`` of rotation matrices ``(F, 3, 3)``; NaN where they are."""
    ok = np.isfinite(R).all(axis=(1, 2))
    out = np.full((R.shape[0], 4), np.nan)
    out[ok] = matrix_to_quat(R[ok])
    return out


def body_rate(R: np.ndarray, rate_hz: float) -> np.ndarray:
    """``(F, 3)`` the body-frame angular velocity of ``R`` ``(F, 3, 3)``, rad/s (central
    differences, NaN at the ends)."""
    dR = (R[2:] - R[:-2]) * (rate_hz / 2.0)
    W = np.einsum("fji,fjk->fik", R[1:-1], dR)
    w = np.full((R.shape[0], 3), np.nan)
    w[1:-1] = 0.5 * np.c_[W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]]
    return w


@dataclasses.dataclass(frozen=True)
class Alignment:
    """``A`` (Vicon world to ENU), ``B`` (Vicon body to IMU axes), the clocks' offset (s), the
    gyroscope's residual against the optical rate (rad/s rms) and the field's fit residual
    (fraction of its strength)."""

    A: np.ndarray
    B: np.ndarray
    offset_s: float
    gyro_residual: float
    field_residual: float


def align(rec: ImuRecording, q_vicon: np.ndarray) -> Alignment:
    """The two constant rotations of the module docstring, from the trial itself."""
    Q = matrices(q_vicon)
    acc, gyro, mag = rec.acc[:, 0], rec.gyro[:, 0], rec.mag[:, 0]
    use = rec.valid[:, 0] & np.isfinite(Q).all(axis=(1, 2))
    wb = body_rate(Q, rec.rate_hz)
    C = misalignment(gyro, wb, use)  # gyro ~ C wb: C = R_imu_body
    B = C.T
    norm = np.linalg.norm
    offset, _ = time_offset(
        np.repeat(norm(gyro, axis=1)[:, None], 3, 1), np.repeat(norm(wb, axis=1)[:, None], 3, 1), rec.rate_hz
    )
    ok = use & np.isfinite(wb).all(axis=1)
    resid = gyro[ok] - wb[ok] @ C.T
    resid = resid - resid.mean(axis=0)  # the gyroscope's bias is not the alignment's
    R = Q @ B  # R_w_imu, Vicon world
    up = np.mean(np.einsum("fij,fj->fi", R[use], acc[use]), axis=0)
    up /= norm(up)
    # m = R^T f + h: rows [R^T | I], normal equations summed over the samples
    J = np.concatenate(
        [np.transpose(R[use], (0, 2, 1)), np.broadcast_to(np.eye(3), (int(use.sum()), 3, 3))], 2
    )
    N = np.einsum("fki,fkj->ij", J, J)
    x = np.linalg.solve(N, np.einsum("fki,fk->i", J, mag[use]))
    f, h = x[:3], x[3:]
    field_res = norm(mag[use] - np.einsum("fji,j->fi", R[use], f) - h, axis=1)
    north = f - (f @ up) * up
    north /= norm(north)
    A = np.vstack([np.cross(north, up), north, up])  # rows: east, north, up in Vicon world
    return Alignment(
        A,
        B,
        float(offset),
        float(np.sqrt(np.mean(resid**2))),
        float(np.sqrt(np.mean(field_res**2)) / norm(f)),
    )


def truth(q_vicon: np.ndarray, al: Alignment) -> np.ndarray:
    """``(F, 1, 4)`` ``R_enu_imu`` = ``A Q B``."""
    return quats(al.A @ matrices(q_vicon) @ al.B)[:, None]


def scored(run_q: np.ndarray, rec: ImuRecording) -> dict[str, float]:
    return score_orientation(run_q, rec.q_true, rec.names, rec.evaluate).per_sensor["imu"]


def trial(path: Path) -> dict:
    """Every figure of one trial."""
    raw, q_vicon = read_repoimu(path)
    al = align(raw, q_vicon)
    raw = dataclasses.replace(raw, q_true=truth(q_vicon, al))
    gyro = np.linalg.norm(raw.gyro[:, 0], axis=1)
    cal, fits = calibrate_magnetometers(raw)
    row: dict = {
        "samples": int(raw.time_s.size),
        "gyro_p90_rad_s": float(np.percentile(gyro, 90)),
        "alignment": {
            "clock_offset_s": al.offset_s,
            "gyro_residual_rad_s": al.gyro_residual,
            "field_residual": al.field_residual,
            "body_to_imu_deg": float(np.rad2deg(np.arccos(np.clip((np.trace(al.B) - 1) / 2, -1, 1)))),
        },
        "mag_fit": describe_fit(fits["imu"]),
        "input_warnings": list(input_warnings(raw, builtin=True)),
        "notes": list(cal.notes),
    }
    methods = {}
    seconds = {}
    for method in METHODS:
        t0 = time.process_time()
        run = estimate(cal, method)
        seconds[method] = time.process_time() - t0
        methods[method] = scored(run.q_enu, cal)
        if method == DEFAULT_METHOD:
            row["warnings"] = list(run.warnings)
    methods["triad_raw"] = scored(estimate(raw, "triad").q_enu, raw)
    run = estimate(raw, DEFAULT_METHOD)
    methods[f"{DEFAULT_METHOD}_no_mag_cal"] = scored(run.q_enu, raw)
    row["methods"] = methods
    row["cpu_s"] = seconds
    d = methods[DEFAULT_METHOD]["total_deg"]
    row["ratio_to_triad"] = d / methods["triad_raw"]["total_deg"]
    row["ratio_to_triad_calibrated"] = d / methods["triad"]["total_deg"]
    row["mag_cal_ratio"] = d / methods[f"{DEFAULT_METHOD}_no_mag_cal"]["total_deg"]
    row["mechanism"] = mechanism(raw, q_vicon, al)
    return row


def mechanism(rec: ImuRecording, q_vicon: np.ndarray, al: Alignment) -> dict[str, float]:
    """What the truth says of the trial's motion: the sustained sensor-frame acceleration (the
    accelerometer less gravity rotated by the truth, its mean over each 2 s window: median and
    90th percentile of the windows' norms, m/s^2; the same in the world frame), and the fraction
    of samples whose optical rate (in the IMU's axes) is beyond the gyroscope's largest reading
    on some axis (a gyroscope that clips; the optical rate is then the motion's)."""
    R = matrices(rec.q_true[:, 0])  # R_enu_imu
    acc = rec.acc[:, 0]
    g = float(np.median(np.linalg.norm(acc, axis=1)))
    lin_s = acc - g * R[:, 2, :]  # a - R^T (0, 0, g)
    lin_w = np.einsum("fij,fj->fi", R, lin_s)
    k = round(2.0 * rec.rate_hz)
    n = lin_s.shape[0] // k

    def windows(x: np.ndarray) -> np.ndarray:
        w = np.linalg.norm(np.nanmean(x[: n * k].reshape(n, k, 3), axis=1), axis=1)
        return w[np.isfinite(w)]  # windows where the markers were never lost: all of them there

    wb = body_rate(matrices(q_vicon), rec.rate_hz) @ al.B  # IMU axes
    top = np.max(np.abs(rec.gyro[:, 0]), axis=0)
    beyond = np.any(np.abs(wb) > top, axis=1)
    return {
        "sensor_acc_2s_median_m_s2": float(np.median(windows(lin_s))),
        "sensor_acc_2s_p90_m_s2": float(np.percentile(windows(lin_s), 90)),
        "world_acc_2s_median_m_s2": float(np.median(windows(lin_w))),
        "gyro_beyond_range_fraction": float(np.mean(beyond)),
        "gyro_range_rad_s": float(np.max(top)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, help="folder of RepoIMU's TStick_*.csv")
    parser.add_argument("--json", metavar="OUT")
    parser.add_argument("--only", nargs="*", help="trial names (file stems) to run")
    parser.add_argument("--pattern", default="TStick_*.csv", help="the trials' file names (glob)")
    args = parser.parse_args()
    paths = sorted(p for p in Path(args.data).glob(args.pattern) if "Static" not in p.stem)
    if args.only:
        paths = [p for p in paths if p.stem in args.only]
    if not paths:
        raise SystemExit(f"{args.data}: no {args.pattern} trials")
    results = {}
    d = DEFAULT_METHOD
    print(
        f"{'trial':<26}{'gyro90':>7}{d:>10}{'head':>7}{'incl':>7}{'TRIAD':>8}{'head':>7}{'incl':>7}"
        f"{'vqf':>7}{'xTRIAD':>8}{'magcal':>8}"
    )
    for path in paths:
        row = trial(path)
        results[path.stem] = row
        m = row["methods"]
        print(
            f"{path.stem.split('_', 1)[1][:25]:<26}{row['gyro_p90_rad_s']:>7.2f}"
            + "".join(
                f"{m[d][k]:>{w}.2f}"
                for k, w in (("total_deg", 10), ("heading_deg", 7), ("inclination_deg", 7))
            )
            + "".join(
                f"{m['triad_raw'][k]:>{w}.2f}"
                for k, w in (("total_deg", 8), ("heading_deg", 7), ("inclination_deg", 7))
            )
            + f"{m['vqf']['total_deg']:>7.2f}{row['ratio_to_triad']:>8.2f}{row['mag_cal_ratio']:>8.2f}",
            flush=True,
        )
    ratios = np.array([r["ratio_to_triad"] for r in results.values()])
    mag = np.array([r["mag_cal_ratio"] for r in results.values()])
    summary = {
        "trials": int(ratios.size),
        "better_than_triad": int(np.sum(ratios < 1)),
        "median_ratio": float(np.median(ratios)),
        "max_ratio": float(np.max(ratios)),
        "mag_cal_worse_by_5pct": int(np.sum(mag > 1.05)),
        "max_mag_cal_ratio": float(np.max(mag)),
    }
    print(
        f"\n{ratios.size} trials: {d} beats TRIAD on {summary['better_than_triad']}, median "
        f"{summary['median_ratio']:.2f} x, max {summary['max_ratio']:.2f} x; magnetometer calibration "
        f"worse by > 5 % on {summary['mag_cal_worse_by_5pct']} (max {summary['max_mag_cal_ratio']:.2f} x)"
    )
    if args.json:
        Path(args.json).write_text(json.dumps({"summary": summary, "trials": results}, indent=1) + "\n")


if __name__ == "__main__":
    main()
