"""Hierarchy from the minimum spanning tree of residuals (O'Brien 3.3), given hierarchies, loops."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import CalibrationError, CalibrationInputError, calibrate, hierarchy_from_parents
from calibration.hierarchy import spanning_tree
from calibration.rotations import rotvec_to_matrix
from simbench.sim.synthetic import HINGE, Segment, Skeleton, chain, linkage, random_tree, simulate_motion


def inferred(cap, root=None):
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names, root=root)
    return cal


@pytest.mark.parametrize(
    "skeleton",
    [
        chain([0.4, 0.35, 0.3, 0.25], ["ball", HINGE, "ball", "ball"]),
        linkage(),
        random_tree(12, np.random.default_rng(1)),
        random_tree(16, np.random.default_rng(2)),
    ],
    ids=["chain", "linkage", "tree12", "tree16"],
)
def test_noise_free_hierarchy_exact(skeleton):
    cap = simulate_motion(skeleton, n_frames=400, rate_hz=100.0, rng=np.random.default_rng(0))
    cal = inferred(cap, root=skeleton.names[0])
    assert cal.parent_of == skeleton.parent_of
    assert cal.loop_candidates == ()


def test_noisy_linkage_hierarchy(linkage_noisy):
    cal = inferred(linkage_noisy)
    assert cal.root == "chest"  # the documented centre rule
    assert cal.parent_of == linkage_noisy.skeleton.parent_of


def test_root_rule_picks_centre_of_chain():
    cap = simulate_motion(chain([0.3] * 4), n_frames=300, rate_hz=100.0, rng=np.random.default_rng(0))
    assert inferred(cap).root == "s2"


def test_tiny_weights_are_kept():
    # scipy would drop 1e-15 as a missing edge; ranks keep the order
    res = np.array(
        [
            [np.inf, 1e-15, 0.3, 0.2],
            [1e-15, np.inf, 2e-15, 0.5],
            [0.3, 2e-15, np.inf, 3e-16],
            [0.2, 0.5, 3e-16, np.inf],
        ]
    )
    tree = spanning_tree(res, root=0)
    assert tree.parent.tolist() == [-1, 0, 1, 2]


def test_disconnected_sensors_named():
    res = np.full((4, 4), np.inf)
    res[0, 1] = res[1, 0] = 0.1
    res[2, 3] = res[3, 2] = 0.1
    with pytest.raises(CalibrationError, match=r"\[\['a', 'b'\], \['c', 'd'\]\]"):
        spanning_tree(res, names=["a", "b", "c", "d"])


def test_given_hierarchy_is_used(linkage_noisy):
    cap = linkage_noisy
    wrong = {
        "head": "chest",
        "upper_arm_l": "head",
        "forearm_l": "upper_arm_l",
        "upper_arm_r": "chest",
        "forearm_r": "upper_arm_r",
    }
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=wrong)
    assert cal.parent_of == wrong and cal.hierarchy_given
    assert {j.name: j.fit.rms_residual for j in cal.joints}["head-upper_arm_l"] > 0.05


@pytest.mark.parametrize(
    ("mapping", "root", "message"),
    [
        ({"b": "a", "c": "x"}, None, r"names sensors the data lacks: \['x'\]"),
        ({"b": "a"}, None, r"sensors without a parent: \['a', 'c'\]"),
        ({"b": "c", "c": "b"}, None, r"sensors without a parent: \['a'\]|cycle"),
        ({"a": "b", "b": "c", "c": "a"}, None, "sensors without a parent: \\[\\]"),
        ({"b": "b", "c": "a"}, None, "their own parent"),
        ({"b": "a", "c": "a"}, "b", "--root is 'b' but the hierarchy's root is 'a'"),
    ],
)
def test_given_hierarchy_errors(mapping, root, message):
    with pytest.raises(CalibrationInputError, match=message):
        hierarchy_from_parents(mapping, ["a", "b", "c"], root=root)


def test_cycle_detected():
    with pytest.raises(CalibrationInputError, match=r"cycle.*\['c', 'd'\]"):
        hierarchy_from_parents({"b": "a", "c": "d", "d": "c"}, ["a", "b", "c", "d"])


def test_two_sensors_on_one_piece_reported_as_loop_candidate():
    segs = linkage().segments
    # a second sensor on the head piece: rigid to the first, and joined to the chest at the neck
    twin = Segment("head2", "head", (0.0, 0.0, 0.0), "ball", sensor_offset=(0.05, 0.1, -0.02))
    sk = Skeleton((*segs, twin))
    cap = simulate_motion(sk, n_frames=500, rate_hz=100.0, rng=np.random.default_rng(3), amplitude_rad=0.8)
    # make head2 rigid to head: copy head's body motion, offset the sensor
    h, h2 = cap.names.index("head"), cap.names.index("head2")
    R_w_b = cap.R_w_s[:, h] @ rotvec_to_matrix(np.array(segs[1].sensor_rotvec)).T
    p_w_b = cap.p_w_s[:, h] - np.einsum("fij,j->fi", R_w_b, segs[1].sensor_offset)
    R = cap.R_w_s.copy()
    p = cap.p_w_s.copy()
    R[:, h2] = R_w_b
    p[:, h2] = p_w_b + np.einsum("fij,j->fi", R_w_b, twin.sensor_offset)
    cal = calibrate(R, p, cap.names, root="chest")
    pairs = {frozenset((a, b)) for a, b, _ in cal.loop_candidates}
    # the three sensors chest, head, head2 are pairwise "joined"; the tree keeps two of the three
    assert len(pairs) == 1
    assert pairs <= {frozenset(x) for x in (("chest", "head"), ("chest", "head2"), ("head", "head2"))}
    assert any("loop joint" in w for w in cal.warnings)
