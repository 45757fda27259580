"""Rigid-body pose trajectories as a recorded motion: each recorded segment (or the one sensor)
follows its recorded poses.

Sources: a pose CSV, a C3D file of marker clusters (a cluster spec, or clusters found
automatically: :func:`simbench.io.read.read_poses`), a wide tracker export, and a BROAD trial's
optical pose of the IMU housing (``opt_pos`` m, ``opt_quat`` wxyz, ENU: :func:`read_broad_poses`).

The model (:func:`poses_mjcf`, built with dm_control's PyMJCF) has one body per recorded segment,
named after it, at the top of the tree with a free joint of the same name, a small box for its
mass (:data:`BOX_HALF_M`, :data:`DENSITY_KG_M3`; the geoms do not collide) and a sensor site
``sensor_<segment>`` at the body's origin, unturned: the simulated sensor's frame is the recorded
one. The segments are not joined: their poses are the recording's, whatever their joints.

Frames where a segment has no pose (an occluded marker) are filled for the smoothing
(:func:`simbench.io.recorded.fill_gaps`); a frame is ``valid`` in the motion when every segment
has its pose there.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.errors import InputError
from simbench.io.imu import read_broad_pose
from simbench.io.poses import PoseRecording
from simbench.io.recorded import RecordedMotion, Track, fill_gaps, frame_grid

#: The model name of a pose trajectory's own bodies (``SessionConfig.model`` with a pose motion).
POSES_MODEL = "poses"

#: Each body's box: half-size, m, and density, kg/m^3 (a sensor housing of about 200 g).
BOX_HALF_M = 0.03
DENSITY_KG_M3 = 1000.0

#: The sensor name of a BROAD trial's one IMU.
BROAD_SENSOR = "imu"


def read_broad_poses(path: str | os.PathLike[str]) -> PoseRecording:
    """A BROAD trial's optical pose of its IMU (:func:`simbench.io.imu.read_broad_pose`) as a pose
    recording of one sensor, :data:`BROAD_SENSOR` (rows with a NaN or a zero quaternion are missing
    poses).

    Raises:
        InputError: what the reader refuses; a file without any optical pose.
    """
    pose = read_broad_pose(path)
    p, q = pose.p_w, pose.q_w
    norm = np.linalg.norm(q, axis=1)
    valid = np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1) & (norm > 0.5)
    if not valid.any():
        raise InputError(
            f"{path}: no frame holds an optical pose (every opt_pos/opt_quat row is NaN or zero)"
        )
    qn = np.where(valid[:, None], q / np.where(norm > 0, norm, 1)[:, None], [1.0, 0, 0, 0])
    R = quat_to_matrix(qn)
    R[~valid] = np.nan
    notes = () if valid.all() else (f"{int((~valid).sum())} of {valid.size} frames without an optical pose",)
    return PoseRecording(
        names=(BROAD_SENSOR,),
        time_s=pose.time_s,
        R_w_s=R[:, None],
        p_w_s=np.where(valid[:, None], p, np.nan)[:, None],
        valid=valid[:, None],
        source=str(path),
        notes=notes,
    )


def poses_recorded(rec: PoseRecording) -> RecordedMotion:
    """The recording as the free joints of its own bodies (module docstring), positions in metres.

    Raises:
        InputError: time stamps off a constant rate, a segment without any pose.
    """
    rec = rec.in_unit("m")
    period, frame = frame_grid(rec.time_s, rec.source, first_line=-1)
    n = int(frame[-1]) + 1
    tracks = []
    for k, name in enumerate(rec.names):
        valid = np.zeros(n, dtype=bool)
        valid[frame] = rec.valid[:, k]
        if not valid.any():
            raise InputError(f"{rec.source}: segment {name!r} has no pose in any frame")
        values = np.zeros((n, 7))
        ok = rec.valid[:, k]
        values[frame[ok], :3] = rec.p_w_s[ok, k]
        values[frame[ok], 3:] = matrix_to_quat(rec.R_w_s[ok, k])
        tracks.append((name, values, valid))
    every = np.logical_and.reduce([v for _, _, v in tracks])
    return RecordedMotion(
        source=rec.source,
        frame_time_s=period,
        tracks=tuple(Track(name, "free", fill_gaps(v, ok, slice(3, 7))) for name, v, ok in tracks),
        valid=every,
        start_s=float(rec.time_s[0]),
        format="poses",
        notes=rec.notes,
    )


def poses_mjcf(names: tuple[str, ...], source: str) -> str:
    """The bodies of a pose trajectory (module docstring) as MJCF text.

    Raises:
        InputError: a segment name MJCF refuses.
    """
    from dm_control import mjcf  # optional heavy dependency: only recorded motions need it

    root = mjcf.RootElement(model=Path(source).stem or POSES_MODEL)
    try:
        for name in names:
            body = root.worldbody.add("body", name=name)
            body.add("freejoint", name=name)
            body.add(
                "geom", type="box", size=[BOX_HALF_M] * 3, density=DENSITY_KG_M3, contype=0, conaffinity=0
            )
            body.add("site", name=f"sensor_{name}", pos=[0.0, 0.0, 0.0])
    except (ValueError, TypeError) as exc:  # PyMJCF refuses names with '/' and the like
        raise InputError(f"{source}: cannot make an MJCF body of each segment: {exc}") from None
    return root.to_xml_string()


def poses_spec(names: tuple[str, ...], source: str) -> mujoco.MjSpec:
    """The bodies as an editable :class:`mujoco.MjSpec` (for
    :func:`simbench.sim.models.load_capture_model`)."""
    try:
        return mujoco.MjSpec.from_string(poses_mjcf(names, source))
    except Exception as exc:  # mujoco raises ValueError with the parser's message
        raise InputError(f"{source}: MuJoCo could not read its bodies: {exc}") from None
