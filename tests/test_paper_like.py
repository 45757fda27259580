"""The paper-like world (issue 13): the tracker's range law, joint play in MuJoCo, the shoulder
girdle, the female subject, and the linkage's Table 1 reproduced by the fitted preset."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.rotations import quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError
from simbench.experiments.obrien import (
    HUMANOID_ROWS,
    LINKAGE_ROWS,
    explain,
    linkage_experiment,
    rigid_pair_scale,
)
from simbench.experiments.paper_tables import TABLE_1, TABLE_4, difference_summary, side_by_side
from simbench.score import truth_lengths
from simbench.sim.models import load_capture_model
from simbench.sim.sensor_config import load_sensor_config, parse_sensor_config
from simbench.sim.sensor_models import TrackerConfig, apply_tracker
from simbench.sim.session import SessionConfig, load_session_model, run_session
from simbench.sim.skin import SkinGirdle, girdle_offsets
from simbench.sim.variants import VARIANTS


def test_range_law_scales_along_and_across_the_line_of_sight():
    """A point at range r is reported at r (r / r_ref)^k on the same ray: lengths across the line
    of sight scale by (r/r_ref)^k, lengths along it by (1 + k)(r/r_ref)^k."""
    k = -0.05
    c = np.array([0.2, -0.8, 1.0])
    r = 1.6
    u = np.array([0.0, 1.0, 0.0])
    v = np.array([1.0, 0.0, 0.0])
    h = 1e-4
    p = c + np.array([r * u, (r + h) * u, r * u + h * v])[None]  # (1, 3, 3): a point, along, across
    q = np.tile([1.0, 0.0, 0.0, 0.0], (1, 3, 1))
    got, _, _ = apply_tracker(
        np.zeros(1), p, q, TrackerConfig(transmitter_pos=tuple(c), range_exponent=k), None
    )
    assert_allclose(got[0, 0], c + r ** (1 + k) * u, atol=1e-12)
    along = np.linalg.norm(got[0, 1] - got[0, 0]) / h
    across = np.linalg.norm(got[0, 2] - got[0, 0]) / h
    assert_allclose(along, (1 + k) * r**k, rtol=1e-4)
    assert_allclose(across, r**k, rtol=1e-4)


def test_range_law_off_is_exact_and_bad_values_are_named():
    p = np.random.default_rng(0).normal(size=(5, 2, 3))
    q = np.tile([1.0, 0.0, 0.0, 0.0], (5, 2, 1))
    got, _, _ = apply_tracker(
        np.arange(5.0), p, q, TrackerConfig(range_exponent=0.0), np.random.default_rng(1)
    )
    assert np.array_equal(got, p)
    with pytest.raises(InputError, match="range_exponent must be a finite number"):
        TrackerConfig(range_exponent=float("nan"))


def test_joint_play_lets_the_ball_move_within_its_clearance():
    """With 0.5 mm of play the linkage's joint centres seen from parent and child part by up to
    sqrt(3) x 0.5 mm and no more (plus what the stops give under load); without play they
    coincide."""
    config = SessionConfig(model="linkage", motion="exercise", duration_s=4.0, seed=3, sensors="ideal")
    play = parse_sensor_config({"joints": {"play_m": 0.0005}}, "test")
    gaps = {}
    for label, sensors in (("rigid", "ideal"), ("play", play)):
        c = replace(config, sensors=sensors)
        ds = run_session(c, load_session_model(c))
        t = ds.truth
        R = quat_to_matrix(t.rigid.q_w_s)
        p = t.rigid.p_w_s
        index = {n: k for k, n in enumerate(ds.sensors)}
        parent = [index[x] for x in t.parent]
        child = [index[x] for x in t.child]
        from_parent = np.einsum("fjab,jb->fja", R[:, parent], t.joint_in_parent) + p[:, parent]
        from_child = np.einsum("fjab,jb->fja", R[:, child], t.joint_in_child) + p[:, child]
        gaps[label] = np.linalg.norm(from_parent - from_child, axis=2)
    assert gaps["rigid"].max() < 1e-6
    assert 0.2e-3 < np.median(gaps["play"].max(axis=0))
    assert gaps["play"].max() < np.sqrt(3) * 0.5e-3 + 0.3e-3


def test_joint_play_bad_values():
    with pytest.raises(InputError, match=r"joints\.play_m"):
        parse_sensor_config({"joints": {"play_m": -0.001}}, "test")
    with pytest.raises(InputError, match="joint play"):
        load_capture_model("linkage", joint_play_m=float("nan"))
    cm = load_session_model(SessionConfig(sensors="ideal"))
    with pytest.raises(InputError, match="need joint play"):
        run_session(SessionConfig(sensors=parse_sensor_config({"joints": {"play_m": 0.001}}, "t")), cm)


def _arm(rotvec: np.ndarray) -> np.ndarray:
    """Chest and left upper arm orientations ``(1, 2, 3, 3)`` with the arm turned by ``rotvec``."""
    return np.stack([np.eye(3), rotvec_to_matrix(np.asarray(rotvec, dtype=float))])[None]


def test_girdle_lifts_the_shoulder_by_a_share_of_the_elevation_in_any_plane():
    """90 degrees of elevation, ratio 1/3, pivot 15 cm medial: the centre turns 30 degrees about
    the pivot -- (0, 0.15 (cos 30 - 1), 0.15 sin 30) -- whether the arm is raised sideways or
    forwards; a twist about the arm's own axis moves nothing."""
    g = SkinGirdle(
        joint="arm", pivot_m=(0.0, -0.15, 0.0), axis=(1.0, 0.0, 0.0), limb_axis=(0.0, 0.0, -1.0), ratio=1 / 3
    )
    expected = [0.0, 0.15 * (np.cos(np.pi / 6) - 1), 0.15 * np.sin(np.pi / 6)]
    for rotvec in ([np.pi / 2, 0, 0], [0, -np.pi / 2, 0]):  # sideways (abduction), forwards (flexion)
        got = girdle_offsets(_arm(rotvec), ("chest", "arm"), [0], [1], [g])
        assert_allclose(got[0, 0], expected, atol=1e-12)
    assert_allclose(girdle_offsets(_arm([0, 0, 1.0]), ("chest", "arm"), [0], [1], [g]), 0.0, atol=1e-12)
    with pytest.raises(InputError, match=r"girdle\.joint 'leg'"):
        girdle_offsets(
            _arm([0, 0, 0]),
            ("chest", "arm"),
            [0],
            [1],
            [SkinGirdle("leg", (0, 0, 0), (1, 0, 0), (0, 0, -1), 0.3)],
        )
    with pytest.raises(InputError, match=r"girdle\.ratio"):
        SkinGirdle("arm", (0, 0, 0), (1, 0, 0), (0, 0, -1), 1.5)


