"""The orientation CSV that ``simbench orient --csv`` writes."""

from __future__ import annotations

import csv
import os

import numpy as np

from simbench.io.atomic import atomic_open
from simbench.io.imu import ImuRecording


def write_orientation_csv(path: str | os.PathLike[str], rec: ImuRecording, q_w_s: np.ndarray) -> None:
    """``time,sensor,qw,qx,qy,qz``: one row per input sample and sensor (``q_w_s`` ``(F, N, 4)``,
    scalar-first ``R_w_s``), NaN where not estimated; written atomically."""
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(("time", "sensor", "qw", "qx", "qy", "qz"))
        for f in range(rec.time_s.size):
            t = repr(float(rec.time_s[f]))
            for k, name in enumerate(rec.names):
                writer.writerow([t, name, *(repr(float(v)) for v in q_w_s[f, k])])
