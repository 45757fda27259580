"""BVH motion files: the reader against an independent composition of known rotations."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.errors import InputError
from simbench.io.bvh import Y_UP_TO_Z_UP, read_bvh

ORDERS = {"hips": "ZXY", "chest": "XYZ", "head": "YZX"}


def _bvh(angles: dict[str, np.ndarray], root_cm: np.ndarray, frame_time: float = 0.01) -> str:
    """A three-joint chain (hips, chest, head with an End Site), each joint with its own Euler
    order (:data:`ORDERS`), the root's position channels first."""
    rot = {name: " ".join(f"{a}rotation" for a in order) for name, order in ORDERS.items()}
    head = f"""HIERARCHY
ROOT hips
{{
  OFFSET 1.0 90.0 -2.0
  CHANNELS 6 Xposition Yposition Zposition {rot["hips"]}
  JOINT chest
  {{
    OFFSET 0.0 20.0 3.0
    CHANNELS 3 {rot["chest"]}
    JOINT head
    {{
      OFFSET 2.0 30.0 0.0
      CHANNELS 3 {rot["head"]}
      End Site
      {{
        OFFSET 0.0 10.0 5.0
      }}
    }}
  }}
}}
MOTION
Frames: {len(root_cm)}
Frame Time: {frame_time}
"""
    rows = [
        " ".join(
            repr(float(v)) for v in [*root_cm[f], *angles["hips"][f], *angles["chest"][f], *angles["head"][f]]
        )
        for f in range(len(root_cm))
    ]
    return head + "\n".join(rows) + "\n"


