"""Slip detection on simulated sessions: skin-mounted sensors, soft-tissue artefact, mounts."""

from __future__ import annotations

import tomllib

import pytest

from calibration import calibrate, detect_slip
from calibration.slip import SLIP_WINDOW_S
from simbench.sim.sensor_config import PRESETS_DIR, parse_sensor_config
from simbench.sim.session import SessionConfig, load_session_model, run_session

WINDOW_S = SLIP_WINDOW_S  # the CLI's default


def detect(config):
    ds = run_session(config, load_session_model(config))
    rec = ds.poses()
    cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    found = []
    for j in cal.joints:
        rep = detect_slip(
            *rec.pair(j.parent, j.child),
            j.fit.joint_in_parent,
            j.fit.joint_in_child,
            window=round(WINDOW_S * rec.rate_hz),
            rate_hz=rec.rate_hz,
        )
        found += [(j, ev, float(ds.time_s[ev.frame])) for ev in rep.events]
    return found


def test_clean_tracker_session_has_no_alarm():
    """30 s of the linkage with Polhemus Liberty noise, no slip: 5 joints x 30 s at 1 alarm/hour
    expects 0.04 alarms."""
    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=30.0, seed=5, sensors="polhemus-liberty"
    )
    assert detect(config) == []


def test_clean_skin_session_has_no_alarm():
    """30 s of the humanoid exercising on skin (skin-paper-human), no slip: 15 joints x 30 s at
    1 alarm/hour expects 0.125 alarms. In this seed the residual moves away and back for a second
    or so while the left hip and the right elbow exercise; the search used to report each
    excursion as a slip and its return (four alarms), less than a window apart."""
    config = SessionConfig(
        model="humanoid", motion="exercise", duration_s=30.0, seed=5, sensors="skin-paper-human"
    )
    assert detect(config) == []


def test_no_event_below_the_smallest_detectable_jump():
    """The validation's third humanoid exercise trial (45 s, seed 103), no slip: once one
    excursion of the right arm's skin was taken as an event, its frames left the noise model and
    three more excursions of 3.6-5.6 mm passed lowered thresholds, below the 6.1-6.2 mm the
    recording's noise lets the test detect. Events below ``min_jump`` are dropped."""
    config = SessionConfig(
        model="humanoid", motion="exercise", duration_s=45.0, seed=103, sensors="skin-paper-human"
    )
    assert detect(config) == []


def _thigh_slip(room: bool):
    """skin-paper-human with a 3 cm slip of the right thigh sensor at 12.3 s; with the paper-like
    room's field distortion (``room``) or without it."""
    doc = tomllib.loads((PRESETS_DIR / "skin-paper-human.toml").read_text())
    doc["skin"]["slip"] = [{"sensor": "thigh_r", "time_s": 12.3, "offset_m": [0.0, 0.03, 0.0]}]
    if not room:
        del doc["tracker"]["distortion"]
    sensors = parse_sensor_config(doc, "skin-paper-human with a thigh slip")
    config = SessionConfig(model="humanoid", motion="exercise", duration_s=24.0, seed=3, sensors=sensors)
    return [(j, ev, t) for j, ev, t in detect(config) if "thigh_r" in (j.parent, j.child)]


def _check_thigh_events(on_thigh):
    assert on_thigh
    for j, ev, t in on_thigh:
        assert abs(t - 12.3) <= 0.5, (j.name, t)
        assert (j.parent if ev.sensor_frame == "parent" else j.child) == "thigh_r", j.name
        assert ev.jump == pytest.approx(0.03, abs=0.01)  # soft tissue and misfit: within 1 cm


def test_skin_slip_found_within_half_a_second_in_its_sensor_frame():
    """A 3 cm slip of the right thigh sensor (skin-paper-human: soft tissue, sprung mounts,
    girdles, the pack), the room without field distortion."""
    _check_thigh_events(_thigh_slip(room=False))


@pytest.mark.xfail(
    strict=True,
    reason="known limitation (issue 13): with the paper-like room's field distortion the knee's "
    "event is attributed to the shank's frame; the per-joint detector does not use the hip's event "
    "to say which sensor moved",
)
def test_skin_slip_in_the_distorted_room_is_attributed_to_its_sensor():
    _check_thigh_events(_thigh_slip(room=True))


def test_gait_that_starts_from_standing_has_no_alarm():
    """30 s of the humanoid walking with skin-mounted marker clusters (skin-markers), no slip.
    The gait fades in from standing over its first second; the soft tissue sits differently
    standing than walking, so most joints' residuals stepped 0.3-1.4 s in (33 alarms per
    joint-hour over eight 60 s seeds) where 15 joints x 30 s at 1 alarm/hour expect 0.125. A
    step within a window of the recording's ends is not a slip."""
    config = SessionConfig(model="humanoid", motion="gait", duration_s=30.0, seed=1, sensors="skin-markers")
    assert detect(config) == []
