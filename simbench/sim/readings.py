"""A session's true sensor readings: MuJoCo's sensors at the samples, then skin and joint laxity.

MuJoCo's sensors give, at every sample, each sensor's pose, specific force and angular velocity
at its bone placement and where it is worn (on its sprung mount, if any), and each segment's
pose. The kinematic skin models of :mod:`simbench.sim.skin` then move them: joint laxity moves
joint centres (and everything below them), soft-tissue artefact, slip and a pushed pack move the
worn sensors off their bone placement. Last, the magnetic field is the Earth's plus dipole disturbances at
each sensor's place.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.dataset import SensorData
from simbench.sim.models import CaptureModel, joint_sensor_indices
from simbench.sim.sensor_config import FieldConfig, SkinConfig
from simbench.sim.sensor_models import dipole_field, earth_field
from simbench.sim.skin import (
    girdle_offsets,
    laxity_offsets,
    pack_offsets,
    per_sensor,
    relative_rotvecs,
    second_derivative,
    slip_offsets,
    soft_tissue_offsets,
    subtree_masks,
)


@dataclass(frozen=True)
class SensorMotion:
    """Sensor frames over a session: poses, specific force, angular velocity.

    Attributes:
        p_w_s: ``(F, N, 3)`` sensor origins in world, m.
        q_w_s: ``(F, N, 4)`` quaternions of ``R_w_s``, wxyz.
        acc: ``(F, N, 3)`` specific force in the sensor frame, m/s^2.
        gyro: ``(F, N, 3)`` angular velocity in the sensor frame, rad/s.
    """

    p_w_s: np.ndarray
    q_w_s: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray


@dataclass(frozen=True)
class Readings:
    """The true readings of a session at its samples.

    Attributes:
        time_s: ``(F,)`` sample times, s (MuJoCo's clock).
        bone: the sensors rigid at their bone placements.
        worn: the sensors where they are worn (on the skin: mount, artefact, slip).
        p_w_b: ``(F, N, 3)`` segment (body) frame origins in world, m.
        q_w_b: ``(F, N, 4)`` segment orientations ``R_w_b``, wxyz.
    """

    time_s: np.ndarray
    bone: SensorMotion
    worn: SensorMotion
    p_w_b: np.ndarray
    q_w_b: np.ndarray


def readings_at_samples(cm: CaptureModel, sensordata: np.ndarray) -> Readings:
    """MuJoCo's sensor readings, out of ``(F, nsensordata)`` rows of ``mjData.sensordata``."""

    def take(kind: str, width: int) -> np.ndarray:
        cols = cm.adr[kind][:, None] + np.arange(width)[None, :]
        return sensordata[:, cols]

    return Readings(
        time_s=sensordata[:, cm.clock_adr],
        bone=SensorMotion(
            take("bone_pos", 3), take("bone_quat", 4), take("bone_acc", 3), take("bone_gyro", 3)
        ),
        worn=SensorMotion(take("site_pos", 3), take("site_quat", 4), take("acc", 3), take("gyro", 3)),
        p_w_b=take("body_pos", 3),
        q_w_b=take("body_quat", 4),
    )


def _laxity_shift_w(
    cm: CaptureModel, R_w_b: np.ndarray, phi: np.ndarray, skin: SkinConfig, rng: np.random.Generator
) -> np.ndarray:
    """``(F, N, 3)`` world shift of every segment from joint laxity and girdles, m.

    A joint centre moves in its parent's frame; the child's subtree moves with it.
    """
    parent, child = joint_sensor_indices(cm)
    laxity_m = per_sensor(skin.laxity_by_joint, cm.sensors, 0.0, "skin.laxity_by_joint")[child]
    laxity_in_parent = laxity_offsets(phi, laxity_m, rng)
    laxity_in_parent += girdle_offsets(R_w_b, cm.sensors, parent, child, skin.girdle)
    laxity_w = np.einsum("fjab,fjb->fja", R_w_b[:, parent], laxity_in_parent)
    below = subtree_masks(len(cm.sensors), parent, child).astype(float)
    return np.einsum("fja,js->fsa", laxity_w, below)


def _skin_offset_w(
    cm: CaptureModel,
    time_s: np.ndarray,
    R_w_b: np.ndarray,
    phi: np.ndarray,
    skin: SkinConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    """``(F, N, 3)`` world offset of every worn sensor from its bone placement: artefact, slip and a
    pushed pack, m."""
    parent, child = joint_sensor_indices(cm)
    sta_m = per_sensor(skin.sta_by_sensor, cm.sensors, skin.sta_amplitude_m, "skin.sta_by_sensor")
    offset_b = soft_tissue_offsets(phi, parent, child, sta_m, rng)
    offset_b += slip_offsets(time_s, cm.sensors, skin.slip)
    offset_b += pack_offsets(R_w_b, cm.sensors, skin.pack)
    return np.einsum("fsab,fsb->fsa", R_w_b, offset_b)


def _shifted(motion: SensorMotion, time_s: np.ndarray, *shifts_w: np.ndarray) -> SensorMotion:
    """Sensors moved by the sum of ``shifts_w`` (each ``(F, N, 3)``, m, world frame).

    The accelerometers feel the second time derivative of the total. The shifts are added one
    after another, in the order given (floating-point sums depend on it).
    """
    R_w_s = quat_to_matrix(motion.q_w_s)
    total_w = functools.reduce(np.add, shifts_w)
    return dataclasses.replace(
        motion,
        p_w_s=functools.reduce(np.add, shifts_w, motion.p_w_s),
        acc=motion.acc + np.einsum("fsji,fsj->fsi", R_w_s, second_derivative(total_w, time_s)),
    )


def wear(readings: Readings, cm: CaptureModel, skin: SkinConfig, rng: np.random.Generator) -> Readings:
    """The readings with joint laxity, soft-tissue artefact, slip and a pushed pack applied
    (:mod:`simbench.sim.skin`).

    Joint laxity moves the segments below a joint, their bone placements and worn sensors; the
    artefact, slip and pack move the worn sensors on their segments. Orientations do not change.

    Args:
        readings: MuJoCo's readings (:func:`readings_at_samples`).
        cm: the capture model.
        skin: the skin configuration.
        rng: the session's ``skin`` stream (laxity draws first, then the artefact).
    """
    time_s, q_w_b = readings.time_s, readings.q_w_b
    R_w_b = quat_to_matrix(q_w_b)
    phi = relative_rotvecs(q_w_b, *joint_sensor_indices(cm))
    shift_w = _laxity_shift_w(cm, R_w_b, phi, skin, rng)
    skin_w = _skin_offset_w(cm, time_s, R_w_b, phi, skin, rng)
    if not (np.any(shift_w) or np.any(skin_w)):
        return readings
    return dataclasses.replace(
        readings,
        bone=_shifted(readings.bone, time_s, shift_w),
        worn=_shifted(readings.worn, time_s, shift_w, skin_w),
        p_w_b=readings.p_w_b + shift_w,
    )


def field_in_sensor_frames(magnetic: FieldConfig, p_w_s: np.ndarray, R_w_s: np.ndarray) -> np.ndarray:
    """Magnetic field in the sensor frames ``(F, N, 3)``, uT.

    Args:
        magnetic: the Earth field and the dipole disturbances in the room.
        p_w_s: ``(F, N, 3)`` sensor positions in world, m.
        R_w_s: ``(F, N, 3, 3)`` sensor orientations.
    """
    b_w = np.broadcast_to(earth_field(magnetic.strength_ut, magnetic.inclination_deg), p_w_s.shape)
    for dist in magnetic.disturbance:
        b_w = b_w + dipole_field(p_w_s, np.asarray(dist.position), np.asarray(dist.moment_am2))
    return np.einsum("fsji,fsj->fsi", R_w_s, b_w)


def attached_field(
    magnetic: FieldConfig, time_s: np.ndarray, sensors: tuple[str, ...] | list[str]
) -> np.ndarray:
    """The field of the magnets riding on sensors (:class:`AttachedMagnet`), ``(F, N, 3)`` uT in
    each sensor's frame."""
    out = np.zeros((np.size(time_s), len(sensors), 3))
    index = {name: k for k, name in enumerate(sensors)}
    for magnet in magnetic.attached:
        if magnet.sensor not in index:
            raise InputError(
                f"magnetic.attached names {magnet.sensor!r}, which carries no sensor; "
                f"sensors: {list(sensors)}"
            )
        out[:, index[magnet.sensor]] += magnet.share(time_s)[:, None] * np.asarray(magnet.field_ut)
    return out


def true_sensor_data(
    motion: SensorMotion,
    valid: np.ndarray,
    magnetic: FieldConfig,
    time_s: np.ndarray | None = None,
    sensors: tuple[str, ...] | list[str] = (),
) -> SensorData:
    """The exact :class:`SensorData` of sensor frames, with the field at their places.

    Args:
        motion: the sensor frames.
        valid: ``(F, N)`` bool.
        magnetic: the field in the room, and the magnets riding on sensors.
        time_s: ``(F,)`` the samples' times, s, and ``sensors`` the sensors' names: where the
            magnets ride (needed when ``magnetic.attached`` names any).
    """
    mag = field_in_sensor_frames(magnetic, motion.p_w_s, quat_to_matrix(motion.q_w_s))
    if magnetic.attached:
        if time_s is None:
            raise InputError("attached magnets need the samples' times and the sensors' names")
        mag = mag + attached_field(magnetic, time_s, sensors)
    return SensorData(
        p_w_s=motion.p_w_s,
        q_w_s=motion.q_w_s,
        valid=valid,
        acc=motion.acc,
        gyro=motion.gyro,
        mag=mag,
    )
