"""Magnetometer calibration by an ellipsoid fit (issue 15, part 3): a known hard and soft iron is
recovered to 1 %, turns about one axis are reported as not determining it, and the calibration
makes the field strength steady."""

from __future__ import annotations

import re

import numpy as np
import pytest

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.orientation.magnetometer import fit_circle_hard_iron, fit_magnetometer
from calibration.rotations import matrix_to_quat, rotvec_to_matrix

FIELD_W = 48.0 * np.array([0.0, np.cos(np.deg2rad(66.0)), -np.sin(np.deg2rad(66.0))])  # ENU, uT


def raw_samples(R, soft_true, hard_true, noise_ut, rng):
    """``m = S^-1 R^T b_w + h + noise`` for rotations ``R_w_s`` (F, 3, 3)."""
    b_s = np.einsum("fji,j->fi", R, FIELD_W)
    return b_s @ np.linalg.inv(soft_true).T + hard_true + rng.normal(scale=noise_ut, size=b_s.shape)


SOFT = np.array([[1.12, 0.06, -0.03], [0.06, 0.91, 0.04], [-0.03, 0.04, 1.02]])  # symmetric, near I
HARD = np.array([12.0, -7.5, 20.0])  # uT


def test_known_hard_and_soft_iron_recovered_to_one_percent():
    rng = np.random.default_rng(3)
    R = rotvec_to_matrix(rng.normal(size=(3000, 3)) * 2.0)  # turned every way
    cal = fit_magnetometer(raw_samples(R, SOFT, HARD, 0.3, rng))
    # the scale of S is not observable (only |b| is): S is known up to its determinant
    expected = SOFT / np.cbrt(np.linalg.det(SOFT))
    assert np.linalg.norm(cal.soft_iron - expected) / np.linalg.norm(expected) < 0.01
    assert np.linalg.norm(cal.hard_iron - HARD) / np.linalg.norm(FIELD_W) < 0.01
    assert cal.determined and cal.axis_error.max() < 0.01
    assert cal.coverage.min() > 0.5  # directions all over the sphere: about 0.58 each
    assert cal.field_strength == pytest.approx(48.0 / np.cbrt(np.linalg.det(SOFT)), rel=0.01)
    assert cal.spread_after < 0.2 * cal.spread_before  # the strength is steady once calibrated


def test_exact_samples_give_the_exact_calibration():
    rng = np.random.default_rng(4)
    R = rotvec_to_matrix(rng.normal(size=(200, 3)) * 2.0)
    cal = fit_magnetometer(raw_samples(R, SOFT, HARD, 0.0, rng))
    np.testing.assert_allclose(cal.hard_iron, HARD, atol=1e-9)
    np.testing.assert_allclose(cal.soft_iron, SOFT / np.cbrt(np.linalg.det(SOFT)), atol=1e-11)
    b = cal.apply(raw_samples(R, SOFT, HARD, 0.0, rng))
    np.testing.assert_allclose(np.linalg.norm(b, axis=1), cal.field_strength, rtol=1e-11)


def test_turns_about_one_axis_do_not_determine_the_fit():
    rng = np.random.default_rng(5)
    angle = rng.uniform(-np.pi, np.pi, 2000)
    tilt = rotvec_to_matrix(np.array([0.3, -0.2, 0.0]))
    R = tilt @ rotvec_to_matrix(angle[:, None] * np.array([0.0, 0.0, 1.0]))  # about one axis only
    m = raw_samples(R, SOFT, HARD, 0.3, rng)
    cal = fit_magnetometer(m)
    # the hard iron along the axis is left out (held at zero), the soft iron too
    assert cal.model in ("hard iron", "none") and any(x.startswith("hard iron along") for x in cal.left_out)
    axis = np.linalg.eigh(np.cov(m.T))[1][:, 0]  # the samples' least spread
    assert abs(cal.hard_iron @ axis) < 1e-9 * 48.0
    assert cal.coverage.min() < 0.1 * cal.coverage.max()


def test_too_few_samples_and_bad_shapes_are_refused():
    with pytest.raises(CalibrationError, match="at least 30 samples"):
        fit_magnetometer(np.ones((10, 3)))
    with pytest.raises(ValueError, match=r"shape \(frames, 3\)"):
        fit_magnetometer(np.ones((100, 2)))


