"""Slip detection a chunk at a time (issue 45): a long recording's memory is a chunk's, and its slips
are found once each, wherever they fall against the chunks."""

from __future__ import annotations

import itertools
import tracemalloc

import h5py
import numpy as np
import pytest

from calibration import CalibrationInputError, calibrate, detect_slip
from calibration import slip as slip_module
from calibration.slip import OVERLAP_WINDOWS, _chunks
from simbench.io.poses import PoseRecording
from simbench.sim.synthetic import Slip, linkage, simulate_motion
from tests.helpers import pair_arrays

RATE_HZ = 120.0
WINDOW = 120
N_FRAMES = 14_400  # 2 min
CHUNK = 3_000  # 25 s: five chunks
JOINT = "upper_arm_l-forearm_l"


@pytest.fixture(scope="module")
def long_capture():
    """Two 3 cm slips of the left forearm's sensor, one near a boundary between chunk cores."""
    cores = _chunks(N_FRAMES, CHUNK, OVERLAP_WINDOWS * WINDOW)
    at_boundary = cores[2][2] + 5  # 5 frames into the third chunk's core
    slips = [Slip("forearm_l", 4_000, (0.0, 0.03, 0.0)), Slip("forearm_l", at_boundary, (0.03, 0.0, 0.0))]
    cap = simulate_motion(
        linkage(),
        n_frames=N_FRAMES,
        rate_hz=RATE_HZ,
        rng=np.random.default_rng(5),
        position_noise_m=0.002,
        rotation_noise_rad=np.deg2rad(0.3),
        slips=slips,
    )
    return cap, sorted(s.frame for s in slips)


def _detect(cap, joint, **kwargs):
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    j = next(j for j in cal.joints if j.name == joint)
    arrays = pair_arrays(cap, j.parent, j.child)
    return detect_slip(
        *arrays, j.fit.joint_in_parent, j.fit.joint_in_child, window=WINDOW, rate_hz=RATE_HZ, **kwargs
    )


def test_chunks_tile_the_recording_with_overlaps():
    pieces = _chunks(N_FRAMES, CHUNK, 480)
    cores = [(lo, hi) for _, _, lo, hi in pieces]
    assert cores[0][0] == 0 and cores[-1][1] == N_FRAMES
    assert all(a[1] == b[0] for a, b in itertools.pairwise(cores))
    for start, stop, lo, hi in pieces:
        assert stop - start <= CHUNK
        assert lo - start == (0 if lo == 0 else 480) and stop - hi == (0 if hi == N_FRAMES else 480)
    assert _chunks(2_000, CHUNK, 480) == [(0, 2_000, 0, 2_000)]


def test_slips_are_found_once_each_in_chunks_as_in_the_whole(long_capture):
    cap, truth = long_capture
    whole = _detect(cap, JOINT, chunk_frames=N_FRAMES)
    chunked = _detect(cap, JOINT, chunk_frames=CHUNK)
    assert [abs(e.frame - t) <= 12 for e, t in zip(chunked.events, truth, strict=True)] == [True, True]
    assert [e.sensor_frame for e in chunked.events] == ["child", "child"]
    assert [e.jump for e in chunked.events] == pytest.approx([0.03, 0.03], abs=0.005)
    assert [e.frame for e in chunked.events] == [e.frame for e in whole.events]
    assert chunked.jump.shape == (N_FRAMES,)
    assert chunked.intervals and chunked.intervals[-1][1] == N_FRAMES
    clean = _detect(
        cap, "base-upper_arm_l" if "base-upper_arm_l" in _names(cap) else _other(cap), chunk_frames=CHUNK
    )
    assert clean.events == ()


def _names(cap):
    return {j.name for j in calibrate(cap.R_w_s, cap.p_w_s, cap.names).joints}


def _other(cap):
    return next(name for name in sorted(_names(cap)) if "forearm_l" not in name)


def test_without_the_series_the_events_are_the_same(long_capture):
    cap, _ = long_capture
    with_series = _detect(cap, JOINT, chunk_frames=CHUNK)
    without = _detect(cap, JOINT, chunk_frames=CHUNK, series=False)
    assert without.events == with_series.events and without.jump.shape == (0,)
    assert without.threshold == with_series.threshold


def test_a_chunk_too_short_for_the_window_is_refused(long_capture):
    cap, _ = long_capture
    with pytest.raises(CalibrationInputError, match="chunk_frames must be at least 1920"):
        _detect(cap, JOINT, chunk_frames=1_000)


def test_memory_is_a_chunk_s_and_the_frames_are_read_a_slice_at_a_time(long_capture, tmp_path):
    """The recording in an HDF5 file, read through views: the peak of the search is the chunk's."""
    cap, truth = long_capture
    path = tmp_path / "poses.h5"
    with h5py.File(path, "w") as fh:
        fh["R"], fh["p"] = cap.R_w_s, cap.p_w_s
    cal = calibrate(cap.R_w_s, cap.p_w_s, cap.names)
    j = next(j for j in cal.joints if j.name == JOINT)
    peaks = {}
    with h5py.File(path, "r") as fh:
        rec = PoseRecording(
            names=cap.names,
            time_s=np.arange(N_FRAMES) / RATE_HZ,
            R_w_s=fh["R"],
            p_w_s=fh["p"],
            valid=np.ones((N_FRAMES, len(cap.names)), dtype=bool),
        )
        drop = np.zeros(N_FRAMES, dtype=bool)
        drop[100:110] = True
        views = rec.pair_views(j.parent, j.child, drop)
        assert np.isnan(views[0][95:115][5:15]).all() and np.isfinite(views[0][95:100]).all()
        for chunk in (N_FRAMES, CHUNK):
            tracemalloc.start()
            rep = detect_slip(
                *views,
                j.fit.joint_in_parent,
                j.fit.joint_in_child,
                window=WINDOW,
                rate_hz=RATE_HZ,
                chunk_frames=chunk,
                series=False,
            )
            peaks[chunk] = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            assert [abs(e.frame - t) <= 12 for e, t in zip(rep.events, truth, strict=True)] == [True, True]
    assert peaks[CHUNK] < 0.5 * peaks[N_FRAMES], peaks


def test_a_long_noise_model_from_every_few_frames_decides_as_every_frame(long_capture, monkeypatch):
    """d is a difference of window means, smooth over the window: its noise model from every
    ``window / 16``-th frame (at least 4,096 samples) finds the same slips, sensors and thresholds
    as from every frame (the long recordings' cost, issue 45)."""
    cap, truth = long_capture
    strided = _detect(cap, JOINT, chunk_frames=N_FRAMES)
    assert slip_module._noise_stride(WINDOW, N_FRAMES) == 3
    monkeypatch.setattr(slip_module, "NOISE_MIN_SAMPLES", 10**12)
    every = _detect(cap, JOINT, chunk_frames=N_FRAMES)
    assert slip_module._noise_stride(WINDOW, N_FRAMES) == 1
    key = [(e.frame, e.sensor_frame) for e in every.events]
    assert [(e.frame, e.sensor_frame) for e in strided.events] == key and len(key) == len(truth)
    assert strided.threshold == pytest.approx(every.threshold, rel=0.02)
    assert strided.noise == pytest.approx(every.noise, rel=0.02)
    assert strided.tests_per_hour == pytest.approx(every.tests_per_hour, rel=0.02)
