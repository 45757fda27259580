"""Skin slip and non-ideal joints, applied to exact poses (kinematic models).

Real sensors sit on skin, not bone, and real joints are not ideal. These kinematic effects are
modelled here as pure functions of the bone-rigid truth (the soft-tissue *mount*, where slip
arises from physics, is part of the MuJoCo model: :mod:`simbench.sim.mounts`):

- **soft-tissue artefact** (STA): each sensor's offset from its bone placement is a smooth
  function of the rotations of the joints next to its segment,
  ``d(t) = A tanh(W phi(t))`` in the segment frame, with ``phi`` the adjacent joints' rotation
  vectors (rad) and ``W`` a fixed random matrix per sensor (seeded, entries ``N(0, 1/k)`` for
  ``k`` adjacent joints): displacements reaching about the amplitude ``A`` over a radian of joint
  rotation (centimetres on the thigh over the knee's range, docs/conventions.md), following the motion as
  skin does. Being a function of the joint angles, STA biases the joint centre a calibration
  finds, which is what makes it the dominant error on people;
- **slip events** (:class:`SkinSlip`): a sensor shifts on its segment by a fixed offset
  (segment frame) at a given time -- a step, complete from the first sample at or after that
  time -- and stays there;
- **a pushed pack** (:class:`SkinPack`): a sensor mounted on something the body pushes -- O'Brien
  et al.'s pelvis sensor sat on the battery pack worn on the hip, and the paper suspects the
  "motion in this sensor caused by rotating the thigh upwards" of the walk trials' wrong
  hierarchies. The sensor shifts on its segment by ``gain * max(theta(t) - threshold, 0)`` along
  a fixed direction (segment frame), ``theta`` being the pushing segment's flexion: the component
  of its rotation vector relative to the pack's segment along a flexion axis. A ramp, not a
  spring: the pack is at rest until the thigh meets it and then rides on it;
- **a girdle** (:class:`SkinGirdle`): a joint whose centre is carried by a girdle that takes a
  share of the limb's elevation -- the shoulder, where the clavicle and scapula turn with the arm
  (the "scapulohumeral rhythm": Inman et al. 1944 found 2 degrees of glenohumeral elevation for
  every degree of the scapula's), so that the centre moves by centimetres as the arm rises;
- **joint laxity**: a joint's centre moves relative to its parent segment by
  ``d(t) = L tanh(W phi(t))`` (parent segment frame), a few millimetres as real knees do
  (Lafortune et al. 1992 in O'Brien et al.: 7 mm compression, 14.3 mm front-back, 5.6 mm
  side-side); the child segment and everything below it move with it.

Positions change; orientations do not (the artefacts are translations). Accelerometer readings
change by the displacement's second time derivative, taken by finite differences.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from calibration.rotations import matrix_to_rotvec, quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError


@dataclass(frozen=True)
class SkinSlip:
    """A slip the simulation injects: a sensor shifts on its segment by ``offset_m`` from ``time_s`` on.

    Configured as ``[[skin.slip]]`` (:mod:`simbench.sim.sensor_config`); not to be confused with
    :class:`calibration.slip.SlipEvent`, a slip the detector finds in a recording.

    Attributes:
        sensor: name of the sensor that slips.
        time_s: when the sensor slips, s (>= 0): a step, complete from the first sample at or
            after ``time_s``.
        offset_m: ``(3,)`` the shift in the segment frame, m.
    """

    sensor: str
    time_s: float
    offset_m: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not isinstance(self.sensor, str) or not self.sensor:
            raise InputError(f"slip.sensor must be a sensor name, got {self.sensor!r}")
        if not np.isfinite(self.time_s) or self.time_s < 0:
            raise InputError(f"slip.time_s must be >= 0, got {self.time_s}")
        if len(self.offset_m) != 3 or not np.all(np.isfinite(self.offset_m)):
            raise InputError(f"slip.offset_m must be 3 finite numbers, got {self.offset_m}")


@dataclass(frozen=True)
class SkinPack:
    """A sensor on a pack that another segment pushes (``[skin.pack]``, module docstring).

    The sensor moves on its segment by ``gain_m_per_rad * max(theta - threshold_rad, 0)`` along
    ``direction``, ``theta`` (rad) being the rotation of the ``pushed_by`` segment relative to the
    sensor's segment about ``flexion_axis`` (the component of the relative rotation vector).

    Attributes:
        sensor: the sensor on the pack (its segment is the pack's segment).
        pushed_by: the sensor whose segment pushes the pack (e.g. the thigh next to the hip).
        flexion_axis: ``(3,)`` the axis of flexion in the pack segment's frame (normalised here),
            signed so that flexion towards the pack is positive.
        threshold_rad: flexion at which the segment meets the pack, rad.
        gain_m_per_rad: displacement per radian of flexion beyond the threshold, m/rad (>= 0;
            0: the effect is off).
        direction: ``(3,)`` the direction the pack moves, in the pack segment's frame (normalised
            here).
    """

    sensor: str
    pushed_by: str
    flexion_axis: tuple[float, float, float]
    threshold_rad: float
    gain_m_per_rad: float
    direction: tuple[float, float, float]

    def __post_init__(self) -> None:
        for name in ("sensor", "pushed_by"):
            v = getattr(self, name)
            if not isinstance(v, str) or not v:
                raise InputError(f"pack.{name} must be a sensor name, got {v!r}")
        if self.sensor == self.pushed_by:
            raise InputError(f"pack.pushed_by must differ from pack.sensor, both are {self.sensor!r}")
        for name in ("flexion_axis", "direction"):
            v = getattr(self, name)
            if len(v) != 3 or not np.all(np.isfinite(v)) or not np.any(np.asarray(v) != 0):
                raise InputError(f"pack.{name} must be 3 finite numbers, not all zero, got {v!r}")
        if not (np.isfinite(self.threshold_rad) and abs(self.threshold_rad) <= np.pi):
            raise InputError(f"pack.threshold_rad must be in [-pi, pi], got {self.threshold_rad!r}")
        if not (np.isfinite(self.gain_m_per_rad) and self.gain_m_per_rad >= 0):
            raise InputError(f"pack.gain_m_per_rad must be a finite number >= 0, got {self.gain_m_per_rad!r}")


def relative_rotvecs(q_w_b: np.ndarray, parent: Sequence[int], child: Sequence[int]) -> np.ndarray:
    """Rotation vectors of each joint's relative rotation ``R_w_parent^T R_w_child``.

    Args:
        q_w_b: ``(F, N, 4)`` segment orientations, wxyz.
        parent, child: ``(J,)`` segment indices of each joint.

    Returns:
        ``(F, J, 3)`` rad.
    """
    R = quat_to_matrix(q_w_b)
    rel = np.einsum("fjba,fjbc->fjac", R[:, list(parent)], R[:, list(child)])
    return matrix_to_rotvec(rel)


def _adjacent(n: int, parent: Sequence[int], child: Sequence[int]) -> list[list[int]]:
    """Joint indices next to each segment (its inboard and outboard joints)."""
    out: list[list[int]] = [[] for _ in range(n)]
    for j, (p, c) in enumerate(zip(parent, child, strict=True)):
        out[p].append(j)
        out[c].append(j)
    return out


def soft_tissue_offsets(
    phi: np.ndarray,
    parent: Sequence[int],
    child: Sequence[int],
    amplitude_m: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """Soft-tissue artefact of every sensor, in its segment frame.

    Args:
        phi: ``(F, J, 3)`` joint rotation vectors, rad.
        parent, child: ``(J,)`` segment indices of each joint.
        amplitude_m: ``(N,)`` amplitude ``A`` per sensor, m (0: none).
        rng: draws each sensor's ``W`` (``3 x 3 k`` for ``k`` adjacent joints, entries
            ``N(0, 1 / k)``, so that a radian of joint rotation gives about ``A``).

    Returns:
        ``(F, N, 3)`` offsets, m.
    """
    f = phi.shape[0]
    n = amplitude_m.shape[0]
    out = np.zeros((f, n, 3))
    for s, joints in enumerate(_adjacent(n, parent, child)):
        W = rng.normal(0.0, 1.0 / np.sqrt(max(len(joints), 1)), size=(3, 3 * len(joints)))
        if amplitude_m[s] == 0 or not joints:
            continue
        x = phi[:, joints].reshape(f, -1)
        out[:, s] = amplitude_m[s] * np.tanh(x @ W.T)
    return out


def slip_offsets(time_s: np.ndarray, sensors: Sequence[str], slips: Sequence[SkinSlip]) -> np.ndarray:
    """``(F, N, 3)`` offsets (segment frame, m) of slip events: zero before, the offset after."""
    index = {name: k for k, name in enumerate(sensors)}
    out = np.zeros((time_s.size, len(sensors), 3))
    for slip in slips:
        if slip.sensor not in index:
            raise InputError(
                f"slip event on {slip.sensor!r}, which carries no sensor; sensors: {list(sensors)}"
            )
        out[time_s >= slip.time_s - 1e-12, index[slip.sensor]] += np.asarray(slip.offset_m)
    return out


def pack_offsets(R_w_b: np.ndarray, sensors: Sequence[str], pack: SkinPack | None) -> np.ndarray:
    """Offsets of a pushed pack's sensor on its segment (:class:`SkinPack`).

    Args:
        R_w_b: ``(F, N, 3, 3)`` segment orientations.
        sensors: ``(N,)`` sensor names, one per segment.
        pack: the pack, or ``None`` (no offsets).

    Returns:
        ``(F, N, 3)`` offsets in each sensor's segment frame, m: zero but for the pack's sensor.

    Raises:
        InputError: the pack names a sensor the model does not carry.
    """
    out = np.zeros((R_w_b.shape[0], len(sensors), 3))
    if pack is None:
        return out
    index = {name: k for k, name in enumerate(sensors)}
    for name in (pack.sensor, pack.pushed_by):
        if name not in index:
            raise InputError(f"skin.pack names {name!r}, which carries no sensor; sensors: {list(sensors)}")
    k, m = index[pack.sensor], index[pack.pushed_by]
    rel = np.einsum("fba,fbc->fac", R_w_b[:, k], R_w_b[:, m])  # R_pack^T R_pusher
    axis = np.asarray(pack.flexion_axis) / np.linalg.norm(pack.flexion_axis)
    theta = matrix_to_rotvec(rel) @ axis  # (F,) rad
    push_m = pack.gain_m_per_rad * np.maximum(theta - pack.threshold_rad, 0.0)
    out[:, k] = push_m[:, None] * (np.asarray(pack.direction) / np.linalg.norm(pack.direction))
    return out


def laxity_offsets(phi: np.ndarray, laxity_m: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Joint-centre displacement of each joint in its parent segment's frame.

    Args:
        phi: ``(F, J, 3)`` joint rotation vectors, rad.
        laxity_m: ``(J,)`` amplitude ``L`` per joint, m (0: an ideal joint).
        rng: draws each joint's ``W`` (``3 x 3``, entries ``N(0, 1)``: ``L`` over a radian).

    Returns:
        ``(F, J, 3)`` m.
    """
    f, n_j = phi.shape[:2]
    out = np.zeros((f, n_j, 3))
    for j in range(n_j):
        W = rng.normal(0.0, 1.0, size=(3, 3))
        if laxity_m[j] > 0:
            out[:, j] = laxity_m[j] * np.tanh(phi[:, j] @ W.T)
    return out