def test_calibration_of_a_recording_applies_only_where_it_pays():
    """Three sensors: one turned every way with a consumer-grade hard and soft iron (calibrated:
    TRIAD's error falls from tens of degrees to a fraction of one), one already calibrated (left
    as it is), one turned about the vertical only (the sphere not determined: the circle and the
    dip give its hard iron; its soft iron stays)."""
    from simbench.io.imu import ImuRecording
    from simbench.orient import calibrate_magnetometers, estimate
    from simbench.score import score_orientation

    rng = np.random.default_rng(7)
    n = 3000
    R = rotvec_to_matrix(rng.normal(size=(n, 3, 3)) * 2.0)
    R[:, 2] = rotvec_to_matrix(rng.uniform(-np.pi, np.pi, (n, 1)) * np.array([0.0, 0.0, 1.0]))
    mag = np.stack(
        [
            raw_samples(R[:, 0], SOFT, HARD, 0.2, rng),
            raw_samples(R[:, 1], np.eye(3), np.zeros(3), 0.2, rng),
            raw_samples(R[:, 2], SOFT, HARD, 0.2, rng),
        ],
        axis=1,
    )
    acc = np.einsum("fsji,j->fsi", R, [0.0, 0.0, 9.81])
    rec = ImuRecording(
        names=("consumer", "calibrated", "one_axis"),
        time_s=np.arange(n) / 100.0,
        acc=acc,
        gyro=np.zeros_like(acc),
        mag=mag,
        valid=np.ones((n, 3), dtype=bool),
        q_true=matrix_to_quat(R),
        evaluate=None,
        rate_hz=100.0,
        source="test",
    )
    fixed, fits = calibrate_magnetometers(rec)
    np.testing.assert_array_equal(fixed.mag[:, 1], rec.mag[:, 1])  # left as it is
    assert fits["consumer"].determined and fits["calibrated"].determined
    assert fits["one_axis"].model == "hard iron, circle"
    assert fit_magnetometer(rec.mag[:, 2]).left_out  # the sphere alone leaves the axis out

    def total(r, name="consumer"):
        return score_orientation(estimate(r, "triad").q_enu, r.q_true, r.names).per_sensor[name]["total_deg"]

    assert total(rec) > 10.0 and total(fixed) < 1.0
    # measured: 27.0 -> 6.5 degrees (the soft iron, 0.91-1.12, is left)
    assert total(rec, "one_axis") > 20.0 and total(fixed, "one_axis") < 0.3 * total(rec, "one_axis")


def test_hard_iron_alone_where_the_directions_do_not_determine_the_soft_iron():
    """A segment that turns little (a torso: +-25 degrees): too few directions for the ellipsoid's
    nine coefficients, enough for the sphere's four; the hard iron comes back to 1 % of the field."""
    rng = np.random.default_rng(8)
    R = rotvec_to_matrix(rng.uniform(-0.45, 0.45, size=(4000, 3)))
    cal = fit_magnetometer(raw_samples(R, np.eye(3), HARD, 0.2, rng))
    assert cal.model == "hard iron" and cal.determined
    assert np.linalg.norm(cal.hard_iron - HARD) / np.linalg.norm(FIELD_W) < 0.01
    np.testing.assert_array_equal(cal.soft_iron, np.eye(3))
    assert cal.spread_after < 0.2 * cal.spread_before


def test_consumer_magnetometers_calibrated_from_the_session_come_close_to_industrial_ones():
    """Issue 15's target: the humanoid exercise with `mems-consumer` (uncalibrated hard and soft
    iron), its magnetometers calibrated from the session itself, within 1.5 x the orientation error
    of `mems-industrial`; uncalibrated, it is three times worse."""
    from simbench.api import orient
    from simbench.sim.session import SessionConfig, run_session

    def error(preset, calibrate):
        ds = run_session(
            SessionConfig(model="humanoid", motion="exercise", duration_s=12.0, seed=31, sensors=preset)
        )
        run = orient(ds, "fontaine", calibrate_mag=calibrate)  # the API's default calibrates
        assert (run.magnetometers is not None) == calibrate
        return run.score.total_rmse_deg

    industrial = error("mems-industrial", True)
    assert error("mems-consumer", False) > 2.5 * industrial
    assert error("mems-consumer", True) < 1.5 * industrial


