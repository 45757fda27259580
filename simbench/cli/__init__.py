"""The ``simbench`` command line: argparse and thin commands, one module per subcommand.

Every subcommand reports bad input as ``simbench: error: ...`` on stderr, on one line, with exit
status 2; anything else that goes wrong is reported the same way, naming the exception, and Ctrl-C
ends with exit status 130. A traceback is shown only with ``--debug``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings
import weakref
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from types import ModuleType

from simbench.cli.help_examples import epilog
from simbench.errors import CalibrationError, InputError
from simbench.versions import __version__

#: The subcommands in the order ``simbench --help`` lists them: ``{command: (module, summary)}``.
#: A command's module adds its options (``add_arguments(parser)``) and runs it; it is imported only
#: when the command is named (:func:`command_parser`), so that ``simbench --help`` reads no module
#: of the library, and ``simbench CMD`` only the one it runs (issue 44: the light start).
COMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": (
        "simbench.cli.calibrate",
        "joint centres, hierarchy, limb lengths and sensor offsets from sensor poses",
    ),
    "replay": (
        "simbench.cli.replay",
        "feed a recorded or simulated session through the live (streaming) calibration",
    ),
    "scale": ("simbench.cli.scale", "unit scale factor of a capture system from two rigidly mounted sensors"),
    "simulate": ("simbench.cli.simulate", "a physics-simulated capture session with exact ground truth"),
    "export": (
        "simbench.cli.export",
        "a dataset into TRC, C3D, OpenSense .sto, IMU CSV, MJCF and .osim files",
    ),
    "orient": ("simbench.cli.orient", "sensor orientations from accelerometer and magnetometer (sourceless)"),
    "twin": (
        "simbench.cli.twin",
        "a real IMU recording's digital twin: its readings simulated from the optical pose",
    ),
    "validate": (
        "simbench.cli.validate",
        "the main job: the paper's experiments reproduced in simulation, scored; writes the report",
    ),
    "report": ("simbench.cli.report", "the report of one dataset (scored against its truth when it has one)"),
    "baseline": (
        "simbench.cli.baseline",
        "accuracy regression check against reports/baseline.json (or --update it)",
    ),
    "sweep": ("simbench.cli.sweep", "a study of seeded trials (noise, slip, placement...), local or on Dask"),
    "bench": (
        "simbench.cli.bench",
        "the benchmark suite: every built-in estimator and yours, a scorecard with significance",
    ),
    "examples": (
        "simbench.cli.starter",
        "write the example recordings, studies, estimators and baseline into a folder",
    ),
}

#: The subparsers whose options their module has added (each is filled once).
_FILLED: weakref.WeakSet[argparse.ArgumentParser] = weakref.WeakSet()


def command_module(command: str) -> ModuleType:
    """The module of one of :data:`COMMANDS`, imported now if it was not."""
    return importlib.import_module(COMMANDS[command][0])


def command_function(func: Callable[[argparse.Namespace], int] | str) -> Callable[[argparse.Namespace], int]:
    """The function a command runs: the parser's ``func`` itself, or the one it names as
    ``"module:function"`` (a command whose options load little, its run loaded only now)."""
    if callable(func):
        return func
    module, _, name = func.partition(":")
    return getattr(importlib.import_module(module), name)


class _Commands(argparse._SubParsersAction):
    """argparse's subcommands, each one's options added by its module when it is named."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        if values and values[0] in self._name_parser_map:
            _fill(values[0], self._name_parser_map[values[0]])
        super().__call__(parser, namespace, values, option_string)


