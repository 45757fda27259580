"""Figures of the reports (matplotlib's object API: no pyplot state, no display needed)."""

from __future__ import annotations

import io
from pathlib import Path

from matplotlib.figure import Figure

from simbench.io.atomic import atomic_open


def save_figure(fig: Figure, path: Path, *, dpi: int = 100) -> None:
    """Write a figure as PNG, atomically (a crash never leaves a half image)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())
