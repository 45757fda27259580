"""BVH motion files (Biovision hierarchy): a skeleton of joints with offsets, and per-frame channels.

**Layout.** ``HIERARCHY`` then one ``ROOT`` (nested ``JOINT`` blocks, each with an ``OFFSET`` and
``CHANNELS``; an ``End Site`` has an ``OFFSET`` only), then ``MOTION``, ``Frames: N``, ``Frame
Time: DT`` and ``N`` lines of numbers, one per channel of every joint in file order.

**Rotations.** A joint's rotation channels, in the order they are listed (any of the six Euler
orders, e.g. ``Zrotation Xrotation Yrotation``), compose as ``R = R_1 @ R_2 @ R_3`` (intrinsic
rotations in listed order, degrees); a joint maps its child's frame into its parent's as
``p_parent = offset + translation + R @ p_child``.

**Frames and units.** BVH is y-up by convention; simbench is z-up: every vector ``v`` is carried
over as ``C @ v`` and every rotation as ``C @ R @ C.T`` with ``C`` the rotation taking +y to +z
(:data:`Y_UP_TO_Z_UP`, +z to -y). Lengths are read in ``units`` (centimetres by convention, the
default; :data:`simbench.units.BVH_LENGTH_UNITS`) and returned in metres.

**Line ends.** LF, CRLF (the CMU conversions are Windows files) or CR alike.

Errors name the file and line: a missing section, a channel count or name that is not BVH's, a
frame whose count of values is not the channels', a value that is not a finite number, a frame
count that is not the lines'.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbench.errors import InputError, read_text
from simbench.units import BVH_LENGTH_UNITS, metres_per_unit

#: ``C``: BVH's y-up coordinates into simbench's z-up ones (x stays, +y becomes +z, +z becomes -y).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

_POSITION = {"Xposition": 0, "Yposition": 1, "Zposition": 2}
_ROTATION = {"Xrotation": "x", "Yrotation": "y", "Zrotation": "z"}


@dataclass(frozen=True)
class BvhMotion:
    """A BVH clip in simbench's frame (z up) and units (metres, seconds).

    Attributes:
        names: ``(J,)`` joint names in file order (the root first).
        parent: ``(J,)`` parent joint index, ``-1`` for the root.
        offset_m: ``(J, 3)`` each joint's origin in its parent's frame, m (the root's: its rest
            position).
        end_sites_m: ``{joint: (K, 3)}`` the ``End Site`` offsets of each joint that has any, m.
        rotation_order: ``(J,)`` each joint's rotation channels as an order such as ``"zxy"``
            (``""`` for a joint without rotation channels).
        R_parent_joint: ``(F, J, 3, 3)`` each joint's rotation, its frame into its parent's.
        translation_m: ``(F, J, 3)`` each joint's position channels added to its offset, m (zero
            where it has none: every joint but the root in most files).
        frame_time_s: the time between frames, s.
        source: the file.
    """

    names: tuple[str, ...]
    parent: np.ndarray
    offset_m: np.ndarray
    end_sites_m: dict[str, np.ndarray]
    rotation_order: tuple[str, ...]
    R_parent_joint: np.ndarray
    translation_m: np.ndarray
    frame_time_s: float
    source: str

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.R_parent_joint.shape[0])

    @property
    def time_s(self) -> np.ndarray:
        """``(F,)`` frame times from 0, s."""
        return np.arange(self.n_frames) * self.frame_time_s

    def world(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics: ``(R_w_j, p_w_j)``, ``(F, J, 3, 3)`` and ``(F, J, 3)`` m, every
        joint's frame in the world (z up) at every frame."""
        f, j = self.R_parent_joint.shape[:2]
        R = np.empty((f, j, 3, 3))
        p = np.empty((f, j, 3))
        local_p = self.offset_m[None] + self.translation_m
        for k in range(j):  # parents come before children in file order
            up = self.parent[k]
            if up < 0:
                R[:, k] = self.R_parent_joint[:, k]
                p[:, k] = local_p[:, k]
            else:
                R[:, k] = R[:, up] @ self.R_parent_joint[:, k]
                p[:, k] = p[:, up] + np.einsum("fij,fj->fi", R[:, up], local_p[:, k])
        return R, p