def test_a_magnet_attached_for_a_while_is_found_and_recalibrated():
    """A sensor turning every way for 60 s; from 20 s to 40 s a magnet rides on it (a hard iron
    of 60 % of the field, constant in the sensor frame): one span is found there, fitted on its
    own samples, and recalibrated; the rest is left alone."""
    from calibration.orientation.magnetometer import fit_disturbed_spans

    rng = np.random.default_rng(8)
    rate = 50.0
    t = np.arange(3000) / rate
    v = np.stack([2.5 * np.sin(0.31 * t), 2.0 * np.sin(0.23 * t + 1), 2.8 * np.sin(0.17 * t + 2)], axis=-1)
    R = rotvec_to_matrix(v)
    mag = raw_samples(R, np.eye(3), np.zeros(3), 0.2, rng)
    ride = (t >= 20.0) & (t < 40.0)
    magnet = 0.6 * 48.0 * np.array([0.6, -0.48, 0.64])
    mag[ride] += magnet
    spans = fit_disturbed_spans(mag, rate)
    assert len(spans) == 1
    span = spans[0]
    assert abs(span.start / rate - 20.0) < 1.0 and abs(span.stop / rate - 40.0) < 1.0  # where |m| departs
    assert span.applied
    assert np.linalg.norm(span.fit.hard_iron - magnet) / 48.0 < 0.01
    fixed = span.fit.apply(mag[span.start : span.stop])
    truth = np.einsum("fji,j->fi", R[span.start : span.stop], FIELD_W)
    angle = np.rad2deg(
        np.arccos(np.clip(np.sum(fixed * truth, 1) / np.linalg.norm(fixed, axis=1) / 48.0, -1, 1))
    )
    assert np.median(angle) < 1.0  # the field's direction is back
    assert fit_disturbed_spans(raw_samples(R, np.eye(3), np.zeros(3), 0.2, rng), rate) == []  # clean: nothing


def test_a_field_that_changes_in_the_world_is_not_recalibrated():
    """A magnet the sensor passes: the extra field is fixed in the world, not in the sensor, so
    the span's samples lie on no ellipsoid and the span is left to the estimator."""
    from calibration.orientation.magnetometer import fit_disturbed_spans

    rng = np.random.default_rng(9)
    rate = 50.0
    t = np.arange(3000) / rate
    v = np.stack([2.5 * np.sin(0.31 * t), 2.0 * np.sin(0.23 * t + 1), 2.8 * np.sin(0.17 * t + 2)], axis=-1)
    R = rotvec_to_matrix(v)
    world = np.broadcast_to(FIELD_W, (t.size, 3)).copy()
    near = (t >= 20.0) & (t < 40.0)
    world[near] += 0.6 * 48.0 * np.sin(np.pi * (t[near] - 20.0) / 20.0)[:, None] * np.array([1.0, 0.0, 0.3])
    mag = np.einsum("fji,fj->fi", R, world) + rng.normal(scale=0.2, size=(t.size, 3))
    spans = fit_disturbed_spans(mag, rate)
    assert spans and not any(s.applied for s in spans)


