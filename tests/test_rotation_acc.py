"""The sustained sensor-frame acceleration of a sensor away from the centre of rotation
(:mod:`calibration.orientation.rotation_acc`): recovered where the data show it, not found where
there is none, where the readings cannot tell it from tilt, or where the field holds an offset
of its own; the API says what it did."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from calibration.errors import CalibrationInputError
from calibration.orientation import rotation_acceleration
from calibration.orientation.rotation_acc import WINDOW_S
from calibration.rotations import quat_to_matrix
from simbench.api import orient
from tests.test_fast_rotation import swung_stick


def true_window_means(rec) -> np.ndarray:
    """``(F, 3)`` the true linear acceleration in the sensor frame, averaged over each sample's
    window (what the fit estimates)."""
    R = quat_to_matrix(rec.q_true[:, 0])
    a_s = rec.acc[:, 0] - np.einsum("fji,j->fi", R, [0.0, 0.0, 9.81])
    return uniform_filter1d(a_s, round(WINDOW_S * rec.rate_hz), axis=0, mode="nearest")


def test_the_stick_acceleration_is_found_and_estimated():
    """Swung stick, 0.2 m: the centripetal acceleration (5.6 m/s^2 towards the wrist, -x, in the
    truth's window means) found on most of the recording; towards the wrist as the truth within
    10 % in the median (measured -5.40 vs -5.58), the whole vector within half the truth's size
    (measured 1.9 m/s^2: the wobble's tangential and centripetal parts are not constant over a
    window)."""
    rec = swung_stick(0, 0.2)
    found = rotation_acceleration(rec.acc[:, 0], rec.mag[:, 0], rec.rate_hz, rec.valid[:, 0])
    applied = np.linalg.norm(found.offset, axis=1) > 0
    assert applied.mean() > 0.5 and found.fired >= found.windows // 3
    truth = true_window_means(rec)[applied]
    assert np.median(found.offset[applied, 0]) == pytest.approx(np.median(truth[:, 0]), rel=0.1)
    error = np.linalg.norm(found.offset[applied] - truth, axis=1)
    assert np.median(error) < 0.5 * np.median(np.linalg.norm(truth, axis=1))


def test_nothing_is_found_at_the_centre_of_rotation():
    """The same stick with its IMU at the wrist (lever 0): the wrist's wandering only."""
    rec = swung_stick(3, 0.0)
    found = rotation_acceleration(rec.acc[:, 0], rec.mag[:, 0], rec.rate_hz, rec.valid[:, 0])
    assert found.fired == 0 and not found.detected.any() and not found.offset.any()


def test_a_still_or_slowly_turning_sensor_determines_nothing():
    """A sensor at rest, then one turning at 0.5 rad/s (less than a full turn in a window),
    with a 3 m/s^2 constant in its frame: the readings cannot tell it from tilt."""
    rng = np.random.default_rng(1)
    n = 6000
    g = np.array([0.0, 0.0, 9.81])
    angle = np.r_[np.zeros(n // 2), 0.5 * np.arange(n // 2) / 100.0]
    c = np.array([-3.0, 0.0, 0.0])
    Rt = np.stack(
        [np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1]]) for a in angle]
    )
    tilt = np.array([[1, 0, 0], [0, np.cos(0.7), np.sin(0.7)], [0, -np.sin(0.7), np.cos(0.7)]])
    acc = (Rt @ tilt) @ g + c + rng.normal(scale=0.05, size=(n, 3))
    mag = (Rt @ tilt) @ np.array([0.0, 20.0, -44.0]) + rng.normal(scale=0.3, size=(n, 3))
    found = rotation_acceleration(acc, mag, 100.0)
    assert found.fired == 0 and not found.offset.any()


def test_a_magnet_carried_with_the_sensor_is_not_taken_for_it():
    """The swung stick whose magnetometer carries a 15 uT offset of its own (a magnet the
    calibration left): the dip no longer holds, and those windows are not used."""
    rec = swung_stick(0, 0.2)
    found = rotation_acceleration(rec.acc[:, 0], rec.mag[:, 0] + [15.0, -5.0, 8.0], rec.rate_hz)
    assert found.fired == 0


def test_bad_input_is_named():
    with pytest.raises(CalibrationInputError, match=r"Expected acc and mag of one shape \(frames, 3\)"):
        rotation_acceleration(np.zeros((10, 3)), np.zeros((10, 2)), 100.0)
    with pytest.raises(CalibrationInputError, match="Expected rate_hz"):
        rotation_acceleration(np.zeros((10, 3)), np.zeros((10, 3)), 0.0)
    with pytest.raises(CalibrationInputError, match=r"Expected valid of shape \(10,\)"):
        rotation_acceleration(np.zeros((10, 3)), np.zeros((10, 3)), 100.0, np.ones(9, dtype=bool))


def test_a_short_recording_has_no_window():
    rng = np.random.default_rng(0)
    found = rotation_acceleration(rng.normal(size=(50, 3)), rng.normal(size=(50, 3)), 100.0)
    assert found.windows == 0 and found.fired == 0


def test_the_api_warns_with_what_it_found_and_did():
    """``orient``'s warnings carry the method's: the stick's, not the same stick at the wrist's."""
    rec = swung_stick(0, 0.2, duration_s=30.0)
    warned = [w for w in orient(rec).warnings if "sustained acceleration" in w]
    assert len(warned) == 1 and warned[0].startswith("stick:") and "m/s^2" in warned[0]
    still = swung_stick(3, 0.0, duration_s=30.0)
    assert not [w for w in orient(still).warnings if "sustained acceleration" in w]
