"""Skin slip and non-ideal joints, applied to exact poses (kinematic models).

Real sensors sit on skin, not bone, and real joints are not ideal. Three kinematic effects are
modelled here as pure functions of the bone-rigid truth (the soft-tissue *mount*, where slip
arises from physics, is part of the MuJoCo model: :mod:`simbench.sim.mounts`):

- **soft-tissue artefact** (STA): each sensor's offset from its bone placement is a smooth
  function of the rotations of the joints next to its segment,
  ``d(t) = A tanh(W phi(t))`` in the segment frame, with ``phi`` the adjacent joints' rotation
  vectors (rad) and ``W`` a fixed random matrix per sensor (seeded, entries ``N(0, 1/k)`` for
  ``k`` adjacent joints): displacements reaching about the amplitude ``A`` over a radian of joint
  rotation (centimetres on the thigh over the knee's range, DESIGN.md), following the motion as
  skin does. Being a function of the joint angles, STA biases the joint centre a calibration
  finds, which is what makes it the dominant error on people;
- **slip events** (:class:`SkinSlip`): a sensor shifts on its segment by a fixed offset
  (segment frame) at a given time -- a step, complete from the first sample at or after that
  time -- and stays there;
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

from calibration.rotations import matrix_to_rotvec, quat_to_matrix
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
        if not np.isfinite(self.time_s) or self.time_s < 0:
            raise InputError(f"slip.time_s must be >= 0, got {self.time_s}")
        if len(self.offset_m) != 3 or not np.all(np.isfinite(self.offset_m)):
            raise InputError(f"slip.offset_m must be 3 finite numbers, got {self.offset_m}")


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
