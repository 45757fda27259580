"""Analytic articulated motion with exact ground truth (plain numpy, no physics).

A skeleton is a tree of rigid segments joined by ball or hinge joints, one sensor per segment.
Each segment's body frame has its origin at its inboard joint; the root's pose and every joint's
rotation follow smooth seeded sums of sines, and forward kinematics gives every sensor's exact
pose. This is the testbed's analytic reference: the MuJoCo sessions add physics, this gives the
exact answer to compare the calibration core with, in milliseconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from calibration.rotations import rotvec_to_matrix

BALL = "ball"
HINGE = "hinge"


@dataclass(frozen=True)
class Segment:
    """One rigid segment and the joint that hangs it from its parent.

    Attributes:
        name: segment (and sensor) name.
        parent: parent segment name, ``None`` for the root.
        joint_in_parent_body: ``(3,)`` this segment's inboard joint in the parent's body frame, m.
        kind: ``"ball"`` or ``"hinge"`` (ignored for the root).
        axis: ``(3,)`` hinge axis in the parent's body frame (unit), for ``"hinge"``.
        sensor_offset: ``(3,)`` sensor origin in this segment's body frame, m.
        sensor_rotvec: ``(3,)`` sensor orientation in the body frame, rotation vector, rad.
    """

    name: str
    parent: str | None
    joint_in_parent_body: tuple[float, float, float] = (0.0, 0.0, 0.0)
    kind: str = BALL
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    sensor_offset: tuple[float, float, float] = (0.03, 0.02, 0.01)
    sensor_rotvec: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Skeleton:
    """A tree of segments, parents listed before children."""

    segments: tuple[Segment, ...]

    def __post_init__(self) -> None:
        seen: set[str] = set()
        for k, seg in enumerate(self.segments):
            if seg.name in seen:
                raise ValueError(f"segment {seg.name!r} is listed twice")
            if (seg.parent is None) != (k == 0):
                raise ValueError("the first segment must be the root and the only one without parent")
            if seg.parent is not None and seg.parent not in seen:
                raise ValueError(f"segment {seg.name!r}: parent {seg.parent!r} must be listed before it")
            if seg.kind not in (BALL, HINGE):
                raise ValueError(f"segment {seg.name!r}: kind must be 'ball' or 'hinge', got {seg.kind!r}")
            seen.add(seg.name)

    @property
    def names(self) -> tuple[str, ...]:
        """Segment names, root first."""
        return tuple(s.name for s in self.segments)

    @property
    def parent_of(self) -> dict[str, str]:
        """``{child: parent}``."""
        return {s.name: s.parent for s in self.segments if s.parent is not None}

    def joint_in_sensor_frames(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Exact ``{child: (joint_in_parent, joint_in_child)}`` in the sensor frames, metres."""
        by_name = {s.name: s for s in self.segments}
        out = {}
        for s in self.segments[1:]:
            par = by_name[s.parent]
            R_b_sp = rotvec_to_matrix(np.array(par.sensor_rotvec))
            R_b_sc = rotvec_to_matrix(np.array(s.sensor_rotvec))
            in_parent = R_b_sp.T @ (np.array(s.joint_in_parent_body) - np.array(par.sensor_offset))
            in_child = R_b_sc.T @ (-np.array(s.sensor_offset))
            out[s.name] = (in_parent, in_child)
        return out

    def segment_lengths(self) -> dict[tuple[str, str, str], float]:
        """Exact distance between every two joints of each segment, metres.

        Keys are ``(segment, joint_a, joint_b)`` with joint names ``"parent-child"``, inboard
        joint first, then outboard joints in listing order (as :mod:`calibration.skeleton`).
        """
        out = {}
        for seg in self.segments:
            located = []
            if seg.parent is not None:
                located.append((f"{seg.parent}-{seg.name}", np.zeros(3)))
            for child in self.segments:
                if child.parent == seg.name:
                    located.append((f"{seg.name}-{child.name}", np.array(child.joint_in_parent_body)))
            for a in range(len(located)):
                for b in range(a + 1, len(located)):
                    length = float(np.linalg.norm(located[a][1] - located[b][1]))
                    out[(seg.name, located[a][0], located[b][0])] = length
        return out


@dataclass(frozen=True)
class Slip:
    """A sensor that shifts on its segment from ``frame`` on by ``delta`` (body frame, m)."""

    sensor: str
    frame: int
    delta: tuple[float, float, float]


