"""Which MJCF tool does what (docs/mjcf.md): a user's model is equipped through ``mujoco.MjSpec``,
which reads whatever the installed MuJoCo reads and keeps the user's names; dm_control's PyMJCF
builds the models simbench writes from nothing (a BVH clip's skeleton, a pose file's bodies)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from numpy.testing import assert_allclose

from simbench.sim.models import load_capture_model

#: A user's arm using ``<frame>`` (MuJoCo 3.1): the elbow sits 0.3 m below the shoulder body,
#: turned 30 degrees about z by the frame.
USER_ARM = """
<mujoco model="user_arm">
  <worldbody>
    <body name="upper" pos="0 0 1">
      <freejoint/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.04"/>
      <frame pos="0 0 -0.3" euler="0 0 30">
        <body name="fore">
          <joint name="elbow" type="ball"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.25" size="0.03"/>
        </body>
      </frame>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_users_model_with_mujoco_3_elements_is_equipped_through_mjspec(tmp_path):
    path = tmp_path / "user_arm.xml"
    path.write_text(USER_ARM)
    cm = load_capture_model(str(path))
    assert cm.sensors == ("upper", "fore") and cm.parent_of == {"fore": "upper"}
    m = cm.model
    assert m.body("fore").name == "fore"  # the user's names, not prefixed by a namespace
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    # the frame's placement compiled in: the forearm's origin 0.3 m below the upper arm's
    assert_allclose(d.xpos[m.body("fore").id] - d.xpos[m.body("upper").id], [0, 0, -0.3], atol=1e-12)
    half = np.deg2rad(30) / 2
    assert_allclose(np.abs(d.xquat[m.body("fore").id]), [np.cos(half), 0, 0, np.sin(half)], atol=1e-12)


def test_pymjcf_cannot_read_that_model():
    """The reason docs/mjcf.md gives for MjSpec on users' models; if this fails, dm_control reads
    MuJoCo 3's elements now, and the page should say so."""
    mjcf = pytest.importorskip("dm_control.mjcf")
    with pytest.raises(KeyError, match="frame"):
        mjcf.from_xml_string(USER_ARM)
