"""A sensor on a lever (issue 43): the acceleration of rotation about a centre away from the sensor,
fitted to an orientation estimate's own rates (:mod:`calibration.orientation.lever`), removed only
where the refit from the corrected estimate agrees."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

import calibration.orientation.lever as lever
from calibration.rotations import matrix_to_quat, quat_to_matrix, rotvec_to_matrix
from simbench.io.imu import ImuRecording
from simbench.orient import estimate
from simbench.score import score_orientation
from tests.helpers import stick_recording, stick_total_deg


def swinging_stick(seed: int, lever_m: float, duration_s: float = 60.0, rate: float = 100.0) -> ImuRecording:
    """A stick held horizontally at the wrist, its IMU ``lever_m`` along it (sensor x), swung about
    the vertical back and forth and round, as on RepoIMU's test 7 (measured there: the rate 90-97 %
    about the vertical, 2.4-3.2 rad/s RMS, its spectrum's median at 0.19-0.26 Hz, the stick within
    6-9 degrees RMS of horizontal): the yaw rate a Gaussian-smoothed (0.6 s) random process of
    3 rad/s RMS, a horizontal tilt wobble of 8 degrees RMS (0.3 s smoothing), the wrist wandering
    by 5 cm. Steady field (48 uT, 66 degrees), acc noise 0.05 m/s^2, field 0.3 uT, no gyroscope;
    simulated at 10 times the rate, the acceleration by differences of positions. With 0.28 m the
    truth's sustained sensor-frame acceleration is 1.8-2.5 m/s^2 (2 s means), TRIAD 42-47 degrees
    off and the default 1.10-1.28 x TRIAD (seeds 0-2), as on 07_1-07_3 (1.7-3.3 m/s^2, 43-60
    degrees, 1.04-1.14 x)."""
    rng = np.random.default_rng(seed)
    sub = 10
    n = int(duration_s * rate)
    fine = rate * sub
    yaw_rate = gaussian_filter1d(rng.normal(size=n * sub), 0.6 * fine)
    yaw = np.cumsum(yaw_rate * 3.0 / yaw_rate.std()) / fine
    tilt = gaussian_filter1d(rng.normal(size=(n * sub, 3)), 0.3 * fine, axis=0)
    tilt[:, 2] = 0.0
    tilt *= np.deg2rad(8.0) / tilt[:, :2].std()
    R = rotvec_to_matrix(yaw[:, None] * np.array([0.0, 0.0, 1.0])) @ rotvec_to_matrix(tilt)
    wrist = gaussian_filter1d(rng.normal(size=(n * sub, 3)), 0.5 * fine, axis=0)
    wrist *= 0.05 / wrist.std(axis=0)
    p = wrist + R @ np.array([lever_m, 0.0, 0.0])
    a = np.gradient(np.gradient(p, 1 / fine, axis=0), 1 / fine, axis=0)
    R, a = R[::sub], a[::sub]
    return stick_recording(R, a, None, rng, rate, "swinging stick")


def test_the_lever_is_recovered_from_true_orientations():
    """From the true orientation sequence, the fitted lever is the simulated one (0.28 m along x)
    within 3 of its standard deviations and 1 cm, and the test fires."""
    rec = swinging_stick(0, 0.28)
    fit = lever.fit_lever(rec.acc[:, 0], rec.q_true[:, 0], 9.81, rec.rate_hz)
    sd = np.sqrt(np.diag(fit.cov))
    assert np.all(np.abs(fit.r_m - [0.28, 0.0, 0.0]) <= np.maximum(3 * sd, 1e-3))
    assert np.linalg.norm(fit.r_m - [0.28, 0.0, 0.0]) < 0.01
    assert fit.statistic > 100


def test_no_lever_from_a_sensor_turning_about_itself():
    """The same motion with the sensor at the centre of rotation (lever 0): the fit does not
    fire (its statistic under the 1e-3 chi-square quantile, 16.3)."""
    rec = swinging_stick(1, 0.0)
    fit = lever.fit_lever(rec.acc[:, 0], rec.q_true[:, 0], 9.81, rec.rate_hz)
    assert fit.statistic < 16.3


def test_a_settled_lever_is_removed_and_one_that_moves_is_not():
    """First estimate: the truth tilted by a wandering 3 degrees RMS (1 s smoothing). An
    estimator that returns the truth whatever it is given: the refit agrees and explains the
    accelerometer better, the truth is kept; one that returns another motion: its refit explains
    the accelerometer worse, the first estimate is kept."""
    rec = swinging_stick(2, 0.3, duration_s=20.0)
    other = swinging_stick(3, 0.3, duration_s=20.0)
    wander = gaussian_filter1d(np.random.default_rng(9).normal(size=(rec.acc.shape[0], 3)), 100.0, axis=0)
    wander *= np.deg2rad(3.0) / np.sqrt(np.mean(np.sum(wander**2, axis=1)))
    tilt = rotvec_to_matrix(wander) @ quat_to_matrix(rec.q_true[:, 0])
    first = matrix_to_quat(tilt)[:, None]
    q, found = lever.lever_compensated(rec.acc, first, [0], 9.81, rec.rate_hz, lambda _a, s: rec.q_true[:, s])
    assert len(found) == 1 and found[0].applied and found[0].explains
    assert np.array_equal(q, rec.q_true)
    q, found = lever.lever_compensated(
        rec.acc, first, [0], 9.81, rec.rate_hz, lambda _a, s: other.q_true[:, s]
    )
    assert len(found) == 1 and not found[0].applied and np.array_equal(q, first)
    assert not found[0].explains


def test_a_recording_without_a_lever_is_unchanged(monkeypatch):
    """The same swings with the sensor at the centre of rotation: the default's estimate is the
    one made without the lever step, bit for bit, and there is no lever warning."""
    rec = swinging_stick(1, 0.0)
    run = estimate(rec, "skeleton")
    monkeypatch.setattr(lever, "PASSES", 0)
    plain = estimate(rec, "skeleton")
    assert not any("lever" in w for w in run.warnings)
    assert np.array_equal(run.q_enu, plain.q_enu)


def test_the_lever_reduces_the_swinging_sticks_error(monkeypatch):
    """Seed 2, 0.28 m: without the lever step the default is 1.28 x TRIAD (measured 54.5 vs 42.5
    degrees); with it 47.1 (1.11 x: better, not yet as good as TRIAD), and the warning names the
    lever and says it was removed."""
    rec = swinging_stick(2, 0.28)
    run = estimate(rec, "skeleton")
    after = score_orientation(run.q_enu, rec.q_true, rec.names).per_sensor["stick"]["total_deg"]
    lines = [w for w in run.warnings if "lever" in w]
    assert len(lines) == 1 and lines[0].startswith("stick: an acceleration of rotation about a centre")
    assert "removed from the accelerometer" in lines[0]
    monkeypatch.setattr(lever, "PASSES", 0)
    before = stick_total_deg(rec, "skeleton")
    assert before > stick_total_deg(rec, "triad")  # the failure: worse than TRIAD
    assert after < 0.9 * before


@pytest.mark.slow
@pytest.mark.parametrize("lever_m", [0.2, 0.28, 0.4])
@pytest.mark.parametrize("seed", range(5))
def test_the_lever_never_makes_the_swinging_stick_worse(seed: int, lever_m: float, monkeypatch):
    """Seeds 0-4, levers 0.2-0.4 m: measured before 0.99-1.33 x TRIAD, after 0.96-1.25 x; applied
    on 6 of 15 (the others fire but do not settle or explain no better), better on each of those
    by 3-14 %; 14 of 15 are still worse than TRIAD."""
    rec = swinging_stick(seed, lever_m)
    run = estimate(rec, "skeleton")
    after = score_orientation(run.q_enu, rec.q_true, rec.names).per_sensor["stick"]["total_deg"]
    monkeypatch.setattr(lever, "PASSES", 0)
    before = stick_total_deg(rec, "skeleton")
    if any("removed from the accelerometer" in w for w in run.warnings):
        assert after < before
    else:
        assert after == before
