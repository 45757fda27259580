"""Frames whose pose noise drowns the rest (:mod:`calibration.frame_noise`, ``drop_noisy_frames``).

Analytic captures of O'Brien's linkage (exact truth) with steady noise, with no noise, and with
noise that jumps 200-fold for most of the recording (a magnetic tracker carried far from its
transmitter); and a simulated humanoid walking away from an Ascension Flock of Birds.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import simbench as sb
from calibration import calibrate
from calibration import frame_noise as fn
from calibration.frame_noise import noisy_frames
from simbench.cli import main
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.sim.synthetic import SyntheticCapture, linkage, simulate_motion

QUIET_M, FAR_M = 0.001, 0.2


def _capture(seed: int, noise_m: float = 0.0, n_frames: int = 3000) -> SyntheticCapture:
    return simulate_motion(
        linkage(), n_frames=n_frames, rate_hz=120.0, rng=np.random.default_rng(seed), position_noise_m=noise_m
    )


def _far(seed: int) -> tuple[SyntheticCapture, np.ndarray]:
    """The exact linkage with 1 mm of noise on the first 40 % of frames and 200 mm after, and
    the ``(F,)`` mask of the far frames."""
    cap = _capture(seed)
    f = cap.p_w_s.shape[0]
    far = np.arange(f) >= int(0.4 * f)
    sigma = np.where(far, FAR_M, QUIET_M)[:, None, None]
    noise = sigma * np.random.default_rng(seed + 100).normal(size=cap.p_w_s.shape)
    return dataclasses.replace(cap, p_w_s=cap.p_w_s_true + noise), far


def _valid(cap: SyntheticCapture) -> np.ndarray:
    return np.ones(cap.p_w_s.shape[:2], dtype=bool)


def _rms_centre_error(cap: SyntheticCapture, cal) -> float:
    """RMS over joints of the centre error in the parent's frame, m; the calibration on the true
    tree (the exact centre is ``R_p^T (joint_w - p_p)``, constant over frames)."""
    out = []
    for j in cal.joints:
        k, pk = cap.names.index(j.child), cap.names.index(j.parent)
        truth = np.einsum("ji,j->i", cap.R_w_s_true[0, pk], cap.joint_w[0, k] - cap.p_w_s_true[0, pk])
        out.append(np.linalg.norm(j.fit.joint_in_parent - truth))
    return float(np.sqrt(np.mean(np.square(out))))


@pytest.mark.parametrize("noise_m", [0.0005, 0.003, 0.01])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_steady_noise_leaves_no_frame_out(seed, noise_m):
    cap = _capture(seed, noise_m)
    out = noisy_frames(cap.p_w_s, _valid(cap))
    assert not out.mask.any()
    assert np.all(out.gain < fn.MIN_GAIN)
    # each frame's estimate of the noise is unbiased, read off the poses alone; the quietest
    # tenth of the estimates lies below it, by their spread
    s2, *_ = fn.frame_noise(cap.p_w_s, _valid(cap))
    assert np.allclose(np.sqrt(np.nanmean(s2, axis=0) / 3.0), noise_m, rtol=0.05)
    assert np.all((out.quiet_m > 0.7 * noise_m) & (out.quiet_m < noise_m))


def test_noise_free_motion_leaves_no_frame_out(linkage_exact):
    out = noisy_frames(linkage_exact.p_w_s, np.ones(linkage_exact.p_w_s.shape[:2], dtype=bool))
    assert not out.mask.any()


def test_noise_free_impacts_leave_no_frame_out():
    """A simulated humanoid walking (heel strikes: kinks in the velocity) with exact poses: the
    third differences are the motion's, not noise, and nothing goes."""
    ds = sb.simulate(model="humanoid", motion="walk", duration_s=10.0, seed=3, sensors="ideal")
    rec = ds.poses()
    out = noisy_frames(rec.p_w_s, rec.valid)
    assert not out.mask.any()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_far_frames_are_left_out(seed):
    cap, far = _far(seed)
    out = noisy_frames(cap.p_w_s, _valid(cap))
    # a window that reaches past the jump sees the far noise
    near_jump = np.abs(np.arange(far.size) - np.argmax(far)) <= fn.WINDOW_FRAMES // 2 + 2
    for k in range(len(cap.names)):
        assert out.mask[far, k].all(), cap.names[k]
        assert not out.mask[~far & ~near_jump, k].any(), cap.names[k]
        assert out.gain[k] > 10.0
        assert out.quiet_m[k] == pytest.approx(QUIET_M, rel=0.2)
        assert out.dropped_median_m[k] == pytest.approx(FAR_M, rel=0.2)
    lines = out.warnings(cap.names)
    assert len(lines) == len(cap.names)
    for name, line in zip(cap.names, lines, strict=True):
        assert line.startswith(f"sensor {name}: ") and "left out for their position noise" in line


