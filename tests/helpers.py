"""Small helpers shared by the tests."""

from __future__ import annotations

from simbench.sim.synthetic import SyntheticCapture


def pair_arrays(cap: SyntheticCapture, parent: str, child: str):
    """``(R_w_p, p_w_p, R_w_c, p_w_c)`` of two sensors of a capture."""
    p, c = cap.names.index(parent), cap.names.index(child)
    return cap.R_w_s[:, p], cap.p_w_s[:, p], cap.R_w_s[:, c], cap.p_w_s[:, c]
