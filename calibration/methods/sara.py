"""SARA, the Symmetrical Axis of Rotation Approach, for hinge (single-axis) joints.

Reference: R. M. Ehrig, W. R. Taylor, G. N. Duda, M. O. Heller, "A survey of formal methods for
determining functional joint axes", Journal of Biomechanics 40 (2007) 2150-2157.

A hinge has no single centre: every point on its axis is fixed in both segments. In SCoRE's
stacked system (:mod:`calibration.methods.score`, ``A[f] = [R_w_p[f], -R_w_c[f]]``,
``b[f] = p_w_c[f] - p_w_p[f]``) the axis shows as the null space of ``A``: with ``a_p`` and
``a_c`` the axis in the parent and child frames, ``R_w_p a_p = R_w_c a_c`` at every frame, so
``A [a_p; a_c] = 0``. SARA takes the axis from the right singular vector of ``A``'s smallest
singular value (each half normalised to a unit vector) and a point on the axis from the
least-squares solution restricted to the other five directions: the minimum-norm point, closest
to the origins of both sensor frames together, as O'Brien et al. (2000, section 3.2) choose.

**Sign.** The null vector's sign is arbitrary; it is fixed so that the parent-frame axis has a
positive largest component (the rule of :func:`calibration.joint.read_spectrum`), and the child
axis takes the same sign, so ``R_w_p a_p = R_w_c a_c`` holds.

SARA always returns an axis; :attr:`SaraFit.axis_ratio` (``s_6 / s_5``) says how well the data
single it out: near 0 for a hinge, near 1 for a ball joint turned in every direction (then the
"axis" is arbitrary).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.methods.score import check_pair, frame_residuals, require_rotation, rms, stacked_system


@dataclass(frozen=True)
class SaraFit:
    """The hinge axis SARA found between a parent and a child sensor.

    Attributes:
        axis_in_parent: ``(3,)`` unit axis direction in the parent sensor's frame.
        axis_in_child: ``(3,)`` unit axis direction in the child sensor's frame (same sign:
            ``R_w_p @ axis_in_parent == R_w_c @ axis_in_child``).
        point_in_parent: ``(3,)`` point on the axis in the parent frame, metres (minimum norm).
        point_in_child: ``(3,)`` the same point in the child frame, metres.
        rms_residual: root mean square over the used frames of the residual's norm at the
            point, metres.
        frame_residual: ``(frames,)`` residual norm per input frame, metres; NaN where unused.
        singular_values: ``(6,)`` singular values of ``A``, descending (dimensionless).
        axis_ratio: ``s_6 / s_5``: near 0 for a hinge, near 1 when the motion has no single axis.
        n_frames: frames used.
    """

    axis_in_parent: np.ndarray
    axis_in_child: np.ndarray
    point_in_parent: np.ndarray
    point_in_child: np.ndarray
    rms_residual: float
    frame_residual: np.ndarray
    singular_values: np.ndarray
    axis_ratio: float
    n_frames: int


def sara(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
) -> SaraFit:
    """SARA (Ehrig et al. 2007): a hinge's axis in both sensor frames and a point on it.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The axis (unit vectors, sign fixed as the module docstring says), the minimum-norm point
        on it in both frames, residuals and the singular values.

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used frame, too few used frames.
        CalibrationError: the child does not rotate relative to the parent (fewer than five
            directions determined, so no single axis).
    """
    pair = check_pair(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    A, b = stacked_system(pair)
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    require_rotation(s, "SARA")
    v = Vt[5]  # the null direction [a_p; a_c] (Ehrig et al. 2007)
    axis_p = v[:3] / np.linalg.norm(v[:3])
    axis_c = v[3:] / np.linalg.norm(v[3:])
    if axis_p[np.argmax(np.abs(axis_p))] < 0.0:
        axis_p, axis_c = -axis_p, -axis_c
    x = Vt[:5].T @ ((U[:, :5].T @ b) / s[:5])  # minimum norm: no component along the null direction
    residual = frame_residuals(pair, x[:3], x[3:])
    return SaraFit(
        axis_in_parent=axis_p,
        axis_in_child=axis_c,
        point_in_parent=x[:3].copy(),
        point_in_child=x[3:].copy(),
        rms_residual=rms(residual),
        frame_residual=residual,
        singular_values=s,
        axis_ratio=float(s[5] / s[4]),
        n_frames=pair.n_frames,
    )
