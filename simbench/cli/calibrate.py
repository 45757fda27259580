"""``simbench calibrate``: joints, hierarchy and skeleton from a pose file (O'Brien et al. 2000).

Its options; the command runs in :mod:`simbench.cli.calibrate_run` (:data:`RUN`), loaded when it
runs. Every name, default and choice the options list comes from a module that loads no numpy
(the estimator catalog, the core's defaults), so that ``simbench calibrate --help`` is a light
start (issue 44).
"""

from __future__ import annotations

import argparse

from calibration.defaults import FALSE_ALARMS_PER_HOUR, SLIP_WINDOW_S
from simbench.cli.types import positive_float
from simbench.estimators.catalog import DEFAULT_JOINTS, TIME_LIMIT_S, builtin, names
from simbench.experiments.live_defaults import RATE_FRAMES, REFRESH_S
from simbench.io.inputs import pose_inputs_text
from simbench.units import LENGTH_UNITS

#: The function that runs the command (``module:function``, :func:`simbench.cli.command_function`).
RUN = "simbench.cli.calibrate_run:cmd_calibrate"

#: ``--drop-noisy-frames``, as ``simbench calibrate`` and ``simbench report`` offer it.
DROP_NOISY_FRAMES_HELP = (
    "leave out each sensor's frames whose position noise (read off its own poses) drowns its "
    "others, where that makes the fit's expected error at least 2 times smaller: a magnetic "
    "tracker far from its transmitter; the warnings say how many"
)


def add_arguments(cal: argparse.ArgumentParser) -> None:
    """The arguments of ``simbench calibrate``; O'Brien's options take their
    defaults and choices from the estimator registry (``obrien``, ``obrien-robust``)."""
    obrien = builtin(DEFAULT_JOINTS)
    hierarchy_method = obrien.param("hierarchy_method")
    single_axis_ratio = obrien.param("single_axis_ratio").default
    losses = builtin("obrien-robust").param("robust").choices or ()
    cal.description = (
        "Estimate joint centres, body hierarchy, limb lengths and sensor placement from "
        "6-DoF sensor poses (O'Brien et al. 2000)."
    )
    cal.add_argument("input", help=f"the poses: {pose_inputs_text()}")
    cal.add_argument(
        "--method",
        default=DEFAULT_JOINTS,
        metavar="SPEC",
        help=f"the joints estimator: {', '.join(names('joints'))} (default {DEFAULT_JOINTS}); or "
        "your own: package.module:function, path/to/file.py:function, an installed plugin's name, or "
        "'cmd:COMMAND ... {poses} [{hierarchy}] {out}' (docs/estimators.md); the methods that fit a "
        "given tree need --hierarchy",
    )
    cal.add_argument(
        "--time-limit",
        type=positive_float,
        default=TIME_LIMIT_S,
        metavar="SECONDS",
        help=f"your estimator's time limit: a command's, or a Python function's (default {TIME_LIMIT_S:g} s)",
    )
    cal.add_argument(
        "--units",
        choices=sorted(LENGTH_UNITS),
        default=None,
        help="length unit of the positions (default: m for a CSV; a C3D file's own POINT:UNITS, a TRC "
        "file's Units, which a unit given here overrides, with a note)",
    )
    cal.add_argument("--hierarchy", metavar="FILE.json", help='known hierarchy {"child": "parent", ...}')
    cal.add_argument("--root", metavar="NAME", help="root sensor (default: the centre of the inferred tree)")
    cal.add_argument(
        "--hierarchy-method",
        choices=hierarchy_method.choices,
        default=hierarchy_method.default,
        help=(
            "how an inferred tree weighs each pair: misfit = the joint-fit residual less its "
            "measurement noise, mst = the residual itself, O'Brien et al.'s minimum spanning tree "
            f"(default {hierarchy_method.default})"
        ),
    )
    cal.add_argument(
        "--robust",
        choices=sorted(losses),
        default=None,
        help=(
            "fit joints (and an inferred hierarchy) by iteratively reweighted least squares with this "
            "loss, so that slip and distortion bursts lose their pull (default: least squares)"
        ),
    )
    cal.add_argument(
        "--intervals",
        action="store_true",
        help=(
            "95%% regions of every joint centre and 95%% intervals of limb lengths (batch means; with "
            "--robust, conditional on the inlier frames), in the table and the JSON"
        ),
    )
    cal.add_argument(
        "--correct-rotation-noise",
        action="store_true",
        help=(
            "correct the joints for the noise on the measured rotations, read off each sensor's own "
            "rotations (it biases least squares where a joint moved little); not with --robust"
        ),
    )
    cal.add_argument("--drop-noisy-frames", action="store_true", help=DROP_NOISY_FRAMES_HELP)
    cal.add_argument("--json", metavar="OUT", help="write the calibration JSON here")
    cal.add_argument(
        "--clusters",
        metavar="SPEC.toml",
        help="C3D or TRC input: marker clusters [clusters] segment = [labels] (default: found)",
    )
    cal.add_argument(
        "--wide",
        metavar="SPEC.toml",
        help="INPUT is a wide tracker export (a row per frame) laid out as SPEC says",
    )
    cal.add_argument(
        "--single-axis-ratio",
        type=positive_float,
        default=single_axis_ratio,
        metavar="R",
        help=(
            f"hard floor of s_min/s_max below which a direction is always undetermined (default "
            f"{single_axis_ratio:g}); above it the single-axis verdict is a statistical test "
            "(calibration.hinge)"
        ),
    )
    cal.add_argument(
        "--slip-window",
        type=positive_float,
        default=SLIP_WINDOW_S,
        metavar="SECONDS",
        help=f"slip detector window (default {SLIP_WINDOW_S:g} s)",
    )
    cal.add_argument(
        "--slip-false-alarms-per-hour",
        type=positive_float,
        default=FALSE_ALARMS_PER_HOUR,
        metavar="RATE",
        help=f"expected slip false alarms per hour of joint time (default {FALSE_ALARMS_PER_HOUR:g})",
    )
    cal.add_argument("--no-slip", action="store_true", help="skip slip detection")
    add_follow_arguments(cal)
    cal.set_defaults(func=RUN)


def add_follow_arguments(cal: argparse.ArgumentParser) -> None:
    """``--follow`` and its options on ``simbench calibrate``."""
    cal.add_argument(
        "--follow",
        action="store_true",
        help="INPUT is a pose CSV a logger is still writing: calibrate live as rows arrive "
        "(Ctrl-C or --timeout stops)",
    )
    cal.add_argument(
        "--timeout",
        type=positive_float,
        default=None,
        metavar="SECONDS",
        help="with --follow: stop after this many seconds of wall time (default: until Ctrl-C)",
    )
    cal.add_argument(
        "--rate-hz",
        type=positive_float,
        default=None,
        metavar="HZ",
        help=f"with --follow: the capture rate (default: from the first {RATE_FRAMES} frames' time stamps)",
    )
    cal.add_argument(
        "--refresh",
        type=positive_float,
        default=REFRESH_S,
        metavar="SECONDS",
        help=f"with --follow: seconds of capture between tables (default {REFRESH_S:g})",
    )
