"""The least-squares rotary-joint fit of one pair of sensors (O'Brien et al. 2000, section 3.1-3.2).

For a parent sensor ``p`` and a child sensor ``c`` joined by a rotary joint, the joint centre is
a point fixed in both sensor frames, ``joint_in_parent`` and ``joint_in_child``, such that at
every frame ``f`` (O'Brien eq. 8)::

    R_w_p[f] @ joint_in_parent + p_w_p[f] == R_w_c[f] @ joint_in_child + p_w_c[f]

Stacked over frames this is the linear system ``A x = b`` of O'Brien eqs. 9-13 with
``A[f] = [R_w_p[f], -R_w_c[f]]`` (3 x 6), ``x = [joint_in_parent; joint_in_child]`` and
``b[f] = p_w_c[f] - p_w_p[f]``, solved here by the singular value decomposition.

**Conditioning and single-axis joints.** ``A`` holds only rotations, so its singular values are
dimensionless and do not depend on the length unit of the positions: metres or centimetres give
the same singular values. Its Gram matrix is ``F [[I, -M], [-M^T, I]]`` with ``M`` the mean
relative rotation ``R_w_p^T R_w_c`` over the frames, so the singular values are
``sqrt(F (1 +- sigma_k(M)))``: all equal when the joint turns through large angles in every
direction, one near zero when the relative motion is about a single axis (section 3.2), three
near zero when the sensors do not rotate relative to each other. The ratio ``s_min / s_max``
(:attr:`JointFit.weak_ratio`) is about half the rms rotation angle (rad) off the weakest axis; it
is reported, but the verdict does not rest on it.

Whether a weak direction is determined is decided by a test against the residual's own noise
(:mod:`calibration.hinge`): the rise of the residual when the centre is held at the minimum-norm
point along that direction, against the batch-means variance of the residual's projection (the
residual is autocorrelated). Undetermined directions are left out of the solution, which then is
the minimum-norm one along them -- the point closest to the origins of both sensor frames, as
the paper chooses -- instead of an arbitrary point driven by noise. One such direction marks a
single-axis joint, and its right singular vector gives the axis in both frames (section 3.2).
Directions with ``s < single_axis_ratio * s_max`` (default :data:`SINGLE_AXIS_RATIO`, a hard
floor) are undetermined whatever the test says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.defaults import SINGLE_AXIS_RATIO  # the hard floor on s / s_max
from calibration.eiv import check_noise, corrected_solution
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hinge import (
    biased_directions,
    block_of_frame,
    critical_t,
    hinge_verdict,
    precise_directions,
    score_t,
    score_variance,
    systematic_rms,
    testable_directions,
)
from calibration.pair_noise import THIRD_DIFFERENCE_GAIN

#: The fewest of a joint's 6 coordinates the motion must determine for its centre to be located:
#: a single-axis joint leaves one free (its centre a point of the axis); fewer is no joint located.
LOCATED_RANK = 5

#: Fewest frames a joint fit accepts (two frames give 6 equations for 6 unknowns).
MIN_FRAMES = 3


@dataclass(frozen=True)
class JointFit:
    """The rotary joint fitted between a parent and a child sensor.

    Attributes:
        joint_in_parent: ``(3,)`` joint centre in the parent sensor's frame, metres.
        joint_in_child: ``(3,)`` joint centre in the child sensor's frame, metres.
        rms_residual: root mean square over the used frames of the 3-D residual's norm
            (O'Brien eq. 13), metres.
        frame_residual: ``(frames,)`` residual norm per input frame, metres; NaN where a frame
            was dropped (non-finite pose). ``None`` when per-frame residuals were not kept.
        singular_values: ``(6,)`` singular values of ``A`` in descending order (dimensionless,
            they scale as ``sqrt(frames)``).
        rank: number of directions the motion determines (6 for a well exercised ball joint,
            5 for a single-axis joint, 3 when the sensors do not rotate relative to each other).
        single_axis: the relative motion is about one axis only (section 3.2).
        axis_in_parent: ``(3,)`` unit joint axis in the parent frame when ``single_axis``.
        axis_in_child: ``(3,)`` unit joint axis in the child frame when ``single_axis``.
        n_frames: frames used in the fit.
        n_dropped: frames dropped because a pose of either sensor was not finite or was marked
            invalid.
        weakest_t: ``|t|`` of the single-axis test of the weakest direction
            (:mod:`calibration.hinge`, dimensionless); NaN when it was not tested.
        orientation_noise_rad2: ``(sigma_p^2, sigma_c^2)`` the rotation-noise variances the
            centre was corrected for (:mod:`calibration.eiv`), rad^2; ``(0, 0)``: O'Brien's plain
            least squares.
    """

    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    rms_residual: float
    frame_residual: np.ndarray | None
    singular_values: np.ndarray
    rank: int
    single_axis: bool
    axis_in_parent: np.ndarray | None
    axis_in_child: np.ndarray | None
    n_frames: int
    n_dropped: int
    weakest_t: float = float("nan")
    orientation_noise_rad2: tuple[float, float] = (0.0, 0.0)

    @property
    def condition(self) -> float:
        """``s_max / s_min`` of ``A``; ``inf`` when a direction is exactly undetermined."""
        s_min = float(self.singular_values[-1])
        return float("inf") if s_min == 0.0 else float(self.singular_values[0]) / s_min

    @property
    def weak_ratio(self) -> float:
        """``s_min / s_max`` of ``A``: about half the rms rotation (rad) off the weakest axis."""
        s_max = float(self.singular_values[0])
        return 0.0 if s_max == 0.0 else float(self.singular_values[-1]) / s_max


@dataclass(frozen=True)
class Spectrum:
    """How a joint fit's singular spectrum is read (shared by the SVD and normal-equation paths).

    Attributes:
        keep: ``(6,)`` bool, the directions used in the solution.
        rank: number of kept directions.
        single_axis: exactly one direction is undetermined.
        axis_in_parent: ``(3,)`` unit axis in the parent frame, or ``None``.
        axis_in_child: ``(3,)`` unit axis in the child frame, or ``None``.
    """

    keep: np.ndarray
    rank: int
    single_axis: bool
    axis_in_parent: np.ndarray | None
    axis_in_child: np.ndarray | None


def determined_directions(singular_values: np.ndarray, single_axis_ratio: float) -> np.ndarray:
    """The hard floor of the single-axis rule (O'Brien 3.2): directions not below it.

    A direction passes the floor when its singular value is at least ``single_axis_ratio * s_max``
    (and not zero); the others are left out of the solution whatever the statistical test of
    :mod:`calibration.hinge` says (module docstring).

    Args:
        singular_values: ``(..., 6)`` singular values of ``A`` per fit, descending (``s_max``
            first); dimensionless.
        single_axis_ratio: the threshold on ``s / s_max``, in (0, 1).

    Returns:
        ``(..., 6)`` bool, True for the determined directions.
    """
    s = np.asarray(singular_values, dtype=float)
    return (s >= single_axis_ratio * s[..., :1]) & (s > 0.0)


def read_spectrum(
    singular_values: np.ndarray,
    right_vectors: np.ndarray,
    single_axis_ratio: float,
    keep: np.ndarray | None = None,
) -> Spectrum:
    """Read which directions a joint fit determines, and the joint axis if there is one.

    Args:
        singular_values: ``(6,)`` singular values of ``A``, descending.
        right_vectors: ``(6, 6)`` right singular vectors as columns, in the same order.
        single_axis_ratio: the hard floor (:func:`determined_directions`), used when ``keep``
            is not given.
        keep: ``(6,)`` bool, the determined directions as the test of :mod:`calibration.hinge`
            found them; ``None`` applies the floor alone.

    Returns:
        The kept directions, the rank and, for a single-axis joint, the axis in both frames
        (sign chosen so that the parent-frame axis has a positive largest component).
    """
    if keep is None:
        keep = determined_directions(singular_values, single_axis_ratio)
    keep = np.asarray(keep, dtype=bool)
    rank = int(np.count_nonzero(keep))
    single_axis = rank == 5
    axis_p = axis_c = None
    if single_axis:
        v = right_vectors[:, 5]
        axis_p = v[:3] / np.linalg.norm(v[:3])
        axis_c = v[3:] / np.linalg.norm(v[3:])
        if axis_p[np.argmax(np.abs(axis_p))] < 0.0:
            axis_p, axis_c = -axis_p, -axis_c
    return Spectrum(keep, rank, single_axis, axis_p, axis_c)


def check_pair(
    R_w_p: np.ndarray, p_w_p: np.ndarray, R_w_c: np.ndarray, p_w_c: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Check the shapes of one pair's pose arrays and return them as float arrays."""
    arrays = [np.asarray(a, dtype=float) for a in (R_w_p, p_w_p, R_w_c, p_w_c)]
    names = ("R_w_p", "p_w_p", "R_w_c", "p_w_c")
    n_frames = arrays[0].shape[0] if arrays[0].ndim else 0
    for name, a, tail in zip(names, arrays, ((3, 3), (3,), (3, 3), (3,)), strict=True):
        if a.ndim != 1 + len(tail) or a.shape[1:] != tail:
            raise CalibrationInputError(
                f"Expected {name} to have shape (frames, {', '.join(map(str, tail))}), got {a.shape}"
            )
        if a.shape[0] != n_frames:
            raise CalibrationInputError(
                f"Expected {name} to have {n_frames} frames like R_w_p, got {a.shape[0]}"
            )
    return arrays[0], arrays[1], arrays[2], arrays[3]


def joint_residual_vectors(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
) -> np.ndarray:
    """World-frame residual of the joint constraint (O'Brien eq. 8) at every frame.

    Args:
        R_w_p: ``(..., 3, 3)`` parent sensor rotations (sensor to world).
        R_w_c: ``(..., 3, 3)`` child sensor rotations (sensor to world).
        p_w_p: ``(..., 3)`` parent sensor positions in world, metres.
        p_w_c: ``(..., 3)`` child sensor positions in world, metres.
        joint_in_parent: ``(3,)`` joint centre in the parent sensor frame, metres.
        joint_in_child: ``(3,)`` joint centre in the child sensor frame, metres.

    Returns:
        ``(..., 3)`` ``(R_w_p l_p + p_w_p) - (R_w_c l_c + p_w_c)``, metres.
    """
    at_parent = np.einsum("...ij,j->...i", R_w_p, joint_in_parent) + p_w_p
    at_child = np.einsum("...ij,j->...i", R_w_c, joint_in_child) + p_w_c
    return at_parent - at_child


def finite_frames(R_w_p: np.ndarray, p_w_p: np.ndarray, R_w_c: np.ndarray, p_w_c: np.ndarray) -> np.ndarray:
    """``(frames,)`` bool: the frames where both poses (``(frames, 3, 3)`` rotations and
    ``(frames, 3)`` positions) are finite, the frames a joint fit can use."""
    return (
        np.isfinite(R_w_p).all(axis=(1, 2))
        & np.isfinite(R_w_c).all(axis=(1, 2))
        & np.isfinite(p_w_p).all(axis=1)
        & np.isfinite(p_w_c).all(axis=1)
    )


def fit_joint(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
    single_axis_ratio: float = SINGLE_AXIS_RATIO,
    orientation_noise_rad2: tuple[float, float] | None = None,
    effect_size: bool = True,
) -> JointFit:
    """Fit the rotary joint between two sensors by SVD of O'Brien eq. 13.

    This is the reference implementation (one SVD per pair, as in the paper); the all-pairs
    path in :mod:`calibration.pairs` gives the same answer from a few matrix products.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are dropped. Frames with any
            non-finite value in either pose are always dropped.
        single_axis_ratio: see the module docstring.
        orientation_noise_rad2: optional ``(sigma_p^2, sigma_c^2)``, each sensor's rotation noise
            per rotation-vector component, rad^2 (e.g. from
            :func:`calibration.eiv.orientation_noise_variance`): the centre is then corrected for
            the bias that noise on the rotations puts into least squares (:mod:`calibration.eiv`).
            The determined directions (the single-axis verdict) are those of the plain fit.
        effect_size: the single-axis verdict also rests on the bias bound along the weakest
            direction (:mod:`calibration.hinge`); False: on the test alone, for a fit that only
            models the residual (the slip detector's refits of short pieces, whose small motion
            the bound would judge, while the verdict is the whole recording's).

    Returns:
        The fitted joint, residuals and diagnostics.

    Raises:
        CalibrationInputError: on malformed arrays.
        CalibrationError: when fewer than :data:`MIN_FRAMES` usable frames remain, or the rotation
            noise swamps the motion along a determined direction.
    """
    noise = (0.0, 0.0) if orientation_noise_rad2 is None else check_noise(orientation_noise_rad2)
    R_w_p, p_w_p, R_w_c, p_w_c = check_pair(R_w_p, p_w_p, R_w_c, p_w_c)
    n_total = R_w_p.shape[0]
    ok = finite_frames(R_w_p, p_w_p, R_w_c, p_w_c)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != (n_total,):
            raise CalibrationInputError(f"Expected valid to have shape ({n_total},), got {valid.shape}")
        ok &= valid
    n_used = int(np.count_nonzero(ok))
    if n_used < MIN_FRAMES:
        raise CalibrationError(
            f"A joint fit needs at least {MIN_FRAMES} frames where both poses are valid, got {n_used}"
        )
    Rp, Rc = R_w_p[ok], R_w_c[ok]
    A = np.concatenate([Rp, -Rc], axis=2).reshape(3 * n_used, 6)  # O'Brien eq. 12-13
    b = (p_w_c[ok] - p_w_p[ok]).reshape(3 * n_used)  # O'Brien eq. 11
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    floor_keep = determined_directions(s, single_axis_ratio)
    frames = np.flatnonzero(ok) if effect_size else None
    keep, t = _tested_directions(A, b, U, s, Vt, floor_keep, block_of_frame(n_total)[ok], frames)
    spectrum = read_spectrum(s, Vt.T, single_axis_ratio, keep)
    x = _min_norm(U, s, Vt, b, keep)
    if max(noise) > 0.0:
        gram, rhs = (Vt.T * s**2) @ Vt, Vt.T @ (s * (U.T @ b))  # A^T A and A^T b from the SVD
        x = corrected_solution(gram, rhs, Vt[keep].T, n_used, noise)
    residual = np.full(n_total, np.nan)
    residual[ok] = np.linalg.norm((A @ x - b).reshape(n_used, 3), axis=1)
    return JointFit(
        joint_in_parent=x[:3].copy(),
        joint_in_child=x[3:].copy(),
        rms_residual=float(np.sqrt(np.mean(residual[ok] ** 2))),
        frame_residual=residual,
        singular_values=s,
        rank=spectrum.rank,
        single_axis=spectrum.single_axis,
        axis_in_parent=spectrum.axis_in_parent,
        axis_in_child=spectrum.axis_in_child,
        n_frames=n_used,
        n_dropped=n_total - n_used,
        weakest_t=float(t[5]),
        orientation_noise_rad2=noise,
    )


def _min_norm(U: np.ndarray, s: np.ndarray, Vt: np.ndarray, b: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``(6,)`` the least-squares solution over the kept directions, zero along the others."""
    return Vt[keep].T @ ((U[:, keep].T @ b) / s[keep])


def _tested_directions(
    A: np.ndarray,
    b: np.ndarray,
    U: np.ndarray,
    s: np.ndarray,
    Vt: np.ndarray,
    floor_keep: np.ndarray,
    block: np.ndarray,
    frame: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(6,)`` bool, the directions the data determine (:func:`calibration.hinge.hinge_verdict`),
    and ``(6,)`` the ``|t|`` of every direction's test.

    ``A`` is ``(3 n, 6)``, ``b`` ``(3 n,)``, ``block`` ``(n,)`` the block of each used frame and
    ``frame`` ``(n,)`` its index in the recording (third differences over four consecutive frames),
    ``None`` to leave the effect size out.
    """
    r = (A @ _min_norm(U, s, Vt, b, floor_keep) - b).reshape(-1, 3)  # the ball model's residual
    per_frame = np.einsum("fij,fi->fj", (A @ Vt.T).reshape(-1, 3, 6), r)  # (n, 6) scores
    n_blocks = int(block.max()) + 1 if block.size else 0
    scores = np.zeros((n_blocks, 6))
    np.add.at(scores, block, per_frame)
    counts = np.bincount(block, minlength=n_blocks)
    proj = s * (U.T @ b)  # v_j . A^T b
    var = score_variance(scores, counts)
    t_crit = critical_t(counts)
    rms = np.sqrt(np.mean(np.sum(r * r, axis=1)))
    precise = precise_directions(var, s * s, t_crit, rms)
    testable = testable_directions(s, block.size)
    t = score_t(proj, var)
    biased = None
    if frame is not None:
        separation = np.sqrt(np.mean(np.sum(b.reshape(-1, 3) ** 2, axis=1)))
        r_sys = systematic_rms(rms, residual_white_variance(r, frame), block.size)
        biased = biased_directions(r_sys, s, block.size, separation, proj)
    return hinge_verdict(floor_keep, t, t_crit, testable, precise, biased), t


def residual_white_variance(residual: np.ndarray, frame: np.ndarray) -> float:
    """The white-noise variance of a joint's ``(n, 3)`` residual vectors at frames ``frame``
    ``(n,)`` (increasing): the mean squared norm of their third differences over four
    consecutive frames over 20 (:mod:`calibration.pair_noise`); 0 with no such four frames."""
    if frame.size < 4:
        return 0.0
    run = frame[3:] - frame[:-3] == 3
    if not run.any():
        return 0.0
    d3 = residual[3:] - 3.0 * residual[2:-1] + 3.0 * residual[1:-2] - residual[:-3]
    return float(np.sum(d3[run] ** 2) / np.count_nonzero(run) / THIRD_DIFFERENCE_GAIN)
