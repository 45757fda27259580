"""Calibration core: joint parameters, hierarchy and skeleton from sensor data.

Pure numpy/scipy; never imports ``mujoco`` or ``simbench``, so it serves real recordings
unchanged. Arrays are ``(frames, sensors, ...)``, SI units, rotations ``R_w_s`` map sensor-frame
vectors into world, quaternions are scalar-first ``(w, x, y, z)``.
"""

from calibration.errors import CalibrationError, CalibrationInputError
from calibration.hierarchy import (
    HIERARCHY_METHODS,
    Hierarchy,
    hierarchy_from_parents,
    loop_candidates,
    misfit_weights,
    spanning_tree,
)
from calibration.joint import SINGLE_AXIS_RATIO, JointFit, fit_joint, joint_residual_vectors
from calibration.pair_noise import pair_noise_variance
from calibration.pairs import (
    PairStatistics,
    frame_residuals,
    pair_residual_matrix,
    pair_statistics,
    solve_pairs,
)
from calibration.pipeline import Calibration, Joint, calibrate
from calibration.replay import remove_residual
from calibration.scale import ScaleEstimate, unit_scale
from calibration.skeleton import SegmentLength, SensorPlacement, segment_lengths, sensor_placements
from calibration.slip import SlipEvent, SlipReport, detect_slip

__all__ = [
    "HIERARCHY_METHODS",
    "SINGLE_AXIS_RATIO",
    "Calibration",
    "CalibrationError",
    "CalibrationInputError",
    "Hierarchy",
    "Joint",
    "JointFit",
    "PairStatistics",
    "ScaleEstimate",
    "SegmentLength",
    "SensorPlacement",
    "SlipEvent",
    "SlipReport",
    "calibrate",
    "detect_slip",
    "fit_joint",
    "frame_residuals",
    "hierarchy_from_parents",
    "joint_residual_vectors",
    "loop_candidates",
    "misfit_weights",
    "pair_noise_variance",
    "pair_residual_matrix",
    "pair_statistics",
    "remove_residual",
    "segment_lengths",
    "sensor_placements",
    "solve_pairs",
    "spanning_tree",
    "unit_scale",
]
