"""Pictures of a simulated session drawn by MuJoCo's offscreen renderer.

Rendering needs an OpenGL context: ``simbench`` sets ``MUJOCO_GL=egl`` when there is no display
and the caller chose no backend. When no context can be made, :func:`render_joint_centres`
writes nothing and returns ``False`` (the report says the pictures are missing).

The pictures are lit for print: a bright headlight, a plain light floor, a white background,
the model in translucent grey, and the joint centres in the reports' colour-blind-safe colours
(:data:`simbench.report.plots.TRUTH_COLOUR`, :data:`~simbench.report.plots.ESTIMATE_COLOUR`),
told apart by shape too: the truth a sphere, the estimate a cube. A legend below says which is
which.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from matplotlib.colors import to_rgb

from calibration.pipeline import Joint
from calibration.rotations import matrix_to_quat, quat_to_matrix
from simbench.io.dataset import Dataset
from simbench.report.plots import ESTIMATE_COLOUR, TRUTH_COLOUR, LegendMark, plot_pictures
from simbench.sim.models import CaptureModel

#: Picture size, pixels.
HEIGHT, WIDTH = 360, 480
#: A mark's radius as a share of the model's span (the largest distance between two of its
#: sensor bodies in the model's reference pose): 3.8 cm on the 0.94 m linkage.
MARK_SHARE_OF_SPAN = 0.04
#: The camera's distance as a multiple of the model's span (1.7 m from the linkage).
CAMERA_DISTANCE_PER_SPAN = 1.8
#: The pale blue behind the scene (above the horizon, 0-255 RGB), the floor's light grey and
#: the model's translucent grey (RGBA, 0-1).
BACKGROUND_RGB = (232, 238, 244)
FLOOR_RGBA = (0.95, 0.95, 0.93, 1.0)
MODEL_RGBA = (0.3, 0.3, 0.3, 0.55)


@dataclass(frozen=True)
class MarkStyle:
    """How one kind of joint-centre mark is drawn.

    Attributes:
        label: its legend text.
        colour: its colour (``#rrggbb``, from :data:`simbench.report.plots.PALETTE`).
        geom: the MuJoCo geom drawn (``mjGEOM_SPHERE``, ``mjGEOM_BOX``).
        marker: the matplotlib marker of the same shape, for the legend.
        size: the geom's radius or half side as a share of the mark radius.
    """

    label: str
    colour: str
    geom: int
    marker: str
    size: float

    @property
    def rgba(self) -> np.ndarray:
        """``(4,)`` float32 RGBA, opaque."""
        return np.array([*to_rgb(self.colour), 1.0], dtype=np.float32)

    def legend(self) -> LegendMark:
        """The legend entry of the mark."""
        return LegendMark(self.label, self.colour, self.marker)


#: The true joint centres: spheres; the estimated ones: smaller cubes, so that where the two
#: coincide the cube's corners show through the sphere.
TRUE_MARK = MarkStyle("true joint centre (sphere)", TRUTH_COLOUR, int(mujoco.mjtGeom.mjGEOM_SPHERE), "o", 1.0)
ESTIMATED_MARK = MarkStyle(
    "estimated joint centre (cube)", ESTIMATE_COLOUR, int(mujoco.mjtGeom.mjGEOM_BOX), "s", 0.75
)


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
) -> list[tuple[np.ndarray, MarkStyle]]:
    """Where to draw the true and the estimated joint centres at a frame.

    Args:
        ds: the dataset (truth ``joint_w`` in metres; measured ``p_w_s`` in its input units).
        joints: the estimated joints (``joint_in_parent`` in the input units).
        scale: metres per input unit.
        R_w_s: ``(frames, sensors, 3, 3)`` measured rotations, sensor to world.
        frame: the frame.

    Returns:
        ``(position in world (m), style)`` of each mark: the true joints first
        (:data:`TRUE_MARK`), then the estimated ones whose position is finite
        (:data:`ESTIMATED_MARK`).
    """
    index = {name: k for k, name in enumerate(ds.sensors)}
    marks = [(ds.truth.joint_w[frame, k], TRUE_MARK) for k in range(len(ds.truth.child))]
    for joint in joints:
        parent = index[joint.parent]
        p_w_joint = scale * (
            R_w_s[frame, parent] @ joint.fit.joint_in_parent + ds.measured.p_w_s[frame, parent]
        )
        if np.all(np.isfinite(p_w_joint)):
            marks.append((p_w_joint, ESTIMATED_MARK))
    return marks


def model_span_m(cm: CaptureModel) -> float:
    """The largest distance between two sensor bodies in the model's reference pose, m."""
    data = mujoco.MjData(cm.model)
    mujoco.mj_kinematics(cm.model, data)
    p_w_b = data.xpos[cm.body_ids]
    return float(np.max(np.linalg.norm(p_w_b[:, None] - p_w_b[None], axis=-1), initial=0.0))


def light_scene(cm: CaptureModel) -> None:
    """Light the model for a picture, in place: a bright headlight, the world's geoms (floor)
    plain light grey, the bodies' geoms translucent grey so that the marks inside them show."""
    model = cm.model
    model.vis.headlight.ambient[:] = 0.7
    model.vis.headlight.diffuse[:] = 0.4
    model.vis.headlight.specular[:] = 0.1
    world = model.geom_bodyid == 0
    model.geom_matid[world] = -1
    model.geom_rgba[world] = FLOOR_RGBA
    model.geom_rgba[~world] = MODEL_RGBA


def _add_marks(
    scene: mujoco.MjvScene, marks: Sequence[tuple[np.ndarray, MarkStyle]], radius_m: float
) -> None:
    """Add a geom to the scene per mark, as many as the scene has room for."""
    for pos, style in marks:
        if scene.ngeom >= scene.maxgeom:
            break
        mujoco.mjv_initGeom(
            scene.geoms[scene.ngeom],
            type=style.geom,
            size=np.full(3, style.size * radius_m),
            pos=np.asarray(pos, dtype=float),
            mat=np.eye(3).ravel(),
            rgba=style.rgba,
        )
        geom = scene.geoms[scene.ngeom]  # mjv_initGeom leaves these three as the buffer held them
        geom.objtype, geom.objid, geom.segid = int(mujoco.mjtObj.mjOBJ_UNKNOWN), -1, scene.ngeom
        scene.ngeom += 1


def _camera(ds: Dataset, frame: int, span_m: float) -> mujoco.MjvCamera:
    """A camera looking at the root segment from the front side, farther for larger models."""
    cam = mujoco.MjvCamera()
    cam.lookat[:] = ds.truth.p_w_b[frame, 0]
    cam.distance = CAMERA_DISTANCE_PER_SPAN * span_m
    cam.azimuth, cam.elevation = 120.0, -12.0
    return cam


def _render(renderer: mujoco.Renderer) -> np.ndarray:
    """The scene as ``(height, width, 3)`` uint8 RGB with :data:`BACKGROUND_RGB` where no geom
    is (the renderer's segmentation marks those pixels ``-1``)."""
    image = renderer.render().copy()
    renderer.enable_segmentation_rendering()
    empty = renderer.render()[..., 1] < 0  # (object id, object type): a mark's type is 0
    renderer.disable_segmentation_rendering()
    image[empty] = BACKGROUND_RGB
    return image


def render_pictures(
    cm: CaptureModel, ds: Dataset, joints: Sequence[Joint], scale: float, frames: Sequence[int]
) -> list[np.ndarray] | None:
    """Pictures of the model in a few poses with its true and estimated joint centres.

    Lights the scene with :func:`light_scene`, which changes ``cm.model``.

    Args:
        cm: the model the dataset was simulated with.
        ds: the simulated dataset (needs its truth).
        joints: the estimated joints, in the dataset's input units.
        scale: metres per input unit.
        frames: the frames to draw, one picture each.

    Returns:
        ``(height, width, 3)`` uint8 RGB pictures, one per frame; ``None`` when no offscreen GL
        context can be made.
    """
    light_scene(cm)
    try:
        renderer = mujoco.Renderer(cm.model, HEIGHT, WIDTH)
    except Exception:  # no GL context on this machine (the error type depends on the backend)
        return None
    data = mujoco.MjData(cm.model)
    q_w_s = np.where(ds.measured.valid[..., None], ds.measured.q_w_s, [1.0, 0, 0, 0])
    R_w_s = quat_to_matrix(q_w_s)
    span_m = model_span_m(cm)
    images = []
    for frame in frames:
        data.qpos[:] = qpos_from_truth(cm, ds, frame)
        mujoco.mj_kinematics(cm.model, data)
        renderer.update_scene(data, _camera(ds, frame, span_m))
        _add_marks(renderer.scene, joint_marks(ds, joints, scale, R_w_s, frame), MARK_SHARE_OF_SPAN * span_m)
        images.append(_render(renderer))
    renderer.close()
    return images


def render_joint_centres(
    cm: CaptureModel, ds: Dataset, joints: Sequence[Joint], scale: float, frames: Sequence[int], path: Path
) -> bool:
    """Pictures of the model in a few poses, true and estimated joint centres, with a legend
    (:func:`render_pictures`, which changes ``cm.model``).

    Args:
        cm, ds, joints, scale, frames: as :func:`render_pictures`.
        path: the PNG to write.

    Returns:
        False (and writes nothing) when no offscreen GL context can be made.
    """
    images = render_pictures(cm, ds, joints, scale, frames)
    if images is None:
        return False
    titles = [f"t = {ds.time_s[f]:.1f} s" for f in frames]
    plot_pictures(images, titles, path, legend=[TRUE_MARK.legend(), ESTIMATED_MARK.legend()])
    return True
