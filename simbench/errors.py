"""Exceptions of the simbench package."""

from __future__ import annotations


class InputError(ValueError):
    """A file or option is not what simbench expects (the message names what and where)."""
