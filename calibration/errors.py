"""Exceptions raised by the calibration core."""

from __future__ import annotations


class CalibrationError(ValueError):
    """A calibration could not be computed from the data given (the message says why)."""


class CalibrationInputError(CalibrationError):
    """The arrays or options given do not have the expected shape, units or values."""
