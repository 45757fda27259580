"""The ``simbench`` command line: argparse and thin commands, one module per subcommand.

Every subcommand reports bad input as ``simbench: error: ...`` on stderr with exit status 2,
never as a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from calibration import CalibrationError
from simbench.cli import baseline, calibrate, orient, report, scale, simulate, sweep, validate
from simbench.errors import InputError
from simbench.versions import __version__

#: The subcommands in the order ``simbench --help`` lists them; each module adds its parser.
COMMANDS = (calibrate, scale, simulate, orient, validate, report, baseline, sweep)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``simbench`` command."""
    parser = argparse.ArgumentParser(
        prog="simbench",
        description="Physics-simulation validation testbed for motion-capture skeleton calibration.",
    )
    parser.add_argument("--version", action="version", version=f"simbench {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simbench`` command (``argv`` defaults to ``sys.argv[1:]``); returns the exit
    status: 0, 1 when ``simbench baseline`` finds a regression, 2 on bad input (a usage error
    exits 2 from argparse)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except (InputError, CalibrationError, OSError) as exc:
        print(f"simbench: error: {exc}", file=sys.stderr)
        return 2


__all__ = ["build_parser", "main"]
