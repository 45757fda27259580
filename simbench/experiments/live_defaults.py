"""The live loop's defaults (:mod:`simbench.experiments.live`) in plain Python: what
``simbench calibrate --follow``'s options show, without loading the loop."""

from __future__ import annotations

#: Seconds of capture between two updates of the calibration.
REFRESH_S = 1.0

#: Frames a followed file must hold before its rate is estimated (count over span, docs/conventions.md).
RATE_FRAMES = 64

__all__ = ["RATE_FRAMES", "REFRESH_S"]