@dataclass(frozen=True)
class SkinGirdle:
    """A joint whose centre a girdle carries (``[[skin.girdle]]``, module docstring).

    The shoulder is the case: the arm's elevation is shared between the glenohumeral joint and
    the shoulder girdle (clavicle and scapula), which lifts the joint centre about the
    sternoclavicular joint. The joint centre turns about ``pivot_m`` (parent frame, from the joint
    centre) and ``axis`` (parent frame) by ``ratio`` times the limb's elevation: the angle
    between the limb's axis (``limb_axis`` in the child's frame) and where it points at the
    reference pose, whatever the plane of elevation. The child segment and everything below it
    move with the centre.

    Attributes:
        joint: the joint's child sensor (e.g. ``upper_arm_l``).
        pivot_m: ``(3,)`` from the joint centre to the girdle's pivot, parent frame, m.
        axis: ``(3,)`` the girdle's axis of rotation, parent frame (normalised here), signed so
            that elevation turns it positively.
        limb_axis: ``(3,)`` the limb's axis in the child's frame (normalised here).
        ratio: the girdle's share of the elevation, in [0, 1].
    """

    joint: str
    pivot_m: tuple[float, float, float]
    axis: tuple[float, float, float]
    limb_axis: tuple[float, float, float]
    ratio: float

    def __post_init__(self) -> None:
        if not isinstance(self.joint, str) or not self.joint:
            raise InputError(f"girdle.joint must be a sensor name, got {self.joint!r}")
        for name in ("pivot_m", "axis", "limb_axis"):
            v = getattr(self, name)
            if len(v) != 3 or not np.all(np.isfinite(v)):
                raise InputError(f"girdle.{name} must be 3 finite numbers, got {v!r}")
        for name in ("axis", "limb_axis"):
            if not np.any(np.asarray(getattr(self, name)) != 0):
                raise InputError(f"girdle.{name} must not be zero")
        if not (np.isfinite(self.ratio) and 0 <= self.ratio <= 1):
            raise InputError(f"girdle.ratio must be in [0, 1], got {self.ratio!r}")


