"""Small helpers shared by the tests."""

from __future__ import annotations

import numpy as np

from calibration.rotations import matrix_to_quat
from simbench.io.imu import ImuRecording
from simbench.orient import estimate
from simbench.score import score_orientation
from simbench.sim.synthetic import SyntheticCapture

#: A steady field for the hand-held sticks: 48 uT, 66 degrees of dip, ENU, uT.
STICK_FIELD_W = 48.0 * np.array([0.0, np.cos(np.deg2rad(66.0)), -np.sin(np.deg2rad(66.0))])


def pair_arrays(cap: SyntheticCapture, parent: str, child: str):
    """``(R_w_p, p_w_p, R_w_c, p_w_c)`` of two sensors of a capture."""
    p, c = cap.names.index(parent), cap.names.index(child)
    return cap.R_w_s[:, p], cap.p_w_s[:, p], cap.R_w_s[:, c], cap.p_w_s[:, c]


def stick_recording(
    R: np.ndarray,
    a: np.ndarray,
    w: np.ndarray | None,
    rng: np.random.Generator,
    rate: float,
    source: str,
) -> ImuRecording:
    """One IMU ("stick") from its true orientations ``R`` ``(F, 3, 3)`` and world accelerations
    ``a`` ``(F, 3)``, m/s^2, at ``rate`` Hz: accelerometer noise 0.05 m/s^2, then magnetometer
    noise 0.3 uT (of :data:`STICK_FIELD_W`), then, given the body rate ``w`` ``(F, 3)``, rad/s, a
    gyroscope with 0.01 rad/s of noise (else none), drawn from ``rng`` in that order."""
    n = len(R)
    acc = np.einsum("fji,fj->fi", R, a + np.array([0.0, 0.0, 9.81])) + rng.normal(scale=0.05, size=(n, 3))
    mag = np.einsum("fji,j->fi", R, STICK_FIELD_W) + rng.normal(scale=0.3, size=(n, 3))
    gyro = np.full((n, 3), np.nan) if w is None else w + rng.normal(scale=0.01, size=(n, 3))
    return ImuRecording(
        names=("stick",),
        time_s=np.arange(n) / rate,
        acc=acc[:, None],
        gyro=gyro[:, None],
        mag=mag[:, None],
        valid=np.ones((n, 1), dtype=bool),
        q_true=matrix_to_quat(R)[:, None],
        evaluate=None,
        rate_hz=rate,
        source=source,
    )


def stick_total_deg(rec: ImuRecording, method: str) -> float:
    """The total orientation error of a built-in method on a stick recording, degrees."""
    q = estimate(rec, method).q_enu
    return score_orientation(q, rec.q_true, rec.names).per_sensor["stick"]["total_deg"]
