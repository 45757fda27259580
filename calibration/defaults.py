"""The calibration core's names and defaults that a command line lists, in plain Python.

Each is defined here once and imported by the module that uses it, so that ``simbench calibrate
--help`` can show them without loading numpy or scipy (issue 44: the light start).
"""

from __future__ import annotations

#: The edge weightings :func:`calibration.hierarchy.spanning_tree` is given; the first is the
#: default.
HIERARCHY_METHODS = ("misfit", "mst")

#: Hard floor on ``s / s_max`` below which a direction is undetermined whatever the test says:
#: 1e-4 is about 0.2 mrad (0.01 degree) rms off the axis, finer than any tracker resolves, so
#: below it the statistical test (:mod:`calibration.hinge`) would compare rounding errors.
SINGLE_AXIS_RATIO = 1e-4

#: The losses :func:`calibration.robust.robust_fit_joint` knows; the first is the default.
LOSSES = ("tukey", "huber")

#: Default expected false alarms per hour of joint time (the one default: ``simbench calibrate
#: --slip-false-alarms-per-hour``, ``sb.slip_reports``, the live monitor of
#: :mod:`calibration.streaming`).
FALSE_ALARMS_PER_HOUR = 1.0

#: Default window ``w`` of the slip detector, seconds (turned into frames at the recording's rate):
#: the one default of ``simbench calibrate --slip-window``, ``sb.slip_reports`` and the validation's
#: decisions (:mod:`simbench.experiments.decisions`). The live monitor's window is its own
#: (:data:`calibration.streaming.LIVE_SLIP_WINDOW_S`).
SLIP_WINDOW_S = 2.0

#: The names of the pose-based joint estimators of :data:`calibration.methods.JOINT_METHODS`, in
#: its order.
JOINT_METHOD_NAMES = ("obrien", "obrien-eiv", "score", "sara", "sphere-gamage-lasenby", "sphere-geometric")

__all__ = [
    "FALSE_ALARMS_PER_HOUR",
    "HIERARCHY_METHODS",
    "JOINT_METHOD_NAMES",
    "LOSSES",
    "SINGLE_AXIS_RATIO",
    "SLIP_WINDOW_S",
]
