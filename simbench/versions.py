"""The software versions recorded with every result (datasets, calibrations, reports, studies)."""

from __future__ import annotations

import functools
import platform
import sys
from importlib import metadata

__version__ = "0.1.0"

#: Distributions whose versions a result records (those not installed are left out).
RECORDED = ("numpy", "scipy", "mujoco", "h5py", "matplotlib")


def software_versions() -> dict[str, str]:
    """``{"simbench": ..., "python": ..., "platform": ..., "numpy": ..., ...}``: what produced a
    result. One source for every file simbench writes. A new dict each call, its contents looked
    up once per process (each package's metadata is a search of the path: 20 ms a call, and
    every simulated session records them)."""
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    out = {"simbench": __version__, "python": platform.python_version(), "platform": sys.platform}
    for name in RECORDED:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out
