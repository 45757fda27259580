"""Issue 43's first failure, simulated: a hand-held stick swung round fast with the IMU away from
the wrist. The rotation itself makes a sustained acceleration in the sensor frame (centripetal,
toward the wrist) that averages out in the world frame, so the default's speed prior does not see
it, and the default was worse than plain TRIAD (65.4 vs 62.5 degrees on seed 0, 0.2 m; worse on
3 of the 15 seeds and levers below). The default now finds that acceleration
(:func:`calibration.orientation.rotation_acceleration`), removes it before its fit and says so."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from calibration.rotations import quat_to_matrix, rotvec_to_matrix
from simbench.io.imu import ImuRecording
from simbench.orient import estimate
from simbench.score import score_orientation
from tests.helpers import stick_recording, stick_total_deg


def swung_stick(seed: int, lever_m: float, duration_s: float = 60.0, rate: float = 100.0) -> ImuRecording:
    """A stick held at the wrist, its IMU ``lever_m`` along it, swung round about one axis of the
    stick's frame (perpendicular to it) at 5 rad/s +-30 % (a 10 s cycle), with a random 1 rad/s
    RMS wobble; the wrist wanders by 5 cm. Steady field (48 uT, 66 degrees), acc noise 0.05 m/s^2,
    field 0.3 uT. Simulated at 10 times the rate, the acceleration by differences of positions."""
    rng = np.random.default_rng(seed)
    sub = 10
    n = int(duration_s * rate)
    fine_rate = rate * sub
    t = np.arange(n * sub) / fine_rate
    spin = 5.0 * (1 + 0.3 * np.sin(2 * np.pi * 0.1 * t + rng.uniform(0, 6)))
    wobble = gaussian_filter1d(rng.normal(size=(t.size, 3)), 0.15 * fine_rate, axis=0)
    wobble /= np.sqrt(np.mean(np.sum(wobble**2, axis=1)))
    w = spin[:, None] * np.array([0.0, 0.0, 1.0]) + wobble  # body rate, rad/s
    step = rotvec_to_matrix(w / fine_rate)
    R = np.empty((t.size, 3, 3))
    R[0] = rotvec_to_matrix(rng.normal(size=3) * 0.5)
    for i in range(1, t.size):
        R[i] = R[i - 1] @ step[i]
    wrist = gaussian_filter1d(rng.normal(size=(t.size, 3)), 0.5 * fine_rate, axis=0)
    wrist *= 0.05 / wrist.std(axis=0)
    p = wrist + R @ np.array([lever_m, 0.0, 0.0])
    a = np.gradient(np.gradient(p, 1 / fine_rate, axis=0), 1 / fine_rate, axis=0)
    R, a, w = R[::sub], a[::sub], w[::sub]
    return stick_recording(R, a, w, rng, rate, "swung stick")


def test_the_swung_stick_is_the_issues_case():
    """Gyro 90th percentile in the issue's 4.5-7.3 rad/s; the field steady (strength spread
    < 1 %); the rotation's acceleration sustained in the sensor frame (5 s means 2-4 m/s^2, as
    measured on the real trials: 1.9-4.3) and small in the world frame."""
    rec = swung_stick(0, 0.2)
    rate = np.linalg.norm(rec.gyro[:, 0], axis=1)
    assert 4.5 <= np.percentile(rate, 90) <= 7.3
    strength = np.linalg.norm(rec.mag[:, 0], axis=1)
    assert np.std(strength) / np.mean(strength) < 0.01
    R = quat_to_matrix(rec.q_true[:, 0])
    linear_s = rec.acc[:, 0] - np.einsum("fji,j->fi", R, [0.0, 0.0, 9.81])
    linear_w = np.einsum("fij,fj->fi", R, linear_s)
    window = int(5 * rec.rate_hz)
    means_s = np.linalg.norm(linear_s.reshape(-1, window, 3).mean(axis=1), axis=1)
    means_w = np.linalg.norm(linear_w.reshape(-1, window, 3).mean(axis=1), axis=1)
    assert 2.0 <= np.median(means_s) <= 6.0 and np.median(means_w) < 0.3 * np.median(means_s)


def test_the_default_is_never_worse_than_triad_on_a_swung_stick():
    """Seed 0, 0.2 m (measured 31.1 vs TRIAD 64.6 degrees); the warning says what was found and
    done."""
    rec = swung_stick(0, 0.2)
    run = estimate(rec, "skeleton")
    total = score_orientation(run.q_enu, rec.q_true, rec.names).per_sensor["stick"]["total_deg"]
    assert total <= stick_total_deg(rec, "triad")
    assert len(run.warnings) == 1 and run.warnings[0].startswith(
        "stick: a sustained acceleration in the sensor"
    )
    assert "subtracted from the accelerometer" in run.warnings[0]


@pytest.mark.slow
@pytest.mark.parametrize("lever_m", [0.2, 0.3, 0.4])
@pytest.mark.parametrize("seed", range(5))
def test_the_default_is_never_worse_than_triad_on_every_swung_stick(seed: int, lever_m: float):
    """Seeds 0-4, levers 0.2-0.4 m: measured 0.48-0.85 x TRIAD (before: 0.87-1.06)."""
    rec = swung_stick(seed, lever_m)
    assert stick_total_deg(rec, "skeleton") <= stick_total_deg(rec, "triad")