def test_female_subject_has_table_4_lengths():
    """``humanoid-female``'s joint-to-joint lengths are Table 4's measured ones."""
    ds = run_session(SessionConfig(model="humanoid-female", motion="static", duration_s=0.5, sensors="ideal"))
    lengths = {k[0]: v * 100 for k, v in truth_lengths(ds).items()}
    rows = {row: key[0] for row, key in HUMANOID_ROWS.items()}  # row -> segment
    for row, segment in rows.items():
        assert lengths[segment] == pytest.approx(TABLE_4.measured_cm[row], abs=1e-6), row
    assert sorted(VARIANTS) == ["humanoid-female"]


def test_difference_summary_and_side_by_side():
    s = difference_summary({"a": [-1.0, 0.5], "b": [2.0, float("nan")]})
    assert s["max_abs_cm"] == 2.0 and s["max_row"] == "b"
    assert s["longer"] == 2 and s["n"] == 3
    assert s["mean_cm"] == pytest.approx(0.5)
    assert s["row_mean_cm"] == {"a": -0.25, "b": 2.0}
    assert s["largest_rows"] == ["b", "a"]
    run = {
        r: {"true_cm": m, "computed_cm": m + 1.0, "difference_cm": 1.0}
        for r, m in TABLE_1.measured_cm.items()
    }
    table = side_by_side(TABLE_1, [run, run])
    assert table["simbench"]["longer"] == 10
    assert table["rows"]["Between Shoulders"]["simbench_computed_cm"] == {"mean": 35.3, "sd": 0.0, "n": 2}
    assert table["paper"]["longer"] == 23  # the paper's computed lengths longer than measured
    with pytest.raises(ValueError, match="lack rows"):
        side_by_side(TABLE_1, [{"Between Shoulders": run["Between Shoulders"]}])


def test_paper_like_linkage_reproduces_table_1():
    """The fitted preset on the six seeded sets (set 6 with the sensors moved): the largest error
    within a factor 1.5 of the paper's 1.1 cm and 18-28 of the 30 computed lengths longer, every
    hierarchy right; with its systematic effects off the errors fall back below 0.5 cm."""
    scale = rigid_pair_scale()["scale"]
    assert scale == pytest.approx(0.94, abs=0.005)  # the paper's measured factor
    sets = linkage_experiment(6, 45.0, scale)["sets"]
    d = np.array([[s["rows"][r]["difference_cm"] for r in LINKAGE_ROWS] for s in sets])
    assert 1.1 / 1.5 <= np.abs(d).max() <= 1.1 * 1.5
    assert 18 <= int((d > 0).sum()) <= 28  # computed - true: positive where computed longer
    assert all(s["hierarchy_correct"] for s in sets)
    flock = load_sensor_config("ascension-flock")
    plain = linkage_experiment(6, 45.0, rigid_pair_scale(tracker=flock.tracker)["scale"], sensors=flock)
    assert max(s["max_abs_error_cm"] for s in plain["sets"]) < 0.5


def test_explain_names_the_cause_that_moves_the_paper_s_largest_row():
    """Two causes: switching off ``a`` moves the paper's largest row by 2 cm, ``b`` by 0.5 cm and
    the mean more: the sentence names ``a`` for the row and ``b`` for the mean, with the numbers."""
    rows = list(TABLE_1.rows)
    printed = {r: [-x for x in TABLE_1.printed_difference_cm[r]] for r in rows}  # computed - measured
    top = difference_summary(printed)["largest_rows"][0]

    def summary(top_value: float, other: float) -> dict:
        return difference_summary({r: [top_value if r == top else other] for r in rows})

    table = {"paper": difference_summary(printed), "simbench": summary(2.0, 0.5)}
    causes = {"a": summary(0.0, 0.5), "b": summary(1.5, -1.0), "all": summary(0.0, 0.0)}
    text = explain(table, causes)
    assert (
        f"the {top} (the paper's largest row, +0.38 cm on average) comes out 2.00 cm longer through the a"
        in text
    )
    assert (
        "(+2.00 cm with it, +0.00 without); the b moves the mean difference most (+0.80 with it, -0.50"
        in text
    )
