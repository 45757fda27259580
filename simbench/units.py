"""Units accepted at the edges (files, options, study parameters), as SI per unit.

One table for every reader: a length unit converts to metres, an angle to radians, a time to
seconds. Inside simbench everything is SI (docs/conventions.md).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

from simbench.errors import InputError

#: ``unit: (SI unit, SI per unit)``.
UNITS: dict[str, tuple[str, float]] = {
    "m": ("m", 1.0),
    "cm": ("m", 0.01),
    "mm": ("m", 0.001),
    "in": ("m", 0.0254),
    "rad": ("rad", 1.0),
    "deg": ("rad", math.pi / 180),
    "s": ("s", 1.0),
    "ms": ("s", 0.001),
    "hz": ("hz", 1.0),
    "1": ("1", 1.0),
}

#: Length units as metres per unit (pose files, ``--units``).
LENGTH_UNITS: dict[str, float] = {u: f for u, (si, f) in UNITS.items() if si == "m"}


#: A BVH file's length units, metres per unit: :data:`LENGTH_UNITS` and ``cmu``, the unit of the
#: CMU Graphics Lab Motion Capture Database's ASF skeletons (``:units length 0.45``: a length of 1
#: is 1/0.45 inch), which its BVH conversions (Bruce Hahne's, cgspeed) keep; mocap.cs.cmu.edu's FAQ
#: scales it by (1.0/0.45)*2.54/100 to metres, 0.0564 m. Read as ``cm``, a CMU skeleton is 5.6
#: times too small (hips 16 cm above the floor).
BVH_LENGTH_UNITS: dict[str, float] = {**LENGTH_UNITS, "cmu": 0.0254 / 0.45}


def metres_per_unit(units: str, table: dict[str, float] = LENGTH_UNITS) -> float:
    """Metres in one ``units`` of ``table`` (by default ``m``, ``cm``, ``mm``, ``in``)."""
    try:
        return table[units]
    except KeyError:
        raise InputError(f"unknown units {units!r}: expected one of {', '.join(table)}") from None


#: Plausible limb lengths, metres: a body segment or a linkage piece.
LIMB_RANGE_M = (1e-3, 10.0)


def implausible_lengths(
    lengths: list, units: str | None, source: str | os.PathLike[str], wide: bool = False
) -> str:
    """A warning naming the limb lengths outside :data:`LIMB_RANGE_M` (metres), or ``""``.

    ``units``: the ``--units`` given (``None``: the default, metres, or a C3D file's own
    ``POINT:UNITS``); ``source``: the file read (its suffix says its kind), ``wide`` when it was
    read as a wide export. The warning names the unit the positions were read in and how to
    change it (an HDF5 dataset holds metres: no option changes that).
    """
    lo, hi = LIMB_RANGE_M
    odd = [x for x in lengths if not lo <= x.length <= hi]
    if not odd:
        return ""
    suffix = "" if wide else Path(source).suffix.lower()
    shown = ", ".join(f"{x.segment} {x.length * 1e3:.3g} mm" for x in odd[:4])
    return f"{len(odd)} limb length(s) outside 1 mm - 10 m ({shown}{', ...' if len(odd) > 4 else ''}): " + (
        "a dataset's positions are in metres: were they written in another unit?"
        if suffix in (".h5", ".hdf5")
        else f"are the positions really in {units or 'm'} (--units)?"
        if units is not None or suffix != ".c3d"
        else "are the positions really in the file's POINT:UNITS? (--units overrides it)"
    )
