"""``simbench calibrate``: the table, the calibration JSON, and clear errors on bad input."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from simbench.cli import main
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.sim.synthetic import Slip, linkage, simulate_motion

HEADER = "time,sensor,x,y,z,qw,qx,qy,qz\n"


@pytest.fixture(scope="module")
def linkage_csv(tmp_path_factory, linkage_noisy_module):
    cap = linkage_noisy_module
    path = tmp_path_factory.mktemp("csv") / "linkage.csv"
    rec = PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones(cap.p_w_s.shape[:2], bool))
    write_pose_csv(path, rec)
    return path


@pytest.fixture(scope="module")
def linkage_noisy_module():
    return simulate_motion(
        linkage(), n_frames=1200, rate_hz=120.0, rng=np.random.default_rng(31), position_noise_m=0.002
    )


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_calibrate_prints_table_and_writes_json(capsys, tmp_path, linkage_csv, linkage_noisy_module):
    out_json = tmp_path / "cal.json"
    code, out, err = run(capsys, "calibrate", str(linkage_csv), "--json", str(out_json))
    assert code == 0, err
    assert "hierarchy: inferred, root chest" in out
    for joint in ("chest -> head", "chest -> upper_arm_l", "upper_arm_l -> forearm_l"):
        assert joint in out
    assert "limb lengths (cm)" in out and "sensor offsets (cm)" in out
    doc = json.loads(out_json.read_text())
    assert doc["units"] == "m" and doc["root"] == "chest"
    truth = linkage_noisy_module.skeleton
    assert {j["child"]: j["parent"] for j in doc["joints"]} == truth.parent_of
    exact = truth.joint_in_sensor_frames()
    for j in doc["joints"]:
        assert set(j) >= {
            "parent",
            "child",
            "joint_in_parent",
            "joint_in_child",
            "rms_residual",
            "single_axis",
            "axis_in_parent",
            "axis_in_child",
        }
        # 2 mm noise, 1200 frames: joints within a few mm of the truth
        assert np.linalg.norm(np.array(j["joint_in_parent"]) - exact[j["child"]][0]) < 0.005
        assert 0.001 < j["rms_residual"] < 0.01
        assert j["single_axis"] is False and j["axis_in_parent"] is None
    lengths = {(x["segment"], x["joint_a"], x["joint_b"]): x["length"] for x in doc["limb_lengths"]}
    for key, value in truth.segment_lengths().items():
        assert lengths[key] == pytest.approx(value, abs=0.005)
    assert doc["software"]["numpy"] == np.__version__
    assert doc["input"]["frames"] == 1200
    assert not list(tmp_path.glob(".*.tmp"))  # the atomic write left nothing behind


def test_units_and_given_hierarchy(capsys, tmp_path, linkage_noisy_module):
    cap = linkage_noisy_module
    rec = PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones(cap.p_w_s.shape[:2], bool))
    csv_cm = tmp_path / "cm.csv"
    write_pose_csv(csv_cm, rec, units="cm")
    hier = tmp_path / "h.json"
    hier.write_text(json.dumps(cap.skeleton.parent_of))
    out_json = tmp_path / "cal.json"
    code, _out, err = run(
        capsys,
        "calibrate",
        str(csv_cm),
        "--units",
        "cm",
        "--hierarchy",
        str(hier),
        "--root",
        "chest",
        "--json",
        str(out_json),
    )
    assert code == 0, err
    doc = json.loads(out_json.read_text())
    assert doc["hierarchy"] == "given"
    arm = next(x for x in doc["limb_lengths"] if x["segment"] == "upper_arm_r")
    assert arm["length"] == pytest.approx(0.286, abs=0.005)  # metres, although the file was in cm


def test_nan_rows_dropped_per_pair_and_reported(capsys, tmp_path, linkage_noisy_module):
    cap = linkage_noisy_module
    p = cap.p_w_s.copy()
    p[100:110, 1] = np.nan
    rec = PoseRecording(cap.names, cap.time_s, cap.R_w_s, p, np.ones(p.shape[:2], bool))
    path = tmp_path / "nan.csv"
    write_pose_csv(path, rec)
    code, out, err = run(capsys, "calibrate", str(path))
    assert code == 0, err
    assert "sensor head: 10 row(s) with NaN or inf values" in out
    assert "joint chest-head: 10 of 1200 frames dropped" in out


def csv_file(tmp_path, text, name="bad.csv"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def hierarchy_file(tmp_path, text):
    path = tmp_path / "h.json"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize(
    ("make_args", "message"),
    [
        (lambda t, c: [str(t / "missing.csv")], "cannot read"),
        (lambda t, c: [csv_file(t, "")], "the file is empty"),
        (lambda t, c: [csv_file(t, "time,sensor,x\n0,a,1\n")], "missing columns"),
        (
            lambda t, c: [csv_file(t, HEADER + "".join(f"{k},a,0,0,0,1,0,0,0\n" for k in range(5)))],
            "at least 2 sensors",
        ),
        (
            lambda t, c: [
                csv_file(
                    t, HEADER + "0,a,0,0,0,1,0,0,0\n0,b,1,0,0,1,0,0,0\n1,a,0,0,0,1,0,0,0\n1,b,1,0,0,1,0,0,0\n"
                )
            ],
            "at least 3 frames",
        ),
        (lambda t, c: [csv_file(t, HEADER + "0,a,0,0,0,1,0,0,0\n0,a,0,0,0,1,0,0,0\n")], "appears twice"),
        (lambda t, c: [csv_file(t, "x", name="poses.trc")], "poses.trc: not a TRC file"),
        (lambda t, c: [csv_file(t, "x", name="poses.xyz")], "unknown pose file type '.xyz'"),
        (
            lambda t, c: [str(c), "--hierarchy", hierarchy_file(t, '{"head": "neck"}')],
            "h.json: sensor\\(s\\) \\['neck'\\] are not in",
        ),
        (lambda t, c: [str(c), "--hierarchy", hierarchy_file(t, "{oops")], "line 1: not valid JSON"),
        (lambda t, c: [str(c), "--hierarchy", hierarchy_file(t, '["a"]')], "expected a JSON object"),
        (
            lambda t, c: [str(c), "--hierarchy", hierarchy_file(t, '{"head": "chest", "head": "x"}')],
            "parent twice",
        ),
        (lambda t, c: [str(c), "--root", "nobody"], "--root: no sensor 'nobody' in"),
        (lambda t, c: [str(c), "--json", str(t / "no" / "such" / "dir.json")], "does not exist"),
        (lambda t, c: [str(c), "--json", str(t)], "--json .*: that is a folder; give the file to write"),
    ],
)
def test_bad_input_exits_2_with_message(capsys, tmp_path, linkage_csv, make_args, message):
    code, _out, err = run(capsys, "calibrate", *make_args(tmp_path, linkage_csv))
    assert code == 2
    assert err.startswith("simbench: error:")
    assert "Traceback" not in err
    assert re.search(message, err), err


def test_an_output_that_cannot_be_written_is_refused_before_any_work(capsys, tmp_path, monkeypatch):
    import simbench.cli.orient as orient_cli

    def never(*args, **kwargs):
        raise AssertionError("the input was read before the output was checked")

    monkeypatch.setattr(orient_cli, "read_imu", never)
    for argv, message in (
        (["orient", "x.hdf5", "--csv", str(tmp_path)], "--csv .*: that is a folder"),
        (["orient", "x.hdf5", "--csv", str(tmp_path / "no" / "q.csv")], "--csv .*: folder .* does not exist"),
        (["simulate", "-o", str(tmp_path)], "--output .*: that is a folder"),
    ):
        code, _out, err = run(capsys, *argv)
        assert code == 2 and re.search(message, err), err


def test_unknown_units_rejected_by_parser(capsys, linkage_csv):
    with pytest.raises(SystemExit) as info:
        main(["calibrate", str(linkage_csv), "--units", "ft"])
    assert info.value.code == 2
    assert "invalid choice: 'ft'" in capsys.readouterr().err


def test_console_entry_point_runs(linkage_csv):
    done = subprocess.run(
        [sys.executable, "-m", "simbench", "calibrate", str(linkage_csv), "--no-slip"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "chest -> head" in done.stdout


def test_scale_command(capsys, tmp_path):
    rng = np.random.default_rng(4)
    n = 2000
    a = rng.normal(size=(n, 3))
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    b = a + 0.565 * u
    factor = 0.94
    p = np.stack([a, b], axis=1) / factor  # the system reports lengths divided by the factor
    R = np.tile(np.eye(3), (n, 2, 1, 1))
    path = tmp_path / "rigid.csv"
    write_pose_csv(
        path, PoseRecording(("s1", "s2"), np.arange(n) / 100.0, R, p, np.ones((n, 2), bool)), units="cm"
    )
    code, out, err = run(
        capsys, "scale", str(path), "--sensors", "s1", "s2", "--distance", "56.5", "--units", "cm"
    )
    assert code == 0, err
    assert "scale factor        0.9400" in out
    assert "note: the distance" not in out  # a fixed distance: no doubt cast on the mount
    code, _, err = run(capsys, "scale", str(path), "--sensors", "s1", "s9", "--distance", "56.5")
    assert code == 2 and "no sensor named ['s9']" in err
    with pytest.raises(SystemExit) as info:  # refused by the parser, naming the option
        main(["scale", str(path), "--sensors", "s1", "s2", "--distance", "-1"])
    assert info.value.code == 2 and "argument --distance: expected a number > 0" in capsys.readouterr().err


def test_scale_says_when_the_distance_is_not_fixed(capsys, tmp_path):
    """Two sensors whose distance drifts by +-2 cm (a loose mount) under 0.5 mm noise: the note
    says so; with the noise alone it stays silent; a factor far below 1 keeps its digits."""
    rng = np.random.default_rng(5)
    n = 2000
    t = np.arange(n) / 100.0
    a = rng.normal(size=(n, 3))
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    R = np.tile(np.eye(3), (n, 2, 1, 1))
    for drift, expect in ((0.02, True), (0.0, False)):
        b = a + (0.3 + drift * np.sin(2 * np.pi * 0.2 * t))[:, None] * u + rng.normal(0, 0.0005, (n, 3))
        path = tmp_path / f"pair{drift}.csv"
        write_pose_csv(
            path, PoseRecording(("s1", "s2"), t, R, np.stack([a, b], axis=1), np.ones((n, 2), bool))
        )
        code, out, err = run(capsys, "scale", str(path), "--sensors", "s1", "s2", "--distance", "0.3")
        assert code == 0, err
        assert ("note: the distance between the two sensors varies" in out) == expect
    code, out, _ = run(capsys, "scale", str(path), "--sensors", "s1", "s2", "--distance", "0.000245")
    factor = next(x for x in out.splitlines() if "scale factor" in x).split()[2]
    assert len(factor.lstrip("0.")) == 4 and abs(float(factor) / (0.000245 / 0.3) - 1) < 1e-3  # 4 digits


def test_slip_reported_in_table_and_json(capsys, tmp_path):
    cap = simulate_motion(
        linkage(),
        n_frames=2400,
        rate_hz=120.0,
        rng=np.random.default_rng(41),
        position_noise_m=0.002,
        slips=[Slip("forearm_r", 1500, (0.0, 0.04, 0.0))],
    )
    path = tmp_path / "slip.csv"
    write_pose_csv(path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones((2400, 6), bool)))
    out_json = tmp_path / "cal.json"
    code, out, err = run(capsys, "calibrate", str(path), "--json", str(out_json))
    assert code == 0, err
    assert re.search(
        r"upper_arm_r-forearm_r: at 12\.[45]\d\d s, jump (3[89]|4[01])\.\d mm \(steady in the child", out
    )
    slips = {s["joint"]: s for s in json.loads(out_json.read_text())["slip"]}
    events = slips["upper_arm_r-forearm_r"]["events"]
    assert len(events) == 1 and abs(events[0]["frame"] - 1500) <= 12
    assert all(not s["events"] for name, s in slips.items() if name != "upper_arm_r-forearm_r")


def test_recording_that_never_moves_is_refused(capsys, tmp_path, linkage_noisy_module):
    """Every frame the same: no joint centre can come from it, so no numbers are reported."""
    cap = linkage_noisy_module
    n = 300
    R, p = np.repeat(cap.R_w_s[:1], n, axis=0), np.repeat(cap.p_w_s[:1], n, axis=0)
    rec = PoseRecording(cap.names, cap.time_s[:n], R, p, np.ones(p.shape[:2], bool))
    path = tmp_path / "still.csv"
    write_pose_csv(path, rec)
    code, out, err = run(capsys, "calibrate", str(path), "--no-slip")
    assert code == 2 and out == ""
    assert "still.csv: no joint centre is determined" in err
    assert len(re.findall(r"\w+-\w+: 3 of 6, rotation range 0\.0, 0\.0, 0\.0 deg", err)) == len(cap.names) - 1
    # the report of the same file, as calibrate: refused, nothing written
    code, out, err = run(capsys, "report", str(path), "--out", str(tmp_path / "rep"))
    assert code == 2 and "still.csv: no joint centre is determined" in err
    assert not (tmp_path / "rep" / "index.md").exists()


def test_joint_that_never_turns_has_no_numbers_in_the_table(capsys, tmp_path, linkage_noisy_module):
    """The head held fixed on the chest: that joint is not located, the others are reported."""
    cap = linkage_noisy_module
    head, chest = cap.names.index("head"), cap.names.index("chest")
    R, p = cap.R_w_s.copy(), cap.p_w_s.copy()
    R[:, head] = R[:, chest] @ (R[0, chest].T @ R[0, head])
    p[:, head] = p[:, chest] + np.einsum("fij,j->fi", R[:, chest], R[0, chest].T @ (p[0, head] - p[0, chest]))
    rec = PoseRecording(cap.names, cap.time_s, R, p, np.ones(p.shape[:2], bool))
    path = tmp_path / "stiff.csv"
    write_pose_csv(path, rec)
    hier = tmp_path / "h.json"
    hier.write_text(json.dumps(cap.skeleton.parent_of))
    code, out, err = run(capsys, "calibrate", str(path), "--hierarchy", str(hier), "--no-slip")
    assert code == 0, err
    row = next(line for line in out.splitlines() if "chest -> head" in line)
    assert row.split()[-2] == "none"
    offsets = [
        line
        for line in out.splitlines()
        if line.strip().startswith(("head ", "chest ")) and "chest-head" in line
    ]
    assert offsets and all("not located" in line for line in offsets)
    assert "chest-upper_arm_l" in out and "not located" not in next(
        line
        for line in out.splitlines()
        if "chest-upper_arm_l" in line and line.strip().startswith("upper_arm_l")
    )


def test_report_warns_of_limb_lengths_a_unit_off(tmp_path, capsys, linkage_noisy_module):
    cap = linkage_noisy_module
    path = tmp_path / "in_mm.csv"
    rec = PoseRecording(
        cap.names, cap.time_s, cap.R_w_s, cap.p_w_s * 1000, np.ones(cap.p_w_s.shape[:2], bool)
    )
    write_pose_csv(path, rec)  # millimetres, read as metres
    code, _out, err = run(capsys, "report", str(path), "--out", str(tmp_path / "rep"))
    assert code == 0, err
    text = (tmp_path / "rep" / "index.md").read_text()
    assert "## Warnings" in text and "limb length(s) outside 1 mm - 10 m" in text and "(--units)?" in text
    code, _out, err = run(capsys, "report", str(path), "--units", "mm", "--out", str(tmp_path / "ok"))
    assert code == 0, err
    assert "limb length(s) outside" not in (tmp_path / "ok" / "index.md").read_text()