def _elementary(axis: str, deg: float) -> np.ndarray:
    """One rotation about a coordinate axis, written out (independent of the reader's)."""
    c, s = np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))
    return {
        "X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    rng = np.random.default_rng(7)
    frames = 40
    # the middle angle within +-85 degrees: each rotation has one set of Euler angles (no gimbal lock)
    angles = {name: rng.uniform([-170, -85, -170], [170, 85, 170], size=(frames, 3)) for name in ORDERS}
    root = rng.uniform(-50, 50, size=(frames, 3))
    path = tmp_path_factory.mktemp("bvh") / "clip.bvh"
    path.write_text(_bvh(angles, root))
    return path, angles, root


def test_rotations_in_three_euler_orders_are_exact(clip):
    path, angles, _ = clip
    motion = read_bvh(path)
    C = Y_UP_TO_Z_UP
    for k, name in enumerate(motion.names):
        order = ORDERS[name]
        assert motion.rotation_order[k] == order.lower()
        for f in range(motion.n_frames):
            R = np.eye(3)
            for axis, a in zip(order, angles[name][f], strict=True):
                R = R @ _elementary(axis, a)
            np.testing.assert_allclose(motion.R_parent_joint[f, k], C @ R @ C.T, atol=1e-12)
        # the joint angles come back (scipy's decomposition, independent of the reader) to 1e-6 rad
        back = Rotation.from_matrix(C.T @ motion.R_parent_joint[:, k] @ C).as_euler(order, degrees=False)
        diff = np.angle(np.exp(1j * (back - np.deg2rad(angles[name]))))
        assert np.abs(diff).max() < 1e-6, name


def test_positions_units_and_up_axis(clip):
    path, angles, root = clip
    motion = read_bvh(path)
    assert motion.frame_time_s == 0.01 and motion.n_frames == 40
    np.testing.assert_allclose(motion.offset_m[1], [0.0, -0.03, 0.20], atol=1e-15)  # cm -> m, y up -> z up
    R_w, p_w = motion.world()
    C = Y_UP_TO_Z_UP
    for f in (0, 17, 39):  # the End Site by hand, in the file's y-up centimetres
        R_h = np.eye(3)
        for axis, a in zip(ORDERS["hips"], angles["hips"][f], strict=True):
            R_h = R_h @ _elementary(axis, a)
        R_c = np.eye(3)
        for axis, a in zip(ORDERS["chest"], angles["chest"][f], strict=True):
            R_c = R_c @ _elementary(axis, a)
        R_e = np.eye(3)
        for axis, a in zip(ORDERS["head"], angles["head"][f], strict=True):
            R_e = R_e @ _elementary(axis, a)
        hips = np.array([1.0, 90.0, -2.0]) + root[f]
        chest = hips + R_h @ [0.0, 20.0, 3.0]
        head = chest + R_h @ R_c @ [2.0, 30.0, 0.0]
        end = head + R_h @ R_c @ R_e @ [0.0, 10.0, 5.0]
        np.testing.assert_allclose(p_w[f, 2], C @ head / 100, atol=1e-12)
        end_z_up = p_w[f, 2] + R_w[f, 2] @ motion.end_sites_m["head"][0]
        np.testing.assert_allclose(end_z_up, C @ end / 100, atol=1e-12)
    assert read_bvh(path, units="m").offset_m[1] == pytest.approx([0.0, -3.0, 20.0])


def test_cmu_units_and_crlf_line_ends(clip, tmp_path):
    """The CMU database's BVH conversions: lengths in its ASF unit (1/0.45 inch, mocap.cs.cmu.edu's
    FAQ: x (1.0/0.45)*2.54/100 to metres) and Windows line ends; both read as the file means them."""
    path, _, root = clip
    crlf = tmp_path / "crlf.bvh"
    crlf.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))
    assert crlf.read_bytes().count(b"\r\n") > 60
    cm, cmu = read_bvh(path), read_bvh(crlf, units="cmu")
    metres_per_unit = 1.0 / 0.45 * 2.54 / 100
    assert metres_per_unit == pytest.approx(0.056444, abs=1e-6)
    np.testing.assert_allclose(cmu.offset_m, cm.offset_m * 100 * metres_per_unit, rtol=1e-12)
    np.testing.assert_allclose(cmu.translation_m[:, 0], (root @ Y_UP_TO_Z_UP.T) * metres_per_unit, rtol=1e-12)
    np.testing.assert_allclose(cmu.R_parent_joint, cm.R_parent_joint, atol=0)
    assert cmu.frame_time_s == cm.frame_time_s and cmu.names == cm.names
    with pytest.raises(InputError, match=r"unknown units 'inch': expected one of m, cm, mm, in, cmu"):
        read_bvh(path, units="inch")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("Frames: 40", "Frames: 41"), r"line 22: 'Frames: 41' but 40 frame line"),
        (
            lambda t: t.replace(
                "CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 3 Xrotation Yrotation Qrotation"
            ),
            r"line 9: CHANNELS 3: expected 1 to 6 distinct channels",
        ),
        (
            lambda t: "\n".join([*t.splitlines()[:-1], t.splitlines()[-1].rsplit(" ", 1)[0]]) + "\n",
            r"line 63: 11 values, expected 12 \(one per channel\)",
        ),
        (lambda t: t.replace("\nMOTION\n", "\nMOTON\n"), "no MOTION section"),
        (
            lambda t: "\n".join([*t.splitlines()[:-1], " ".join(["nan"] * 12)]) + "\n",
            "line 63: a value that is not finite",
        ),
        (
            lambda t: t.replace("OFFSET 0.0 20.0 3.0", "OFFSET 0.0 twenty 3.0"),
            r"line 8: OFFSET: expected 3 numbers",
        ),
        (lambda t: t.replace("Frame Time: 0.01", "Frame Time: -1"), "line 23: expected a frame time > 0 s"),
    ],
)
def test_bad_files_are_named_by_line(clip, tmp_path, edit, message):
    path = tmp_path / "bad.bvh"
    path.write_text(edit(clip[0].read_text()))
    with pytest.raises(InputError, match=f"{path}, {message}" if "line" in message else message):
        read_bvh(path)


def test_not_a_bvh_file(tmp_path):
    path = tmp_path / "x.bvh"
    path.write_text("time,sensor\n")
    with pytest.raises(InputError, match=r"line 1: not a BVH file: expected HIERARCHY first"):
        read_bvh(path)
    with pytest.raises(InputError, match="unknown units 'furlong'"):
        read_bvh(path, units="furlong")
    with pytest.raises(InputError, match="cannot read"):
        read_bvh(Path(tmp_path / "missing.bvh"))
