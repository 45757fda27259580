"""Bad input at the command line (issue 14, first part): every case is one line on stderr naming
the file or option, exit status 2, no traceback and nothing written; Ctrl-C is exit 130."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from simbench import cli
from simbench.cli import main


def _files(tmp_path):
    (tmp_path / "latin1.csv").write_bytes(b"time,sensor,x\n\xe9t\xe9,1,2\n")
    (tmp_path / "binary.csv").write_bytes(bytes(range(256)) * 4)
    (tmp_path / "nul.csv").write_bytes(b"time,sensor\x00,x\n")
    (tmp_path / "axis.toml").write_text("[tracker]\ntransmitter_axis = [0, 0, 0]\n")
    (tmp_path / "sta.toml").write_text("[skin]\nsta_by_sensor = 5\n")
    (tmp_path / "play.toml").write_text("[joints]\nplay_m = -0.001\n")
    (tmp_path / "girdle.toml").write_text(
        '[[skin.girdle]]\njoint = "upper_arm_l"\npivot_m = [0, 0, 0]\naxis = [1, 0, 0]\n'
        "limb_axis = [0, 0, -1]\nratio = 2.0\n"
    )
    (tmp_path / "range.toml").write_text("[tracker]\nrange_exponent = nan\n")


CASES = [
    (["simulate", "--seed", "-1"], "--seed"),
    (["simulate", "--seed", "1.5"], "--seed"),
    (["simulate", "--duration", "nan"], "--duration"),
    (["simulate", "--duration", "-2"], "--duration"),
    (["simulate", "--rate", "0"], "--rate"),
    (["calibrate", "{tmp}/none.csv", "--slip-window", "nan"], "--slip-window"),
    (["calibrate", "{tmp}/none.csv", "--slip-window", "0"], "--slip-window"),
    (["calibrate", "{tmp}/none.csv", "--slip-window", "-5"], "--slip-window"),
    (["calibrate", "{tmp}/none.csv", "--slip-false-alarms-per-hour", "inf"], "--slip-false-alarms-per-hour"),
    (["calibrate", "{tmp}/none.csv", "--single-axis-ratio", "-1"], "--single-axis-ratio"),
    (["sweep", "{tmp}/none.toml", "--workers", "0"], "--workers"),
    (["scale", "{tmp}/none.csv", "--sensors", "a", "b", "--distance", "0"], "--distance"),
    (["orient", "{tmp}/none.h5", "--smooth-hz", "-1"], "--smooth-hz"),
    (["baseline", "--tolerance", "-0.1"], "--tolerance"),
    (["calibrate", "{tmp}/latin1.csv"], "latin1.csv"),
    (["calibrate", "{tmp}/binary.csv"], "binary.csv"),
    (["calibrate", "{tmp}/nul.csv"], "nul.csv"),
    (["simulate", "--duration", "1", "--sensors", "{tmp}/axis.toml", "--out", "{tmp}/o.h5"], "axis.toml"),
    (["simulate", "--duration", "1", "--sensors", "{tmp}/sta.toml", "--out", "{tmp}/o.h5"], "sta.toml"),
    (["simulate", "--duration", "1", "--sensors", "{tmp}/play.toml", "--out", "{tmp}/o.h5"], "play.toml"),
    (["simulate", "--duration", "1", "--sensors", "{tmp}/girdle.toml", "--out", "{tmp}/o.h5"], "girdle.toml"),
    (["simulate", "--duration", "1", "--sensors", "{tmp}/range.toml", "--out", "{tmp}/o.h5"], "range.toml"),
    (["simulate", "--duration", "1", "--sensors", "../../etc/passwd", "--out", "{tmp}/o.h5"], "etc/passwd"),
]


def _run(args: list[str]) -> int:
    try:
        return main(args)
    except SystemExit as exc:  # argparse refuses a bad option value itself
        return int(exc.code)


@pytest.mark.parametrize(("argv", "named"), CASES, ids=[" ".join(a) for a, _ in CASES])
def test_bad_input_is_one_line_naming_it_exit_2_nothing_written(capsys, tmp_path, argv, named):
    _files(tmp_path)
    before = set(tmp_path.iterdir())
    assert _run([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert not any("Traceback" in line for line in lines)
    errors = [line for line in lines if ": error: " in line]
    assert len(errors) == 1 and errors[0] == lines[-1], lines  # argparse prints its usage above
    assert named in errors[0], errors[0]
    assert set(tmp_path.iterdir()) == before


def test_ctrl_c_exits_130_without_a_traceback(capsys, monkeypatch):
    def interrupted(args):
        raise KeyboardInterrupt

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser, "baseline", interrupted))
    assert main(["baseline"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "simbench: interrupted"


def test_internal_errors_are_one_line_and_debug_shows_them(capsys, monkeypatch):
    def broken(args):
        raise RuntimeError("something\nunexpected")

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: _with_func(parser, "baseline", broken))
    assert main(["baseline"]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        err == "simbench: error: RuntimeError: something unexpected (an internal error; --debug shows where)"
    )
    with pytest.raises(RuntimeError, match="something"):
        main(["--debug", "baseline"])


def _with_func(parser, command, func):
    """The parser with ``command``'s function replaced."""
    cli.command_parser(parser, command).set_defaults(func=func)
    return parser