def test_turns_about_the_vertical_are_calibrated_by_the_circle_and_the_dip():
    """The trunk in gait turns about the vertical only: the circle gives the hard iron across
    the axis, the accelerometer's up and the field's dip give it along (module docstring)."""
    rng = np.random.default_rng(6)
    heading = np.cumsum(rng.normal(scale=0.05, size=3000))  # wandering about the vertical
    sway = rng.normal(scale=0.005, size=(3000, 3)) * np.array([1.0, 1.0, 0.0])
    mount = rotvec_to_matrix(np.array([0.0, -np.pi / 2, 0.0]))  # a pelvis sensor: x down
    R = rotvec_to_matrix(heading[:, None] * np.array([0.0, 0.0, 1.0])) @ rotvec_to_matrix(sway) @ mount
    m = raw_samples(R, np.eye(3), HARD, 0.2, rng)
    up = np.mean(R[:, 2, :], axis=0)  # the sensor frame's mean up: its accelerometer at rest
    dip = np.deg2rad(66.0)
    cal = fit_circle_hard_iron(m, up, dip)
    assert cal.model == "hard iron, circle" and cal.determined
    assert np.linalg.norm(cal.hard_iron - HARD) / np.linalg.norm(FIELD_W) < 0.01
    assert cal.field_strength == pytest.approx(48.0, rel=0.01)
    assert cal.spread_after < 0.2 * cal.spread_before
    # a dip 5 degrees off moves the hard iron along the axis only: the heading is unchanged
    off = fit_circle_hard_iron(m, up, dip + np.deg2rad(5.0))
    shift = off.hard_iron - cal.hard_iron
    axis = mount.T @ np.array([0.0, 0.0, 1.0])
    assert np.linalg.norm(shift - (shift @ axis) * axis) < 0.05 * np.linalg.norm(shift)
    # the sphere alone leaves the axis out
    assert fit_magnetometer(m).left_out
    with pytest.raises(CalibrationInputError, match="dip within 80 degrees"):
        fit_circle_hard_iron(m, up, np.deg2rad(85.0))
    with pytest.raises(CalibrationInputError, match=r"up \(3,\)"):
        fit_circle_hard_iron(m, up[:2], dip)


def test_a_fit_of_part_of_an_attachment_is_followed_over_all_of_it_and_no_farther():
    """A magnet rides on a turning sensor from 20 s to 60 s. The fit of its last 20 s alone (as
    a span's own fit is, when the departures of ``|m|`` break the attachment into pieces) is
    followed back to the moment the magnet went on, across the stretches where ``|m|`` is near
    the Earth field's and the departures alone see nothing, and stops where it came off."""
    from calibration.orientation.magnetometer import SWITCH_S, disturbed_spans, follow_fits

    rng = np.random.default_rng(8)
    rate = 50.0
    t = np.arange(4000) / rate
    v = np.stack([2.5 * np.sin(0.31 * t), 2.0 * np.sin(0.23 * t + 1), 2.8 * np.sin(0.17 * t + 2)], axis=-1)
    R = rotvec_to_matrix(v)
    magnet = 0.6 * 48.0 * np.array([0.6, -0.48, 0.64])
    on = (t >= 20.0) & (t < 60.0)
    mag = raw_samples(R, np.eye(3), np.zeros(3), 0.2, rng) + on[:, None] * magnet
    spans, _ = disturbed_spans(mag, rate, gap_s=0.0)
    departing = np.zeros(t.size, dtype=bool)
    for a, b in spans:
        departing[a:b] = True
    assert (on & ~departing).sum() > 100  # the departures miss stretches of the attachment
    late = (t >= 40.0) & (t < 60.0)
    part = fit_magnetometer(mag[late])
    follows = follow_fits(mag, rate, [part])
    wrong = (follows == 0) != on
    assert wrong.sum() <= SWITCH_S * rate  # a few samples at the edges at most
    assert np.all(np.minimum(np.abs(t[wrong] - 20.0), np.abs(t[wrong] - 60.0)) < 1.0)
    # no fit: nothing to follow; the clean recording follows none of a magnet's fit
    assert np.all(follow_fits(mag, rate, []) == -1)
    clean = raw_samples(R, np.eye(3), np.zeros(3), 0.2, rng)
    assert np.all(follow_fits(clean, rate, [part]) == -1)


def test_the_cheapest_path_is_the_cheapest_of_all_paths():
    """The Viterbi pass against every path of a small problem (3 states, 8 samples), each change
    of state costing the same, the path starting in state 0."""
    import itertools

    from calibration.orientation.magnetometer import _cheapest_path

    rng = np.random.default_rng(4)
    for change in (0.0, 0.3, 2.0):
        cost = rng.random((3, 8))

        def total(path, cost=cost, change=change):
            p = np.asarray(path)
            return cost[p, np.arange(p.size)].sum() + change * (np.count_nonzero(np.diff(p)) + (p[0] != 0))

        best = min(total(p) for p in itertools.product(range(3), repeat=8))
        assert total(_cheapest_path(cost, change)) == pytest.approx(best, abs=1e-12)