@dataclass(frozen=True)
class SyntheticCapture:
    """Exact and measured poses of a synthetic capture.

    Attributes:
        names: sensor names (one per segment), root first.
        time_s: ``(frames,)`` seconds.
        R_w_s: ``(frames, sensors, 3, 3)`` measured sensor rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` measured sensor positions, m.
        R_w_s_true: ``(frames, sensors, 3, 3)`` exact rotations (after slips, before noise).
        p_w_s_true: ``(frames, sensors, 3)`` exact positions (after slips, before noise), m.
        joint_w: ``(frames, sensors, 3)`` world position of each segment's inboard joint
            (the root's row is its body origin), m.
        skeleton: the skeleton moved.
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    R_w_s: np.ndarray
    p_w_s: np.ndarray
    R_w_s_true: np.ndarray
    p_w_s_true: np.ndarray
    joint_w: np.ndarray
    skeleton: Skeleton


def _smooth(rng: np.random.Generator, t: np.ndarray, dims: int, amplitude: float) -> np.ndarray:
    """``(frames, dims)`` sums of three sines per dimension, frequencies 0.1-0.7 Hz."""
    freq = rng.uniform(0.1, 0.7, size=(3, dims))
    phase = rng.uniform(0, 2 * np.pi, size=(3, dims))
    amp = amplitude * rng.uniform(0.5, 1.0, size=(3, dims)) / np.sqrt(3.0)
    return np.einsum("kd,tkd->td", amp, np.sin(2 * np.pi * freq * t[:, None, None] + phase))


def simulate_motion(
    skeleton: Skeleton,
    *,
    n_frames: int,
    rate_hz: float,
    rng: np.random.Generator,
    amplitude_rad: float = 0.8,
    position_noise_m: float = 0.0,
    rotation_noise_rad: float = 0.0,
    slips: Sequence[Slip] = (),
    root_travel_m: float = 0.4,
) -> SyntheticCapture:
    """Move a skeleton through smooth seeded motion and return exact and noisy sensor poses.

    Args:
        skeleton: the tree to move.
        n_frames: frames to generate.
        rate_hz: sample rate, Hz.
        rng: the only source of randomness.
        amplitude_rad: joint rotation amplitude (rotation-vector components for ball joints,
            the angle for hinges), rad.
        position_noise_m: standard deviation of white Gaussian noise on each position
            component, m.
        rotation_noise_rad: standard deviation of each component of a white Gaussian rotation
            vector applied to each measured rotation (world side), rad.
        slips: sensor shifts on their segments.
        root_travel_m: amplitude of the root's movement through the volume, m.
    """
    if n_frames < 1 or rate_hz <= 0:
        raise ValueError(f"need n_frames >= 1 and rate_hz > 0, got {n_frames}, {rate_hz}")
    t = np.arange(n_frames) / rate_hz
    n = len(skeleton.segments)
    index = {s.name: k for k, s in enumerate(skeleton.segments)}
    R_w_b = np.empty((n_frames, n, 3, 3))
    p_w_b = np.empty((n_frames, n, 3))
    R_w_b[:, 0] = rotvec_to_matrix(_smooth(rng, t, 3, 1.2))
    p_w_b[:, 0] = np.array([0.0, 0.0, 1.0]) + _smooth(rng, t, 3, root_travel_m)
    for k, seg in enumerate(skeleton.segments[1:], start=1):
        par = index[seg.parent]
        if seg.kind == HINGE:
            axis = np.array(seg.axis) / np.linalg.norm(seg.axis)
            rotvec = _smooth(rng, t, 1, amplitude_rad) * axis
        else:
            rotvec = _smooth(rng, t, 3, amplitude_rad)
        R_joint = rotvec_to_matrix(rotvec)
        p_w_b[:, k] = p_w_b[:, par] + R_w_b[:, par] @ np.array(seg.joint_in_parent_body)
        R_w_b[:, k] = R_w_b[:, par] @ R_joint
    offsets = np.tile(np.array([s.sensor_offset for s in skeleton.segments], dtype=float), (n_frames, 1, 1))
    for slip in slips:
        offsets[slip.frame :, index[slip.sensor]] += np.array(slip.delta)
    R_b_s = rotvec_to_matrix(np.array([s.sensor_rotvec for s in skeleton.segments], dtype=float))
    R_true = R_w_b @ R_b_s[None]
    p_true = p_w_b + np.einsum("fsij,fsj->fsi", R_w_b, offsets)
    R_meas, p_meas = R_true, p_true
    if rotation_noise_rad > 0:
        R_meas = rotvec_to_matrix(rng.normal(0.0, rotation_noise_rad, size=(n_frames, n, 3))) @ R_true
    if position_noise_m > 0:
        p_meas = p_true + rng.normal(0.0, position_noise_m, size=p_true.shape)
    return SyntheticCapture(
        names=skeleton.names,
        time_s=t,
        R_w_s=np.array(R_meas),
        p_w_s=np.array(p_meas),
        R_w_s_true=R_true,
        p_w_s_true=p_true,
        joint_w=p_w_b,
        skeleton=skeleton,
    )


def _neck_position(d_left: float, d_right: float, half_span: float) -> tuple[float, float, float]:
    """Point in the chest plane at ``d_left``/``d_right`` from shoulders at ``-+half_span``."""
    x = (d_left**2 - d_right**2) / (4.0 * half_span)
    y = float(np.sqrt(d_left**2 - (x + half_span) ** 2))
    return (x, y, 0.0)


def linkage() -> Skeleton:
    """O'Brien et al.'s wooden linkage: six pieces, five ball joints, one sensor per piece.

    Joint-to-joint distances are the paper's measured values (docs/conventions.md): neck-left shoulder
    39.0 cm, neck-right shoulder 39.7 cm, between shoulders 34.3 cm, right upper arm 28.6 cm,
    left upper arm 31.4 cm. Sensors sit off the joint axes.
    """
    half = 0.343 / 2.0
    return Skeleton(
        (
            Segment("chest", None, sensor_offset=(0.02, 0.10, 0.03), sensor_rotvec=(0.1, -0.2, 0.3)),
            Segment(
                "head",
                "chest",
                _neck_position(0.390, 0.397, half),
                BALL,
                sensor_offset=(0.01, 0.12, 0.04),
                sensor_rotvec=(0.3, 0.1, 0.0),
            ),
            Segment(
                "upper_arm_l",
                "chest",
                (-half, 0.0, 0.0),
                BALL,
                sensor_offset=(-0.15, 0.03, 0.03),
                sensor_rotvec=(0.0, 0.4, -0.2),
            ),
            Segment(
                "forearm_l",
                "upper_arm_l",
                (-0.314, 0.0, 0.0),
                BALL,
                sensor_offset=(-0.14, -0.02, 0.03),
                sensor_rotvec=(-0.3, 0.0, 0.5),
            ),
            Segment(
                "upper_arm_r",
                "chest",
                (half, 0.0, 0.0),
                BALL,
                sensor_offset=(0.13, 0.03, -0.03),
                sensor_rotvec=(0.2, 0.2, 0.2),
            ),
            Segment(
                "forearm_r",
                "upper_arm_r",
                (0.286, 0.0, 0.0),
                BALL,
                sensor_offset=(0.15, 0.02, 0.03),
                sensor_rotvec=(0.5, -0.1, 0.0),
            ),
        )
    )


def chain(lengths: Sequence[float], kinds: Sequence[str] | None = None) -> Skeleton:
    """A serial chain ``s0 - s1 - ... - sK`` of ``K = len(lengths)`` joints.

    Joint ``k`` (between ``s{k-1}`` and ``s{k}``) sits ``lengths[k-1]`` metres along the x axis
    of ``s{k-1}``'s body frame, so segment ``s{k}``'s length is ``lengths[k]``; ``kinds[k-1]`` is
    its kind. Hinge axes are the parent's z axis; sensors sit off the axes.
    """
    kinds = list(kinds) if kinds is not None else [BALL] * len(lengths)
    if len(kinds) != len(lengths):
        raise ValueError(f"need one kind per link: {len(lengths)} lengths, {len(kinds)} kinds")
    segs = [Segment("s0", None, sensor_offset=(0.05, 0.02, 0.03))]
    for k in range(1, len(lengths) + 1):
        own = lengths[k] if k < len(lengths) else 0.2
        segs.append(
            Segment(
                f"s{k}",
                f"s{k - 1}",
                (lengths[k - 1], 0.0, 0.0),
                kinds[k - 1],
                axis=(0.0, 0.0, 1.0),
                sensor_offset=(0.4 * own, 0.03 + 0.01 * k, -0.02),
                sensor_rotvec=(0.1 * k, -0.2, 0.05 * k),
            )
        )
    return Skeleton(tuple(segs))


def random_tree(n: int, rng: np.random.Generator) -> Skeleton:
    """A random tree of ``n`` ball-jointed segments with limbs of 0.2-0.5 m."""
    if n < 2:
        raise ValueError(f"a tree needs at least 2 segments, got {n}")
    segs = [Segment("b0", None, sensor_offset=tuple(rng.uniform(-0.1, 0.1, 3)))]
    for k in range(1, n):
        parent = int(rng.integers(0, k))
        direction = rng.normal(size=3)
        joint = direction / np.linalg.norm(direction) * rng.uniform(0.2, 0.5)
        segs.append(
            Segment(
                f"b{k}",
                f"b{parent}",
                tuple(joint),
                BALL,
                sensor_offset=tuple(rng.uniform(-0.15, 0.15, 3)),
                sensor_rotvec=tuple(rng.uniform(-1, 1, 3)),
            )
        )
    return Skeleton(tuple(segs))


def messy_joint(
    joint_amplitude_rad: Sequence[float],
    *,
    n_frames: int,
    rate_hz: float,
    rng: np.random.Generator,
    sensor_offsets: Sequence[Sequence[float]] = ((0.28, 0.05, -0.03), (0.20, 0.04, 0.03)),
    play_m: float = 0.002,
    skin_m: float = 0.005,
    position_noise_m: float = 0.002,
    rotation_noise_rad: float = 0.01,
) -> SyntheticCapture:
    """Two sensors across one imperfect joint, as a real rig or limb records it.

    The parent segment runs along its body x axis to the joint at ``(0.35, 0, 0)``; the child
    continues along x. The joint turns by a rotation vector whose components about the parent's
    body x, y, z axes are smooth seeded signals of amplitude ``joint_amplitude_rad``: a hinge
    with wobble is ``(0.04, 0.04, 0.8)`` (a few degrees about the other axes), a ball joint moved
    in flexion and abduction with little twist ``(0.04, 0.8, 0.8)``. On top: play (the child's
    joint point wanders by ``play_m`` in the parent frame), soft-tissue-like slow offsets of each
    sensor on its segment (``skin_m``; the child's half of it follows the largest joint angle),
    and white tracker noise on every position component (``position_noise_m``, m) and
    rotation-vector component (``rotation_noise_rad``). ``sensor_offsets`` are the nominal sensor
    origins in the parent's and the child's body frames, m. The skeleton's joint is the nominal
    one: a hinge about the axis whose amplitude is tenfold the others', else a ball.
    """
    amp = np.asarray(joint_amplitude_rad, dtype=float)
    if amp.shape != (3,) or n_frames < 1 or rate_hz <= 0:
        raise ValueError(f"need 3 amplitudes, n_frames >= 1, rate_hz > 0; got {amp}, {n_frames}, {rate_hz}")
    main = int(np.argmax(amp))
    kind = HINGE if amp[main] >= 10.0 * np.max(np.delete(amp, main)) else BALL
    off = [tuple(float(v) for v in o) for o in sensor_offsets]
    skeleton = Skeleton(
        (
            Segment("parent", None, sensor_offset=off[0], sensor_rotvec=(0.2, -0.3, 0.1)),
            Segment(
                "child", "parent", (0.35, 0.0, 0.0), kind, tuple(np.eye(3)[main]), off[1], (-0.4, 0.1, 0.3)
            ),
        )
    )
    t = np.arange(n_frames) / rate_hz
    R_w_p = rotvec_to_matrix(_smooth(rng, t, 3, 1.2))
    p_w_p = np.array([0.0, 0.0, 1.0]) + _smooth(rng, t, 3, 0.4)
    rotvec = np.concatenate([_smooth(rng, t, 1, a) for a in amp], axis=1)
    R_w_c = R_w_p @ rotvec_to_matrix(rotvec)
    joint_b = np.array(skeleton.segments[1].joint_in_parent_body) + _smooth(rng, t, 3, play_m)
    p_w_joint = p_w_p + np.einsum("fij,fj->fi", R_w_p, joint_b)
    direction = rng.normal(size=3)
    follow = 0.5 * skin_m * (rotvec[:, main : main + 1] / amp[main]) * direction / np.linalg.norm(direction)
    off_p = np.array(off[0]) + _smooth(rng, t, 3, skin_m)
    off_c = np.array(off[1]) + _smooth(rng, t, 3, 0.5 * skin_m) + follow
    R_b_s = rotvec_to_matrix(np.array([s.sensor_rotvec for s in skeleton.segments]))
    R_true = np.stack([R_w_p @ R_b_s[0], R_w_c @ R_b_s[1]], axis=1)
    at_p = p_w_p + np.einsum("fij,fj->fi", R_w_p, off_p)
    p_true = np.stack([at_p, p_w_joint + np.einsum("fij,fj->fi", R_w_c, off_c)], axis=1)
    R_meas = rotvec_to_matrix(rng.normal(0.0, rotation_noise_rad, size=(n_frames, 2, 3))) @ R_true
    p_meas = p_true + rng.normal(0.0, position_noise_m, size=p_true.shape)
    joint_w = np.stack([p_w_p, p_w_joint], axis=1)
    return SyntheticCapture(skeleton.names, t, R_meas, p_meas, R_true, p_true, joint_w, skeleton)
