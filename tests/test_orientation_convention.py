"""An orientation estimate in another convention than stated (scalar last, the inverse, NED) is
named, from the accelerometer alone; an estimate right in the stated convention is not."""

from __future__ import annotations

import numpy as np
import pytest

import simbench
from calibration.errors import CalibrationInputError
from calibration.orientation import triad
from calibration.orientation.convention import ALTERNATIVES, better_reading
from calibration.rotations import matrix_to_quat, quat_to_matrix

ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@pytest.fixture(scope="module")
def imu():
    return simbench.simulate(
        model="humanoid", motion="exercise", sensors="mems-industrial", duration_s=20, seed=5
    )


def _as_ned(q):
    return matrix_to_quat(np.einsum("ij,...jk->...ik", ENU_TO_NED, quat_to_matrix(q)))


CASES = {
    ALTERNATIVES[0]: lambda q: q[..., [1, 2, 3, 0]],  # the same rotation written scalar last
    ALTERNATIVES[1]: lambda q: q * np.array([1.0, -1.0, -1.0, -1.0]),  # world to sensor
    ALTERNATIVES[2]: _as_ned,
}


@pytest.mark.parametrize("alternative", ALTERNATIVES)
def test_each_wrong_convention_is_named_on_every_sensor(imu, alternative):
    wrong = CASES[alternative]
    got = simbench.orient(imu, method=lambda r: wrong(r.q_true))
    named = [w for w in got.warnings if "read as" in w]
    assert len(named) == len(imu.imu().names)
    assert all(f"read as {alternative} " in w for w in named), named


@pytest.mark.parametrize("method", ["truth", "triad", "skeleton"])
def test_an_estimate_in_the_stated_convention_is_not_named(imu, method):
    fn = {"truth": lambda r: r.q_true, "triad": lambda r: triad(r.acc, r.mag).q_w_s}.get(method, method)
    got = simbench.orient(imu, method=fn)
    assert not [w for w in got.warnings if "read as" in w]


def test_short_recordings_and_bad_shapes():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(500, 4))
    acc = rng.normal(size=(500, 3))
    assert better_reading(q, acc, 100.0) is None  # 5 one-second blocks cannot reach 1e-3
    with pytest.raises(
        CalibrationInputError, match=r"q_w_s \(F, 4\) and acc \(F, 3\), got \(500, 4\) and \(400, 3\)"
    ):
        better_reading(q, acc[:400], 100.0)
    with pytest.raises(CalibrationInputError, match="positive rate_hz"):
        better_reading(q, acc, 0.0)