def test_a_diverging_simulation_writes_no_dataset(capsys, tmp_path):
    """dm_control's humanoid with its feet and arms left without sensors (so unactuated): the
    physics blows up; the error names the model, the time and the joint, and nothing is written."""
    pytest.importorskip("dm_control")
    out = tmp_path / "x.h5"
    sensors = "torso,lower_waist,pelvis,right_thigh,right_shin,left_thigh,left_shin"
    argv = [
        "simulate",
        "--model",
        "dm_control:humanoid",
        "--sensors-on",
        sensors,
        "--duration",
        "3",
        "-o",
        str(out),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("simbench: error: model dm_control:humanoid: the simulation diverged at t = ")
    assert "joint '" in err and "no dataset is written" in err and len(err.splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_stale_temporary_files_of_dead_writers_are_swept(tmp_path):
    """A writer killed outright leaves ``.NAME.<pid>.<random>.tmp``; the next write of NAME
    removes it when that process is gone, and leaves a running writer's and other names' alone."""
    from simbench.io.atomic import atomic_write_text

    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    pid = int(dead.stdout)
    stale = tmp_path / f".out.txt.{pid}.abc123.tmp"
    alive = tmp_path / f".out.txt.{os.getppid()}.def456.tmp"
    other = tmp_path / f".other.txt.{pid}.abc123.tmp"
    for p in (stale, alive, other):
        p.write_text("half")
    atomic_write_text(tmp_path / "out.txt", "whole")
    assert (tmp_path / "out.txt").read_text() == "whole"
    assert not stale.exists() and alive.exists() and other.exists()


def _wait_for_sigterm_handler(proc: subprocess.Popen, within_s: float = 30.0) -> None:
    """Wait until ``proc`` catches SIGTERM (the command line's handler, set once its imports are
    done): its ``SigCgt`` mask in ``/proc`` on Linux; elsewhere 4 s, the time the imports took."""
    status = f"/proc/{proc.pid}/status"
    if not os.path.exists(status):
        time.sleep(4)
        return
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline and proc.poll() is None:
        with open(status) as fh:
            caught = next((int(x.split()[1], 16) for x in fh if x.startswith("SigCgt:")), 0)
        if caught >> (signal.SIGTERM - 1) & 1:
            return
        time.sleep(0.02)
    raise AssertionError("the command never set its SIGTERM handler")


def test_sigterm_ends_with_143_and_no_traceback(tmp_path):
    """SIGTERM mid-run: exit 143, one line, nothing half-written."""
    out = tmp_path / "x.h5"
    cmd = [sys.executable, "-m", "simbench", "simulate", "--duration", "600", "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_sigterm_handler(proc)  # imported, in the command (loading the model, then physics)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "simbench: terminated" and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def linkage_recording():
    import numpy as np

    from simbench.io.poses import PoseRecording
    from simbench.sim.synthetic import linkage, simulate_motion

    cap = simulate_motion(
        linkage(), n_frames=600, rate_hz=120.0, rng=np.random.default_rng(1), position_noise_m=0.001
    )
    return PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones((600, 6), bool))


def test_a_coordinate_of_1e30_is_refused_naming_sensor_and_time(capsys, tmp_path, linkage_recording):
    from dataclasses import replace

    from simbench.io.poses import write_pose_csv

    p = linkage_recording.p_w_s.copy()
    p[100, 2, 0] = 1e30
    write_pose_csv(tmp_path / "far.csv", replace(linkage_recording, p_w_s=p))
    assert main(["calibrate", str(tmp_path / "far.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        err.startswith(f"simbench: error: {tmp_path / 'far.csv'}: sensor ")
        and "1e+30 m from the origin" in err
    )


def test_wrong_units_warn_about_implausible_limbs(capsys, tmp_path, linkage_recording):
    """Metres read as millimetres: the limbs come out a thousand times too short, and the table
    says so (a warning, not an error: the fit itself is fine)."""
    from simbench.io.poses import write_pose_csv

    write_pose_csv(tmp_path / "m.csv", linkage_recording)
    assert (
        main(["calibrate", str(tmp_path / "m.csv"), "--units", "mm", "--json", str(tmp_path / "c.json")]) == 0
    )
    out = capsys.readouterr().out
    assert "warning: 5 limb length(s) outside 1 mm - 10 m" in out and "really in mm (--units)?" in out
    assert "limb length(s) outside 1 mm - 10 m" in (tmp_path / "c.json").read_text()
    assert main(["calibrate", str(tmp_path / "m.csv")]) == 0
    assert "outside 1 mm - 10 m" not in capsys.readouterr().out


def test_a_recording_without_a_valid_pose_is_refused(linkage_recording):
    from dataclasses import replace

    import numpy as np

    from simbench.errors import InputError
    from simbench.io.read import check_plausible

    empty = replace(linkage_recording, valid=np.zeros_like(linkage_recording.valid))
    with pytest.raises(InputError, match=r"x\.csv: no valid pose in 600 frame\(s\) of 6 sensor\(s\)"):
        check_plausible(empty, "x.csv")


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    from simbench.io.dataset import write_dataset
    from simbench.sim.session import SessionConfig, run_session

    path = tmp_path_factory.mktemp("ds") / "ok.h5"
    write_dataset(path, run_session(SessionConfig(duration_s=1.0)))
    return path


def _drop_time(fh):
    n = fh["time_s"].shape[0]
    del fh["time_s"]
    fh["time_s"] = [b"a"] * n


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda fh: fh.__delitem__("measured"), "not a complete simbench dataset: missing /measured"),
        (lambda fh: fh["measured"].__delitem__("p_w_s"), "missing dataset(s) /measured/p_w_s"),
        (lambda fh: fh.attrs.__setitem__("meta", "{not json"), "the meta attribute is not JSON"),
        (lambda fh: fh.attrs.__setitem__("meta", "[1, 2]"), "the meta attribute is not a JSON object"),
        (_drop_time, "/time_s must be a 1-D array of numbers (seconds), got object"),
    ],
    ids=["no measured", "no positions", "meta not JSON", "meta a list", "time as strings"],
)
def test_a_damaged_dataset_is_named(capsys, tmp_path, small_dataset, damage, message):
    import shutil

    import h5py

    path = tmp_path / "damaged.h5"
    shutil.copy(small_dataset, path)
    with h5py.File(path, "a") as fh:
        damage(fh)
    assert main(["calibrate", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"simbench: error: {path}: ") and message in err and len(err.splitlines()) == 1


def test_implausibly_fine_time_steps_are_refused(capsys, tmp_path, linkage_recording):
    """Time stamps 1e-14 s apart (a counter, or another unit): refused, asking about seconds."""
    from dataclasses import replace

    from simbench.io.poses import write_pose_csv

    write_pose_csv(
        tmp_path / "fine.csv", replace(linkage_recording, time_s=linkage_recording.time_s * 1.2e-12)
    )
    assert main(["calibrate", str(tmp_path / "fine.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert "time steps of 1e-14 s" in err and "are the times in seconds?" in err
