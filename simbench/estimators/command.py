"""External commands as estimators, in any language: ``cmd:COMMAND ARGS...`` with placeholders.

The command line is split as a POSIX shell would (``shlex``; no shell runs it) and each
placeholder in it is replaced by the path of a file in a temporary working folder, which is the
command's working directory and is removed afterwards, whatever happens:

- joint centres: ``{poses}`` a pose CSV in metres (``time,sensor,x,y,z,qw,qx,qy,qz``, the README's
  format), ``{hierarchy}`` a JSON ``{child: parent}`` (the command then needs one: the true tree
  where a scenario scores on it), ``{out}`` where the command writes a calibration JSON
  (``joints`` with ``parent``, ``child``, ``joint_in_parent``, ``joint_in_child``; ``units``);
- orientation: ``{imu}`` the raw readings as the IMU CSV (:mod:`simbench.io.imu_csv`), ``{out}``
  where the command writes ``time,sensor,qw,qx,qy,qz`` (scalar-first ``R_w_s`` in ENU, one row per
  sample and sensor; a missing row is a sample not estimated).

A file the command line names from the caller's working directory (``python3 fit.py``,
``./fit``) is given to it by its full path.

A command that exits non-zero, runs past its time limit (it and its children are killed), writes
nothing, or writes a file that cannot be read raises :class:`EstimatorError` naming the command
and what went wrong, with the end of its standard error.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from simbench.errors import InputError
from simbench.estimators.catalog import TIME_LIMIT_S as TIME_LIMIT_S  # a command's, per call
from simbench.estimators.registry import Estimator, JointsResult, OrientationResult, Param
from simbench.io.atomic import outside_output_set
from simbench.io.calibration_json import read_calibration_json
from simbench.io.imu import ImuRecording
from simbench.io.imu_csv import write_imu_csv
from simbench.io.orientation_csv import read_orientation_csv
from simbench.io.poses import PoseRecording, write_pose_csv

PREFIX = "cmd:"

#: The placeholders of each kind and the file each stands for.
PLACEHOLDERS = {
    "joints": {"poses": "poses.csv", "hierarchy": "hierarchy.json", "out": "calibration.json"},
    "orientation": {"imu": "imu.csv", "out": "orientation.csv"},
}

#: How much of a failed command's standard error a message quotes, characters.
STDERR_TAIL = 600


class EstimatorError(InputError):
    """An estimator (a user's function or command) failed or gave an unusable result; the message
    names the estimator and what went wrong. Scoring harnesses record it as a failure and go on."""


def _placeholders(argv: list[str]) -> set[str]:
    return {m for a in argv for m in re.findall(r"\{([A-Za-z_]\w*)\}", a)}


def command_estimator(spec: str, kind: str | None = None) -> Estimator:
    """The estimator of ``cmd:COMMAND ...`` (module docstring).

    Args:
        spec: ``cmd:`` then the command line.
        kind: the kind expected; ``None``: the placeholders tell.

    Raises:
        InputError: no command, unbalanced quotes, an unknown placeholder, no ``{out}``, or
            placeholders of the wrong kind.
    """
    line = spec[len(PREFIX) :].strip()
    try:
        argv = shlex.split(line)
    except ValueError as exc:
        raise InputError(f"{spec!r}: cannot split the command line: {exc}") from None
    if not argv:
        raise InputError(f"{spec!r}: no command after {PREFIX!r}")
    used = _placeholders(argv)
    known = {p for table in PLACEHOLDERS.values() for p in table}
    if used - known:
        raise InputError(
            f"{spec!r}: unknown placeholder(s) {sorted('{' + u + '}' for u in used - known)}; a joints "
            "command takes {poses}, {hierarchy}, {out}; an orientation command {imu}, {out}"
        )
    own = "joints" if used & {"poses", "hierarchy"} else "orientation" if "imu" in used else kind
    if own is None:
        raise InputError(
            f"{spec!r}: cannot tell what it estimates: give {{poses}} (joint centres) "
            "or {imu} (orientation)"
        )
    if kind is not None and own != kind:
        raise InputError(f"{spec!r}: its placeholders are those of an estimator of {own}, not {kind}")
    allowed = PLACEHOLDERS[own]
    unknown = sorted(used - allowed.keys())
    if unknown:
        raise InputError(
            f"{spec!r}: unknown placeholder(s) {['{' + u + '}' for u in unknown]}; a {own} command takes "
            f"{['{' + a + '}' for a in allowed]}"
        )
    data = "poses" if own == "joints" else "imu"
    if "out" not in used or data not in used:
        raise InputError(
            f"{spec!r}: a {own} command needs {{{data}}} and {{out}} (where it writes its result)"
        )
    needs = {"hierarchy"} if "hierarchy" in used else set()
    time_limit = Param("time_limit_s", TIME_LIMIT_S, unit="s", help="the command's time limit per call")

    if own == "joints":

        def run_joints(
            poses: PoseRecording,
            *,
            hierarchy: Mapping[str, str] | None = None,
            time_limit_s: float = TIME_LIMIT_S,
        ) -> JointsResult | dict[str, Any]:
            with tempfile.TemporaryDirectory(prefix="simbench-cmd-") as tmp:
                paths = {k: Path(tmp) / v for k, v in allowed.items()}
                with outside_output_set():  # the program's inputs, read before the command ends
                    write_pose_csv(paths["poses"], poses, units="m")
                if "hierarchy" in used:
                    paths["hierarchy"].write_text(json.dumps(dict(hierarchy or {}), indent=2) + "\n")
                _run(spec, argv, paths, tmp, time_limit_s)
                try:
                    return read_calibration_json(paths["out"])
                except InputError as exc:
                    raise EstimatorError(f"{spec!r} wrote an unusable {{out}}: {exc}") from None

        fn: Any = run_joints
    else:

        def run_orientation(imu: ImuRecording, *, time_limit_s: float = TIME_LIMIT_S) -> OrientationResult:
            with tempfile.TemporaryDirectory(prefix="simbench-cmd-") as tmp:
                paths = {k: Path(tmp) / v for k, v in allowed.items()}
                with outside_output_set():  # the program's input, read before the command ends
                    write_imu_csv(paths["imu"], imu.names, imu.time_s, imu.acc, imu.gyro, imu.mag)
                _run(spec, argv, paths, tmp, time_limit_s)
                try:
                    q = read_orientation_csv(paths["out"], imu.names, imu.time_s)
                except InputError as exc:
                    raise EstimatorError(f"{spec!r} wrote an unusable {{out}}: {exc}") from None
                ok = (q == q).all(axis=-1)
                return OrientationResult(q, ok)

        fn = run_orientation
    return Estimator(
        spec,
        own,
        fn,
        (time_limit,),
        frozenset(needs),
        summary=f"the external command {argv[0]}",
        origin="command",
        takes_hierarchy=own == "joints",
    )


def _run(spec: str, argv: list[str], paths: Mapping[str, Path], cwd: str, time_limit_s: float) -> None:
    """Run the command with its placeholders filled in; its own session, so that a timeout kills
    its children too.

    Raises:
        EstimatorError: not found, not executable, non-zero exit, past the time limit, no output.
    """
    args = []
    for k, a in enumerate(argv):
        for key, path in paths.items():
            a = a.replace("{" + key + "}", str(path))
        # the command runs in its temporary folder: a file named from the caller's folder
        # (python3 fit.py, ./fit) is given by its full path
        if a == argv[k] and not Path(a).is_absolute() and (k > 0 or "/" in a) and Path(a).exists():
            a = str(Path(a).resolve())
        args.append(a)
    try:
        proc = subprocess.Popen(
            args,
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )
    except OSError as exc:
        raise EstimatorError(f"{spec!r}: cannot run {args[0]!r}: {exc.strerror}") from None
    try:
        _, err = proc.communicate(timeout=time_limit_s)
    except subprocess.TimeoutExpired:
        _kill(proc)
        raise EstimatorError(
            f"{spec!r}: still running after its time limit of {time_limit_s:g} s; stopped"
        ) from None
    except BaseException:  # interrupted: the command and its children go too
        _kill(proc)
        raise
    tail = err.decode("utf-8", "replace").strip()[-STDERR_TAIL:]
    said = f"; its stderr ends: {' '.join(tail.split())}" if tail else ""
    if proc.returncode != 0:
        how = (
            f"was killed by signal {-proc.returncode}" if proc.returncode < 0 else f"exited {proc.returncode}"
        )
        raise EstimatorError(f"{spec!r} {how}{said}")
    if not paths["out"].is_file():
        raise EstimatorError(f"{spec!r} exited 0 but wrote nothing to {{out}}{said}")


def _kill(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.communicate()