def test_calibration_with_far_frames_left_out_is_the_quiet_frames_calibration():
    cap, far = _far(4)
    tree = cap.skeleton.parent_of
    plain = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=tree)
    dropped = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=tree, drop_noisy_frames=True)
    quiet_only = calibrate(cap.R_w_s, cap.p_w_s, cap.names, parent_of=tree, valid=~far[:, None] & _valid(cap))
    assert plain.noisy_frames is None and dropped.noisy_frames is not None
    # the far frames make the plain fit 10 times worse and more; left out, it is the quiet frames'
    e_plain, e_dropped, e_quiet = (_rms_centre_error(cap, c) for c in (plain, dropped, quiet_only))
    assert e_plain > 10 * e_quiet
    assert e_dropped < 1.5 * e_quiet
    # the inferred hierarchy is the true one again
    inferred = calibrate(cap.R_w_s, cap.p_w_s, cap.names, drop_noisy_frames=True)
    assert inferred.parent_of == {c: p for c, p in tree.items() if p}
    # a pose left out for its noise is not missing; the warnings say which it was
    assert not dropped.missing.any()
    assert any("left out for their position noise" in w for w in dropped.warnings)
    assert not any("pose missing or not finite in" in w for w in dropped.warnings)


def test_off_by_default_and_off_is_the_plain_calibration():
    cap, _ = _far(5)
    a = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    b = calibrate(cap.R_w_s, cap.p_w_s, cap.names, drop_noisy_frames=False)
    for x, y in zip(a.joints, b.joints, strict=True):
        assert np.array_equal(x.fit.joint_in_parent, y.fit.joint_in_parent)
    assert a.warnings == b.warnings


def test_chunks_do_not_change_the_choice(monkeypatch):
    cap, _ = _far(6)
    whole = noisy_frames(cap.p_w_s, _valid(cap))
    monkeypatch.setattr(fn, "MIN_CHUNK_FRAMES", 1)
    chunked = noisy_frames(cap.p_w_s, _valid(cap), chunk_frames=257)
    assert np.array_equal(whole.mask, chunked.mask)
    assert np.allclose(whole.gain, chunked.gain, rtol=1e-12)


def test_missing_poses_and_short_recordings():
    cap, far = _far(7)
    valid = _valid(cap)
    valid[:, 2] = False  # a sensor never seen
    valid[::7, 3] = False  # one with dropouts
    p = np.where(valid[..., None], cap.p_w_s, np.nan)
    out = noisy_frames(p, valid)
    assert not out.mask[:, 2].any() and np.isnan(out.quiet_m[2])
    assert not out.mask[~valid].any()  # only valid poses are left out
    assert out.mask[far & valid[:, 3], 3].mean() > 0.95
    short = noisy_frames(cap.p_w_s[:40], _valid(cap)[:40])  # too few frames to tell
    assert not short.mask.any()


def test_humanoid_walking_away_from_a_flock_of_birds():
    """The Flock of Birds' noise grows as the fourth power of the range (docs/conventions.md): the walk
    takes the sensors metres out. Leaving out the frames whose noise drowns the rest brings the
    joint centres closer to the truth by more than half."""
    ds = sb.simulate(model="humanoid", motion="walk", duration_s=30.0, seed=0, sensors="ascension-flock")
    tree = {c: p for c, p in ds.truth.parent_of.items() if p}
    errors = []
    for drop in (False, True):
        score = sb.score(sb.calibrate(ds, hierarchy=tree, drop_noisy_frames=drop), ds)
        errors.append(np.sqrt(np.mean([j.centre_error_in_parent_m**2 for j in score.joints])))
    assert errors[1] < 0.5 * errors[0]


def test_cli_option(tmp_path, capsys):
    cap, _ = _far(8)
    path = tmp_path / "far.csv"
    write_pose_csv(path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, _valid(cap)))
    out_json = tmp_path / "cal.json"
    assert main(["calibrate", str(path), "--drop-noisy-frames", "--json", str(out_json)]) == 0
    text = capsys.readouterr().out
    assert "left out for their position noise" in text
    doc = json.loads(out_json.read_text())
    assert doc["options"]["drop_noisy_frames"] is True
    assert main(["calibrate", str(path), "--follow", "--drop-noisy-frames"]) == 2
    assert "does not take --drop-noisy-frames" in capsys.readouterr().err


