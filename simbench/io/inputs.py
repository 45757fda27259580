"""The pose recordings simbench reads, by kind, in plain Python: what ``--help`` and the readers'
errors list (:mod:`simbench.io.read` reads them; this module loads nothing, so that a command's
``--help`` does not load the readers)."""

from __future__ import annotations

#: The pose recordings simbench reads, by kind: what ``--help`` and the errors list.
POSE_INPUTS: dict[str, str] = {
    "csv": "a pose CSV (.csv, .txt: time,sensor,x,y,z,qw,qx,qy,qz)",
    "wide": "a tracker's wide export (.csv with --wide SPEC.toml)",
    "c3d": "optical markers (.c3d, .trc: clustered by --clusters SPEC.toml or found)",
    "h5": "a simbench dataset (.h5, .hdf5)",
}


def pose_inputs_text(without: tuple[str, ...] = ()) -> str:
    """The kinds of :data:`POSE_INPUTS` (less those of ``without``) as one phrase (``a; b or c``)."""
    kinds = [text for kind, text in POSE_INPUTS.items() if kind not in without]
    return "; ".join(kinds[:-1]) + " or " + kinds[-1]


__all__ = ["POSE_INPUTS", "pose_inputs_text"]