def test_a_simulated_magnet_riding_on_a_forearm_is_recalibrated_from_put_on_to_take_off():
    """The simulator's ``[[magnetic.attached]]``: a magnet rides on the humanoid's left forearm
    from 5 s to 12 s (60 % of the Earth field, put on and taken off over 1 s) while every joint
    moves (``walk``). The recording's calibration finds the span, fits it, and follows the fit
    from the putting-on to the taking-off: there the field's direction is back to within a degree
    of its error elsewhere; uncalibrated it is tens of degrees off."""
    import dataclasses
    import importlib

    from simbench.sim.readings import attached_field
    from simbench.sim.sensor_config import AttachedMagnet, load_sensor_config
    from simbench.sim.session import SessionConfig, run_session

    orient = importlib.import_module("simbench.orient")  # the module, not sb.orient
    base = load_sensor_config("mems-industrial")
    magnet = AttachedMagnet("forearm_l", 5.0, 12.0, (15.0, -12.0, 16.0), 1.0)
    sensors = dataclasses.replace(
        base, name="with-magnet", magnetic=dataclasses.replace(base.magnetic, attached=(magnet,))
    )
    config = SessionConfig(model="humanoid", motion="walk", duration_s=16.0, seed=31, sensors=sensors)
    ds = run_session(config)
    rec = ds.imu()
    k = list(rec.names).index("forearm_l")
    t = rec.time_s
    earth = ds.truth.actual.mag[:, k] - attached_field(sensors.magnetic, ds.time_s, ds.sensors)[:, k]

    def angle_deg(m):
        c = np.sum(m * earth, axis=1) / np.linalg.norm(m, axis=1) / np.linalg.norm(earth, axis=1)
        return np.rad2deg(np.arccos(np.clip(c, -1.0, 1.0)))

    cal, _ = orient.calibrate_magnetometers(rec)
    on = (t >= 6.0) & (t < 11.0)  # the magnet fully on
    off = (t < 5.0) | (t >= 12.0)
    after = angle_deg(cal.mag[:, k])
    assert np.median(after[on]) < np.median(after[off]) + 1.0
    assert np.median(angle_deg(rec.mag[:, k])[on]) > 20.0
    note = next(n for n in cal.notes if n.startswith("magnetometer forearm_l"))
    start, stop = (float(x) for x in re.search(r"recalibrated ([\d.]+)-([\d.]+) s", note).groups())
    assert 5.0 <= start <= 6.0 and 11.0 <= stop <= 12.0  # within the ramps
    assert not any(n.startswith("magnetometer ") and "forearm_l" not in n for n in cal.notes)


def _one_sensor(R: np.ndarray, mag: np.ndarray, name: str = "s", rate: float = 100.0):
    """One sensor's recording with orientations ``R`` (``(n, 3, 3)``), field samples ``mag``, the
    accelerometer reading gravity alone and a gyroscope at zero, at ``rate`` Hz."""
    from simbench.io.imu import ImuRecording

    n = R.shape[0]
    return ImuRecording(
        names=(name,),
        time_s=np.arange(n) / rate,
        acc=np.einsum("fji,j->fi", R, [0.0, 0.0, 9.81])[:, None],
        gyro=np.zeros((n, 1, 3)),
        mag=mag[:, None],
        valid=np.ones((n, 1), dtype=bool),
        q_true=matrix_to_quat(R)[:, None],
        evaluate=None,
        rate_hz=rate,
        source="test",
    )


