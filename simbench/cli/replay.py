"""``simbench replay``: a recorded or simulated session fed frame by frame through the live
(streaming) calibration (:mod:`simbench.cli.live`)."""

from __future__ import annotations

import argparse

from simbench.cli.live import add_replay_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench replay``."""
    add_replay_arguments(parser)
