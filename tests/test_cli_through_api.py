"""The command line goes through the public API (issue 40), and the API gives what it prints.

**The rule.** A module of ``simbench/cli`` imports, of simbench and calibration, only:

- ``simbench.api``: the one door to the layers below, so that whatever ``simbench`` does, a
  Python user does through ``sb.`` too (reading, slip reports, the calibration JSON, the live
  follower, the unit scale, the estimator registry's names are all there);
- the base: ``simbench.errors`` (with the core's ``CalibrationError``), ``simbench.versions``,
  ``simbench.units``;
- its own modules, ``simbench.cli.*``;
- the plain-Python modules of names and defaults that a command's options list (:data:`LISTS`:
  the estimator catalog, the core's defaults, the pose inputs, the live loop's defaults), which
  ``simbench.api`` exports too: read from there, ``--help`` would load the whole library (issue
  44's light start, ``tests/test_light_start.py``);
- and, in the commands that run experiments and write their reports (:data:`EXPERIMENT_COMMANDS`:
  validate, sweep, bench, baseline, report), ``simbench.experiments`` and ``simbench.report``.

Never ``calibration`` or ``simbench.io`` (any submodule), nor ``simbench.sim``,
``simbench.score``, ``simbench.orient`` or ``simbench.estimators``: those go through
``simbench.api``. Other packages (argparse, numpy, tqdm) are the modules' own business.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import simbench as sb
from simbench.cli import main
from simbench.cli.live import LivePrinter, follow_csv
from simbench.io.poses import PoseRecording
from simbench.sim.synthetic import Slip, linkage, random_tree, simulate_motion
from tests.test_import_boundary import imports

ROOT = Path(sb.__file__).resolve().parent.parent

#: What every module of the command line may import of simbench and calibration (a name allows
#: its submodules).
ALLOWED = ("simbench.api", "simbench.errors", "simbench.versions", "simbench.units", "simbench.cli")

#: The plain-Python modules of names and defaults a command's options may read (module docstring).
LISTS = (
    "calibration.defaults",
    "simbench.estimators.catalog",
    "simbench.io.inputs",
    "simbench.experiments.live_defaults",
)

#: The commands that run experiments and write their reports, and the layers they may use besides.
EXPERIMENT_COMMANDS = {"validate", "sweep", "bench", "baseline", "report"}
EXPERIMENT_LAYERS = ("simbench.experiments", "simbench.report")

CLI_MODULES = sorted(p for p in (ROOT / "simbench" / "cli").rglob("*.py") if "__pycache__" not in p.parts)


def door_violations(path: Path, root: Path = ROOT) -> list[str]:
    """``file:line: what`` of every import of ``path`` (a module of ``simbench/cli``) that breaks
    the rule of the module docstring."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    me = ".".join(parts)
    allowed = ALLOWED + LISTS + (EXPERIMENT_LAYERS if parts[-1] in EXPERIMENT_COMMANDS else ())
    problems = []
    for target, line, _ in imports(path):
        if target.split(".")[0] not in ("simbench", "calibration"):
            continue
        if any(target == a or target.startswith(a + ".") for a in allowed):
            continue
        problems.append(
            f"{path.relative_to(root)}:{line}: {me} imports {target}; the command line goes through "
            "simbench.api"
        )
    return problems


def test_the_cli_has_modules():
    assert {p.stem for p in CLI_MODULES} >= {"__init__", "calibrate", "live", "orient", "scale", "table"}


@pytest.mark.parametrize("path", CLI_MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_the_cli_imports_only_through_the_api(path):
    assert door_violations(path) == []


def test_checker_names_the_module_and_line_of_a_forbidden_import(tmp_path):
    probe = tmp_path / "simbench" / "cli" / "scale.py"
    probe.parent.mkdir(parents=True)
    probe.write_text(
        "import argparse\n"
        "from calibration.slip import SLIP_WINDOW_S\n"
        "import simbench.io.poses\n"
        "from simbench import io\n"
        "from simbench.api import read_poses\n"
        "from simbench.experiments.live import follow\n"
        "import calibration\n"
    )
    assert door_violations(probe, tmp_path) == [
        f"simbench/cli/scale.py:{line}: simbench.cli.scale imports {target}; the command line goes "
        "through simbench.api"
        for line, target in (
            (2, "calibration.slip"),
            (3, "simbench.io.poses"),
            (4, "simbench.io"),
            (6, "simbench.experiments.live"),
            (7, "calibration"),
        )
    ]
    # a command that runs experiments may use their layers, and no lower one
    sweep = probe.with_name("sweep.py")
    sweep.write_text("from simbench.experiments.sweep import run_study\nfrom simbench.io.atomic import x\n")
    assert door_violations(sweep, tmp_path) == [
        "simbench/cli/sweep.py:2: simbench.cli.sweep imports simbench.io.atomic; the command line goes "
        "through simbench.api"
    ]


# ------------------------------------------------------------------ the API gives what the CLI prints


@pytest.fixture(scope="module")
def slip_csv(tmp_path_factory) -> Path:
    """The linkage, 20 s at 120 Hz, 2 mm noise, the right forearm's sensor slipping 4 cm at frame
    1500 (12.5 s): the slip case of ``tests/test_cli.py``."""
    cap = simulate_motion(
        linkage(),
        n_frames=2400,
        rate_hz=120.0,
        rng=np.random.default_rng(41),
        position_noise_m=0.002,
        slips=[Slip("forearm_r", 1500, (0.0, 0.04, 0.0))],
    )
    path = tmp_path_factory.mktemp("slip") / "slip.csv"
    sb.write_pose_csv(
        path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones((2400, 6), bool))
    )
    return path