def girdle_offsets(
    R_w_b: np.ndarray,
    sensors: Sequence[str],
    parent: Sequence[int],
    child: Sequence[int],
    girdles: Sequence[SkinGirdle],
) -> np.ndarray:
    """Joint-centre displacement of each joint carried by a girdle, in its parent's frame.

    Args:
        R_w_b: ``(F, N, 3, 3)`` segment orientations.
        sensors: ``(N,)`` sensor (segment) names.
        parent, child: ``(J,)`` segment indices of each joint.
        girdles: the girdles; each names a joint by its child sensor.

    Returns:
        ``(F, J, 3)`` m: ``(G - I)(-pivot)``, ``G`` the girdle's rotation.
    """
    R = R_w_b
    out = np.zeros((R_w_b.shape[0], len(child), 3))
    for g in girdles:
        if g.joint not in sensors or sensors.index(g.joint) not in child:
            raise InputError(
                f"girdle.joint {g.joint!r} is not the child sensor of a joint; sensors: {list(sensors)}"
            )
        j = list(child).index(sensors.index(g.joint))
        u0 = np.asarray(g.limb_axis) / np.linalg.norm(g.limb_axis)
        rel = np.einsum("fba,fbc->fac", R[:, parent[j]], R[:, child[j]])
        u = rel @ u0  # (F, 3) the limb's axis in the parent frame
        elevation = np.arctan2(np.linalg.norm(np.cross(u0, u), axis=1), u @ u0)  # (F,) in [0, pi]
        axis = np.asarray(g.axis) / np.linalg.norm(g.axis)
        G = rotvec_to_matrix(g.ratio * elevation[:, None] * axis)
        minus_pivot = -np.asarray(g.pivot_m, dtype=float)
        out[:, j] = G @ minus_pivot - minus_pivot
    return out


def subtree_masks(n: int, parent: Sequence[int], child: Sequence[int]) -> np.ndarray:
    """``(J, N)`` bool: segment ``s`` is ``child[j]`` or below it."""
    kids: list[list[int]] = [[] for _ in range(n)]
    for p, c in zip(parent, child, strict=True):
        kids[p].append(c)
    out = np.zeros((len(child), n), dtype=bool)
    for j, c in enumerate(child):
        stack = [c]
        while stack:
            s = stack.pop()
            out[j, s] = True
            stack.extend(kids[s])
    return out


def second_derivative(x: np.ndarray, time_s: np.ndarray) -> np.ndarray:
    """``d^2 x / dt^2`` along axis 0 by central differences (one-sided at the ends)."""
    if x.shape[0] < 3:
        return np.zeros_like(x)
    return np.gradient(np.gradient(x, time_s, axis=0), time_s, axis=0)


def per_sensor(values: Mapping[str, float], names: Sequence[str], default: float, what: str) -> np.ndarray:
    """An array over ``names`` from a ``{name: value}`` table, checking the names."""
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise InputError(f"{what} names {unknown}, which carry no sensor; sensors: {list(names)}")
    return np.array([float(values.get(name, default)) for name in names])
