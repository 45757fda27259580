"""Exceptions of the simbench package."""

from __future__ import annotations


class InputError(ValueError):
    """A file or option is not what simbench expects (the message names what and where)."""


def load_toml(path) -> dict:
    """Parse a TOML file; a missing file or bad TOML is an :class:`InputError` naming the file."""
    import tomllib
    from pathlib import Path

    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