def test_a_joint_that_explains_nothing_is_named():
    """No joint at all leaves the sensors' distance as the residual: a joint whose residual is most
    of it explains nothing (far noise); the plain fit of the far capture says so for every joint,
    the fit without the far frames for none, and the steady capture never."""
    cap, _ = _far(9)
    plain = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    named = [w for w in plain.warnings if "explains almost nothing" in w]
    assert len(named) == len(plain.joints)
    assert all("--drop-noisy-frames" in w for w in named)
    dropped = calibrate(cap.R_w_s, cap.p_w_s, cap.names, drop_noisy_frames=True)
    assert not any("explains almost nothing" in w for w in dropped.warnings)
    steady = _capture(9, 0.01)
    assert not any(
        "explains almost nothing" in w for w in calibrate(steady.R_w_s, steady.p_w_s, steady.names).warnings
    )


def test_unexplained_fraction_is_of_the_sensors_distance():
    from calibration.diagnostics import UNEXPLAINED_FRACTION, residual_warnings

    names = ("a", "b", "c")
    pairs = [(0, 1), (1, 2)]
    sep = np.array([0.3, 0.3])
    below = residual_warnings(names, pairs, np.array([0.99, 1.0]) * UNEXPLAINED_FRACTION * sep, sep)
    assert below == []
    above = residual_warnings(names, pairs, np.array([1.01, 0.2]) * UNEXPLAINED_FRACTION * sep, sep)
    assert len(above) == 1 and above[0].startswith("joint a-b: residual 152 mm rms is 0.51")


def test_the_choice_is_unit_free():
    """Millimetres or metres: the same frames go (every threshold is a ratio of the data's own)."""
    cap, _ = _far(10)
    metres = noisy_frames(cap.p_w_s, _valid(cap))
    millimetres = noisy_frames(cap.p_w_s * 1000.0, _valid(cap))
    assert np.array_equal(metres.mask, millimetres.mask)
    assert np.allclose(metres.quiet_m * 1000.0, millimetres.quiet_m, rtol=1e-9)
    assert np.allclose(metres.gain, millimetres.gain, rtol=1e-9)


def test_out_of_core_poses(tmp_path):
    """Poses in an HDF5 file (sliced along frames, never read whole) give the same choice."""
    import h5py

    cap, _ = _far(11)
    with h5py.File(tmp_path / "p.h5", "w") as fh:
        fh["p"] = cap.p_w_s
    with h5py.File(tmp_path / "p.h5", "r") as fh:
        on_disk = noisy_frames(fh["p"], _valid(cap), chunk_frames=500)
    assert np.array_equal(on_disk.mask, noisy_frames(cap.p_w_s, _valid(cap)).mask)


def test_glitches_in_exact_poses_are_left_out(linkage_exact):
    """Exact poses but for three frames thrown 5 cm off (a tracker's glitch): the glitches make the
    expected error thousands of times that without them (the rest is exact up to the motion's own
    third differences), and the frames about them go."""
    cap = linkage_exact
    p = cap.p_w_s.copy()
    glitches = [200, 400, 600]
    p[glitches, 1] += np.array([0.05, 0.0, 0.0])
    valid = np.ones(p.shape[:2], dtype=bool)
    out = noisy_frames(p, valid)
    assert out.mask[glitches, 1].all() and out.gain[1] > 100.0
    assert out.mask[:, 1].sum() <= len(glitches) * (fn.WINDOW_FRAMES + 4)
    assert not out.mask[:, [0, 2, 3, 4, 5]].any()


def test_report_option(tmp_path, capsys):
    """``simbench report --drop-noisy-frames``: the report's calibration leaves the far frames out
    (its warnings say how many; the plain report's say each joint explains almost nothing), and a
    calibration file given with it is refused."""
    cap, _ = _far(8)
    path = tmp_path / "far.csv"
    write_pose_csv(path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, _valid(cap)))
    docs = {}
    for name, extra in (("plain", []), ("dropped", ["--drop-noisy-frames"])):
        assert main(["report", str(path), "--out", str(tmp_path / name), *extra]) == 0
        docs[name] = json.loads((tmp_path / name / "results.json").read_text())
    capsys.readouterr()
    assert any("explains almost nothing" in w for w in docs["plain"]["warnings"])
    assert not any("explains almost nothing" in w for w in docs["dropped"]["warnings"])
    assert any("left out for their position noise" in w for w in docs["dropped"]["warnings"])
    assert docs["dropped"]["calibration"] == "calibrated here (hierarchy inferred, noisy frames left out)"
    assert main(["calibrate", str(path), "--json", str(tmp_path / "cal.json")]) == 0
    args = ["report", str(path), "--calibration", str(tmp_path / "cal.json"), "--drop-noisy-frames"]
    assert main([*args, "--out", str(tmp_path / "x")]) == 2
    assert "--drop-noisy-frames leaves frames out of a calibration made here" in capsys.readouterr().err
