"""Estimators: one registry for simbench's own methods and anyone else's.

:mod:`.registry` says what an estimator is (kind, parameters with their defaults and units, what it
needs) and holds the built-ins, which :mod:`.builtin` registers; :mod:`.spec` finds an estimator
from a spec string (a built-in's or plugin's name, ``module:function``, ``file.py:function``,
``cmd:COMMAND``); :mod:`.run` runs one on its data with the same checks for all.
"""

from simbench.estimators.builtin import DEFAULT_JOINTS, DEFAULT_ORIENTATION, joints_of
from simbench.estimators.command import TIME_LIMIT_S, EstimatorError
from simbench.estimators.registry import (
    ENTRY_POINT_GROUP,
    KINDS,
    Estimator,
    JointsResult,
    OrientationResult,
    Param,
    estimator,
)
from simbench.estimators.run import (
    check_hierarchy,
    joints_result,
    orientation_result,
    run_joints,
    run_orientation,
)
from simbench.estimators.spec import default, names, resolve

__all__ = [
    "DEFAULT_JOINTS",
    "DEFAULT_ORIENTATION",
    "ENTRY_POINT_GROUP",
    "KINDS",
    "TIME_LIMIT_S",
    "Estimator",
    "EstimatorError",
    "JointsResult",
    "OrientationResult",
    "Param",
    "check_hierarchy",
    "default",
    "estimator",
    "joints_of",
    "joints_result",
    "names",
    "orientation_result",
    "resolve",
    "run_joints",
    "run_orientation",
]
