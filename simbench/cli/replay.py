"""``simbench replay``: a recorded or simulated session fed frame by frame through the live
(streaming) calibration (:mod:`simbench.cli.live`)."""

from __future__ import annotations

import argparse

from simbench.cli.live import add_replay_parser


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand to ``simbench``'s subparsers."""
    add_replay_parser(sub)