def _hand_held(rng, about_one_axis: bool, n: int = 6000, rate: float = 100.0):
    """A hand-held sensor, 60 s at 100 Hz: turned back and forth about one axis (the world's
    vertical, the sensor mounted tilted) with a wobble of 3 degrees, or every way; a hard iron of
    about 10 uT and some soft iron. Returns the recording and the turning axis in the sensor frame."""
    from scipy.ndimage import gaussian_filter1d

    t = np.arange(n) / rate
    mount = rotvec_to_matrix(np.array([0.3, -0.2, 0.0]))
    if about_one_axis:
        psi = 2.5 * np.sin(2 * np.pi * 0.2 * t + rng.uniform(0, 6))
        psi += np.cumsum(rng.normal(scale=0.01, size=n))
        wobble = gaussian_filter1d(rng.normal(size=(n, 3)), 30, axis=0)
        wobble *= np.deg2rad(3.0) / wobble.std(axis=0)
        wobble[:, 2] = 0.0
        R = rotvec_to_matrix(psi[:, None] * np.array([0.0, 0.0, 1.0])) @ rotvec_to_matrix(wobble) @ mount
    else:
        R = rotvec_to_matrix(gaussian_filter1d(rng.normal(size=(n, 3)), 20, axis=0) * 40.0) @ mount
    soft = np.array([[1.05, 0.03, -0.02], [0.03, 0.96, 0.02], [-0.02, 0.02, 1.0]])
    hard = np.array([6.0, -4.0, 10.0])
    rec = _one_sensor(R, raw_samples(R, soft, hard, 0.3, rng), "stick", rate)
    return rec, mount.T @ np.array([0.0, 0.0, 1.0]), soft, hard


@pytest.mark.parametrize("seed", [0, 1])
def test_turns_about_one_axis_leave_the_axis_uncorrected_and_are_never_worse_than_none(seed):
    """Issue 43: a recording that turns about one axis (a 3-degree wobble) with a 10 uT hard
    iron: the hard iron along the axis is left out (a note says so) instead of fitted to the
    wobble and the soft iron's misfit (before: 1.4-5.2 uT off along the axis, the field strength
    pulled from 39.7 to 43-47 uT); across the axis it is applied, and the estimate is better than
    without calibration (TRIAD and the default)."""
    from simbench.orient import calibrate_magnetometers, describe_fit, estimate
    from simbench.score import score_orientation

    rec, axis, _, hard = _hand_held(np.random.default_rng(seed), about_one_axis=True)
    fixed, fits = calibrate_magnetometers(rec)
    fit = fits["stick"]
    assert fit.model == "hard iron" and fit.determined
    assert any(x.startswith("hard iron along") for x in fit.left_out)
    assert "left out, not determined: hard iron along" in describe_fit(fit)
    assert abs(fit.hard_iron @ axis) < 0.1 * abs(hard @ axis)  # the axis is not corrected
    # the strength stays that of the field with the axis's part left in (not pulled)
    across = hard - (hard @ axis) * axis
    expected = np.median(np.linalg.norm(rec.mag[:, 0] - across, axis=1))
    assert np.median(np.linalg.norm(fixed.mag[:, 0], axis=1)) == pytest.approx(expected, rel=0.02)
    for method in ("triad", "skeleton"):
        before, after = (
            score_orientation(estimate(r, method).q_enu, r.q_true, r.names).per_sensor["stick"]["total_deg"]
            for r in (rec, fixed)
        )
        assert after < before


def test_turns_about_two_axes_are_never_worse_than_no_calibration():
    """Turns about the vertical (+-143 degrees) and a horizontal axis (+-46 degrees), a 2-degree
    wobble, the same iron: whatever the fit keeps, TRIAD and the default are better calibrated
    than not (measured: 19.9 -> 2.7 degrees, the default 20.0 -> 2.7)."""
    from scipy.ndimage import gaussian_filter1d

    from simbench.orient import calibrate_magnetometers, estimate
    from simbench.score import score_orientation

    rng = np.random.default_rng(0)
    n = 6000
    t = np.arange(n) / 100.0
    heading = 2.5 * np.sin(2 * np.pi * 0.2 * t + rng.uniform(0, 6))
    pitch = 0.8 * np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6))
    wobble = gaussian_filter1d(rng.normal(size=(n, 3)), 30, axis=0)
    wobble *= np.deg2rad(2.0) / wobble.std(axis=0)
    R = (
        rotvec_to_matrix(heading[:, None] * np.array([0.0, 0.0, 1.0]))
        @ rotvec_to_matrix(pitch[:, None] * np.array([1.0, 0.0, 0.0]))
        @ rotvec_to_matrix(wobble)
        @ rotvec_to_matrix(np.array([0.3, -0.2, 0.0]))
    )
    soft = np.array([[1.05, 0.03, -0.02], [0.03, 0.96, 0.02], [-0.02, 0.02, 1.0]])
    rec = _one_sensor(R, raw_samples(R, soft, np.array([6.0, -4.0, 10.0]), 0.3, rng))
    fixed, _ = calibrate_magnetometers(rec)
    for method in ("triad", "skeleton"):
        before, after = (
            score_orientation(estimate(r, method).q_enu, r.q_true, r.names).per_sensor["s"]["total_deg"]
            for r in (rec, fixed)
        )
        assert after < 0.5 * before