def euler_matrices(order: str, angles_deg: np.ndarray) -> np.ndarray:
    """``R = R_1 @ R_2 @ R_3`` of intrinsic rotations about the axes of ``order`` (e.g. ``"zxy"``).

    Args:
        order: the axes, in the order the channels list them (one to three of ``x``, ``y``, ``z``).
        angles_deg: ``(F, len(order))`` angles, degrees.

    Returns:
        ``(F, 3, 3)`` rotation matrices.
    """
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    out = np.broadcast_to(np.eye(3), (a.shape[0], 3, 3)).copy()
    for k, axis in enumerate(order):
        c, s = np.cos(a[:, k]), np.sin(a[:, k])
        m = np.zeros((a.shape[0], 3, 3))
        i = "xyz".index(axis)
        j, l = (i + 1) % 3, (i + 2) % 3
        m[:, i, i] = 1.0
        m[:, j, j] = c
        m[:, l, l] = c
        m[:, j, l] = -s
        m[:, l, j] = s
        out = out @ m
    return out


@dataclass
class _Joint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str]
    line: int
    end_sites: list[np.ndarray]


def read_bvh(path: str | os.PathLike[str], *, units: str = "cm") -> BvhMotion:
    """Read a BVH file (module docstring) into simbench's frame and units.

    Args:
        path: the file.
        units: the file's length unit (``cm`` by convention; ``m``, ``mm``, ``in``, ``cmu``:
            :data:`simbench.units.BVH_LENGTH_UNITS`).

    Raises:
        InputError: naming the file and line (module docstring), or an unknown unit.
    """
    scale = metres_per_unit(units, BVH_LENGTH_UNITS)
    path = Path(path)
    lines = read_text(path).splitlines()
    tokens: list[tuple[int, str]] = []
    motion_line = None
    for number, line in enumerate(lines, start=1):
        words = line.split()
        if words and words[0] == "MOTION":
            motion_line = number
            break
        tokens.extend((number, w) for w in words)
    if not tokens or tokens[0][1] != "HIERARCHY":
        raise InputError(f"{path}, line 1: not a BVH file: expected HIERARCHY first")
    if motion_line is None:
        raise InputError(f"{path}: no MOTION section after the hierarchy")
    joints = _parse_hierarchy(path, tokens)
    values, frame_time = _parse_motion(path, lines, motion_line, sum(len(j.channels) for j in joints))
    return _motion(path, joints, values, frame_time, scale)


def _parse_hierarchy(path: Path, tokens: list[tuple[int, str]]) -> list[_Joint]:
    joints: list[_Joint] = []
    stack: list[int] = []  # open blocks: a joint's index, or -2 for an End Site
    pending: tuple[str, int] | None = None  # a ROOT/JOINT/End Site whose "{" is next
    k = 1

    def where(at: int) -> str:
        return f"{path}, line {tokens[min(at, len(tokens) - 1)][0]}"

    def numbers(at: int, count: int, what: str) -> list[float]:
        words = [w for _, w in tokens[at : at + count]]
        try:
            out = [float(w) for w in words]
        except ValueError:
            raise InputError(
                f"{where(at)}: {what}: expected {count} numbers, got {' '.join(words)!r}"
            ) from None
        if len(out) != count or not all(math.isfinite(v) for v in out):
            raise InputError(f"{where(at)}: {what}: expected {count} finite numbers, got {' '.join(words)!r}")
        return out

    while k < len(tokens):
        word = tokens[k][1]
        if word in ("ROOT", "JOINT"):
            if (word == "ROOT") != (not joints and not stack):
                raise InputError(f"{where(k)}: {word} here: a BVH file has one ROOT, and JOINTs inside it")
            if k + 1 >= len(tokens):
                raise InputError(f"{where(k)}: {word} without a name")
            pending = (tokens[k + 1][1], k)
            k += 2
        elif word == "End":
            if k + 1 >= len(tokens) or tokens[k + 1][1] != "Site" or not stack or stack[-1] < 0:
                raise InputError(f"{where(k)}: expected 'End Site' inside a joint")
            pending = ("End Site", k)
            k += 2
        elif word == "{":
            if pending is None:
                raise InputError(f"{where(k)}: '{{' without a ROOT, JOINT or End Site before it")
            name, at = pending
            if name == "End Site":
                stack.append(-2)
            else:
                parent = stack[-1] if stack else -1
                joints.append(_Joint(name, parent, np.zeros(3), [], tokens[at][0], []))
                stack.append(len(joints) - 1)
            pending = None
            k += 1
        elif word == "}":
            if not stack:
                raise InputError(f"{where(k)}: '}}' without an open block")
            stack.pop()
            k += 1
        elif word == "OFFSET":
            if not stack:
                raise InputError(f"{where(k)}: OFFSET outside a joint")
            offset = np.array(numbers(k + 1, 3, "OFFSET"))
            if stack[-1] == -2:
                joints[stack[-2]].end_sites.append(offset)
            else:
                joints[stack[-1]].offset = offset
            k += 4
        elif word == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise InputError(f"{where(k)}: CHANNELS outside a joint")
            try:
                count = int(tokens[k + 1][1])
            except (ValueError, IndexError):
                raise InputError(f"{where(k)}: CHANNELS: expected a count") from None
            names = [w for _, w in tokens[k + 2 : k + 2 + count]]
            bad = [n for n in names if n not in _POSITION and n not in _ROTATION]
            if count < 1 or count > 6 or len(names) != count or bad or len(set(names)) != count:
                raise InputError(
                    f"{where(k)}: CHANNELS {count}: expected 1 to 6 distinct channels of "
                    f"{sorted({*_POSITION, *_ROTATION})}, got {names}"
                )
            joints[stack[-1]].channels = names
            k += 2 + count
        else:
            raise InputError(f"{where(k)}: unexpected {word!r} in the hierarchy")
    if stack or pending is not None:
        raise InputError(f"{path}: the hierarchy ends with {len(stack)} block(s) still open")
    if not joints:
        raise InputError(f"{path}: no ROOT joint in the hierarchy")
    names = [j.name for j in joints]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"{path}: joint names given twice: {twice}")
    return joints


