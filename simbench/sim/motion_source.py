"""Which recorded motion a session's ``motion`` names, on which model, read once.

A motion that is a file of a recorded format is played back (:mod:`simbench.sim.playback`):

============================== ========== ===================================================
file                           format     model
============================== ========== ===================================================
``.bvh``                       ``bvh``    the clip's own skeleton (``bvh``)
``.npz``, ``.csv`` of ``qpos`` ``qpos``   the model given (an archive may name its own)
``.mot``, ``.sto``             ``opensim`` the model given (default ``humanoid``: a mapping table)
``.c3d``, pose ``.csv``/``.txt`` ``poses`` one free body per segment (``poses``)
BROAD ``.hdf5``/``.h5``        ``poses``  one free body, the IMU housing (``poses``)
============================== ========== ===================================================

A ``.csv`` is a pose CSV when its header has a ``sensor`` column, a ``qpos`` series otherwise.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco

from simbench.errors import InputError
from simbench.io.opensim_motion import read_opensim_motion
from simbench.io.qpos import npz_model, read_qpos_csv, read_qpos_npz
from simbench.io.read import is_simbench_dataset, read_poses
from simbench.io.recorded import RecordedMotion
from simbench.sim.bvh_model import bvh_recorded, bvh_spec, read_clip
from simbench.sim.mjcf import compile_spec, read_spec
from simbench.sim.pose_model import poses_recorded, poses_spec, read_broad_poses
from simbench.units import BVH_LENGTH_UNITS

#: Suffixes of recorded motions and their format (``.csv``: :func:`motion_format` looks inside).
SUFFIXES = {
    ".bvh": "bvh",
    ".npz": "qpos",
    ".mot": "opensim",
    ".sto": "opensim",
    ".c3d": "poses",
    ".hdf5": "poses",
    ".h5": "poses",
    ".txt": "poses",
    ".csv": "csv",
}

#: Formats that bring their own model, and its name.
OWN_MODEL = {"bvh": "bvh", "poses": "poses"}

#: The model OpenSim joint angles play on when none is given.
OPENSIM_DEFAULT_MODEL = "humanoid"


def motion_format(motion: object) -> str | None:
    """``bvh``, ``qpos``, ``opensim`` or ``poses`` for a recorded motion, ``None`` for a program."""
    if not isinstance(motion, str):
        return None
    fmt = SUFFIXES.get(Path(motion).suffix.lower())
    if fmt != "csv":
        return fmt
    try:
        with open(motion, encoding="utf-8-sig", errors="replace") as fh:
            header = fh.readline()
    except OSError:
        return "poses"  # read_poses names the file that cannot be read
    return "poses" if "sensor" in [h.strip() for h in header.split(",")] else "qpos"


def is_recorded(motion: object) -> bool:
    """The motion names a recorded motion file (module docstring)."""
    return motion_format(motion) is not None


def own_model(motion: str) -> str | None:
    """The model a recorded motion brings (``bvh``, ``poses``), or ``None`` (played on a given one)."""
    return OWN_MODEL.get(motion_format(motion) or "")


@dataclass(frozen=True)
class MotionSource:
    """A recorded motion and the model it plays on.

    Attributes:
        recorded: the motion.
        model: the model's name (``bvh``, ``poses``, or the model given).
        make_spec: makes the motion's own model as a new spec (a capture model edits the spec it
            is given), or ``None`` (the model is read by name).
    """

    recorded: RecordedMotion
    model: str
    make_spec: Callable[[], mujoco.MjSpec] | None

    def spec(self) -> mujoco.MjSpec | None:
        """A new spec of the motion's own model, or ``None``."""
        return None if self.make_spec is None else self.make_spec()


def default_model(motion: str, units: str | None = None, clusters: str | None = None) -> str:
    """The model a recorded motion plays on when none is given.

    Raises:
        InputError: a ``qpos`` series that names no model.
    """
    fmt = motion_format(motion)
    if fmt in OWN_MODEL:
        return OWN_MODEL[fmt]
    if fmt == "opensim":
        return OPENSIM_DEFAULT_MODEL
    if fmt == "qpos" and Path(motion).suffix.lower() == ".npz":
        _exists(motion)
        named = npz_model(motion)
        if named:
            return named
    raise InputError(
        f"motion {motion}: a qpos series plays on a model: give one (linkage, humanoid, an MJCF path)"
    )


