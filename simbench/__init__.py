"""simbench: a physics-simulation validation testbed for motion-capture skeleton calibration.

The public API (:mod:`simbench.api`)::

    import simbench as sb

    ds = sb.simulate(model="linkage", motion="exercise", sensors="ascension-flock", duration_s=45, seed=1)
    cal = sb.calibrate(ds)
    result = sb.score(cal, ds)
    ori = sb.orient(ds, method="fontaine")
    sb.export(ds, sto="imu.sto", mjcf="skeleton.xml")  # OpenSense orientations, MuJoCo skeleton
    rec = sb.read("recording.c3d")   # pose CSV, wide export, C3D, simbench HDF5, BROAD
    slips = sb.slip_reports(ds, cal)  # (joint, report) per joint, as `simbench calibrate` prints
    for update in sb.follow("poses.csv", timeout_s=60): ...  # `simbench calibrate --follow`

Whatever the command line does goes through :mod:`simbench.api`, so a Python user can do it too.

The layers and the import rule between them are in ARCHITECTURE.md.
"""

import os

# MuJoCo picks its OpenGL backend when it is first imported: without a display, offscreen EGL
# (Mesa) renders the report's pictures; a caller's own MUJOCO_GL choice (e.g. osmesa) wins.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

from calibration import Calibration
from simbench import estimators
from simbench.api import (
    FALSE_ALARMS_PER_HOUR,
    SLIP_WINDOW_S,
    LiveUpdate,
    Orientations,
    Priors,
    SlipReport,
    calibrate,
    calibration_document,
    export,
    follow,
    orient,
    read,
    read_hierarchy,
    read_imu,
    read_poses,
    replay,
    score,
    simulate,
    slip_reports,
    truth_document,
    unit_scale,
    write_calibration,
    write_orientation_csv,
    write_pose_csv,
)
from simbench.errors import CalibrationError, InputError
from simbench.io.dataset import Dataset, read_dataset, write_dataset
from simbench.io.imu import ImuRecording
from simbench.io.marker_data import MarkerData
from simbench.io.poses import PoseRecording
from simbench.score import CalibrationScore, OrientationScore
from simbench.sim.marker_clusters import MarkerConfig
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.sim.session import SessionConfig
from simbench.versions import __version__, software_versions

__all__ = [
    "FALSE_ALARMS_PER_HOUR",
    "SLIP_WINDOW_S",
    "Calibration",
    "CalibrationError",
    "CalibrationScore",
    "Dataset",
    "ImuRecording",
    "InputError",
    "LiveUpdate",
    "MarkerConfig",
    "MarkerData",
    "OrientationScore",
    "Orientations",
    "PoseRecording",
    "Priors",
    "SensorConfig",
    "SessionConfig",
    "SlipReport",
    "__version__",
    "calibrate",
    "calibration_document",
    "estimators",
    "export",
    "follow",
    "load_sensor_config",
    "orient",
    "read",
    "read_dataset",
    "read_hierarchy",
    "read_imu",
    "read_poses",
    "replay",
    "score",
    "simulate",
    "slip_reports",
    "software_versions",
    "truth_document",
    "unit_scale",
    "write_calibration",
    "write_dataset",
    "write_orientation_csv",
    "write_pose_csv",
]
