"""The hierarchy JSON that ``simbench calibrate --hierarchy`` reads: ``{"child": "parent", ...}``."""

from __future__ import annotations

import json
import os
from typing import Any

from simbench.errors import InputError, read_text


def read_hierarchy_json(path: str | os.PathLike[str]) -> dict[str, str]:
    """Read a known body hierarchy from a JSON file.

    Args:
        path: a JSON object mapping each child sensor's name to its parent sensor's name,
            ``{"thigh_l": "pelvis", "shank_l": "thigh_l", ...}``.

    Returns:
        ``{child: parent}`` for every sensor that has a parent (the root has none).

    Raises:
        InputError: the file cannot be read, is not UTF-8 or valid JSON (with the line), names a
            sensor twice as a child, is not an object of strings, or makes a sensor its own
            parent or ancestor (a cycle).
    """

    def no_repeats(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        keys = [k for k, _ in pairs]
        repeated = sorted({k for k in keys if keys.count(k) > 1})
        if repeated:
            raise InputError(f"{path}: sensors given a parent twice: {repeated}")
        return dict(pairs)

    text = read_text(path)
    try:
        doc = json.loads(text, object_pairs_hook=no_repeats)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}, line {exc.lineno}: not valid JSON: {exc.msg}") from None
    if not isinstance(doc, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in doc.items()
    ):
        raise InputError(f'{path}: expected a JSON object {{"child": "parent", ...}} of sensor names')
    own = sorted(child for child, parent in doc.items() if child == parent)
    if own:
        raise InputError(f"{path}: sensors given as their own parent: {own}")
    for start in doc:
        seen = [start]
        while seen[-1] in doc:
            seen.append(doc[seen[-1]])
            if seen[-1] in seen[:-1]:
                cycle = seen[seen.index(seen[-1]) :]
                raise InputError(f"{path}: the hierarchy has a cycle: {' -> '.join(cycle)} (child -> parent)")
    return doc