def _exists(motion: str) -> Path:
    p = Path(motion)
    if not p.is_file():
        raise InputError(f"motion file {p} does not exist" if not p.exists() else f"motion {p} is not a file")
    return p


def load_motion(
    motion: str, model: str | None = None, units: str | None = None, clusters: str | None = None
) -> MotionSource:
    """Read a recorded motion for a session on ``model`` (``None``: :func:`default_model`).

    Args:
        motion: the file.
        model: the model name, or ``None``.
        units: a length unit overriding the file's convention (BVH: ``cm``; a pose CSV: ``m``; C3D:
            its ``POINT:UNITS``); ``qpos`` and OpenSim files are SI and refuse another unit.
        clusters: a C3D file's cluster spec (TOML), or ``None`` (found automatically).

    Raises:
        InputError: naming the file: what its reader refuses, a model beside a motion that brings its
            own, a unit or cluster spec that does not apply.
    """
    p = _exists(motion)
    stat = p.stat()
    return _load_cached(str(p.resolve()), str(motion), model, units, clusters, stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=8)
def _load_cached(
    path: str, name: str, model: str | None, units: str | None, clusters: str | None, mtime_ns: int, size: int
) -> MotionSource:
    fmt = motion_format(path)
    own = OWN_MODEL.get(fmt or "")
    if own is not None and model not in (None, own):
        raise InputError(
            f"motion {name}: a {fmt} recording moves its own {'skeleton' if fmt == 'bvh' else 'bodies'}: "
            f"leave the model at its default or give {own!r}, got {model!r}"
        )
    if clusters is not None and Path(path).suffix.lower() != ".c3d":
        raise InputError(f"motion {name}: a cluster spec applies to a C3D file of markers")
    if fmt in ("qpos", "opensim") and units not in (None, "m"):
        raise InputError(f"motion {name}: {fmt} files hold SI units; units {units!r} do not apply")
    model = model if model is not None else default_model(name)
    if fmt == "bvh":
        clip = read_clip(path, units or "cm")
        rec = bvh_recorded(clip)
        return MotionSource(_named(rec, name), model, functools.partial(bvh_spec, clip))
    if fmt == "poses":
        suffix = Path(path).suffix.lower()
        if suffix in (".h5", ".hdf5"):
            if is_simbench_dataset(path):
                raise InputError(
                    f"motion {name}: a simbench dataset is not a recorded motion; give its poses as a pose "
                    "CSV (simbench export) or a BROAD-layout trial"
                )
            if units not in (None, "m"):
                raise InputError(f"motion {name}: a BROAD trial holds metres; units {units!r} do not apply")
            poses = read_broad_poses(path)
        else:
            poses = read_poses(path, units=units, clusters=clusters)
        rec = poses_recorded(poses)
        poses_spec(rec.joints, name)  # refuse names MJCF refuses now
        return MotionSource(_named(rec, name), model, functools.partial(poses_spec, rec.joints, name))
    m = compile_spec(read_spec(model), model)
    if fmt == "qpos":
        reader = read_qpos_npz if Path(path).suffix.lower() == ".npz" else read_qpos_csv
        return MotionSource(_named(reader(path, m), name), model, None)
    return MotionSource(_named(read_opensim_motion(path, m, model), name), model, None)


def _named(rec: RecordedMotion, name: str) -> RecordedMotion:
    """The motion with the file named as the user gave it (messages), not resolved."""
    return rec if rec.source == name else dataclasses.replace(rec, source=name)


def check_units(units: str | None) -> None:
    """Refuse a unit that is not a length unit simbench knows.

    Raises:
        InputError: naming the known units.
    """
    if units is not None and units not in BVH_LENGTH_UNITS:
        raise InputError(f"motion units {units!r}: expected one of {', '.join(BVH_LENGTH_UNITS)}")
