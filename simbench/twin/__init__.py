"""The digital twin of a real IMU recording (issue 41): its readings simulated from the optical
pose of the housing, what the real sensor adds identified, the two compared sample by sample, and
the orientation methods scored on both (:mod:`.run`).

:mod:`.simulate` is the one seam to the simulator (ideal readings from a pose trajectory),
:mod:`.identify` finds biases, noise, iron, field, time offsets, misalignment and lever arm, and
:mod:`.compare` gives R^2, rms and spectra. ``docs/twin.md`` explains how to read the results.
"""

from simbench.twin.run import (
    BASELINE,
    DEFAULT_CUTOFF_HZ,
    DEFAULT_POSITION_CUTOFF_HZ,
    EFFECTS,
    METHODS,
    R2_TARGETS,
    RATIO_FACTOR,
    REFERENCE,
    Identified,
    TwinResult,
    parse_window,
    summary,
    targets,
    twin,
)
from simbench.twin.simulate import twin_readings

__all__ = [
    "BASELINE",
    "DEFAULT_CUTOFF_HZ",
    "DEFAULT_POSITION_CUTOFF_HZ",
    "EFFECTS",
    "METHODS",
    "R2_TARGETS",
    "RATIO_FACTOR",
    "REFERENCE",
    "Identified",
    "TwinResult",
    "parse_window",
    "summary",
    "targets",
    "twin",
    "twin_readings",
]
