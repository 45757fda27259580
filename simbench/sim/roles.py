"""The humanoid's segments under the names other skeletons give them, so that a built-in preset
written for the humanoid applies to a recorded skeleton (a BVH clip's).

A segment name is normalised (a namespace prefix such as ``mixamorig:`` dropped, lower case,
separators ``_ - . space`` removed), its side read (a ``left``/``right`` prefix or suffix, an
``l``/``r`` prefix before a capital as in Poser's ``lThigh``, or an ``_l``/``_r`` suffix), and
the rest looked up in :data:`ALIASES` (the names of the CMU, Mixamo, Biovision/Poser and
3ds Max Biped conventions). A role several segments could fill goes to the first alias in
order (the CMU and Mixamo spines: ``Spine`` is the abdomen, ``Spine1``/``Spine2`` the chest).
"""

from __future__ import annotations

import re

#: Each humanoid segment (without side) and the side-free names other skeletons give it, first
#: preferred.
ALIASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("pelvis", "hips", "hip", "bip01pelvis", "root"),
    "abdomen": ("abdomen", "spine", "lowerback", "waist", "bip01spine"),
    "chest": ("chest", "thorax", "upperchest", "spine2", "spine1", "bip01spine1"),
    "head": ("head", "bip01head"),
    "upper_arm": ("upperarm", "uparm", "arm", "shldr", "humerus"),
    "forearm": ("forearm", "lowarm", "lowerarm"),
    "hand": ("hand", "wrist"),
    "thigh": ("thigh", "upleg", "upperleg", "femur"),
    "shank": ("shank", "shin", "leg", "lowleg", "lowerleg", "calf", "tibia"),
    "foot": ("foot", "ankle"),
}

_SIDED = {"upper_arm", "forearm", "hand", "thigh", "shank", "foot"}


def _side_and_stem(name: str) -> tuple[str, str]:
    """``("l" | "r" | "", normalised stem)`` of a segment name (module docstring)."""
    base = name.rsplit(":", 1)[-1]
    side = ""
    poser = re.match(r"^([lr])([A-Z].*)$", base)
    if poser:
        side, base = poser.group(1), poser.group(2)
    stem = re.sub(r"[_\-. ]", "", base.lower())
    for word, s in (("left", "l"), ("right", "r")):
        if stem.startswith(word):
            side, stem = s, stem[len(word) :]
        elif stem.endswith(word):
            side, stem = s, stem[: -len(word)]
    suffix = re.search(r"[_\-. ]([lr])$", base.lower())
    if not side and suffix:
        side, stem = suffix.group(1), stem[:-1]
    if not side and re.match(r"^bip01[lr]", stem):  # 3ds Max Biped: Bip01 L Thigh
        side, stem = stem[5], stem[6:]
    return side, stem


def humanoid_roles(names: tuple[str, ...] | list[str]) -> dict[str, str]:
    """``{humanoid segment: the name in names that plays it}`` for the segments found (a name
    plays at most one role; the humanoid's own names map to themselves)."""
    parsed = {n: _side_and_stem(n) for n in names}
    roles: dict[str, str] = {}
    used: set[str] = set()
    for role, aliases in ALIASES.items():
        sides = ("l", "r") if role in _SIDED else ("",)
        for side in sides:
            target = f"{role}_{side}" if side else role
            if target in names:
                roles[target] = target
                used.add(target)
                continue
            for alias in aliases:
                hit = next(
                    (n for n, (s, stem) in parsed.items() if n not in used and s == side and stem == alias),
                    None,
                )
                if hit is not None:
                    roles[target] = hit
                    used.add(hit)
                    break
    return roles
