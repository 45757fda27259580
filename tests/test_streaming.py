"""The streaming calibration (calibration.streaming): the batch calibration's answer at any time,
in constant memory, with causal slip alerts and operator guidance."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import calibrate, pair_statistics
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hinge import N_BLOCKS
from calibration.pair_sums import PairSums
from calibration.rotations import rotvec_to_matrix
from calibration.streaming import MIN_ROTATION_DEG, StreamingCalibrator
from simbench.sim.synthetic import Slip, random_tree, simulate_motion

RATE = 120.0


def _capture(n_frames=5000, seed=3, noise=0.004, slips=()):
    skeleton = random_tree(8, np.random.default_rng(2))
    cap = simulate_motion(
        skeleton,
        n_frames=n_frames,
        rate_hz=RATE,
        rng=np.random.default_rng(seed),
        position_noise_m=noise,
        slips=slips,
    )
    return skeleton, cap


def _feed(sc, R, p, valid, lo, hi, rng):
    """Push frames ``lo:hi`` in blocks of random sizes, some as single frames."""
    f = lo
    while f < hi:
        k = min(hi, f + int(rng.integers(1, 60)))
        if k - f == 1:
            sc.push(R[f], p[f], valid[f])
        else:
            sc.push(R[f:k], p[f:k], valid[f:k])
        f = k


def _assert_same(batch, live, *, rms_atol):
    assert live.parent_of == batch.parent_of and live.root == batch.root
    assert live.n_frames == batch.n_frames
    assert_allclose(live.missing, batch.missing, atol=0)
    for b, s in zip(batch.joints, live.joints, strict=True):
        assert (b.parent, b.child) == (s.parent, s.child)
        # 1e-9 m: the target; the sums differ only in the order of additions
        assert_allclose(s.fit.joint_in_parent, b.fit.joint_in_parent, rtol=0, atol=1e-9)
        assert_allclose(s.fit.joint_in_child, b.fit.joint_in_child, rtol=0, atol=1e-9)
        assert s.fit.rms_residual == pytest.approx(b.fit.rms_residual, rel=0, abs=rms_atol)
        assert (s.fit.rank, s.fit.single_axis, s.fit.n_frames) == (
            b.fit.rank,
            b.fit.single_axis,
            b.fit.n_frames,
        )
        assert_allclose(s.fit.singular_values, b.fit.singular_values, rtol=1e-9)
    finite = np.isfinite(batch.residual_matrix)
    assert np.array_equal(finite, np.isfinite(live.residual_matrix))
    assert_allclose(live.residual_matrix[finite], batch.residual_matrix[finite], rtol=0, atol=1e-9)
    assert [(a, b) for a, b, _ in live.loop_candidates] == [(a, b) for a, b, _ in batch.loop_candidates]
    assert_allclose([x.length for x in live.lengths], [x.length for x in batch.lengths], atol=1e-9)


# stops before, at and after block merges (32 frames, 64, ...) and a partial last block
STOPS = (3, 32, 33, 100, 1025, 4097, 5000)


def test_equals_the_batch_calibration_at_every_stop():
    skeleton, cap = _capture()
    R, p = cap.R_w_s, cap.p_w_s
    valid = np.ones(R.shape[:2], dtype=bool)
    valid[1000:1100, 3] = False  # a dropout: blocks with fewer frames for its pairs
    R = R.copy()
    R[2000, 5] = np.nan  # a non-finite pose is missing, as in the batch
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    rng = np.random.default_rng(0)
    done = 0
    for stop in STOPS:
        _feed(sc, R, p, valid, done, stop, rng)
        done = stop
        live = sc.calibration()
        fast = calibrate(R[:stop], p[:stop], skeleton.names, valid=valid[:stop], keep_frame_residuals=False)
        exact = calibrate(R[:stop], p[:stop], skeleton.names, valid=valid[:stop])
        _assert_same(fast, live, rms_atol=1e-9)
        # the batch default recomputes residuals from the data: 4 mm of noise, far above the
        # normal equations' rounding floor, so they agree to 1e-9 m too
        _assert_same(exact, live, rms_atol=1e-9)
    edges = {frozenset(j) for j in sc.calibration().parent_of.items()}
    assert edges == {frozenset(j) for j in skeleton.parent_of.items()}  # and the tree is right


def test_statistics_hold_the_batch_blocks():
    skeleton, cap = _capture(n_frames=3000)
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE, slip=False)
    _feed(sc, cap.R_w_s, cap.p_w_s, np.ones(cap.R_w_s.shape[:2], bool), 0, 3000, np.random.default_rng(1))
    live, batch = sc.statistics(), pair_statistics(cap.R_w_s, cap.p_w_s)
    assert live.block_count.shape == batch.block_count.shape and live.block_count.shape[0] <= N_BLOCKS
    assert np.array_equal(live.block_count, batch.block_count)  # the same frames in every block
    # sums of ~100 rotation products per block, added in another order
    assert_allclose(live.block_gram, batch.block_gram, rtol=0, atol=1e-10)
    assert_allclose(
        live.block_cross - live.block_self_cross, batch.block_cross - batch.block_self_cross, atol=1e-10
    )


def test_known_hierarchy_and_paper_tree_equal_the_batch():
    skeleton, cap = _capture(n_frames=2000)
    R, p = cap.R_w_s, cap.p_w_s
    ok = np.ones(R.shape[:2], dtype=bool)
    for kwargs in (
        {"parent_of": dict(skeleton.parent_of)},
        {"hierarchy_method": "mst", "root": skeleton.names[2]},
    ):
        sc = StreamingCalibrator(skeleton.names, rate_hz=RATE, slip=False, **kwargs)
        _feed(sc, R, p, ok, 0, 2000, np.random.default_rng(2))
        batch = calibrate(R, p, skeleton.names, keep_frame_residuals=False, **kwargs)
        _assert_same(batch, sc.calibration(), rms_atol=1e-9)


def test_noise_free_data_equal_the_batch_centres():
    skeleton, cap = _capture(n_frames=1500, noise=0.0)
    R, p = cap.R_w_s, cap.p_w_s
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    _feed(sc, R, p, np.ones(R.shape[:2], bool), 0, 1500, np.random.default_rng(3))
    live = sc.calibration()
    batch = calibrate(R, p, skeleton.names)
    truth = skeleton.joint_in_sensor_frames()
    for b, s in zip(batch.joints, live.joints, strict=True):
        assert_allclose(s.fit.joint_in_parent, b.fit.joint_in_parent, atol=1e-9)
        assert_allclose(s.fit.joint_in_child, b.fit.joint_in_child, atol=1e-9)
        # exact data, exact joint (the tree may be rooted elsewhere than the skeleton)
        if skeleton.parent_of.get(s.child) == s.parent:
            assert_allclose(s.fit.joint_in_parent, truth[s.child][0], atol=1e-9)
        else:
            assert_allclose(s.fit.joint_in_child, truth[s.parent][0], atol=1e-9)
        # the residual is at the normal equations' rounding floor (pairs.py: below about 1e-8 m)
        assert s.fit.rms_residual < 1e-7
    assert sc.alerts == ()  # nothing moves: no slip


def test_memory_does_not_grow_with_the_session():
    skeleton, cap = _capture(n_frames=6000, noise=0.002)
    R, p = cap.R_w_s, cap.p_w_s
    sizes = []
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    block_bytes = sum(x.nbytes for x in vars(PairSums(8)).values() if isinstance(x, np.ndarray))
    for _ in range(4):  # the same 50 s again and again: 200 s in all
        sc.push(R, p)
        assert len(sc._blocks) <= N_BLOCKS
        sizes.append(sc.nbytes - len(sc._blocks) * block_bytes)
    assert sc.n_frames == 24000
    # besides at most N_BLOCKS blocks, nothing grows once the slip history (60 s) is full
    assert sizes[1] == sizes[2] == sizes[3]


def test_bad_input_names_expected_and_received_shapes():
    sc = StreamingCalibrator(["a", "b", "c"], rate_hz=RATE)
    with pytest.raises(
        CalibrationInputError,
        match=r"Expected R_w_s to have shape \(3, 3, 3\) or \(frames, 3, 3, 3\), got \(2, 3, 3\)",
    ):
        sc.push(np.zeros((2, 3, 3)), np.zeros((2, 3)))
    with pytest.raises(
        CalibrationInputError, match=r"Expected p_w_s to have shape \(5, 3, 3\) to match R_w_s, got \(5, 3\)"
    ):
        sc.push(np.zeros((5, 3, 3, 3)), np.zeros((5, 3)))
    with pytest.raises(CalibrationInputError, match=r"Expected valid to have shape \(3,\), got \(2,\)"):
        sc.push(np.zeros((3, 3, 3)), np.zeros((3, 3)), np.ones(2, bool))
    with pytest.raises(CalibrationInputError, match="unique"):
        StreamingCalibrator(["a", "a"], rate_hz=RATE)
    with pytest.raises(CalibrationInputError, match="rate_hz"):
        StreamingCalibrator(["a", "b"], rate_hz=0.0)
    with pytest.raises(CalibrationError, match="at least 3 frames"):
        sc.calibration()
    assert sc.n_frames == 0  # refused input is not counted


def _two_sensors(rotvec, n=2400):
    """A parent sensor at rest and a child turning about the joint by ``rotvec`` (``(n, 3)``, parent
    frame), the joint 0.1 m from each sensor: exact, with 0.5 mm noise."""
    rng = np.random.default_rng(4)
    lp, lc = np.array([0.1, 0.02, 0.0]), np.array([-0.1, 0.0, 0.03])
    R = np.zeros((n, 2, 3, 3))
    R[:, 0] = np.eye(3)
    R[:, 1] = rotvec_to_matrix(rotvec)
    p = np.zeros((n, 2, 3))
    p[:, 1] = lp - np.einsum("fab,b->fa", R[:, 1], lc)
    return R, p + rng.normal(scale=5e-4, size=p.shape)


def test_guidance_from_the_joints_conditioning():
    t = np.arange(2400) / RATE
    amp = np.radians(30.0)
    hinge = np.stack([amp * np.sin(2 * t), 0 * t, 0 * t], axis=1)  # about the parent's x only
    ball = np.stack([amp * np.sin(2 * t), amp * np.sin(1.3 * t + 1), 0 * t], axis=1)
    small = ball * (np.radians(2.0) / amp)
    verdicts = {}
    for name, rv in (("hinge", hinge), ("ball", ball), ("small", small)):
        R, p = _two_sensors(rv)
        sc = StreamingCalibrator(["p", "c"], rate_hz=RATE, parent_of={"c": "p"}, slip=False)
        sc.push(R, p)
        verdicts[name] = sc.state().coverage[0]
    hinge_cov = verdicts["hinge"]
    # a sinusoid of 30 degrees has 21.2 degrees rms; the small-angle reading is within 10 %
    assert hinge_cov.rotation_rms_deg[0] == pytest.approx(30.0 / np.sqrt(2), rel=0.1)
    assert abs(hinge_cov.axes_in_parent[0][0]) > 0.99  # turned about x
    assert hinge_cov.rotation_rms_deg[1] < 1.0
    assert abs(hinge_cov.axes_in_parent[1][0]) < 0.05  # the next axis is across x
    # found single-axis: it cannot turn across its axis, so its own axis decides
    assert hinge_cov.moved_enough and hinge_cov.advice.startswith("single-axis joint, axis [1.0, ")
    short = StreamingCalibrator(["p", "c"], rate_hz=RATE, parent_of={"c": "p"}, slip=False)
    R, p = _two_sensors(hinge * (np.radians(3.0) / amp))  # 3 degrees about x: not enough
    short.push(R, p)
    small_hinge = short.state().coverage[0]
    assert short.state().calibration.joints[0].fit.single_axis  # 2.1 degrees rms, still a hinge
    assert not small_hinge.moved_enough
    assert small_hinge.advice.startswith("single-axis joint: move more about its axis [1.0, ")
    assert verdicts["ball"].moved_enough and verdicts["ball"].advice == "moved enough"
    assert verdicts["ball"].rotation_rms_deg[1] > MIN_ROTATION_DEG
    assert not verdicts["small"].moved_enough  # 2 degrees in two axes is not enough


def test_causal_alert_after_a_slip_and_no_other():
    # 2 mm of noise, a 2 cm slip of one sensor at 40 s (frame 4800) of 60 s
    skeleton, _ = _capture(n_frames=10)
    sensor = skeleton.names[4]
    slip_frame = 4800
    _, cap = _capture(n_frames=7200, seed=5, noise=0.002, slips=[Slip(sensor, slip_frame, (0.0, 0.02, 0.0))])
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    raised = []
    for lo in range(0, 7200, 12):  # 0.1 s blocks, as a driver would deliver them
        sc.push(cap.R_w_s[lo : lo + 12], cap.p_w_s[lo : lo + 12])
        raised += [(lo + 12, a) for a in sc.new_alerts()]
    assert len(raised) == 1, [a.message for _, a in raised]
    pushed, alert = raised[0]
    assert alert.sensor == sensor
    assert 0 <= (pushed - slip_frame) / RATE <= 0.5  # raised within 0.5 s of the slip
    assert abs(alert.frame - slip_frame) <= 6  # located within 50 ms
    assert alert.size_m == pytest.approx(0.02, abs=0.005)  # 2 mm noise over a quarter second
    assert alert.message.startswith(f"sensor {sensor} may have slipped at 40.0")
    assert alert.message.endswith("cm")
    # the same session without the slip raises nothing
    _, clean = _capture(n_frames=7200, seed=5, noise=0.002)
    quiet = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    quiet.push(clean.R_w_s, clean.p_w_s)
    assert quiet.alerts == ()


def test_batched_correlation_time_is_slip_stats():
    from calibration.slip_stats import correlation_frames
    from calibration.streaming import _correlation_frames

    rng = np.random.default_rng(6)
    x = np.cumsum(rng.normal(size=(3000, 4)), axis=0) * 0.01 + rng.normal(size=(3000, 4))
    x[:, 3] = 1.0  # a constant: no correlation to measure
    want = [correlation_frames(x[:, k]) for k in range(4)]
    assert_allclose(_correlation_frames(x), want, rtol=1e-9)


def test_equals_the_batch_on_a_simulated_session():
    # MuJoCo physics, Polhemus Liberty noise, latency and dropouts (6 missing poses), 20 s at 120 Hz
    from simbench.sim.plan import SessionConfig, load_session_model
    from simbench.sim.session import run_session

    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=20.0, seed=3, sensors="polhemus-liberty"
    )
    rec = run_session(config, load_session_model(config)).poses()
    sc = StreamingCalibrator(rec.names, rate_hz=rec.rate_hz)
    rng = np.random.default_rng(7)
    done = 0
    for stop in (500, 1201, rec.time_s.size):
        _feed(sc, rec.R_w_s, rec.p_w_s, rec.valid, done, stop, rng)
        done = stop
        sl = slice(0, stop)
        batch = calibrate(rec.R_w_s[sl], rec.p_w_s[sl], rec.names, valid=rec.valid[sl])
        # the batch's exact residuals: millimetres of noise, far above the rounding floor
        _assert_same(batch, sc.calibration(), rms_atol=1e-9)


def test_slip_statistic_is_the_window_difference_with_the_joint_as_fitted_now():
    # the monitor keeps window differences of pose products, in which d is affine in the joint:
    # with any joint they give exactly the window difference of the residual in each frame
    from calibration.slip_stats import window_difference

    skeleton, cap = _capture(n_frames=600, noise=0.003)
    valid = np.random.default_rng(4).random((600, 8)) > 0.1  # missing poses in the windows
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    sc.push(cap.R_w_s, cap.p_w_s, valid)
    monitor = sc._monitor
    d, frames = monitor._latest
    assert frames[-1] == 599
    w = monitor.w
    fitted = (monitor.lp, monitor.lc)
    other = np.random.default_rng(5).normal(scale=0.1, size=(2, len(monitor.keys), 3))
    for lp, lc in (fitted, other):
        after, before = monitor.q[w:], monitor.q[:w]  # the last 2 w frames' products
        delta = after[..., :15].sum(0) / after[..., 15:].sum(0) - before[..., :15].sum(0) / before[
            ..., 15:
        ].sum(0)
        got = monitor._d(delta, lp, lc)  # (J, 2, 3)
        for k, (a, b) in enumerate(monitor.keys):
            Rp, Rc = cap.R_w_s[:, a], cap.R_w_s[:, b]
            ok = valid[:, a] & valid[:, b]
            r = np.einsum("fab,b->fa", Rp, lp[k]) + cap.p_w_s[:, a] - np.einsum("fab,b->fa", Rc, lc[k])
            r -= cap.p_w_s[:, b]
            for side, Rs in enumerate((Rp, Rc)):
                e = np.einsum("fba,fb->fa", Rs, r)
                want = window_difference(e, ok, w)[600 - w]  # [600 - 2w, 600 - w) against [600 - w, 600)
                assert_allclose(got[k, side], want, atol=1e-12)
                if lp is fitted[0]:  # what the monitor tested at the last frame
                    assert_allclose(d[-1, k, side], want, atol=1e-12)


def test_a_joint_whose_parent_and_child_swap_keeps_its_slip_history():
    # a new root turns a joint round: its residual changes sign and its two frames swap, so its
    # history's window differences give d' = -d with the frames swapped (the joint kept, not reset)
    from calibration.streaming import _flipped

    skeleton, cap = _capture(n_frames=400, noise=0.003)
    sc = StreamingCalibrator(skeleton.names, rate_hz=RATE)
    sc.push(cap.R_w_s, cap.p_w_s)
    monitor = sc._monitor
    hist = monitor.hist[:, : int(monitor.n_hist.min())]  # (J, n, 15)
    lp, lc = monitor.lp, monitor.lc
    d = np.stack([monitor._d(hist[k], lp[k], lc[k]) for k in range(len(monitor.keys))])
    d_swapped = np.stack([monitor._d(_flipped(hist[k]), lc[k], lp[k]) for k in range(len(monitor.keys))])
    assert hist.shape[1] >= 10 and np.abs(d).max() > 1e-3  # something to compare
    assert_allclose(d_swapped, -d[..., ::-1, :], atol=1e-12)


def _pushed_one_at_a_time(names, R, p, valid, rate=RATE, **kwargs):
    sc = StreamingCalibrator(names, rate_hz=rate, **kwargs)
    for f in range(R.shape[0]):
        sc.push(R[f], p[f], valid[f])
    return sc


def test_a_joint_new_to_the_tree_gets_the_history_it_would_have_had():
    # the poses held in the ring give a joint that joins the tree exactly the window differences
    # the monitor would have kept had it followed the joint all along
    skeleton, cap = _capture(n_frames=900, noise=0.003)
    valid = np.random.default_rng(6).random((900, 8)) > 0.05
    sc = _pushed_one_at_a_time(skeleton.names, cap.R_w_s, cap.p_w_s, valid)
    monitor = sc._monitor
    assert sc.alerts == ()  # no frame left out of the histories
    for j in range(len(monitor.keys)):
        n = int(monitor.n_hist[j])
        kept = monitor.hist[j, :n].copy()
        monitor.hist[j], monitor.n_hist[j] = 0.0, 0
        monitor._backfill(np.array([j]))
        k = int(monitor.n_hist[j])
        assert monitor.warmup <= k < n  # a warm-up's history, not the whole
        assert_allclose(monitor.hist[j, :k], kept[n - k :], rtol=0, atol=1e-12)


def test_joints_arm_as_their_pairs_are_seen_not_when_the_tree_settles():
    # a leaf sensor hidden for the first 5 s (a marker cluster out of view): the other joints arm
    # 3 s after the start, the leaf's joint 3 s after it appears (plus at most one refit), and
    # nothing is alerted
    from calibration.streaming import FLUSH_S, REFIT_S

    skeleton, cap = _capture(n_frames=1500, noise=0.003)
    parents = {seg.parent for seg in skeleton.segments}
    leaf = next(s.name for s in reversed(skeleton.segments) if s.name not in parents)
    hidden_s = 5.0
    valid = np.ones((1500, 8), dtype=bool)
    valid[: round(hidden_s * RATE), skeleton.names.index(leaf)] = False
    sc = _pushed_one_at_a_time(skeleton.names, cap.R_w_s, cap.p_w_s, valid)
    armed = sc.slip_armed_s()
    joints = {j.name: j for j in sc.calibration().joints}
    assert set(armed) >= set(joints)
    for name, joint in joints.items():
        if leaf in (joint.parent, joint.child):
            # (armed at a refit, which comes before the flush's frames are examined)
            assert hidden_s + 3.0 - FLUSH_S - 1 / RATE <= armed[name] <= hidden_s + 3.0 + REFIT_S, (
                name,
                armed[name],
            )
        else:
            assert armed[name] <= 3.0, (name, armed[name])
    assert sc.alerts == ()


def test_a_joint_kept_over_a_refit_arms_and_one_that_returns_keeps_its_history():
    skeleton, cap = _capture(n_frames=720, noise=0.003)
    sc = _pushed_one_at_a_time(skeleton.names, cap.R_w_s, cap.p_w_s, np.ones((720, 8), dtype=bool))
    assert sc._refit_at % sc._refit_every == 0  # refits at multiples of REFIT_S of the stream
    monitor = sc._monitor
    keys, lp, lc = list(monitor.keys), monitor.lp.copy(), monitor.lc.copy()
    assert np.isfinite(monitor.threshold).all()
    saved = monitor.hist[0, : monitor.n_hist[0]].copy()
    # the tree swaps joint 0 for a pair that is no joint: a tie of the weights at one refit
    pair = next(
        (a, b)
        for a in range(8)
        for b in range(a + 1, 8)
        if (a, b) not in keys and (b, a) not in keys and a not in keys[0] and b not in keys[0]
    )
    swapped = [*keys[1:], pair]
    monitor.set_joints(swapped, np.vstack([lp[1:], np.zeros(3)]), np.vstack([lc[1:], np.zeros(3)]))
    new = swapped.index(pair)
    assert monitor.n_hist[new] >= monitor.warmup  # its history is there (the ring)...
    assert np.isinf(monitor.threshold[new]).all()  # ... but it is not armed at its first refit
    assert np.isfinite(np.delete(monitor.threshold, new, axis=0)).all()
    monitor.set_joints(swapped, np.vstack([lp[1:], np.zeros(3)]), np.vstack([lc[1:], np.zeros(3)]))
    assert np.isfinite(monitor.threshold[new]).all()  # kept over a refit: armed
    monitor.set_joints(keys, lp, lc)  # joint 0 returns with its history
    assert_allclose(monitor.hist[0, : saved.shape[0]], saved, rtol=0, atol=0)
    assert monitor.n_hist[0] == saved.shape[0]