def _fill(command: str, parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``parser`` with the options of ``command``, its description and its examples."""
    if parser not in _FILLED:
        command_module(command).add_arguments(parser)
        if not parser.description:  # the one-line summary, as the command list gives it
            parser.description = COMMANDS[command][1].capitalize() + "."
        parser.epilog = epilog(command)
        _FILLED.add(parser)
    return parser


def build_parser(commands: Iterable[str] = ()) -> argparse.ArgumentParser:
    """The argument parser of the ``simbench`` command. The options of the ``commands`` named are
    added now (``COMMANDS`` for all, as the tests that read every option want); any other
    command's when the command line names it."""
    parser = argparse.ArgumentParser(
        prog="simbench",
        description="Physics-simulation validation testbed for motion-capture skeleton calibration.",
    )
    parser.add_argument("--version", action="version", version=f"simbench {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of any error")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", action=_Commands)
    for name, (_module, summary) in COMMANDS.items():
        sub.add_parser(name, help=summary, formatter_class=_Formatter)
    for name in commands:
        command_parser(parser, name)
    return parser


def command_parser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    """The subparser of ``command`` in ``parser`` (:func:`build_parser`'s), its options added.

    Raises:
        KeyError: ``command`` is not one of :data:`COMMANDS`.
    """
    sub = next(a for a in parser._actions if isinstance(a, _Commands))
    if command not in COMMANDS:
        raise KeyError(f"no command {command!r}: expected one of {', '.join(COMMANDS)}")
    return _fill(command, sub.choices[command])


class _Formatter(argparse.HelpFormatter):
    """argparse's formatter, which keeps an ``examples:`` block's lines as they are written."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith("examples:\n"):
            return "\n".join(indent + line for line in text.splitlines())
        return super()._fill_text(text, width, indent)


class Terminated(BaseException):
    """SIGTERM, raised where the program is so that ``finally`` blocks (temporary files) run."""


def _interrupted(signum: int, frame: object) -> None:
    """The first SIGINT or SIGTERM: ignore both from now on (a second one would interrupt the
    cleanup it starts: workers stopped, temporary files removed) and raise."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line (MuJoCo's and others' span several)."""
    return " ".join(str(exc).split()) or type(exc).__name__


#: Commands whose outputs are one set (:func:`simbench.api.output_set`): a failure part way leaves
#: none of them. (``sweep``, ``validate``, ``report``, ``twin``, ``bench`` and ``calibrate --follow``
#: keep what they finished: their outputs are results of their own, written as they come, and a
#: report's page embeds the figures written before it.)
OUTPUT_SETS = ("simulate", "export", "calibrate", "scale", "orient")

#: The options that name a file to write (argparse ``dest``), checked before any work is done.
FILE_OUTPUTS = ("json", "csv", "output", "trc", "c3d", "sto", "imu_csv", "mjcf", "osim", "truth_json")


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _same(a: Path, b: Path) -> bool:
    """Two paths name one file: the same inode when both exist, else the same resolved path."""
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any work, an output file that is a folder or whose folder does not exist
    (it would otherwise fail only when the result is written), one that names the same file as
    another output or as a file the command reads (any other argument naming an existing file:
    a recording, a model, a spec, after resolving links), and one that exists but is not a
    regular file (a FIFO, a device: writing would replace it with a file).

    Raises:
        InputError: naming the option(s) and the path(s), on one line.
    """
    outputs: list[tuple[str, Path]] = []
    for dest in FILE_OUTPUTS:
        value = getattr(args, dest, None)
        if not isinstance(value, str):
            continue
        path = Path(value)
        flag = _flag(dest)
        if path.is_dir():
            raise InputError(f"{flag} {value}: that is a folder; give the file to write")
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.is_dir():
            raise InputError(f"{flag} {value}: folder {folder} does not exist")
        if path.exists() and not Path(os.path.realpath(path)).is_file():
            raise InputError(
                f"{flag} {value}: exists and is not a regular file (a FIFO or device); not replaced"
            )
        for other_flag, other in outputs:
            if _same(path, other):
                raise InputError(
                    f"{other_flag} {other} and {flag} {value} name the same file; give each its own"
                )
        outputs.append((flag, path))
    for dest, value in vars(args).items():
        values = value if isinstance(value, list) else [value]
        for v in values:
            if dest in FILE_OUTPUTS or not isinstance(v, str) or not v or not Path(v).is_file():
                continue
            for flag, out in outputs:
                if _same(Path(v), out):
                    what = dest if dest.isidentifier() and not dest.startswith("_") else "an input"
                    raise InputError(
                        f"{flag} {out} is the file the command reads ({what.replace('_', ' ')}: {v}); "
                        "writing it would destroy the input: give another file"
                    )


def _note(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning raised while a command runs, as one line on stderr."""
    print(f"simbench: note: {_one_line(message)}", file=sys.stderr if file is None else file)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``simbench`` command (``argv`` defaults to ``sys.argv[1:]``); returns the exit
    status: 0, 1 when ``simbench baseline`` finds a regression, 2 on bad input or any other
    error (a usage error exits 2 from argparse), 130 when interrupted (Ctrl-C), 143 when
    terminated (SIGTERM; temporary files are removed on the way out)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = {sig: signal.signal(sig, _interrupted) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        # BLAS on one thread: simbench's products are small (a chunk of frames, a 6 x 6 system),
        # where BLAS's threads cost more than they give (1M x 32 poses from HDF5: 4.5 s on one
        # thread, 7.2 s on two; benchmarks/results/calibration*.json)
        if args.command == "simulate" and args.output is None:
            args.output = command_module("simulate").default_output(args)
        check_outputs(args)
        api = importlib.import_module("simbench.api")  # the library: loaded once a command runs
        with api.one_blas_thread(), warnings.catch_warnings():
            if not args.debug:  # one line a note, as the errors; --debug keeps Python's form
                warnings.showwarning = _note
            run = command_function(args.func)
            if args.command in OUTPUT_SETS:
                with api.output_set():
                    return int(run(args))
            return int(run(args))
    except Terminated:
        print("simbench: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("simbench: interrupted", file=sys.stderr)
        return 130
    except (InputError, CalibrationError, OSError) as exc:
        if args.debug:
            raise
        print(f"simbench: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # every other failure: one line, no traceback (--debug shows it)
        if args.debug:
            raise
        print(
            f"simbench: error: {type(exc).__name__}: {_one_line(exc)} (an internal error; --debug shows "
            "where)",
            file=sys.stderr,
        )
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


__all__ = ["COMMANDS", "build_parser", "command_module", "command_parser", "main"]