def test_turns_every_way_apply_the_calibration_and_recover_the_iron():
    """The same sensor and iron turned every way: the ellipsoid is determined, applied, and
    gives back the hard iron to 1 % of the field and the soft iron to 1 %."""
    from simbench.orient import calibrate_magnetometers

    rec, _, soft, hard = _hand_held(np.random.default_rng(2), about_one_axis=False)
    fixed, fits = calibrate_magnetometers(rec)
    fit = fits["stick"]
    assert fit.model == "ellipsoid" and fit.determined and fit.left_out == ()
    assert np.linalg.norm(fit.hard_iron - hard) / 48.0 < 0.01
    expected = soft / np.cbrt(np.linalg.det(soft))
    assert np.linalg.norm(fit.soft_iron - expected) / np.linalg.norm(expected) < 0.01
    assert not np.array_equal(fixed.mag, rec.mag)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_magnetometer_axis_that_picks_up_the_horizontal_field_is_not_taken_for_hard_iron(seed):
    """Issue 43's RepoIMU trial 04_2: turns about the vertical (+-143 degrees) and a horizontal
    axis (+-34 degrees), the magnetometer's z axis picking up 6 % of the field's x and 4.5 % of its
    y (a cross-axis coupling, not symmetric soft iron) and a hard iron of 0.7 uT. The field
    strength then varies with the heading as an offset in the plane of the turn makes it vary:
    the sphere's centre moves there (measured before: TRIAD 1.74 -> 5.66 degrees, the default
    2.37 -> 6.25, calibrated vs not). The ellipsoid, with the soft iron free, does not follow it:
    the sphere departs from it beyond its standard errors (Hausman's test) and nothing is
    applied, no worse than none."""
    from scipy.ndimage import gaussian_filter1d

    from simbench.orient import applies, calibrate_magnetometers, describe_fit, estimate
    from simbench.score import score_orientation

    rng = np.random.default_rng(seed)
    n = 6000
    t = np.arange(n) / 100.0
    heading = 2.5 * np.sin(2 * np.pi * 0.2 * t + rng.uniform(0, 6))
    heading += np.cumsum(rng.normal(scale=0.01, size=n))
    pitch = 0.6 * np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6))
    wobble = gaussian_filter1d(rng.normal(size=(n, 3)), 30, axis=0)
    wobble *= np.deg2rad(3.0) / wobble.std(axis=0)
    wobble[:, 2] = 0.0
    R = (
        rotvec_to_matrix(heading[:, None] * np.array([0.0, 0.0, 1.0]))
        @ rotvec_to_matrix(pitch[:, None] * np.array([1.0, 0.0, 0.0]))
        @ rotvec_to_matrix(wobble)
    )
    coupling = np.eye(3)
    coupling[2, :2] = (0.06, 0.045)
    b_s = np.einsum("fji,j->fi", R, FIELD_W)
    mag = b_s @ coupling.T + np.array([0.5, -0.3, 0.4]) + rng.normal(scale=0.3, size=b_s.shape)
    rec = _one_sensor(R, mag)
    fixed, fits = calibrate_magnetometers(rec)
    assert not applies(fits["s"])
    assert "the sphere's centre departs from the ellipsoid's" in describe_fit(fits["s"])
    for method in ("triad", "skeleton"):
        before, after = (
            score_orientation(estimate(r, method).q_enu, r.q_true, r.names).per_sensor["s"]["total_deg"]
            for r in (rec, fixed)
        )
        assert after <= 1.05 * before
