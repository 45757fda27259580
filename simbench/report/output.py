"""The files of a report folder: ``index.md``, a self-contained ``index.html`` and ``results.json``.

Writes are atomic: a crash never leaves a half-written file.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from simbench.io.atomic import atomic_write_text
from simbench.report.markdown import markdown_to_html


def json_safe(x: Any) -> Any:
    """``x`` with numpy scalars made Python numbers, tuples lists, and NaN or inf ``None``
    (JSON cannot hold them)."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer | np.bool_):
        return x.item()
    return x


def write_report_files(out: Path, md: str, results: dict[str, Any]) -> dict[str, Path]:
    """Write ``index.md``, ``index.html`` (images of ``out`` embedded) and ``results.json``.

    Args:
        out: the report folder (exists; holds the images the Markdown links to).
        md: the report in Markdown.
        results: the report's figures (JSON-able after :func:`json_safe`).

    Returns:
        ``{"md": ..., "html": ..., "json": ...}``: the paths written.
    """
    paths = {"md": out / "index.md", "html": out / "index.html", "json": out / "results.json"}
    atomic_write_text(paths["md"], md)
    atomic_write_text(paths["html"], markdown_to_html(md, out))
    atomic_write_text(paths["json"], json.dumps(json_safe(results), indent=1, allow_nan=False) + "\n")
    return paths
