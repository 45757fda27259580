"""Pictures of a simulated session drawn by MuJoCo's offscreen renderer.

Rendering needs an OpenGL context: ``simbench`` sets ``MUJOCO_GL=egl`` when there is no display
and the caller chose no backend. When no context can be made, :func:`render_joint_centres`
writes nothing and returns ``False`` (the report says the pictures are missing).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np

from calibration.pipeline import Joint
from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.io.dataset import Dataset
from simbench.report.plots import plot_pictures
from simbench.sim.models import CaptureModel

#: Picture size, pixels.
HEIGHT, WIDTH = 360, 480
#: Colours (RGBA) and radius (m) of the joint-centre marks.
TRUE_RGBA = (0.1, 0.8, 0.1, 1.0)
ESTIMATED_RGBA = (0.9, 0.1, 0.1, 1.0)
MARK_RADIUS_M = 0.022


def qpos_from_truth(cm: CaptureModel, ds: Dataset, frame: int) -> np.ndarray:
    """The model's joint positions that reproduce the dataset's true segment poses at a frame.

    Sets the root's free joint from the truth's ``p_w_b``/``q_w_b`` and every ball joint from
    the relative rotation ``R_p_c = R_w_p.T @ R_w_c`` of its parent and child segments (hinge
    joints keep ``qpos0``).

    Returns:
        ``(nq,)`` joint positions of ``cm.model``.
    """
    model = cm.model
    qpos = model.qpos0.copy()
    R_w_b = quat_to_matrix(np.asarray(ds.truth.q_w_b[frame]))
    index = {name: k for k, name in enumerate(ds.sensors)}
    root = cm.body_ids[0]
    for j in range(model.njnt):
        if model.jnt_bodyid[j] == root and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            adr = model.jnt_qposadr[j]
            qpos[adr : adr + 3] = ds.truth.p_w_b[frame, 0]
            qpos[adr + 3 : adr + 7] = ds.truth.q_w_b[frame, 0]
    for art in cm.articulations:
        if art.kinds != ("ball",):
            continue
        child = index[art.sensor]
        parent = index[cm.parent_of[art.sensor]]
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, art.joints[0])
        adr = model.jnt_qposadr[j]
        qpos[adr : adr + 4] = matrix_to_quat(R_w_b[parent].T @ R_w_b[child])
    return qpos


def joint_marks(
    ds: Dataset, joints: Sequence[Joint], scale: float, R_w_s: np.ndarray, frame: int
) -> list[tuple[np.ndarray, tuple[float, ...]]]:
    """Where to draw the true and the estimated joint centres at a frame.

    Args:
        ds: the dataset (truth ``joint_w`` in metres; measured ``p_w_s`` in its input units).
        joints: the estimated joints (``joint_in_parent`` in the input units).
        scale: metres per input unit.
        R_w_s: ``(frames, sensors, 3, 3)`` measured rotations, sensor to world.
        frame: the frame.

    Returns:
        ``(position in world (m), RGBA)`` of each mark: the true joints first, then the
        estimated ones whose position is finite.
    """
    index = {name: k for k, name in enumerate(ds.sensors)}
    marks = [(ds.truth.joint_w[frame, k], TRUE_RGBA) for k in range(len(ds.truth.child))]
    for joint in joints:
        parent = index[joint.parent]
        p_w_joint = scale * (
            R_w_s[frame, parent] @ joint.fit.joint_in_parent + ds.measured.p_w_s[frame, parent]
        )
        if np.all(np.isfinite(p_w_joint)):
            marks.append((p_w_joint, ESTIMATED_RGBA))
    return marks


def _add_spheres(scene: mujoco.MjvScene, marks: Sequence[tuple[np.ndarray, tuple[float, ...]]]) -> None:
    """Add a sphere to the scene per mark, as many as the scene has room for."""
    for pos, rgba in marks:
        if scene.ngeom >= scene.maxgeom:
            break
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=np.array([MARK_RADIUS_M, 0.0, 0.0]),
            pos=np.asarray(pos, dtype=float),
            mat=np.eye(3).ravel(),
            rgba=np.asarray(rgba, dtype=np.float32),
        )
        scene.ngeom += 1


def _camera(ds: Dataset, frame: int) -> mujoco.MjvCamera:
    """A camera looking at the root segment from the front side, farther for larger models."""
    cam = mujoco.MjvCamera()
    cam.lookat[:] = ds.truth.p_w_b[frame, 0]
    cam.distance = 2.0 if len(ds.sensors) < 10 else 2.8
    cam.azimuth, cam.elevation = 120.0, -15.0
    return cam


def render_joint_centres(
    cm: CaptureModel, ds: Dataset, joints: Sequence[Joint], scale: float, frames: Sequence[int], path: Path
) -> bool:
    """Pictures of the model in a few poses, true joint centres green, estimated red.

    The model's geoms are made see-through (alpha at most 0.35) so that the marks show; this
    changes ``cm.model``.

    Args:
        cm: the model the dataset was simulated with.
        ds: the simulated dataset (needs its truth).
        joints: the estimated joints, in the dataset's input units.
        scale: metres per input unit.
        frames: the frames to draw, one picture each.
        path: the PNG to write.

    Returns:
        False (and writes nothing) when no offscreen GL context can be made.
    """
    model = cm.model
    model.geom_rgba[:, 3] = np.minimum(model.geom_rgba[:, 3], 0.35)
    try:
        renderer = mujoco.Renderer(model, HEIGHT, WIDTH)
    except Exception:  # no GL context on this machine (the error type depends on the backend)
        return False
    data = mujoco.MjData(model)
    q_w_s = np.where(ds.measured.valid[..., None], ds.measured.q_w_s, [1.0, 0, 0, 0])
    R_w_s = quat_to_matrix(q_w_s)
    images = []
    for frame in frames:
        data.qpos[:] = qpos_from_truth(cm, ds, frame)
        mujoco.mj_kinematics(model, data)
        renderer.update_scene(data, _camera(ds, frame))
        _add_spheres(renderer.scene, joint_marks(ds, joints, scale, R_w_s, frame))
        images.append(renderer.render().copy())
    renderer.close()
    titles = [f"t = {ds.time_s[f]:.1f} s (green: true, red: estimated)" for f in frames]
    plot_pictures(images, titles, path)
    return True