@pytest.mark.parametrize("window_s", [None, 1.5])
def test_slip_reports_are_what_calibrate_prints_and_writes(capsys, tmp_path, slip_csv, window_s):
    out_json = tmp_path / "cal.json"
    argv = ["calibrate", str(slip_csv), "--json", str(out_json)]
    argv += [] if window_s is None else ["--slip-window", str(window_s)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    rec = sb.read_poses(slip_csv)
    cal = sb.calibrate(rec)
    slips = sb.slip_reports(rec, cal) if window_s is None else sb.slip_reports(rec, cal, window_s=window_s)
    assert [name for name, _ in slips] == [j.name for j in cal.joints]
    events = [(name, ev) for name, rep in slips for ev in rep.events]
    assert [name for name, _ in events] == ["upper_arm_r-forearm_r"]  # the slip, and no false alarm
    assert abs(events[0][1].frame - 1500) <= 12
    assert slips[0][1].window == round((window_s or sb.SLIP_WINDOW_S) * 120)
    # the table's slip lines, one per event
    for name, ev in events:
        line = (
            f"{name}: at {rec.time_s[ev.frame]:.3f} s, jump {ev.jump * 1e3:.1f} mm (steady in the "
            f"{ev.sensor_frame} frame, z {ev.z:.3g})"
        )
        assert line in printed
    assert len(re.findall(r"jump [\d.]+ mm", printed)) == len(events)
    # the JSON's slip section, and the document of the API alike
    written = json.loads(out_json.read_text())
    assert written["slip"] == sb.calibration_document(cal, rec, slips=slips)["slip"]
    assert written["options"]["slip_window_s"] == (window_s or sb.SLIP_WINDOW_S)


def test_slip_reports_check_their_arguments(slip_csv):
    rec = sb.read_poses(slip_csv)
    cal = sb.calibrate(rec)
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(sb.InputError, match="window_s"):
            sb.slip_reports(rec, cal, window_s=bad)
    with pytest.raises(sb.InputError, match="false_alarms_per_hour"):
        sb.slip_reports(rec, cal, false_alarms_per_hour=0)
    ds = sb.read(slip_csv)  # a Dataset: its measured poses
    assert [n for n, _ in sb.slip_reports(ds, sb.calibrate(ds))] == [j.name for j in cal.joints]
    short = PoseRecording(rec.names, rec.time_s[:3], rec.R_w_s[:3], rec.p_w_s[:3], rec.valid[:3])
    assert sb.slip_reports(short, cal) == []  # too short for any window
    renamed = PoseRecording(tuple(n.upper() for n in rec.names), rec.time_s, rec.R_w_s, rec.p_w_s, rec.valid)
    with pytest.raises(sb.InputError, match="a calibration of another recording"):
        sb.slip_reports(renamed, cal)


def _pose_csv(path: Path) -> Path:
    """A random 5-sensor tree, 10 s at 120 Hz, 2 mm noise, as a pose CSV (``tests/test_live.py``)."""
    skeleton = random_tree(5, np.random.default_rng(2))
    cap = simulate_motion(
        skeleton, n_frames=1200, rate_hz=120.0, rng=np.random.default_rng(3), position_noise_m=0.002
    )
    rec = PoseRecording(
        skeleton.names, np.arange(1200) / 120.0, cap.R_w_s, cap.p_w_s, np.ones((1200, 5), bool)
    )
    sb.write_pose_csv(path, rec)
    return path


def _over_at_once():
    """A clock at which the follow's time is up as soon as it starts: it reads the file once (one
    piece of at most 1 MiB: the whole of these files) and calibrates what it read, whatever the
    machine's speed."""
    times = iter([0.0])
    return lambda: next(times, 1e9)


def test_follow_gives_the_live_states_the_cli_prints(tmp_path):
    path = _pose_csv(tmp_path / "poses.csv")
    updates = list(sb.follow(path, timeout_s=5.0, refresh_s=2.0, clock=_over_at_once()))
    kinds = [u.kind for u in updates]
    assert kinds[-1] == "final" and "alert" not in kinds and "stopped" not in kinds
    states = [u for u in updates if u.kind == "state"]
    # a state every 2 s of capture from the first frame: 2.0 + 64 frames' worth, then every 2 s
    assert len(states) == 4
    assert [u.state.time_s for u in states] == pytest.approx([2.0, 4.0, 6.0, 8.0], abs=1 / 120 + 1e-9)
    final = updates[-1]
    assert final.calibrator is not None and final.calibrator.n_frames == 1200
    assert final.state.n_frames == 1200
    # the final state is the batch calibration of the whole file
    batch = sb.calibrate(sb.read_poses(path))
    live = final.state.calibration
    assert live.parent_of == batch.parent_of
    for b, s in zip(batch.joints, live.joints, strict=True):
        assert_allclose(s.fit.joint_in_parent, b.fit.joint_in_parent, atol=1e-9)
    # the command's lines are these updates printed
    lines: list[str] = []
    cal = follow_csv(path, timeout_s=5.0, refresh_s=2.0, out=lines.append, clock=_over_at_once())
    assert cal is not None and cal.n_frames == 1200
    shown: list[str] = []
    printer = LivePrinter(str(path), out=shown.append)
    for u in updates:
        printer.show(u)
    assert lines == shown
    assert lines[-1].startswith("simbench final") and sum(x.startswith("simbench live") for x in lines) == 4


def test_follow_checks_its_options_and_a_bad_row_names_its_line(tmp_path):
    path = _pose_csv(tmp_path / "poses.csv")
    with pytest.raises(sb.InputError, match="refresh_s"):
        sb.follow(path, refresh_s=0)
    with pytest.raises(sb.InputError, match="root 'nobody' is not a sensor"):
        list(sb.follow(path, root="nobody", clock=_over_at_once(), timeout_s=1.0))
    bad = tmp_path / "bad.csv"
    bad.write_text("time,sensor,x,y,z,qw,qx,qy,qz\n0,a,1,2,3,1,0,0,0\n0,b,1,2,3,0,0,0,0\n")
    with pytest.raises(sb.InputError, match=r"bad\.csv, line 3: zero quaternion"):
        list(sb.follow(bad, clock=_over_at_once(), timeout_s=1.0))
    empty = tmp_path / "empty.csv"
    empty.write_text("time,sensor,x,y,z,qw,qx,qy,qz\n")
    assert list(sb.follow(empty, clock=_over_at_once(), timeout_s=1.0)) == []  # no frame: no final


def test_replay_raises_the_slip_alert_the_cli_prints(tmp_path, capsys):
    """40 s of the linkage at 120 Hz, the left forearm's sensor slipping 2 cm at 30 s (the
    README's live example), replayed as fast as it goes."""
    skeleton = linkage()
    cap = simulate_motion(
        skeleton,
        n_frames=4800,
        rate_hz=120.0,
        rng=np.random.default_rng(1),
        position_noise_m=0.002,
        slips=[Slip("forearm_l", 3600, (0.0, 0.02, 0.0))],
    )
    rec = PoseRecording(skeleton.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones((4800, 6), bool))
    updates = list(sb.replay(rec, speed=None, refresh_s=100.0))
    alerts = [u for u in updates if u.kind == "alert"]
    assert len(alerts) == 1 and alerts[0].alert.sensor == "forearm_l"
    assert 0.0 <= alerts[0].raised_s - 30.0 <= 0.5
    assert updates[-1].kind == "final" and len(updates[-1].state.alerts) == 1
    # the command prints the same alert, from the same frames in a file
    path = tmp_path / "slip.csv"
    sb.write_pose_csv(path, rec)
    assert main(["replay", str(path), "--rate", "max", "--refresh", "100"]) == 0
    out = capsys.readouterr().out
    printed = [line for line in out.splitlines() if line.startswith("ALERT")]
    a = alerts[0]
    assert printed == [f"ALERT at {a.raised_s:.2f} s: {a.alert.message} (joint {a.alert.joint})"]
    with pytest.raises(sb.InputError, match="too few frames to replay"):
        sb.replay(PoseRecording(rec.names, rec.time_s[:1], rec.R_w_s[:1], rec.p_w_s[:1], rec.valid[:1]))
