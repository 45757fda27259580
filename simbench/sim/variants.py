"""Built-in model variants: a built-in model with other limb lengths.

``humanoid-female`` is the ``humanoid`` with the limb lengths of O'Brien et al.'s female subject
(Table 4, "Meas." column, cm): each limb's distal joint is moved along the limb, the limb's
capsule and its sensor placement scaled with it, and the pelvis lowered by the shorter leg's
change so that the feet clear the floor as the model's do. What the paper did not measure
(trunk, shoulder and hip widths, hands, feet) stays as in ``humanoid``.
"""

from __future__ import annotations

import mujoco
import numpy as np

#: variant name -> (the built-in model it edits, {limb body: (distal body, joint-to-joint m)}).
VARIANTS: dict[str, tuple[str, dict[str, tuple[str, float]]]] = {
    "humanoid-female": (
        "humanoid",
        {
            "shank_r": ("foot_r", 0.368),
            "shank_l": ("foot_l", 0.365),
            "thigh_r": ("shank_r", 0.422),
            "thigh_l": ("shank_l", 0.419),
            "forearm_r": ("hand_r", 0.248),
            "forearm_l": ("hand_l", 0.248),
            "upper_arm_r": ("forearm_r", 0.276),
            "upper_arm_l": ("forearm_l", 0.276),
        },
    ),
}

#: The body whose height carries the legs, and the legs' limb bodies (thigh, shank) per side.
_ROOT = "pelvis"
_LEGS = (("thigh_l", "shank_l"), ("thigh_r", "shank_r"))


def _limb_length(spec: mujoco.MjSpec, distal: str) -> float:
    return float(np.linalg.norm(spec.body(distal).pos))


def set_limb_lengths(spec: mujoco.MjSpec, lengths: dict[str, tuple[str, float]]) -> None:
    """Give limbs new joint-to-joint lengths (edits ``spec`` in place).

    Args:
        spec: a model whose limb bodies have their inboard joint at the body origin and their
            distal body's origin at the distal joint (as ``humanoid``).
        lengths: ``{limb body: (distal body, new length m)}``.

    The distal body moves along the limb; the limb body's capsules (``fromto``) and sites are
    scaled along the limb by the same ratio. If the spec has the humanoid's pelvis and legs, the
    pelvis is lowered by the smaller of the two legs' shortening.
    """
    old = {limb: _limb_length(spec, distal) for limb, (distal, _) in lengths.items()}
    for limb, (distal, new) in lengths.items():
        ratio = new / old[limb]
        axis = spec.body(distal).pos / old[limb]
        spec.body(distal).pos = axis * new
        body = spec.body(limb)
        for geom in body.geoms:
            if geom.type == mujoco.mjtGeom.mjGEOM_CAPSULE and np.all(np.isfinite(geom.fromto)):
                ends = geom.fromto.reshape(2, 3)
                along = ends @ axis
                geom.fromto = (ends + np.outer(along * (ratio - 1), axis)).ravel()
        for site in body.sites:
            along = float(site.pos @ axis)
            site.pos = site.pos + along * (ratio - 1) * axis
    names = {b.name for b in spec.bodies}
    if _ROOT in names and all(limb in lengths for leg in _LEGS for limb in leg):
        shortening = min(sum(old[b] - lengths[b][1] for b in leg) for leg in _LEGS)
        spec.body(_ROOT).pos = spec.body(_ROOT).pos - np.array([0.0, 0.0, max(shortening, 0.0)])
