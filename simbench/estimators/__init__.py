"""Estimators: one registry for simbench's own methods and anyone else's.

:mod:`.catalog` lists the built-ins as data (names, kinds, parameters) without loading them;
:mod:`.registry` says what an estimator is (kind, parameters with their defaults and units, what it
needs) and holds the built-ins, which :mod:`.builtin` registers from the catalog; :mod:`.spec`
finds an estimator from a spec string (a built-in's or plugin's name, ``module:function``,
``file.py:function``, ``cmd:COMMAND``); :mod:`.run` runs one on its data with the same checks for
all.

The names below are loaded from their modules when first asked for (PEP 562), so that a light
module of the package (:mod:`.catalog`: the command line's ``--help``) loads none of the others.
"""

import importlib as _importlib

#: ``{public name: the module that defines it}``.
_LAZY = {
    "DEFAULT_JOINTS": "simbench.estimators.catalog",
    "DEFAULT_ORIENTATION": "simbench.estimators.catalog",
    "ENTRY_POINT_GROUP": "simbench.estimators.catalog",
    "KINDS": "simbench.estimators.catalog",
    "Param": "simbench.estimators.catalog",
    "TIME_LIMIT_S": "simbench.estimators.catalog",
    "names": "simbench.estimators.catalog",
    "joints_of": "simbench.estimators.builtin",
    "EstimatorError": "simbench.estimators.command",
    "Estimator": "simbench.estimators.registry",
    "JointsResult": "simbench.estimators.registry",
    "OrientationResult": "simbench.estimators.registry",
    "estimator": "simbench.estimators.registry",
    "check_hierarchy": "simbench.estimators.run",
    "joints_result": "simbench.estimators.run",
    "orientation_result": "simbench.estimators.run",
    "run_joints": "simbench.estimators.run",
    "run_orientation": "simbench.estimators.run",
    "default": "simbench.estimators.spec",
    "resolve": "simbench.estimators.spec",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> object:
    """A public name, imported from its module the first time it is asked for (PEP 562); the
    registry is filled (:mod:`.builtin`) before any name of it is given."""
    if name in _LAZY:
        if _LAZY[name] != "simbench.estimators.catalog":
            _importlib.import_module("simbench.estimators.spec")  # the registry, filled
        value = getattr(_importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # asked once
        return value
    raise AttributeError(f"module 'simbench.estimators' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
