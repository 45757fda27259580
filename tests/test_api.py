"""The public API (``import simbench as sb``) and the public scoring (``simbench.score``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import simbench as sb
from calibration import calibrate as calibrate_arrays
from simbench.io.dataset import dataset_from_poses
from simbench.io.poses import write_pose_csv
from simbench.orient import estimate
from simbench.score import compare_trees, length_of, score, score_orientation, truth_lengths

ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = ROOT.parent / "shared" / "data"


@pytest.fixture(scope="module")
def flock() -> sb.Dataset:
    """A linkage session through the Flock of Birds preset (positions in its units, scale 0.94)."""
    return sb.simulate(model="linkage", sensors="ascension-flock", duration_s=12, seed=4)


def test_simulate_is_seeded_and_records_its_config(flock):
    again = sb.simulate(model="linkage", sensors="ascension-flock", duration_s=12, seed=4)
    other = sb.simulate(model="linkage", sensors="ascension-flock", duration_s=12, seed=5)
    assert np.array_equal(flock.measured.p_w_s, again.measured.p_w_s, equal_nan=True)
    assert not np.array_equal(flock.measured.p_w_s, other.measured.p_w_s, equal_nan=True)
    assert flock.position_unit_scale == pytest.approx(0.94)
    assert flock.meta["config"]["duration_s"] == 12 and flock.meta["seed"] == 4
    assert flock.time_s.shape == (12 * 120,)


def test_simulate_takes_sensors_on_and_placement():
    ds = sb.simulate(
        model="linkage", duration_s=2, sensors_on=["chest", "head"], placement={"head": (0.0, 0.0, 0.02)}
    )
    moved = ds.truth.p_b_s[ds.sensors.index("head")]
    plain = sb.simulate(model="linkage", duration_s=2, sensors_on=["chest", "head"])
    assert ds.sensors == ("chest", "head")
    assert_allclose(moved - plain.truth.p_b_s[1], [0.0, 0.0, 0.02], atol=1e-12)  # an exact shift


def test_calibrate_equals_the_array_api_and_score_applies_the_unit_scale(flock):
    cal = sb.calibrate(flock)
    rec = flock.poses()
    direct = calibrate_arrays(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
    assert cal.parent_of == direct.parent_of
    for a, b in zip(cal.joints, direct.joints, strict=True):
        assert_allclose(a.fit.joint_in_parent, b.fit.joint_in_parent, rtol=0, atol=1e-15)
    result = sb.score(cal, flock)
    assert result.tree.correct and result.scale == pytest.approx(0.94)
    # lengths are compared in metres: the tracker reports metres / 0.94, so unscaled they are 6 % long
    truth = truth_lengths(flock)
    in_tracker_units = {(x.segment, x.joint_a, x.joint_b): x.length for x in cal.lengths}
    for limb in result.limbs:
        key = (limb.segment, limb.joint_a, limb.joint_b)
        assert limb.estimated_m == pytest.approx(length_of(in_tracker_units, key) * 0.94, rel=1e-12)
        assert limb.true_m == truth[key]
    assert result.max_length_error_m < 0.011  # the paper's 1.1 cm
    unscaled = score(cal, flock, scale=1.0)
    assert unscaled.max_length_error_m > 0.015  # 6 % of 30-40 cm limbs


def test_score_names_the_wrong_edges():
    true = {"b": "a", "c": "b", "d": "b"}
    assert compare_trees({"a": "b", "c": "b", "d": "b"}, true).correct  # direction does not matter
    wrong = compare_trees({"b": "a", "c": "b", "d": "c"}, true)
    assert not wrong.correct and wrong.wrong_edges == ("c-d",) and wrong.missed_edges == ("b-d",)


def test_score_needs_truth(flock):
    real = dataset_from_poses(flock.poses())
    with pytest.raises(sb.InputError, match="no ground truth"):
        sb.score(sb.calibrate(real), real)


def test_orient_scores_against_the_actual_orientations():
    ds = sb.simulate(model="humanoid", motion="static", sensors="mems-industrial", duration_s=3, seed=5)
    ori = sb.orient(ds, method="triad")
    assert ori.q_w_s.shape == (ds.time_s.size, 16, 4) and ori.names == ds.sensors
    assert 0.05 < ori.score.total_rmse_deg < 2.0  # industrial MEMS noise, static: fractions of a degree
    rec = ds.imu()
    direct = estimate(rec, "triad")
    assert np.array_equal(ori.q_w_s, direct.q_enu, equal_nan=True)
    scored = score_orientation(direct.q_enu, rec.q_true, rec.names)
    assert ori.score.total_rmse_deg == scored.total_rmse_deg


def test_score_orientation_checks_shapes_and_masks():
    q = np.zeros((5, 2, 4))
    q[..., 0] = 1.0
    s = score_orientation(q, q, ["a", "b"], evaluate=np.array([1, 1, 0, 0, 0], bool))
    assert s.total_rmse_deg == 0.0 and s.per_sensor["a"]["samples"] == 2
    with pytest.raises(sb.InputError, match=r"shape \(F, 3, 4\)"):
        score_orientation(q, q, ["a", "b", "c"])


def test_read_opens_every_kind_into_the_api_types(flock, tmp_path):
    csv = tmp_path / "poses.csv"
    write_pose_csv(csv, flock.poses())
    from_csv = sb.read(csv)
    assert isinstance(from_csv, sb.Dataset) and from_csv.truth is None
    assert_allclose(from_csv.measured.p_w_s, flock.measured.p_w_s, rtol=0, atol=1e-12)
    h5 = tmp_path / "ds.h5"
    sb.write_dataset(h5, flock)
    from_h5 = sb.read(h5)
    assert from_h5.position_unit_scale == pytest.approx(0.94) and from_h5.truth is not None
    assert sb.calibrate(from_csv).parent_of == sb.calibrate(from_h5).parent_of
    with pytest.raises(sb.InputError, match="unknown pose file type"):
        sb.read(tmp_path / "poses.xyz")
    with pytest.raises(sb.InputError, match="Expected a Dataset or a PoseRecording"):
        sb.calibrate(sb.simulate(duration_s=1).imu())


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="../shared/data not beside the repository")
def test_read_real_recordings():
    broad = sb.read(SHARED_DATA / "broad_02_undisturbed_slow_rotation_B.hdf5")
    assert isinstance(broad, sb.ImuRecording) and broad.q_true is not None
    assert sb.orient(broad, method="triad").score.per_sensor["imu"]["samples"] > 10_000
    hip = sb.read(SHARED_DATA / "biobuddy_right_hip.c3d", clusters=ROOT / "studies" / "hip_c3d.toml")
    assert isinstance(hip, sb.Dataset) and len(hip.sensors) >= 3


def test_api_arguments_of_the_wrong_kind_are_named(flock):
    import dataclasses

    from simbench.errors import InputError

    for kwargs, message in (
        ({"placement": {"chest": (0.0, 0.0)}}, r"placement 'chest': expected a finite shift \(dx, dy, dz\)"),
        ({"placement": {"chest": (0.0, float("nan"), 0.0)}}, "placement 'chest': expected a finite shift"),
        ({"model": 3}, "Expected model to be a name or a file path"),
        ({"sensors": {"tracker": {}}}, "Expected sensors to be a preset name, a TOML path or a SensorConfig"),
        ({"seed": 1.7}, "Expected seed to be an integer, got 1.7"),
    ):
        with pytest.raises(InputError, match=message):
            sb.simulate(duration_s=0.5, **kwargs)
    cal = sb.calibrate(flock)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match=r"scale .* finite number > 0"):
            sb.score(cal, flock, scale=bad)
    other = sb.simulate(model="humanoid", duration_s=0.5, seed=2)
    with pytest.raises(InputError, match=r"are not the dataset's .* a calibration of another recording"):
        sb.score(cal, other)
    rec = sb.simulate(model="linkage", duration_s=1.0, sensors="mems-industrial", seed=1).imu()
    for change, message in (
        ({"acc": rec.acc.transpose(1, 0, 2)}, r"expected acc as an array of shape \(120, \d+, 3\)"),
        ({"names": rec.names[:-1]}, "expected acc as an array of shape"),
        ({"names": (rec.names[0],) * len(rec.names)}, "sensor names must be unique"),
        ({"mag": rec.mag.tolist()}, r"expected mag as an array of shape .* got list"),
    ):
        with pytest.raises(InputError, match=message):
            sb.orient(dataclasses.replace(rec, **change), method="triad")
