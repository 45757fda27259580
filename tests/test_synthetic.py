"""The analytic generator's ground truth is self-consistent (O'Brien eq. 8 holds exactly)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.sim.synthetic import HINGE, Segment, Skeleton, chain, linkage, random_tree, simulate_motion


@pytest.mark.parametrize(
    "skeleton",
    [linkage(), chain([0.4, 0.3, 0.25], [HINGE, "ball", HINGE]), random_tree(9, np.random.default_rng(3))],
    ids=["linkage", "chain", "random"],
)
def test_joints_stay_together(skeleton):
    cap = simulate_motion(skeleton, n_frames=300, rate_hz=100.0, rng=np.random.default_rng(0))
    truth = skeleton.joint_in_sensor_frames()
    for child, parent in skeleton.parent_of.items():
        p, c = cap.names.index(parent), cap.names.index(child)
        lp, lc = truth[child]
        at_p = np.einsum("fij,j->fi", cap.R_w_s[:, p], lp) + cap.p_w_s[:, p]
        at_c = np.einsum("fij,j->fi", cap.R_w_s[:, c], lc) + cap.p_w_s[:, c]
        # both are the world joint centre; rounding of ~1 m quantities only
        assert_allclose(at_p, at_c, atol=1e-13)
        assert_allclose(at_c, cap.joint_w[:, c], atol=1e-13)


def test_linkage_dimensions_are_the_papers():
    lengths = linkage().segment_lengths()
    expected = {
        ("chest", "chest-head", "chest-upper_arm_l"): 0.390,
        ("chest", "chest-head", "chest-upper_arm_r"): 0.397,
        ("chest", "chest-upper_arm_l", "chest-upper_arm_r"): 0.343,
        ("upper_arm_l", "chest-upper_arm_l", "upper_arm_l-forearm_l"): 0.314,
        ("upper_arm_r", "chest-upper_arm_r", "upper_arm_r-forearm_r"): 0.286,
    }
    assert set(lengths) == set(expected)
    for key, value in expected.items():
        assert lengths[key] == pytest.approx(value, abs=1e-12)


def test_seeded_and_noise_statistics():
    kw = dict(n_frames=4000, rate_hz=100.0, position_noise_m=0.002)
    a = simulate_motion(linkage(), rng=np.random.default_rng(5), **kw)
    b = simulate_motion(linkage(), rng=np.random.default_rng(5), **kw)
    c = simulate_motion(linkage(), rng=np.random.default_rng(6), **kw)
    assert np.array_equal(a.p_w_s, b.p_w_s)
    assert not np.array_equal(a.p_w_s, c.p_w_s)
    err = (a.p_w_s - a.p_w_s_true).ravel()
    # 72,000 samples: the sample std is within 2 % of 2 mm with overwhelming probability
    assert np.std(err) == pytest.approx(0.002, rel=0.02)


def test_skeleton_rejects_bad_order():
    with pytest.raises(ValueError, match="listed before"):
        Skeleton((Segment("a", None), Segment("b", "c"), Segment("c", "a")))
