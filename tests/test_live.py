"""The live loop end to end: a simulated capture emitted at capture rate (simbench.sim.live),
``simbench replay`` and ``simbench calibrate --follow`` (simbench.cli.live, simbench.experiments.live)."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import calibrate
from calibration.streaming import StreamingCalibrator
from simbench.cli import main
from simbench.cli.live import follow_csv, parse_speed
from simbench.errors import InputError
from simbench.io.dataset import write_dataset
from simbench.io.follow import CsvFollower, first_seen
from simbench.io.poses import CSV_COLUMNS, PoseRecording, write_pose_csv
from simbench.io.read import read_poses
from simbench.sim.live import live_blocks, with_slip
from simbench.sim.plan import SessionConfig, load_session_model
from simbench.sim.session import run_session
from simbench.sim.synthetic import random_tree, simulate_motion

SLIP_SENSOR, SLIP_S = "upper_arm_r", 16.61


def _session(slip: bool):
    sensors = "polhemus-liberty"
    if slip:
        sensors = with_slip(sensors, SLIP_SENSOR, SLIP_S, (0.0, 0.02, 0.0))
    config = SessionConfig(model="humanoid", motion="exercise", duration_s=30.0, seed=0, sensors=sensors)
    return run_session(config, load_session_model(config))


def _alerts(text: str) -> list[tuple[float, str, float, float]]:
    """``(raised s, sensor, slip s, size cm)`` of every ALERT line."""
    pattern = r"ALERT at ([\d.]+) s: sensor (\S+) may have slipped at ([\d.]+) s, size ([\d.]+) cm"
    return [(float(a), s, float(b), float(c)) for a, s, b, c in re.findall(pattern, text)]


def test_replay_raises_the_slip_alert_within_half_a_second_and_no_other(tmp_path, capsys):
    # a 2 cm slip of the right upper arm's sensor at 16.61 s of a 30 s humanoid exercise session,
    # Polhemus Liberty noise and latency
    path = tmp_path / "slip.h5"
    ds = _session(slip=True)
    write_dataset(path, ds)
    t0 = float(ds.time_s[0])
    assert main(["replay", str(path), "--rate", "max", "--refresh", "100"]) == 0
    out = capsys.readouterr().out
    alerts = _alerts(out)
    assert len(alerts) == 1, out
    raised, sensor, at, size_cm = alerts[0]
    assert sensor == SLIP_SENSOR
    assert 0.0 <= raised - t0 - SLIP_S <= 0.5  # raised within 0.5 s of the slip
    assert abs(at - t0 - SLIP_S) < 0.05  # and placed within 50 ms of it
    assert 1.5 < size_cm < 2.5  # a 2 cm slip, measured over a few tenths of a second
    assert "simbench final" in out and "slip alerts: 1" in out
    # the same session without the slip: no alert at all
    clean = tmp_path / "clean.h5"
    write_dataset(clean, _session(slip=False))
    assert main(["replay", str(clean), "--rate", "max", "--refresh", "100"]) == 0
    out = capsys.readouterr().out
    assert _alerts(out) == [] and "slip alerts: 0" in out


def test_live_blocks_pace_frames_at_the_capture_rate():
    n = 240
    t = np.arange(n) / 120.0
    rec = PoseRecording(
        names=("a", "b"),
        time_s=t,
        R_w_s=np.tile(np.eye(3), (n, 2, 1, 1)),
        p_w_s=np.zeros((n, 2, 3)),
        valid=np.ones((n, 2), dtype=bool),
    )
    now = [0.0]
    waits = []

    def sleep(s):
        waits.append(s)
        now[0] += s

    blocks = list(live_blocks(rec, block_frames=7, speed=10.0, clock=lambda: now[0], sleep=sleep))
    assert [b.start for b in blocks] == list(range(0, n, 7))
    assert np.array_equal(np.concatenate([b.time_s for b in blocks]), t)
    # the last block is due when its last frame would have been captured, at ten times real time
    assert now[0] == pytest.approx(t[-1] / 10.0, rel=1e-12)
    assert all(w > 0 for w in waits)
    assert sum(1 for _ in live_blocks(rec, block_frames=50, speed=None, sleep=sleep)) == 5
    with pytest.raises(InputError, match="block_frames"):
        next(live_blocks(rec, block_frames=0))
    assert parse_speed("10x") == 10.0 and parse_speed("max") is None and parse_speed("1x") == 1.0
    with pytest.raises(InputError, match="1x, 10x or max"):
        parse_speed("fast")


WRITER = textwrap.dedent(
    """
    import sys, time
    src, dst = sys.argv[1], sys.argv[2]
    lines = open(src).read().splitlines(keepends=True)
    with open(dst, "w") as fh:
        fh.write(lines[0]); fh.flush()
        body = "".join(lines[1:])
        step = 9000  # characters a write: rows are cut in the middle, as a logger's buffer does
        for k in range(0, len(body), step):
            fh.write(body[k : k + step]); fh.flush()
            time.sleep(0.02)
    """
)


class _UntilWriterDone:
    """A follower's clock that runs as the wall clock until the writer has exited and the follower
    has had time to read the finished file (it asks the clock once per frame, so counting calls
    would cut a backlog short on a loaded machine), then jumps past any timeout: the follow ends
    when the file is complete instead of waiting out its bound."""

    #: wall seconds after the writer's exit before the jump: the backlog of 1,200 frames takes
    #: about 0.3 s at 4,000 frames/s
    GRACE_S = 2.0

    def __init__(self, writer: subprocess.Popen) -> None:
        self.writer = writer
        self.exited_at: float | None = None

    def __call__(self) -> float:
        now = time.monotonic()
        if self.exited_at is None and self.writer.poll() is not None:
            self.exited_at = now
        done = self.exited_at is not None and now - self.exited_at > self.GRACE_S
        return now + (1e6 if done else 0.0)


def test_follow_reads_a_file_another_process_is_appending(tmp_path):
    skeleton = random_tree(5, np.random.default_rng(2))
    cap = simulate_motion(
        skeleton, n_frames=1200, rate_hz=120.0, rng=np.random.default_rng(3), position_noise_m=0.002
    )
    rec = PoseRecording(
        names=skeleton.names,
        time_s=np.arange(1200) / 120.0,
        R_w_s=cap.R_w_s,
        p_w_s=cap.p_w_s,
        valid=np.ones((1200, 5), dtype=bool),
    )
    whole = tmp_path / "whole.csv"
    write_pose_csv(whole, rec)
    growing = tmp_path / "growing.csv"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(whole), str(growing)])
    lines: list[str] = []
    try:
        # bounded: the writer needs about 1 s; the follower stops once it has read the finished
        # file, and after 8 s whatever happens
        clock = _UntilWriterDone(writer)
        cal = follow_csv(growing, timeout_s=8.0, refresh_s=2.0, out=lines.append, clock=clock)
    finally:
        writer.wait(timeout=30)
    assert writer.returncode == 0
    assert cal is not None and cal.n_frames == 1200
    assert any(line.startswith("simbench live") for line in lines)  # tables while it grew
    assert lines[-1].startswith("simbench final")
    # the same answer as the batch calibration of the finished file
    batch = calibrate(*(getattr(read_poses(whole), k) for k in ("R_w_s", "p_w_s", "names")))
    live = cal.calibration()
    assert live.parent_of == batch.parent_of
    for b, s in zip(batch.joints, live.joints, strict=True):
        # both read the same decimal text into the same quaternions and rotations
        assert_allclose(s.fit.joint_in_parent, b.fit.joint_in_parent, atol=1e-9)
        assert_allclose(s.fit.joint_in_child, b.fit.joint_in_child, atol=1e-9)


def test_calibrate_follow_on_the_command_line(tmp_path, capsys):
    skeleton = random_tree(3, np.random.default_rng(4))
    cap = simulate_motion(skeleton, n_frames=300, rate_hz=100.0, rng=np.random.default_rng(5))
    rec = PoseRecording(
        names=skeleton.names,
        time_s=np.arange(300) / 100.0,
        R_w_s=cap.R_w_s,
        p_w_s=1e3 * cap.p_w_s,  # the file in mm
        valid=np.ones((300, 3), dtype=bool),
    )
    path = tmp_path / "poses.csv"
    write_pose_csv(path, rec)
    code = main(["calibrate", str(path), "--follow", "--timeout", "0.5", "--units", "mm", "--rate-hz", "100"])
    out = capsys.readouterr().out
    assert code == 0
    assert "simbench final" in out and "frames: 300" in out
    assert main(["calibrate", str(path), "--follow", "--json", str(tmp_path / "x.json")]) == 2
    assert "--follow calibrates a pose CSV live; it does not take --json" in capsys.readouterr().err
    bad = tmp_path / "bad.csv"
    bad.write_text("t,sensor,x\n")
    assert main(["calibrate", str(bad), "--follow", "--timeout", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "bad.csv, line 1: missing columns ['time', 'y', 'z', 'qw', 'qx', 'qy', 'qz']" in err


def _follow_all(path):
    follower = CsvFollower(path, 1.0)
    try:
        frames = [*follower.frames(), *follower.flush()]
        follower.set_names(first_seen(frames))
        return [follower.arrays(f) for f in frames]
    finally:
        follower.close()


def test_follow_refuses_what_the_batch_reader_refuses_and_names_the_line(tmp_path):
    good = "0,{s},1,2,3,1,0,0,0"
    path = tmp_path / "p.csv"
    # extra columns are ignored, in any order; a row of NaN is a missing pose
    path.write_text(
        "sensor,extra,time,x,y,z,qw,qx,qy,qz\n"
        "a,9,0,1,2,3,1,0,0,0\nb,9,0,4,5,6,1,0,0,0\n"
        "a,9,0.01,1,2,3,1,0,0,0\nb,9,0.01,nan,nan,nan,nan,nan,nan,nan\n"
    )
    frames = _follow_all(path)
    assert [f[0] for f in frames] == [0.0, 0.01]
    assert_allclose(frames[0][2], [[1, 2, 3], [4, 5, 6]])
    assert frames[1][3].tolist() == [True, False]  # valid
    cal = StreamingCalibrator(["a", "b"], rate_hz=100.0, slip=False)
    cal.push(*frames[0][1:])
    cal.push(*frames[1][1:])  # the NaN pose reaches the calibrator as missing
    assert cal.statistics().count[0, 1] == 1  # frames where both poses are valid
    header = ",".join(CSV_COLUMNS)
    cases = {
        "time is not finite": [good.format(s="a"), "inf,b,1,2,3,1,0,0,0"],
        "time 0.01 s is earlier than the row before \\(0.02 s\\)": [
            "0.02,a,1,2,3,1,0,0,0",
            "0.01,b,1,2,3,1,0,0,0",
        ],
        "empty sensor name": [good.format(s="a"), "0, ,1,2,3,1,0,0,0"],
        "zero quaternion": [good.format(s="a"), "0,b,1,2,3,0,0,0,0"],
        "sensor 'a' appears twice at time 0.0 \\(also on line 2\\)": [good.format(s="a"), good.format(s="a")],
        "expected 9 fields, got 8": [good.format(s="a"), "0,b,1,2,3,1,0,0"],
        "column 'y' is not a number: 'two'": [good.format(s="a"), "0,b,1,two,3,1,0,0,0"],
    }
    for message, rows in cases.items():
        path.write_text("\n".join([header, *rows]) + "\n")
        with pytest.raises(InputError, match=rf"p\.csv, line 3: {message}"):
            _follow_all(path)


def test_replay_that_never_calibrates_exits_2_saying_why(tmp_path, capsys):
    n = 300
    R = np.tile(np.eye(3), (n, 3, 1, 1))
    p = np.zeros((n, 3, 3))
    p[:, 1:, 0] = [0.3, 0.6]
    valid = np.ones((n, 3), dtype=bool)
    valid[2:, 2] = False  # the third sensor seen in 2 frames only: never a pair to fit it with
    path = tmp_path / "blind.csv"
    write_pose_csv(path, PoseRecording(("a", "b", "c"), np.arange(n) / 100.0, R, p, valid))
    assert main(["replay", str(path), "--rate", "max", "--refresh", "1"]) == 2
    captured = capsys.readouterr()
    assert "waiting" in captured.out  # while frames came in
    assert "no calibration from its" in captured.err and "simbench final" not in captured.out
