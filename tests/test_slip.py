"""Slip detection finds injected sensor shifts (O'Brien section 5)."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import CalibrationInputError, calibrate, detect_slip
from simbench.sim.synthetic import Slip, linkage, simulate_motion
from tests.helpers import pair_arrays

WINDOW = 120  # 1 s at 120 Hz


def capture(slips, seed=21):
    return simulate_motion(
        linkage(),
        n_frames=3000,
        rate_hz=120.0,
        rng=np.random.default_rng(seed),
        position_noise_m=0.002,
        rotation_noise_rad=np.deg2rad(0.3),
        slips=slips,
    )


def reports(cap):
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    out = {}
    for j in cal.joints:
        out[j.name] = detect_slip(
            *pair_arrays(cap, j.parent, j.child), j.fit.joint_in_parent, j.fit.joint_in_child, window=WINDOW
        )
    return out


def test_injected_slip_found_on_its_joint_only():
    cap = capture([Slip("forearm_l", 1700, (0.0, 0.03, 0.0))])
    found = reports(cap)
    rep = found["upper_arm_l-forearm_l"]
    assert len(rep.events) == 1
    ev = rep.events[0]
    # the jump statistic peaks at the slip, to within a small part of the window
    assert abs(ev.frame - 1700) <= WINDOW // 10
    assert ev.sensor_frame == "child"
    assert ev.jump == pytest.approx(0.03, abs=0.004)  # the full 3 cm shift, within noise
    assert rep.intervals == ((ev.frame, 3000),)
    for name, other in found.items():
        if name != "upper_arm_l-forearm_l":
            assert other.events == (), name


def test_slip_and_return_gives_one_interval():
    cap = capture(
        [Slip("upper_arm_r", 900, (0.02, 0.0, 0.02)), Slip("upper_arm_r", 2000, (-0.02, 0.0, -0.02))]
    )
    rep = reports(cap)["chest-upper_arm_r"]
    assert [abs(e.frame - t) <= WINDOW // 10 for e, t in zip(rep.events, (900, 2000), strict=True)] == [
        True,
        True,
    ]
    assert len(rep.intervals) == 1
    start, stop = rep.intervals[0]
    assert abs(start - 900) <= WINDOW // 10 and abs(stop - 2000) <= WINDOW // 10


def test_no_slip_no_event():
    found = reports(capture([], seed=22))
    assert all(rep.events == () and rep.intervals == () for rep in found.values())


def test_window_checked(linkage_noisy):
    with pytest.raises(CalibrationInputError, match="window must be between 2"):
        detect_slip(*pair_arrays(linkage_noisy, "chest", "head"), np.zeros(3), np.zeros(3), window=1)
