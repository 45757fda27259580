"""``--help`` is generated from the code that defines what it lists, every command has a
description and examples, and every example parses (issue 44)."""

from __future__ import annotations

import contextlib
import io
import shlex

import pytest

from simbench.api import (
    BUILTIN_MODELS,
    BUILTIN_PROGRAMS,
    POSE_INPUTS,
    TWIN_EFFECTS,
    estimator_names,
    preset_names,
)
from simbench.cli import COMMANDS, build_parser
from simbench.cli.help_examples import EXAMPLES
from simbench.estimators import catalog
from simbench.estimators.registry import REGISTRY


def _help(monkeypatch, *argv: str) -> str:
    """The help text, unwrapped (a wide terminal: no name is broken at a hyphen)."""
    monkeypatch.setenv("COLUMNS", "2000")
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        build_parser().parse_args([*argv, "--help"])  # the command's options added as it is named
    return out.getvalue()


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_a_description_and_examples_that_parse(command, monkeypatch):
    text = _help(monkeypatch, command)
    parser = build_parser(COMMANDS)._subparsers._group_actions[0].choices[command]
    assert parser.description and len(parser.description) > 20, command
    assert "\nexamples:\n  simbench " + command in text
    assert EXAMPLES.get(command)
    for line in EXAMPLES[command]:
        argv = shlex.split(line.split("  #")[0])
        assert argv[:2] == ["simbench", command], line
        build_parser().parse_args(argv[1:])  # exits 2 on an option that does not exist


def test_every_option_has_help(monkeypatch):
    for command, parser in build_parser(COMMANDS)._subparsers._group_actions[0].choices.items():
        for action in parser._actions:
            if action.dest != "help":
                assert action.help, f"simbench {command} {'/'.join(action.option_strings) or action.dest}"


def test_every_preset_model_motion_and_method_is_listed(monkeypatch):
    simulate = _help(monkeypatch, "simulate")
    for name in (*preset_names(), *BUILTIN_MODELS, *BUILTIN_PROGRAMS):
        assert name in simulate, name
    calibrate = _help(monkeypatch, "calibrate")
    for name in estimator_names("joints"):
        assert name in calibrate, name
    for kind in POSE_INPUTS.values():
        assert kind in calibrate and kind in _help(monkeypatch, "report"), kind
    orient = _help(monkeypatch, "orient")
    for name in estimator_names("orientation"):
        assert name in orient, name
    twin = _help(monkeypatch, "twin")
    for name in TWIN_EFFECTS:
        assert name in twin, name


def test_the_catalog_is_the_registry():
    """The names, kinds and parameters ``--help`` reads from the catalog (no numpy) are those the
    registry holds, in its order: the registry is filled from the catalog, with the functions."""
    assert catalog.names(plugins=False) == tuple(REGISTRY)
    for entry in catalog.BUILTINS:
        est = REGISTRY[entry.name]
        assert (est.kind, est.needs, est.data, est.takes_skeleton) == (
            entry.kind,
            entry.needs,
            entry.data,
            entry.takes_skeleton,
        )
        if entry.params is not None:
            assert est.params == entry.params, entry.name
        assert est.summary and (not entry.summary or est.summary == entry.summary)
    for kind in catalog.KINDS:
        assert catalog.names(kind) == estimator_names(kind)
