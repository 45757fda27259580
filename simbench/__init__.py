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

import importlib as _importlib
import os
import sys as _sys
import types as _types

# MuJoCo picks its OpenGL backend when it is first imported: without a display, offscreen EGL
# (Mesa) renders the report's pictures; a caller's own MUJOCO_GL choice (e.g. osmesa) wins.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"
del os

from simbench.versions import __version__ as __version__  # noqa: E402 (light: no numpy)
from simbench.versions import software_versions as software_versions  # noqa: E402

#: ``{public name: the module that defines it}``: imported when first used (PEP 562), so that
#: ``import simbench`` costs nothing until something is asked of it.
_LAZY = {
    **dict.fromkeys(
        (
            "FALSE_ALARMS_PER_HOUR",
            "SLIP_WINDOW_S",
            "LiveUpdate",
            "Orientations",
            "Priors",
            "SlipReport",
            "calibrate",
            "calibration_document",
            "export",
            "follow",
            "orient",
            "read",
            "read_hierarchy",
            "read_imu",
            "read_poses",
            "replay",
            "score",
            "simulate",
            "slip_reports",
            "truth_document",
            "unit_scale",
            "write_calibration",
            "write_examples",
            "write_orientation_csv",
            "write_pose_csv",
        ),
        "simbench.api",
    ),
    "Calibration": "calibration",
    "CalibrationError": "simbench.errors",
    "InputError": "simbench.errors",
    "Dataset": "simbench.io.dataset",
    "read_dataset": "simbench.io.dataset",
    "write_dataset": "simbench.io.dataset",
    "ImuRecording": "simbench.io.imu",
    "MarkerData": "simbench.io.marker_data",
    "PoseRecording": "simbench.io.poses",
    "CalibrationScore": "simbench.score",
    "OrientationScore": "simbench.score",
    "MarkerConfig": "simbench.sim.marker_clusters",
    "SensorConfig": "simbench.sim.sensor_config",
    "load_sensor_config": "simbench.sim.sensor_config",
    "SessionConfig": "simbench.sim.session",
}


#: Public functions named as submodules are (``simbench.score``, ``simbench.orient``): the package's
#: attribute is the function, as ``sb.score(...)`` wants, even after the submodule is imported
#: (which would otherwise set the attribute to the module; the module stays in ``sys.modules``).
_SHADOWING = frozenset({"score", "orient"})


class _Package(_types.ModuleType):
    def __setattr__(self, name: str, value: object) -> None:
        if name in _SHADOWING and isinstance(value, _types.ModuleType):
            return  # the import system naming the submodule: the function keeps the name
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> object:
    """A public name, imported from its module the first time it is asked for (PEP 562)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # asked once
        return value
    if name == "estimators":
        return _importlib.import_module("simbench.estimators")
    raise AttributeError(f"module 'simbench' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = sorted([*_LAZY, "__version__", "estimators", "software_versions"])
