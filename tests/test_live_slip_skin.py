"""The live slip monitor where the residual is not white: skin-artefact sessions and a real trial
(issue 42: a monitor whose warm-up restarted whenever the fit moved by ten times the white noise
never armed on skin, and alerted none of the slips injected into real recordings)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from calibration.streaming import StreamingCalibrator
from simbench.errors import InputError
from simbench.io.c3d import c3d_poses, read_cluster_spec
from simbench.io.poses import PoseRecording
from simbench.sim.live import recording_with_slip
from simbench.sim.plan import SessionConfig, load_session_model
from simbench.sim.session import run_session

HERE = Path(__file__).resolve().parent
HIP_C3D = HERE.parents[1] / "shared" / "data" / "biobuddy_right_hip.c3d"
HIP_SPEC = HERE.parent / "studies" / "hip_c3d.toml"
ARMED_BY_S = 3.0  # issue 42's target: the monitor armed within 3 s of the start
LATENCY_S = 0.5  # ... and a 2 cm slip alerted within 0.5 s


def _live(rec: PoseRecording) -> StreamingCalibrator:
    """Every frame pushed one at a time, as a driver delivers them."""
    sc = StreamingCalibrator(rec.names, rate_hz=rec.rate_hz)
    for f in range(rec.n_frames):
        sc.push(rec.R_w_s[f], rec.p_w_s[f], rec.valid[f])
    return sc


@pytest.fixture(scope="module")
def hip() -> PoseRecording:
    if not HIP_C3D.is_file():
        pytest.skip("../shared/data not beside the repository")
    return c3d_poses(HIP_C3D, clusters=read_cluster_spec(HIP_SPEC))


def test_real_hip_trial_arms_within_3_s_and_stays_quiet(hip):
    # 17 s of skin-mounted marker clusters (pelvis, thigh, shank): their residual is skin motion
    sc = _live(hip)
    armed = sc.slip_armed_s()
    assert set(armed) == {j.name for j in sc.calibration().joints}
    assert max(armed.values()) <= ARMED_BY_S, armed
    assert sc.alerts == ()


@pytest.mark.parametrize(
    ("sensor", "time_s", "offset"),
    [
        ("shank_r", 13.4, (0.02, 0.0, 0.0)),
        ("thigh_r", 12.0, (0.0, 0.02, 0.0)),
        ("pelvis", 10.0, (0.02, 0, 0)),
    ],
)
def test_real_hip_trial_with_an_injected_slip(hip, sensor, time_s, offset):
    sc = _live(recording_with_slip(hip, sensor, time_s, offset))
    assert len(sc.alerts) == 1, [a.message for a in sc.alerts]
    alert = sc.alerts[0]
    assert alert.sensor == sensor
    assert 0.0 <= alert.raised_frame / hip.rate_hz - time_s <= LATENCY_S
    assert alert.size_m == pytest.approx(0.02, abs=0.006)  # skin motion of millimetres in the windows


@pytest.fixture(scope="module")
def skin_session() -> PoseRecording:
    # the humanoid with O'Brien et al.'s subjects' soft tissue (centimetres, following the joints'
    # rotation), a pack-mounted pelvis sensor, knee laxity: not white
    config = SessionConfig(
        model="humanoid", motion="exercise", duration_s=20.0, seed=0, sensors="skin-paper-human"
    )
    return run_session(config, load_session_model(config)).poses()


@pytest.mark.parametrize("sensor", ["forearm_l", "shank_r", "upper_arm_r"])
def test_skin_session_slip_is_alerted_on_the_right_sensor(skin_session, sensor):
    slip_s = 12.0
    rec = skin_session
    t0 = float(rec.time_s[0])
    sc = _live(recording_with_slip(rec, sensor, t0 + slip_s, (0.0, 0.02, 0.0)))
    armed = sc.slip_armed_s()
    joints = [j for j in armed if sensor in j.split("-")]
    assert joints and all(armed[j] <= slip_s for j in joints), armed  # armed before the slip
    hits = [a for a in sc.alerts if 0.0 <= a.raised_frame / rec.rate_hz - slip_s <= LATENCY_S]
    assert [a.sensor for a in hits] == [sensor], [a.message for a in sc.alerts]


def test_recording_with_slip_moves_the_sensor_in_its_own_frame(hip):
    moved = recording_with_slip(hip, "thigh_r", 5.0, (0.0, 0.0, 0.01))
    k, frame = hip.names.index("thigh_r"), int(np.searchsorted(hip.time_s, 5.0))
    shift = moved.p_w_s[:, k] - hip.p_w_s[:, k]
    assert np.all(shift[:frame] == 0.0)
    in_sensor = np.einsum("fba,fb->fa", hip.R_w_s[frame:, k], shift[frame:])
    np.testing.assert_allclose(in_sensor, np.tile([0.0, 0.0, 0.01], (hip.n_frames - frame, 1)), atol=1e-12)
    others = np.delete(np.arange(len(hip.names)), k)
    assert np.array_equal(moved.p_w_s[:, others], hip.p_w_s[:, others])
    with pytest.raises(InputError, match="no sensor 'arm'"):
        recording_with_slip(hip, "arm", 5.0, (0.0, 0.0, 0.01))
    with pytest.raises(InputError, match="past the recording's last frame"):
        recording_with_slip(hip, "thigh_r", 500.0, (0.0, 0.0, 0.01))


def test_skin_markers_session_quiet_when_the_legs_start_moving():
    # skin-markers: a 4 cm pelvis cluster artefact driven by the hips, which stay still for the
    # exercise's first 18 s and then turn at about 3.7 rad/s. The pelvis-abdomen joint does not see
    # the hips turn; judged against its own quiet history alone it alerted a 1.9 cm "slip" of the
    # pelvis at 18.4 s. Judged against its neighbours' motion too, the clean session is quiet.
    config = SessionConfig(
        model="humanoid", motion="exercise", duration_s=30.0, seed=0, sensors="skin-markers"
    )
    rec = run_session(config, load_session_model(config)).poses()
    sc = _live(rec)
    assert "abdomen-pelvis" in sc.slip_armed_s()  # armed, and so tested, before the legs move
    assert sc.alerts == (), [a.message for a in sc.alerts]


def test_real_hip_trial_with_the_shank_cluster_hidden_at_first(hip):
    # a cluster out of view for the first 6 s (as sprintbasket's forearm, 11 s): the pelvis-thigh
    # joint arms 3 s after the start, the thigh-shank joint 3 s after the shank appears (at a
    # refit, at most REFIT_S later), and the skin's motion raises no alert
    from calibration.streaming import FLUSH_S, REFIT_S

    hidden_s = 6.0
    valid = hip.valid.copy()
    valid[: round(hidden_s * hip.rate_hz), hip.names.index("shank_r")] = False
    sc = _live(dataclasses.replace(hip, valid=valid))
    armed = sc.slip_armed_s()
    assert armed["thigh_r-pelvis"] <= ARMED_BY_S
    late = hidden_s + ARMED_BY_S - FLUSH_S - 1.0 / hip.rate_hz  # a refit comes before its flush's frames
    assert late <= armed["thigh_r-shank_r"] <= hidden_s + ARMED_BY_S + REFIT_S
    assert sc.alerts == (), [a.message for a in sc.alerts]
