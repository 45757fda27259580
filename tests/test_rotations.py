"""Quaternion conventions: scalar-first, q and -q equal, round trips."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.errors import CalibrationInputError
from calibration.rotations import (
    matrix_to_quat,
    matrix_to_rotvec,
    orthonormal_to_quat,
    quat_to_matrix,
    rotvec_to_matrix,
)


def test_scalar_first_golden():
    # 90 degrees about z: (w, x, y, z) = (cos 45, 0, 0, sin 45) maps x to y.
    q = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])
    assert_allclose(quat_to_matrix(q) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("batch", [(), (1,), (3, 1, 2)])
def test_round_trip_keeps_batch_shape(batch):
    rng = np.random.default_rng(0)
    q = rng.normal(size=(*batch, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    R = quat_to_matrix(q)
    assert R.shape == (*batch, 3, 3)
    back = matrix_to_quat(R)
    # q and -q are the same rotation: compare up to sign
    assert_allclose(np.abs(np.sum(back * q, axis=-1)), 1.0, atol=1e-12)
    assert np.all(back[..., 0] >= 0)
    assert_allclose(rotvec_to_matrix(matrix_to_rotvec(R)), R, atol=1e-12)


def test_negated_quaternion_same_matrix():
    q = np.array([0.3, -0.5, 0.1, 0.8])
    assert_allclose(quat_to_matrix(q), quat_to_matrix(-q), atol=1e-15)


def test_bad_shapes_and_zero():
    with pytest.raises(CalibrationInputError, match=r"shape \(\.\.\., 4\), got \(3, 3\)"):
        quat_to_matrix(np.eye(3))
    with pytest.raises(CalibrationInputError, match="zero quaternion"):
        quat_to_matrix(np.zeros((2, 4)))


def test_fast_conversion_matches_scipy():
    rng = np.random.default_rng(5)
    R = rotvec_to_matrix(rng.normal(size=(20_000, 3)) * 3.0)
    # include every branch of Shepperd's method: angles near 0 and near pi about each axis
    special = rotvec_to_matrix(
        np.array([[0, 0, 0], [np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], [3.14, 0.01, 0]])
    )
    R = np.concatenate([R, special])
    assert_allclose(orthonormal_to_quat(R), matrix_to_quat(R), atol=1e-12)
