"""Exceptions of the simbench package.

:class:`InputError` is simbench's own; :class:`CalibrationError` (the data cannot be calibrated)
and its :class:`CalibrationInputError` (arrays or options the estimators refuse) are the
calibration core's, re-exported here so that the command line and users catch every error of
simbench from one module (``sb.CalibrationError``).
"""

from __future__ import annotations

import importlib
import tomllib
from pathlib import Path
from types import ModuleType

from calibration.errors import CalibrationError, CalibrationInputError


class InputError(ValueError):
    """A file or option is not what simbench expects (the message names what and where)."""


def read_text(path) -> str:
    """A text file's contents (UTF-8); a file that cannot be read, or is not UTF-8 text, is an
    :class:`InputError` naming the file and why."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: {not_utf8(exc)}") from None


def load_toml(path) -> dict:
    """Parse a TOML file; a missing file, one that is not UTF-8 text or bad TOML is an
    :class:`InputError` naming the file."""
    text = read_text(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None


def not_utf8(exc: UnicodeDecodeError) -> str:
    """What a :class:`UnicodeDecodeError` means to the user: the byte and where it is."""
    return (
        f"expected UTF-8 text, got byte 0x{exc.object[exc.start]:02x} at byte {exc.start} (a binary file, "
        "or another encoding: save it as UTF-8)"
    )


def optional_module(name: str, extra: str, feature: str) -> ModuleType:
    """Import an optional dependency, or fail with the extra that installs it.

    Args:
        name: the module (``pyarrow.parquet``).
        extra: the extra of the simbench distribution that installs it (``studies``).
        feature: what needs it, for the message (``simbench sweep``).
    """
    try:
        return importlib.import_module(name)
    except ImportError:
        raise InputError(
            f"{feature} needs the optional package {name.split('.')[0]!r}: pip install 'simbench[{extra}]'"
        ) from None


__all__ = [
    "CalibrationError",
    "CalibrationInputError",
    "InputError",
    "load_toml",
    "not_utf8",
    "optional_module",
]
