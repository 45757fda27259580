"""A BVH clip's own MJCF skeleton.

The clips are written here (small, a few seconds) with the chain of ``tests/test_bvh.py``: the
expected poses come from the file's numbers composed independently of the reader and the model.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from simbench.io.bvh import Y_UP_TO_Z_UP, read_bvh
from simbench.sim.bvh_model import DENSITY_KG_M3, bvh_mjcf, capsule_radius
from tests.test_bvh import ORDERS, _bvh

C = Y_UP_TO_Z_UP
FRAME_TIME = 0.01
ROOT_OFFSET_CM = np.array([1.0, 90.0, -2.0])  # the hips' OFFSET in test_bvh's clip


def _smooth_clip(frames: int = 300) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Angles (deg) and root path (cm) of a smooth clip: slow sines, well below the cutoff."""
    t = np.arange(frames) * FRAME_TIME
    angles = {
        name: np.stack(
            [40 * np.sin(np.pi * t + i), 30 * np.sin(2 * np.pi * 0.7 * t + i), 60 * np.sin(0.9 * t)], 1
        )
        for i, name in enumerate(ORDERS)
    }
    root = np.stack([20 * np.sin(t), 10 * t, 5 * np.cos(t)], 1)
    return angles, root


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    angles, root = _smooth_clip()
    path = tmp_path_factory.mktemp("bvh") / "clip.bvh"
    path.write_text(_bvh(angles, root, FRAME_TIME))
    return path, angles, root


def test_skeleton_model_loads_without_warnings_and_has_the_stated_masses(clip):
    motion = read_bvh(clip[0])
    m = mujoco.MjModel.from_xml_string(bvh_mjcf(motion))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    for _ in range(10):
        mujoco.mj_step(m, d)
    assert all(w.number == 0 for w in d.warning)
    assert [m.body(b).name for b in range(1, m.nbody)] == list(motion.names)
    kinds = [int(m.jnt_type[j]) for j in range(m.njnt)]
    assert kinds == [mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL, mujoco.mjtJoint.mjJNT_BALL]
    np.testing.assert_allclose(m.body_pos[2], motion.offset_m[1], atol=1e-15)
    # the head: one capsule to its End Site, radius by the stated rule, water density
    length = float(np.linalg.norm(motion.end_sites_m["head"][0]))
    r = capsule_radius(length)
    mass = DENSITY_KG_M3 * (np.pi * r * r * length + 4 / 3 * np.pi * r**3)
    assert m.body_mass[3] == pytest.approx(mass, rel=1e-9)
    assert all(mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"sensor_{n}") >= 0 for n in motion.names)
