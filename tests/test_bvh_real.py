"""A real recording drives a session: a CMU walk (docs/recorded-motion.md gives the source, the
frames kept and the licence), played back with its own 31-joint skeleton. The clip is not in the
repository (material from the public code store is not committed here): these tests run when it
lies in ``../shared/data``, and are skipped otherwise.

The expected poses come from the file's text here, parsed without simbench's reader: the hierarchy
by its braces, the frames by ``np.loadtxt``, each joint's rotation composed from its channels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import simbench as sb
from calibration.rotations import quat_to_matrix
from simbench.cli import main
from simbench.io.bvh import Y_UP_TO_Z_UP

C = Y_UP_TO_Z_UP
CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu_82_11_normal_walk.bvh"

pytestmark = pytest.mark.skipif(not CLIP.is_file(), reason=f"{CLIP} not at hand")
METRES_PER_CMU_UNIT = 1.0 / 0.45 * 2.54 / 100  # mocap.cs.cmu.edu's FAQ


def _parse(text: str) -> tuple[list[str], list[int], list[list[str]], np.ndarray, np.ndarray, float]:
    """``(names, parents, channels, root offset, frames, frame time)`` from a BVH file's text;
    ``parents[k]`` is -1 for the root."""
    head, motion = text.split("MOTION")
    names: list[str] = []
    parents: list[int] = []
    channels: list[list[str]] = []
    stack: list[int | None] = []  # the open blocks: a joint's index, or None for an End Site
    pending: int | None = None
    root_offset = None
    for line in head.splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] in ("ROOT", "JOINT"):
            parents.append(next((j for j in reversed(stack) if j is not None), -1))
            names.append(words[1])
            pending = len(names) - 1
        elif words[0] == "End":
            pending = None
        elif words[0] == "{":
            stack.append(pending)
        elif words[0] == "}":
            stack.pop()
        elif words[0] == "CHANNELS":
            channels.append(words[2:])
        elif words[0] == "OFFSET" and root_offset is None:
            root_offset = np.array(words[1:], dtype=float)
    lines = motion.splitlines()
    time_line = next(k for k, line in enumerate(lines) if line.startswith("Frame Time:"))
    frames = np.loadtxt(lines[time_line + 1 :], ndmin=2)
    return names, parents, channels, root_offset, frames, float(lines[time_line].split(":")[1])


@pytest.fixture(scope="module")
def clip():
    data = CLIP.read_bytes()
    return data, _parse(data.decode("ascii"))


@pytest.fixture(scope="module")
def played():
    return sb.simulate(motion=str(CLIP), motion_units="cmu", sensors="mems-industrial", seed=1)


def test_the_clip_is_the_stated_excerpt(clip):
    data, (names, parents, channels, _, frames, frame_time) = clip
    # docs/recorded-motion.md: 348 frames at 60 Hz of 31 joints, Windows line ends, small
    assert len(data) < 400_000 and data.count(b"\r\n") == data.count(b"\n") == 535
    assert frames.shape == (348, 96) and frame_time == 0.0166667
    assert len(names) == 31 and names[0] == "Hips" and names[-1] == "RThumb"
    assert names[parents[names.index("LeftHandIndex1")]] == "LeftFingerBase"
    assert names[parents[names.index("LThumb")]] == "LeftHand"
    assert sum(len(c) for c in channels) == 96 and channels[0][:3] == ["Xposition", "Yposition", "Zposition"]
    assert {tuple(c) for c in channels[1:]} == {("Zrotation", "Yrotation", "Xrotation")}


def test_truth_is_the_file_exactly(clip, played):
    _, (names, parents, channels, root_offset, frames, frame_time) = clip
    ds = played
    assert ds.time_s.size == 348 and ds.meta["rate_hz"] == pytest.approx(1 / frame_time, rel=1e-12)
    assert (
        ds.meta["model"] == "bvh"
        and ds.meta["mujoco_warnings"] == {}
        and not ds.meta["playback"]["resampled"]
    )
    # every joint's world rotation composed from the file's channels (y up), parents first
    R_w = {}
    turned = {}
    column = 0
    for k, name in enumerate(names):
        values = frames[:, column : column + len(channels[k])]
        column += len(channels[k])
        rotations = [c for c, name in enumerate(channels[k]) if name.endswith("rotation")]
        order = "".join(channels[k][c][0] for c in rotations)  # upper case: intrinsic, as BVH's
        file_R = Rotation.from_euler(order, values[:, rotations], degrees=True)
        turned[name] = (file_R[0].inv() * file_R).magnitude().max()
        R_w[name] = file_R.as_matrix() if parents[k] < 0 else R_w[names[parents[k]]] @ file_R.as_matrix()
    # the joints that never turn (the conversion's hip and clavicle joints, two fingers) are welded
    moving = [n for k, n in enumerate(names) if k == 0 or turned[n] > 1e-9]
    assert ds.sensors == tuple(moving) and len(moving) == 25
    R_w_b = quat_to_matrix(ds.truth.q_w_b)
    for s, name in enumerate(ds.sensors):
        # the angle between the truth's rotation (back to y up) and the file's
        diff = Rotation.from_matrix(np.einsum("fji,fjk->fik", R_w[name], C.T @ R_w_b[:, s] @ C)).magnitude()
        assert diff.max() < 1e-6, (name, diff.max())
    # the root path: its OFFSET plus its position channels, CMU units -> m, y up -> z up
    expected = (root_offset + frames[:, :3]) * METRES_PER_CMU_UNIT @ C.T
    assert np.abs(ds.truth.p_w_b[:, ds.sensors.index("Hips")] - expected).max() < 1e-6
    # a person: hips about 0.9 m above the floor, 3.4 m walked forward
    assert 0.85 < expected[:, 2].min() < expected[:, 2].max() < 1.0
    assert 3.2 < np.ptp(expected[:, 0]) < 3.6


def test_orientation_of_the_walk_is_scored(played):
    # the target: the recorded walk's orientations estimated from mems-industrial readings
    # and scored against the truth; measured 2.47 deg total, 2.01 deg heading over 31 sensors
    ori = sb.orient(played, "vqf")
    assert ori.score.total_rmse_deg < 4.0 and ori.score.heading_rmse_deg < 3.5


def test_cli_simulates_the_clip_in_cmu_units(tmp_path, monkeypatch, capsys):
    out = tmp_path / "walk.h5"
    assert main(["simulate", "--motion", str(CLIP), "--motion-units", "cmu", "-o", str(out)]) == 0
    assert "348 at 59.9999 Hz" in capsys.readouterr().out
    ds = sb.read_dataset(out)
    assert ds.time_s.size == 348 and 0.85 < ds.truth.p_w_b[:, ds.sensors.index("Hips"), 2].min() < 1.0
