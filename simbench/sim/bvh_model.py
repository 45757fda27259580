"""A BVH clip's own skeleton as an MJCF model, built with dm_control's PyMJCF.

The model follows the file's hierarchy (:func:`simbench.io.bvh.read_bvh`, z up, metres):

- **bodies**: one per BVH joint, named after it, nested as the BVH tree; a body's ``pos`` is its
  joint's offset in its parent (plus the joint's position channels when they are constant: a
  joint other than the root whose position channels move cannot be a rotary joint and is
  refused); a body's frame at rest is its BVH joint's frame at zero angles, so the body frame
  *is* the BVH joint frame at every frame;
- **joints**: a free joint on the root and a ball joint on every other body, each named after
  its BVH joint; ``qpos`` of a ball joint is the quaternion of the file's ``R_parent_joint``. A
  joint whose rotation does not change over the clip (a conversion's fixed hip or clavicle
  joints, a finger held still; within :data:`FIXED_ROTATION_RAD`) is welded: its body is turned
  by that rotation and has no joint and no sensor, so that the sensors of the joints that move are
  joined by one joint each;
- **geometry and mass**: a capsule from each joint to each child's offset and to each of its End
  Sites, of radius :data:`RADIUS_FRACTION` of its length clipped to
  [:data:`RADIUS_MIN_M`, :data:`RADIUS_MAX_M`], density :data:`DENSITY_KG_M3` (water: MuJoCo
  computes masses and inertias from the geoms); a body without a segment longer than
  :data:`MIN_SEGMENT_M` gets a sphere of radius :data:`RADIUS_MIN_M` so that it has a mass. The
  geoms do not collide (the motion is played back, not simulated);
- **sensor sites**: ``sensor_<joint>`` on every body, half-way along its segment to its first
  child (or End Site), shifted and turned by :func:`simbench.sim.instrument.default_site_frame`
  (a real sensor is never aligned with the bone), so that the instrumentation of
  :mod:`simbench.sim.models` puts a sensor on every body as on the built-in models.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat
from simbench.errors import InputError
from simbench.io.bvh import BvhMotion, read_bvh
from simbench.io.recorded import RecordedMotion, Track
from simbench.sim.instrument import default_site_frame

#: The model name of a BVH clip's own skeleton (``SessionConfig.model`` with a ``.bvh`` motion).
BVH_MODEL = "bvh"

#: Capsule density, kg/m^3 (water, about that of the body), radius as a fraction of the capsule's
#: length, and its bounds, m.
DENSITY_KG_M3 = 1000.0
RADIUS_FRACTION = 0.1
RADIUS_MIN_M = 0.01
RADIUS_MAX_M = 0.05

#: Segments shorter than this get no capsule, m.
MIN_SEGMENT_M = 1e-4

#: A joint other than the root whose rotation turns less than this over the clip (from its first
#: frame's) is welded, rad.
FIXED_ROTATION_RAD = 1e-9

#: A joint's position channels that move less than this over the clip are a constant offset, m.
CONSTANT_TRANSLATION_M = 1e-9


def is_bvh(motion: str) -> bool:
    """The motion names a BVH file (``.bvh``, any case)."""
    return isinstance(motion, str) and motion.lower().endswith(".bvh")


@functools.lru_cache(maxsize=4)
def _read_cached(path: str, units: str, mtime_ns: int, size: int) -> BvhMotion:
    return read_bvh(path, units=units)


def read_clip(path: str | os.PathLike[str], units: str = "cm") -> BvhMotion:
    """:func:`~simbench.io.bvh.read_bvh`, kept for the file as it is on disk (a session reads its
    clip for its timing, its model and its motion: once).

    Raises:
        InputError: a file that does not exist, or what :func:`read_bvh` refuses.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"motion file {p} does not exist" if not p.exists() else f"motion {p} is not a file")
    stat = p.stat()
    return _read_cached(str(p.resolve()), units, stat.st_mtime_ns, stat.st_size)


def capsule_radius(length_m: float) -> float:
    """The stated radius rule: :data:`RADIUS_FRACTION` of the length, within the bounds, m."""
    return float(np.clip(RADIUS_FRACTION * length_m, RADIUS_MIN_M, RADIUS_MAX_M))


def body_positions(motion: BvhMotion) -> np.ndarray:
    """``(J, 3)`` each body's position in its parent, m: the offset, plus constant position channels.

    Raises:
        InputError: a joint other than the root whose position channels move.
    """
    pos = motion.offset_m.copy()
    for k in range(1, len(motion.names)):
        t = motion.translation_m[:, k]
        if np.ptp(t, axis=0).max() > CONSTANT_TRANSLATION_M:
            raise InputError(
                f"{motion.source}: joint {motion.names[k]!r} has position channels that move "
                f"({np.ptp(t, axis=0).max():.3g} m over the clip): only the root may translate; a "
                "joint of the skeleton model is a ball joint"
            )
        pos[k] += t[0]
    return pos


