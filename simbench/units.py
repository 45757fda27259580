"""Units accepted at the edges (files, options, study parameters), as SI per unit.

One table for every reader: a length unit converts to metres, an angle to radians, a time to
seconds. Inside simbench everything is SI (DESIGN.md).
"""

from __future__ import annotations

import math

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


def metres_per_unit(units: str) -> float:
    """Metres in one ``units`` (``m``, ``cm``, ``mm``, ``in``)."""
    try:
        return LENGTH_UNITS[units]
    except KeyError:
        raise InputError(f"unknown units {units!r}: expected one of {', '.join(LENGTH_UNITS)}") from None
