"""SCoRE, the Symmetrical Centre of Rotation Estimation, and the checks every pose-based method shares.

Reference: R. M. Ehrig, W. R. Taylor, G. N. Duda, M. O. Heller, "A survey of formal methods for
determining the centre of rotation of ball joints", Journal of Biomechanics 39 (2006) 2798-2809.

Two segments (here: two sensors, a parent ``p`` and a child ``c``) whose poses are known at every
frame ``f`` share a point fixed in both, the joint centre, at ``c_p`` in the parent frame and
``c_c`` in the child frame. SCoRE minimises over both at once, symmetrically in the two segments::

    sum_f | R_w_p[f] c_p + p_w_p[f] - R_w_c[f] c_c - p_w_c[f] |^2

a linear least-squares problem ``A x = b`` with ``A[f] = [R_w_p[f], -R_w_c[f]]`` (3 x 6),
``x = [c_p; c_c]`` and ``b[f] = p_w_c[f] - p_w_p[f]``. This is the formulation O'Brien et al.
(2000) published six years earlier (their eqs. 8-13, :func:`calibration.joint.fit_joint`): the two
give the same centre on well-exercised data (the tests check it to 1e-9 m). They differ in what
they do when the motion does not determine the centre: :func:`calibration.joint.fit_joint` tests
each weak direction against the residual's noise, while :func:`score` applies only a hard floor on
the singular values (:data:`calibration.joint.SINGLE_AXIS_RATIO`) and reports the rank; for a hinge
use SARA (:mod:`calibration.methods.sara`).

The helpers :func:`check_pair`, :func:`stacked_system` and :func:`rotation_rank` are shared by the
other pose-based methods of this package.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import SINGLE_AXIS_RATIO, determined_directions, joint_residual_vectors

#: Fewest usable frames SCoRE accepts (two frames give 6 equations for 6 unknowns).
MIN_FRAMES = 3


@dataclass(frozen=True)
class PosePair:
    """One pair's pose arrays, checked, with the frames a fit uses.

    Attributes:
        R_w_p, R_w_c: ``(frames, 3, 3)`` parent and child rotations, sensor to world.
        p_w_p, p_w_c: ``(frames, 3)`` parent and child positions in world, metres.
        used: ``(frames,)`` bool, the frames a fit uses (``valid`` where given, else all).
    """

    R_w_p: np.ndarray
    p_w_p: np.ndarray
    R_w_c: np.ndarray
    p_w_c: np.ndarray
    used: np.ndarray

    @property
    def n_frames(self) -> int:
        """Frames a fit uses."""
        return int(np.count_nonzero(self.used))


def check_valid(valid: np.ndarray | None, n_frames: int) -> np.ndarray:
    """``(n_frames,)`` bool: ``valid`` checked, or all True when it is ``None``."""
    if valid is None:
        return np.ones(n_frames, dtype=bool)
    v = np.asarray(valid)
    if v.shape != (n_frames,) or v.dtype != bool:
        raise CalibrationInputError(
            f"Expected valid to be a bool array of shape ({n_frames},), got {v.dtype} {v.shape}"
        )
    return v


def check_finite(name: str, a: np.ndarray, used: np.ndarray) -> None:
    """Raise :class:`CalibrationInputError` when ``a`` (``(frames, ...)``) is not finite in a used frame."""
    bad = used & ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise CalibrationInputError(
            f"Expected {name} to be finite in every used frame, got non-finite values in "
            f"{int(bad.sum())} frames (first: frame {first}); mark such frames False in valid"
        )


def check_pair(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
    min_frames: int = MIN_FRAMES,
) -> PosePair:
    """Check one pair's pose arrays at the boundary of a pose-based method.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used and may hold NaN
            (gaps in a recording).
        min_frames: fewest used frames accepted.

    Returns:
        The arrays as float and the frames used.

    Raises:
        CalibrationInputError: wrong shapes, frame counts that differ, a non-bool or misshapen
            ``valid``, a non-finite value in a used frame, or fewer than ``min_frames`` used frames.
    """
    names = ("R_w_p", "p_w_p", "R_w_c", "p_w_c")
    tails = ((3, 3), (3,), (3, 3), (3,))
    arrays = []
    for name, a, tail in zip(names, (R_w_p, p_w_p, R_w_c, p_w_c), tails, strict=True):
        try:
            a = np.asarray(a, dtype=float)
        except (TypeError, ValueError) as exc:
            raise CalibrationInputError(
                f"Expected {name} to be a numeric array, got {type(a).__name__}"
            ) from exc
        if a.ndim != 1 + len(tail) or a.shape[1:] != tail:
            dims = ", ".join(map(str, tail))
            raise CalibrationInputError(f"Expected {name} to have shape (frames, {dims}), got {a.shape}")
        if arrays and a.shape[0] != arrays[0].shape[0]:
            raise CalibrationInputError(
                f"Expected {name} to have {arrays[0].shape[0]} frames like R_w_p, got {a.shape[0]}"
            )
        arrays.append(a)
    used = check_valid(valid, arrays[0].shape[0])
    for name, a in zip(names, arrays, strict=True):
        check_finite(name, a, used)
    n_used = int(np.count_nonzero(used))
    if n_used < min_frames:
        raise CalibrationInputError(f"Expected at least {min_frames} used frames, got {n_used}")
    return PosePair(arrays[0], arrays[1], arrays[2], arrays[3], used)


def stacked_system(pair: PosePair) -> tuple[np.ndarray, np.ndarray]:
    """The stacked system of SCoRE (O'Brien eqs. 11-13) over the used frames.

    Returns:
        ``A`` ``(3 n, 6)`` rows ``[R_w_p[f], -R_w_c[f]]`` (dimensionless) and ``b`` ``(3 n,)``
        ``p_w_c[f] - p_w_p[f]`` (metres), ``n`` the used frames.
    """
    Rp, Rc = pair.R_w_p[pair.used], pair.R_w_c[pair.used]
    A = np.concatenate([Rp, -Rc], axis=2).reshape(-1, 6)
    b = (pair.p_w_c[pair.used] - pair.p_w_p[pair.used]).reshape(-1)
    return A, b


def rotation_rank(singular_values: np.ndarray, single_axis_ratio: float = SINGLE_AXIS_RATIO) -> int:
    """Directions of ``x = [c_p; c_c]`` the relative rotation determines (hard floor only).

    ``A``'s singular values are ``sqrt(F (1 +- sigma_k(M)))`` with ``M`` the mean relative rotation
    (:mod:`calibration.joint`): 6 for a ball joint turned in every direction, 5 for a hinge, 3 when
    the child does not rotate relative to the parent.

    Args:
        singular_values: ``(6,)`` singular values of ``A``, descending; dimensionless.
        single_axis_ratio: a direction counts when ``s >= single_axis_ratio * s_max``.
    """
    return int(np.count_nonzero(determined_directions(singular_values, single_axis_ratio)))


def require_rotation(singular_values: np.ndarray, method: str, needed: int = 5) -> int:
    """The rank of ``A`` (:func:`rotation_rank`); :class:`CalibrationError` when below ``needed``."""
    rank = rotation_rank(singular_values)
    if rank < needed:
        ratio = float(singular_values[needed - 1] / singular_values[0]) if singular_values[0] > 0 else 0.0
        raise CalibrationError(
            f"{method} needs the child to rotate relative to the parent: the motion determines "
            f"{rank} of the 6 coordinates of the joint (needs {needed}; s_{needed}/s_max = {ratio:.2e}, "
            f"floor {SINGLE_AXIS_RATIO:.0e})"
        )
    return rank


def frame_residuals(pair: PosePair, joint_in_parent: np.ndarray, joint_in_child: np.ndarray) -> np.ndarray:
    """``(frames,)`` norm of the joint constraint's residual (O'Brien eq. 8) per frame, metres;
    NaN in unused frames."""
    out = np.full(pair.used.shape[0], np.nan)
    u = pair.used
    r = joint_residual_vectors(
        pair.R_w_p[u], pair.p_w_p[u], pair.R_w_c[u], pair.p_w_c[u], joint_in_parent, joint_in_child
    )
    out[u] = np.linalg.norm(r, axis=1)
    return out


def rms(frame_residual: np.ndarray) -> float:
    """Root mean square of the finite entries of a per-frame residual."""
    r = frame_residual[np.isfinite(frame_residual)]
    return float(np.sqrt(np.mean(r * r)))


@dataclass(frozen=True)
class ScoreFit:
    """The joint centre SCoRE found between a parent and a child sensor.

    Attributes:
        joint_in_parent: ``(3,)`` joint centre in the parent sensor's frame, metres.
        joint_in_child: ``(3,)`` joint centre in the child sensor's frame, metres.
        rms_residual: root mean square over the used frames of the residual's norm, metres.
        frame_residual: ``(frames,)`` residual norm per input frame, metres; NaN where unused.
        singular_values: ``(6,)`` singular values of ``A``, descending (dimensionless).
        rank: directions the motion determines (:func:`rotation_rank`): 6 for a ball joint, 5 when
            the motion is about one axis (the solution is then the minimum-norm one along it).
        n_frames: frames used.
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    rms_residual: float
    frame_residual: np.ndarray
    singular_values: np.ndarray
    rank: int
    n_frames: int


def score(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
) -> ScoreFit:
    """SCoRE (Ehrig et al. 2006): the joint centre in both sensor frames by linear least squares.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre in both frames, residuals and the singular values of the system.

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used frame, fewer than
            :data:`MIN_FRAMES` used frames.
        CalibrationError: the child does not rotate relative to the parent (fewer than five
            directions determined).
    """
    pair = check_pair(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    A, b = stacked_system(pair)
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    rank = require_rotation(s, "SCoRE")
    x = Vt[:rank].T @ ((U[:, :rank].T @ b) / s[:rank])  # minimum norm along undetermined directions
    residual = frame_residuals(pair, x[:3], x[3:])
    return ScoreFit(
        joint_in_parent=x[:3].copy(),
        joint_in_child=x[3:].copy(),
        rms_residual=rms(residual),
        frame_residual=residual,
        singular_values=s,
        rank=rank,
        n_frames=pair.n_frames,
    )