def fixed_joints(motion: BvhMotion) -> np.ndarray:
    """``(J,)`` bool: the joints (never the root) whose rotation stays within
    :data:`FIXED_ROTATION_RAD` of its first frame's over the clip."""
    R = motion.R_parent_joint
    rel = np.einsum("jba,fjbc->fjac", R[0], R)  # R_0^T R_f
    cos = np.clip((np.trace(rel, axis1=-2, axis2=-1) - 1) / 2, -1.0, 1.0)
    turned = np.arccos(cos).max(axis=0)
    fixed = turned <= FIXED_ROTATION_RAD
    fixed[0] = False
    return fixed


def _segments(motion: BvhMotion, pos: np.ndarray) -> list[list[np.ndarray]]:
    """Each joint's segment ends in its own frame: its children's positions, then its End Sites."""
    ends: list[list[np.ndarray]] = [[] for _ in motion.names]
    for k in range(1, len(motion.names)):
        ends[motion.parent[k]].append(pos[k])
    for k, name in enumerate(motion.names):
        ends[k].extend(motion.end_sites_m.get(name, np.zeros((0, 3))))
    return ends


def bvh_mjcf(motion: BvhMotion) -> str:
    """The clip's skeleton (module docstring) as MJCF text.

    Raises:
        InputError: position channels on a joint other than the root, or a name MJCF refuses.
    """
    from dm_control import mjcf  # optional heavy dependency: only BVH motions need it

    pos = body_positions(motion)
    ends = _segments(motion, pos)
    fixed = fixed_joints(motion)
    quat0 = matrix_to_quat(motion.R_parent_joint[0])
    root = mjcf.RootElement(model=Path(motion.source).stem or "bvh")
    bodies = []
    try:
        for k, name in enumerate(motion.names):
            up = root.worldbody if motion.parent[k] < 0 else bodies[motion.parent[k]]
            body = up.add("body", name=name, pos=pos[k], **({"quat": quat0[k]} if fixed[k] else {}))
            if motion.parent[k] < 0:
                body.add("freejoint", name=name)
            elif not fixed[k]:
                body.add("joint", name=name, type="ball")
            segments = [e for e in ends[k] if np.linalg.norm(e) > MIN_SEGMENT_M]
            for end in segments:
                body.add(
                    "geom",
                    type="capsule",
                    fromto=[0.0, 0.0, 0.0, *end],
                    size=[capsule_radius(float(np.linalg.norm(end)))],
                    density=DENSITY_KG_M3,
                    contype=0,
                    conaffinity=0,
                )
            if not segments:
                body.add(
                    "geom",
                    type="sphere",
                    size=[RADIUS_MIN_M],
                    density=DENSITY_KG_M3,
                    contype=0,
                    conaffinity=0,
                )
            if not fixed[k]:
                shift, quat = default_site_frame(k)
                mid = 0.5 * ends[k][0] if ends[k] else np.zeros(3)
                body.add("site", name=f"sensor_{name}", pos=mid + shift, quat=quat)
            bodies.append(body)
    except (ValueError, TypeError) as exc:  # PyMJCF refuses names with '/' and the like
        raise InputError(f"{motion.source}: cannot make an MJCF skeleton of it: {exc}") from None
    return root.to_xml_string()


def bvh_spec(motion: BvhMotion) -> mujoco.MjSpec:
    """The clip's skeleton as an editable :class:`mujoco.MjSpec` (for
    :func:`simbench.sim.models.load_capture_model`)."""
    xml = bvh_mjcf(motion)
    try:
        return mujoco.MjSpec.from_string(xml)
    except Exception as exc:  # mujoco raises ValueError with the parser's message
        raise InputError(f"{motion.source}: MuJoCo could not read its skeleton: {exc}") from None


def bvh_recorded(motion: BvhMotion) -> RecordedMotion:
    """The clip as the tracks of its skeleton's joints: the root's free joint (its offset plus
    position channels, and its rotation), a ball joint per other joint that moves (the quaternion
    of its ``R_parent_joint``; a welded joint's rotation is its body's)."""
    quat = matrix_to_quat(motion.R_parent_joint)
    root = motion.offset_m[0] + motion.translation_m[:, 0]
    tracks = [Track(motion.names[0], "free", np.concatenate([root, quat[:, 0]], axis=1))]
    fixed = fixed_joints(motion)
    tracks += [
        Track(name, "ball", quat[:, k]) for k, name in enumerate(motion.names) if k > 0 and not fixed[k]
    ]
    return RecordedMotion(
        source=motion.source,
        frame_time_s=motion.frame_time_s,
        tracks=tuple(tracks),
        valid=np.ones(motion.n_frames, dtype=bool),
        format="bvh",
    )
