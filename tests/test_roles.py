"""Built-in presets written for the humanoid apply to a recorded skeleton: its segments that play
the humanoid's roles take the values, the rest is left out and said."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import simbench as sb
from simbench.errors import InputError
from simbench.sim.roles import humanoid_roles
from simbench.sim.sensor_config import load_sensor_config

PRESETS = sorted(p.stem for p in (Path(sb.__file__).parent / "sim" / "presets").glob("*.toml"))

#: A CMU-named skeleton: (name, parent, offset in cm, y up).
CMU = [
    ("Hips", None, (0, 95, 0)),
    ("LeftUpLeg", "Hips", (9, -5, 0)),
    ("LeftLeg", "LeftUpLeg", (0, -43, 0)),
    ("LeftFoot", "LeftLeg", (0, -41, 0)),
    ("RightUpLeg", "Hips", (-9, -5, 0)),
    ("RightLeg", "RightUpLeg", (0, -43, 0)),
    ("RightFoot", "RightLeg", (0, -41, 0)),
    ("Spine", "Hips", (0, 10, 0)),
    ("Spine1", "Spine", (0, 20, 0)),
    ("Head", "Spine1", (0, 30, 0)),
    ("LeftArm", "Spine1", (18, 24, 0)),
    ("LeftForeArm", "LeftArm", (0, -29, 0)),
    ("LeftHand", "LeftForeArm", (0, -27, 0)),
    ("RightArm", "Spine1", (-18, 24, 0)),
    ("RightForeArm", "RightArm", (0, -29, 0)),
    ("RightHand", "RightForeArm", (0, -27, 0)),
]


def cmu_bvh(frames: int = 240, frame_time: float = 1 / 120) -> str:
    """A BVH clip on the CMU-named skeleton: every joint turning through slow sines."""
    children: dict[str | None, list[int]] = {}
    for k, (_, parent, _) in enumerate(CMU):
        children.setdefault(parent, []).append(k)
    lines = ["HIERARCHY"]

    def block(k: int, depth: int) -> None:
        name, parent, off = CMU[k]
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {off[0]} {off[1]} {off[2]}")
        chans = "6 Xposition Yposition Zposition " if parent is None else "3 "
        lines.append(f"{pad}  CHANNELS {chans}Zrotation Xrotation Yrotation")
        for c in children.get(name, []):
            block(c, depth + 1)
        if name not in children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 -10 0", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    block(0, 0)
    t = np.arange(frames) * frame_time
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time:.7f}"]
    for f in range(frames):
        row = [3 * np.sin(t[f]), 95.0, 10 * t[f]]
        for k in range(len(CMU)):
            row += [20 * np.sin(1.1 * t[f] + k), 25 * np.sin(1.7 * t[f] + 2 * k), 15 * np.sin(0.8 * t[f] + k)]
        lines.append(" ".join(f"{x:.5f}" for x in row))
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def cmu_clip(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cmu") / "cmu.bvh"
    path.write_text(cmu_bvh())
    return path


def test_roles_of_the_common_naming_conventions():
    cmu = humanoid_roles([n for n, _, _ in CMU] + ["LowerBack", "LHipJoint", "Neck", "LeftToeBase"])
    assert cmu["thigh_l"] == "LeftUpLeg" and cmu["shank_r"] == "RightLeg" and cmu["foot_l"] == "LeftFoot"
    assert (
        cmu["upper_arm_l"] == "LeftArm" and cmu["forearm_r"] == "RightForeArm" and cmu["hand_l"] == "LeftHand"
    )
    assert cmu["pelvis"] == "Hips" and cmu["abdomen"] == "Spine" and cmu["chest"] == "Spine1"
    mixamo = humanoid_roles(["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2"])
    assert mixamo == {"pelvis": "mixamorig:Hips", "abdomen": "mixamorig:Spine", "chest": "mixamorig:Spine2"}
    poser = humanoid_roles(["hip", "abdomen", "chest", "lShldr", "lForeArm", "rThigh", "rShin"])
    assert poser["upper_arm_l"] == "lShldr" and poser["thigh_r"] == "rThigh" and poser["shank_r"] == "rShin"
    assert "thigh_l" not in poser  # no left thigh: no role filled by a right one
    own = humanoid_roles(["pelvis", "thigh_l", "shank_l"])
    assert own == {"pelvis": "pelvis", "thigh_l": "thigh_l", "shank_l": "shank_l"}


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_applies_to_a_recorded_skeleton(cmu_clip, preset):
    ds = sb.simulate(motion=str(cmu_clip), sensors=preset, duration_s=1.0)
    assert ds.sensors[0] == "Hips" and np.isfinite(ds.truth.rigid.p_w_s).all()


def test_a_humanoid_preset_lands_on_the_segments_that_play_its_roles(cmu_clip):
    ds = sb.simulate(motion=str(cmu_clip), sensors="skin-paper-human", duration_s=1.0)
    preset = load_sensor_config("skin-paper-human").skin
    used = ds.meta["sensor_config"]["skin"]
    assert used["sta_by_sensor"]["LeftUpLeg"] == preset.sta_by_sensor["thigh_l"]
    assert used["sta_by_sensor"]["RightArm"] == preset.sta_by_sensor["upper_arm_r"]
    assert used["laxity_by_joint"] == {"LeftLeg": 0.007, "RightLeg": 0.007}
    notes = " ".join(ds.meta["sensor_notes"])
    assert (
        "thigh_l -> LeftUpLeg" in notes
        and "skin.pack on pelvis" in notes
        and "skin.girdle upper_arm_l" in notes
    )
    # the skin moved the sensors off their bones where the preset says
    off = np.linalg.norm(ds.truth.actual.p_w_s - ds.truth.rigid.p_w_s, axis=2).max(axis=0)
    assert off[ds.sensors.index("LeftUpLeg")] > 1e-3


def test_joint_play_of_a_preset_is_left_out_on_a_recording_and_said(cmu_clip):
    ds = sb.simulate(motion=str(cmu_clip), sensors="ascension-flock-paper", duration_s=1.0)
    assert ds.meta["sensor_config"]["joints"]["play_m"] == 0.0
    assert any("joint play left out" in n for n in ds.meta["sensor_notes"])


def test_a_users_own_configuration_is_never_changed(cmu_clip):
    preset = load_sensor_config("skin-paper-human")
    own = dataclasses.replace(preset, name="mine")
    with pytest.raises(InputError, match=r"skin\.sta_by_sensor names"):
        sb.simulate(motion=str(cmu_clip), sensors=own, duration_s=1.0)


def test_presets_on_the_humanoid_are_unchanged():
    ds = sb.simulate("humanoid", "exercise", sensors="skin-paper-human", duration_s=0.5)
    assert "sensor_notes" not in ds.meta
    assert ds.meta["sensor_config"] == load_sensor_config("skin-paper-human").as_dict()
