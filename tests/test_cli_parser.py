"""The ``simbench`` parser: its subcommands, ``--version``, help and usage errors (exit status 2)."""

from __future__ import annotations

import re

import pytest

from simbench.cli import build_parser, command_function, main
from simbench.versions import __version__

COMMANDS = (
    "calibrate",
    "scale",
    "simulate",
    "export",
    "orient",
    "twin",
    "validate",
    "report",
    "baseline",
    "sweep",
    "examples",
)


def test_version_comes_from_the_versions_module(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out == f"simbench {__version__}\n"


def test_help_lists_every_command_in_order(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    positions = [re.search(rf"^    {name}\b", out, re.MULTILINE).start() for name in COMMANDS]
    assert positions == sorted(positions)


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help_and_a_handler(capsys, command):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: simbench {command} ")
    args = build_parser().parse_args(
        {
            "calibrate": ["calibrate", "poses.csv"],
            "scale": ["scale", "poses.csv", "--sensors", "a", "b", "--distance", "1"],
            "simulate": ["simulate", "-o", "out.h5"],
            "export": ["export", "data.h5", "--trc", "out.trc"],
            "orient": ["orient", "imu.h5"],
            "twin": ["twin", "trial.hdf5"],
            "report": ["report", "data.h5"],
            "sweep": ["sweep", "study.toml"],
            "examples": ["examples", "first-steps"],
        }.get(command, [command])
    )
    assert args.command == command
    run = command_function(args.func)  # a command may name its run ("module:function"), loaded now
    assert callable(run) and run.__name__ == f"cmd_{command}"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "the following arguments are required: COMMAND"),
        (["bogus"], "invalid choice: 'bogus'"),
        (["scale", "poses.csv", "--sensors", "a", "b"], "the following arguments are required: --distance"),
        (["examples"], "the following arguments are required: DIR"),
        (["baseline", "--tolerance", "x"], "argument --tolerance: expected a number, got 'x'"),
    ],
)
def test_usage_errors_exit_2(capsys, argv, message):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: simbench") and message in err


@pytest.mark.parametrize("command", ["orient", "calibrate"])
def test_an_unknown_method_is_refused_before_reading(capsys, command):
    """--method takes any estimator spec: one that names nothing is refused, naming the built-ins,
    before the (missing) input is read."""
    assert main([command, "missing.h5", "--method", "kalman"]) == 2
    err = capsys.readouterr().err
    assert "unknown estimator 'kalman': expected one of" in err and "missing.h5" not in err


def test_missing_input_is_an_error_not_a_traceback(capsys, tmp_path):
    code = main(["orient", str(tmp_path / "missing.h5")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("simbench: error:") and "Traceback" not in err
