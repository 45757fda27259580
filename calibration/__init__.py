"""Calibration core: joint parameters, hierarchy and skeleton from sensor data.

Pure numpy/scipy; never imports ``mujoco`` or ``simbench``, so it serves real recordings
unchanged. Arrays are ``(frames, sensors, ...)``, SI units, rotations ``R_w_s`` map sensor-frame
vectors into world, quaternions are scalar-first ``(w, x, y, z)``.
"""

import importlib as _importlib

#: ``{public name: the module that defines it}``: imported when first used (PEP 562), so that
#: ``import calibration`` (and any light submodule, such as :mod:`calibration.errors`) costs nothing
#: until something is asked of it: the command line's ``--help`` reads no numpy or scipy.
_LAZY = {
    "CalibrationError": "calibration.errors",
    "CalibrationInputError": "calibration.errors",
    "HIERARCHY_METHODS": "calibration.hierarchy",
    "Hierarchy": "calibration.hierarchy",
    "hierarchy_from_parents": "calibration.hierarchy",
    "loop_candidates": "calibration.hierarchy",
    "misfit_weights": "calibration.hierarchy",
    "spanning_tree": "calibration.hierarchy",
    "SINGLE_AXIS_RATIO": "calibration.joint",
    "JointFit": "calibration.joint",
    "fit_joint": "calibration.joint",
    "joint_residual_vectors": "calibration.joint",
    "pair_noise_variance": "calibration.pair_noise",
    "PairStatistics": "calibration.pairs",
    "frame_residuals": "calibration.pairs",
    "pair_residual_matrix": "calibration.pairs",
    "pair_statistics": "calibration.pairs",
    "solve_pairs": "calibration.pairs",
    "Calibration": "calibration.pipeline",
    "Joint": "calibration.pipeline",
    "calibrate": "calibration.pipeline",
    "remove_residual": "calibration.replay",
    "ScaleEstimate": "calibration.scale",
    "unit_scale": "calibration.scale",
    "SegmentLength": "calibration.skeleton",
    "SensorPlacement": "calibration.skeleton",
    "segment_lengths": "calibration.skeleton",
    "sensor_placements": "calibration.skeleton",
    "SlipEvent": "calibration.slip",
    "SlipReport": "calibration.slip",
    "detect_slip": "calibration.slip",
}


def __getattr__(name: str) -> object:
    """A public name, imported from its module the first time it is asked for (PEP 562)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # asked once
        return value
    raise AttributeError(f"module 'calibration' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = sorted(_LAZY)
