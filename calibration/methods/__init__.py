"""The field's joint-centre methods behind one estimator interface.

Every method here finds the joint between a parent sensor ``p`` and a child sensor ``c``: its
centre in both sensor frames (``joint_in_parent``, ``joint_in_child``, metres, the project's
naming: ``R_w_p @ joint_in_parent + p_w_p == R_w_c @ joint_in_child + p_w_c``) and, for a hinge,
its axis in both frames. Each returns a :class:`JointEstimate`; each method's own result, with its
diagnostics, is in :attr:`JointEstimate.fit`.

**Modules**, one method each (pure numpy/scipy, like the rest of :mod:`calibration`):

- O'Brien et al. (2000), the least-squares joint fit with the single-axis test:
  :func:`calibration.joint.fit_joint`, wrapped by :func:`estimate_obrien`; and the same fit
  corrected for the rotations' noise (:mod:`calibration.eiv`), :func:`estimate_obrien_eiv`.
- :mod:`.score`: SCoRE (Ehrig et al. 2006), the same linear system with a hard rank floor only.
- :mod:`.sara`: SARA (Ehrig et al. 2007), a hinge's axis from the system's null space.
- :mod:`.sphere`: sphere fits of child points in the parent frame, Gamage and Lasenby's (2002)
  closed form (optionally bias-corrected) or geometric least squares.
- :mod:`.inertial`: Seel et al. (2012; 2014), joint position (and hinge axis) from gyroscopes and
  accelerometers alone, no poses.

**The common signature** of the pose-based estimators (every value of :data:`JOINT_METHODS`)::

    method(R_w_p, p_w_p, R_w_c, p_w_c, *, valid=None) -> JointEstimate

with ``R_w_p``, ``R_w_c`` ``(frames, 3, 3)`` sensor-to-world rotations, ``p_w_p``, ``p_w_c``
``(frames, 3)`` sensor positions in world (metres), ``valid`` an optional ``(frames,)`` bool of the
frames to use (unused frames may hold NaN). The inertial estimator takes other data (angular
velocity and specific force) and is not in the registry: :func:`estimate_inertial`.

**Errors.** Malformed input (shapes, frame counts, NaN in a used frame, too few frames, bad
options) raises :class:`calibration.errors.CalibrationInputError` naming what was expected and what
arrived; motion that cannot determine the joint (no relative rotation; a sphere fit of a hinge)
raises :class:`calibration.errors.CalibrationError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Protocol

import numpy as np

from calibration.defaults import JOINT_METHOD_NAMES
from calibration.eiv import orientation_noise_variance
from calibration.errors import CalibrationError, CalibrationInputError
from calibration.joint import LOCATED_RANK, JointFit, fit_joint
from calibration.methods.inertial import (
    InertialAxis,
    InertialFit,
    angular_acceleration,
    seel_joint_axis,
    seel_joint_position,
)
from calibration.methods.sara import SaraFit, sara
from calibration.methods.score import ScoreFit, check_pair, score
from calibration.methods.sphere import (
    VARIANTS,
    SphereFit,
    SphereJoint,
    fit_sphere,
    gamage_lasenby,
    geometric_sphere,
    points_in_parent,
    sphere_joint,
)


@dataclass(frozen=True)
class JointEstimate:
    """One joint as any method of this package estimates it.

    Attributes:
        method: the method's name (a key of :data:`JOINT_METHODS`, or ``"inertial"``).
        joint_in_parent: ``(3,)`` joint centre (a point on the axis for a hinge) in the parent
            sensor's frame, metres.
        joint_in_child: ``(3,)`` the same point in the child sensor's frame, metres.
        axis_in_parent: ``(3,)`` unit hinge axis in the parent frame, or ``None`` when the method
            found (or looked for) no single axis.
        axis_in_child: ``(3,)`` the same axis in the child frame (``R_w_p @ axis_in_parent ==
            R_w_c @ axis_in_child``), or ``None``.
        rms_residual: root mean square over the used frames of the joint constraint's residual
            norm (O'Brien eq. 8) at the estimate, metres; NaN for the inertial method, which has
            no poses (its residual, in m/s^2, is in ``fit``).
        n_frames: frames (samples) used.
        fit: the method's own result with its diagnostics (:class:`calibration.joint.JointFit`,
            :class:`ScoreFit`, :class:`SaraFit`, :class:`SphereJoint` or :class:`InertialFit`).
    """

    method: str
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    axis_in_parent: np.ndarray | None
    axis_in_child: np.ndarray | None
    rms_residual: float
    n_frames: int
    fit: JointFit | ScoreFit | SaraFit | SphereJoint | InertialFit

    def __post_init__(self) -> None:
        for name in ("joint_in_parent", "joint_in_child", "axis_in_parent", "axis_in_child"):
            value = getattr(self, name)
            if value is not None and np.shape(value) != (3,):
                raise CalibrationInputError(f"Expected {name} to have shape (3,), got {np.shape(value)}")
        if (self.axis_in_parent is None) != (self.axis_in_child is None):
            raise CalibrationInputError("Expected both axes or neither, got only one")


class PoseMethod(Protocol):
    """The common signature of the pose-based estimators (module docstring)."""

    def __call__(
        self,
        R_w_p: np.ndarray,
        p_w_p: np.ndarray,
        R_w_c: np.ndarray,
        p_w_c: np.ndarray,
        *,
        valid: np.ndarray | None = None,
    ) -> JointEstimate: ...


def estimate_obrien(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
) -> JointEstimate:
    """O'Brien et al. (2000): :func:`calibration.joint.fit_joint`, with its single-axis test.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre in both frames (the minimum-norm point on the axis for a hinge) and the axis
        when the fit finds a single-axis joint; ``fit`` is the :class:`calibration.joint.JointFit`.

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used frame, too few used frames.
        CalibrationError: the fit determines fewer than five directions (no relative rotation,
            or too little for the single-axis test to locate a centre).
    """
    pair = check_pair(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    fit = fit_joint(pair.R_w_p, pair.p_w_p, pair.R_w_c, pair.p_w_c, valid=pair.used)
    _check_rank(fit)
    return _obrien_estimate("obrien", fit)


def estimate_obrien_eiv(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
    orientation_noise_rad2: tuple[float, float] | None = None,
) -> JointEstimate:
    """O'Brien's fit corrected for the noise on the rotations (:mod:`calibration.eiv`).

    The same determined directions and single-axis verdict as :func:`estimate_obrien`; the centre
    solves ``(A^T A - 2 F D) x = A^T b`` (corrected least squares, Fuller 1987), which removes the
    errors-in-variables bias that rotation noise puts into the plain fit.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).
        orientation_noise_rad2: ``(sigma_p^2, sigma_c^2)`` per rotation-vector component, rad^2;
            ``None`` reads each from its sensor's own rotations
            (:func:`calibration.eiv.orientation_noise_variance`).

    Returns:
        As :func:`estimate_obrien`, method ``"obrien-eiv"``; ``fit.orientation_noise_rad2`` holds
        the variances used.

    Raises:
        CalibrationInputError: malformed arrays or variances, NaN in a used frame, too few frames.
        CalibrationError: as :func:`estimate_obrien`, or the noise swamps the motion along a
            determined direction, or too few consecutive frames to read the noise from.
    """
    pair = check_pair(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    if orientation_noise_rad2 is None:
        try:
            orientation_noise_rad2 = (
                orientation_noise_variance(pair.R_w_p, pair.used),
                orientation_noise_variance(pair.R_w_c, pair.used),
            )
        except CalibrationError:  # motion that cannot locate the joint is the first thing to say
            _check_rank(fit_joint(pair.R_w_p, pair.p_w_p, pair.R_w_c, pair.p_w_c, valid=pair.used))
            raise
    fit = fit_joint(
        pair.R_w_p,
        pair.p_w_p,
        pair.R_w_c,
        pair.p_w_c,
        valid=pair.used,
        orientation_noise_rad2=orientation_noise_rad2,
    )
    _check_rank(fit)  # the determined directions are the plain fit's
    return _obrien_estimate("obrien-eiv", fit)


def _check_rank(fit: JointFit) -> None:
    if fit.rank < LOCATED_RANK:
        raise CalibrationError(
            f"O'Brien's fit needs the child to rotate relative to the parent: the motion determines "
            f"{fit.rank} of the 6 coordinates of the joint (needs {LOCATED_RANK})"
        )


def _obrien_estimate(method: str, fit: JointFit) -> JointEstimate:
    return JointEstimate(
        method=method,
        joint_in_parent=fit.joint_in_parent,
        joint_in_child=fit.joint_in_child,
        axis_in_parent=fit.axis_in_parent,
        axis_in_child=fit.axis_in_child,
        rms_residual=fit.rms_residual,
        n_frames=fit.n_frames,
        fit=fit,
    )


def estimate_score(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
) -> JointEstimate:
    """SCoRE (Ehrig et al. 2006): :func:`calibration.methods.score.score`.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The centre in both frames; no axis (SCoRE assumes a ball joint); ``fit`` is the
        :class:`ScoreFit` (its ``rank`` is 5 when the motion was about one axis).

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used frame, too few used frames.
        CalibrationError: no relative rotation.
    """
    fit = score(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    return JointEstimate(
        "score", fit.joint_in_parent, fit.joint_in_child, None, None, fit.rms_residual, fit.n_frames, fit
    )


def estimate_sara(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
) -> JointEstimate:
    """SARA (Ehrig et al. 2007): :func:`calibration.methods.sara.sara`.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).

    Returns:
        The minimum-norm point on the axis in both frames and the unit axis in both frames;
        ``fit`` is the :class:`SaraFit` (its ``axis_ratio`` says how hinge-like the motion was).

    Raises:
        CalibrationInputError: malformed arrays, NaN in a used frame, too few used frames.
        CalibrationError: no relative rotation.
    """
    fit = sara(R_w_p, p_w_p, R_w_c, p_w_c, valid=valid)
    return JointEstimate(
        "sara",
        fit.point_in_parent,
        fit.point_in_child,
        fit.axis_in_parent,
        fit.axis_in_child,
        fit.rms_residual,
        fit.n_frames,
        fit,
    )


def estimate_sphere(
    R_w_p: np.ndarray,
    p_w_p: np.ndarray,
    R_w_c: np.ndarray,
    p_w_c: np.ndarray,
    *,
    valid: np.ndarray | None = None,
    variant: str = "gamage-lasenby",
    bias_correction: bool = False,
    noise_std_m: float | None = None,
) -> JointEstimate:
    """Sphere fit of the child sensor's origin in the parent's frame (:mod:`.sphere`).

    The child's origin ``p_w_c`` is carried into the parent frame and fitted with a sphere; the
    centre is carried into the child frame by least squares over the frames
    (:func:`calibration.methods.sphere.centre_in_child`). For markers instead of the sensor origin
    use :func:`calibration.methods.sphere.sphere_joint`.

    Args:
        R_w_p: ``(frames, 3, 3)`` parent sensor rotations, sensor to world.
        p_w_p: ``(frames, 3)`` parent sensor positions in world, metres.
        R_w_c: ``(frames, 3, 3)`` child sensor rotations, sensor to world.
        p_w_c: ``(frames, 3)`` child sensor positions in world, metres.
        valid: optional ``(frames,)`` bool; frames marked False are not used (and may hold NaN).
        variant: ``"gamage-lasenby"`` (closed form) or ``"geometric"`` (:data:`VARIANTS`).
        bias_correction: Gamage and Lasenby's fit only: correct its noise bias.
        noise_std_m: with ``bias_correction``: the noise per axis of the child's origin in the
            parent frame, metres; ``None`` estimates it.

    Returns:
        The centre in both frames, no axis; ``fit`` is the :class:`SphereJoint`.

    Raises:
        CalibrationInputError: malformed arrays or options, NaN in a used frame, too few frames.
        CalibrationError: no relative rotation, or a rotation about one axis (use SARA).
    """
    fit = sphere_joint(
        R_w_p,
        p_w_p,
        p_w_c,
        R_w_c=R_w_c,
        p_w_c=p_w_c,
        variant=variant,
        bias_correction=bias_correction,
        noise_std_m=noise_std_m,
        valid=valid,
    )
    assert fit.joint_in_child is not None  # the child's pose was given
    return JointEstimate(
        f"sphere-{variant}",
        fit.joint_in_parent,
        fit.joint_in_child,
        None,
        None,
        fit.rms_residual,
        fit.sphere.n_frames,
        fit,
    )


def estimate_inertial(
    w_p: np.ndarray,
    w_c: np.ndarray,
    f_p: np.ndarray,
    f_c: np.ndarray,
    *,
    rate_hz: float | None = None,
    dw_p: np.ndarray | None = None,
    dw_c: np.ndarray | None = None,
    hinge: bool = False,
    hinge_axes: tuple[np.ndarray, np.ndarray] | None = None,
    valid: np.ndarray | None = None,
) -> JointEstimate:
    """Seel et al. (2012; 2014): the joint from gyroscopes and accelerometers, no poses.

    Args:
        w_p: ``(frames, 3)`` parent sensor angular velocity in its own frame, rad/s.
        w_c: ``(frames, 3)`` child sensor angular velocity in its own frame, rad/s.
        f_p: ``(frames, 3)`` parent sensor specific force in its own frame (+9.81 m/s^2 along up
            at rest), m/s^2.
        f_c: ``(frames, 3)`` child sensor specific force in its own frame, m/s^2.
        rate_hz: sample rate, Hz; needed when ``dw_p``/``dw_c`` are not given.
        dw_p: optional ``(frames, 3)`` parent angular acceleration, rad/s^2 (with ``dw_c``).
        dw_c: optional ``(frames, 3)`` child angular acceleration, rad/s^2.
        hinge: the joint is a hinge: estimate its axis from the gyroscopes
            (:func:`calibration.methods.inertial.seel_joint_axis`) unless ``hinge_axes`` is given,
            and shift the centre along it to the point closest to both sensors.
        hinge_axes: optional known ``(axis_in_parent, axis_in_child)``, each ``(3,)``; implies
            ``hinge``.
        valid: optional ``(frames,)`` bool; samples marked False are not used (and may hold NaN).

    Returns:
        The centre in both frames (from each sensor to the joint), the axis for a hinge;
        ``rms_residual`` is NaN (no poses); ``fit`` is the :class:`InertialFit`.

    Raises:
        CalibrationInputError: malformed arrays or options, NaN in a used sample, too few samples.
        CalibrationError: no rotation, or no relative rotation.
    """
    if hinge and hinge_axes is None:
        axis = seel_joint_axis(w_p, w_c, valid=valid)
        hinge_axes = (axis.axis_in_parent, axis.axis_in_child)
    fit = seel_joint_position(
        w_p, w_c, f_p, f_c, rate_hz=rate_hz, dw_p=dw_p, dw_c=dw_c, hinge_axes=hinge_axes, valid=valid
    )
    return JointEstimate(
        "inertial",
        fit.joint_in_parent,
        fit.joint_in_child,
        fit.axis_in_parent,
        fit.axis_in_child,
        float("nan"),
        fit.n_frames,
        fit,
    )


#: The pose-based estimators by name, all with the common signature (module docstring).
#: Their names are :data:`calibration.defaults.JOINT_METHOD_NAMES` (read without numpy).
JOINT_METHODS: dict[str, PoseMethod] = dict(
    zip(
        JOINT_METHOD_NAMES,
        (
            estimate_obrien,
            estimate_obrien_eiv,
            estimate_score,
            estimate_sara,
            partial(estimate_sphere, variant="gamage-lasenby"),
            partial(estimate_sphere, variant="geometric"),
        ),
        strict=True,
    )
)

__all__ = [
    "JOINT_METHODS",
    "VARIANTS",
    "InertialAxis",
    "InertialFit",
    "JointEstimate",
    "PoseMethod",
    "SaraFit",
    "ScoreFit",
    "SphereFit",
    "SphereJoint",
    "angular_acceleration",
    "estimate_inertial",
    "estimate_obrien",
    "estimate_obrien_eiv",
    "estimate_sara",
    "estimate_score",
    "estimate_sphere",
    "fit_sphere",
    "gamage_lasenby",
    "geometric_sphere",
    "points_in_parent",
    "sara",
    "score",
    "seel_joint_axis",
    "seel_joint_position",
    "sphere_joint",
]