def _parse_motion(
    path: Path, lines: list[str], motion_line: int, n_channels: int
) -> tuple[np.ndarray, float]:
    body = [
        (n, line.strip()) for n, line in enumerate(lines[motion_line:], start=motion_line + 1) if line.strip()
    ]
    if len(body) < 2:
        raise InputError(f"{path}, line {motion_line}: MOTION needs 'Frames: N' and 'Frame Time: DT'")
    (n1, frames_line), (n2, time_line) = body[0], body[1]
    try:
        key, value = frames_line.split(":", 1)
        if key.strip() != "Frames":
            raise ValueError
        n_frames = int(value)
    except ValueError:
        raise InputError(f"{path}, line {n1}: expected 'Frames: N', got {frames_line!r}") from None
    try:
        key, value = time_line.split(":", 1)
        if key.strip() != "Frame Time":
            raise ValueError
        frame_time = float(value)
    except ValueError:
        raise InputError(
            f"{path}, line {n2}: expected 'Frame Time: DT' (seconds), got {time_line!r}"
        ) from None
    if not (math.isfinite(frame_time) and frame_time > 0):
        raise InputError(f"{path}, line {n2}: expected a frame time > 0 s, got {frame_time!r}")
    rows = body[2:]
    if n_frames < 1 or len(rows) != n_frames:
        raise InputError(
            f"{path}, line {n1}: 'Frames: {n_frames}' but {len(rows)} frame line(s) follow (the file may "
            "be cut short)"
        )
    values = np.empty((n_frames, n_channels))
    for f, (number, line) in enumerate(rows):
        words = line.split()
        if len(words) != n_channels:
            raise InputError(
                f"{path}, line {number}: {len(words)} values, expected {n_channels} (one per channel)"
            )
        try:
            values[f] = [float(w) for w in words]
        except ValueError:
            raise InputError(f"{path}, line {number}: expected numbers, got {line[:80]!r}") from None
        if not np.isfinite(values[f]).all():
            raise InputError(f"{path}, line {number}: a value that is not finite (NaN or inf)")
    return values, frame_time


def _motion(
    path: Path, joints: list[_Joint], values: np.ndarray, frame_time: float, scale: float
) -> BvhMotion:
    C = Y_UP_TO_Z_UP
    n_frames, n = values.shape[0], len(joints)
    R = np.empty((n_frames, n, 3, 3))
    t = np.zeros((n_frames, n, 3))
    orders = []
    col = 0
    for k, joint in enumerate(joints):
        cols = {name: col + i for i, name in enumerate(joint.channels)}
        col += len(joint.channels)
        for name, axis in _POSITION.items():
            if name in cols:
                t[:, k, axis] = values[:, cols[name]] * scale
        rot = [c for c in joint.channels if c in _ROTATION]
        order = "".join(_ROTATION[c] for c in rot)
        orders.append(order)
        R_y = (
            euler_matrices(order, values[:, [cols[c] for c in rot]])
            if rot
            else np.broadcast_to(np.eye(3), (n_frames, 3, 3))
        )
        R[:, k] = C @ R_y @ C.T
    t = t @ C.T
    return BvhMotion(
        names=tuple(j.name for j in joints),
        parent=np.array([j.parent for j in joints], dtype=int),
        offset_m=np.array([C @ j.offset for j in joints]) * scale,
        end_sites_m={j.name: np.array([C @ e for e in j.end_sites]) * scale for j in joints if j.end_sites},
        rotation_order=tuple(orders),
        R_parent_joint=R,
        translation_m=t,
        frame_time_s=frame_time,
        source=str(path),
    )
