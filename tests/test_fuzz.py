"""The command line fuzzed (issue 14): a table of bad inputs run through every command that reads
them, and property-based mutations of valid files through the parsers.

Every table case must end with exit status 2, exactly one ``simbench: error:`` line (the last
line of stderr) naming the file (or option), no traceback, no "internal error", and nothing
written in the case's folder (the working directory, so that default outputs would land there
too) other than the inputs the case made. :mod:`tests.test_bad_inputs` holds the first cases of
the issue; these are on top of them. A case whose fix belongs to a module being rewritten by
others is marked ``xfail(strict=True)`` with the fix it needs: it fails loudly once fixed.

The property-based tests mutate valid files (bytes inserted and deleted, fields replaced with
random text, numbers, huge, negative and non-finite values, lines dropped, duplicated and
swapped) and require each parser to return a valid object or raise an
:class:`~simbench.errors.InputError` naming the file, never any other exception. They run the
same examples every time; ``SIMBENCH_FUZZ_EXAMPLES=5000`` hunts longer, with fresh examples.
"""

from __future__ import annotations

import functools
import gzip
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simbench.cli import main
from simbench.errors import InputError

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
REAL_C3D = SHARED_DATA / "biobuddy_right_hip.c3d"

# ---------------------------------------------------------------------------------------------
# Valid inputs, made once: every bad input is one of these damaged.
# ---------------------------------------------------------------------------------------------

WIDE_SPEC = """[wide]
time = "Time"
units = "cm"
orientation = "quaternion"
repeated = "keep"
"""

STUDY = """name = "fuzz"
seed = 1
seeds_per_cell = 1
estimators = ["calibration"]
metrics = ["joint_centre_error_m", "limb_length_error_m"]

[base]
model = "linkage"
motion = "exercise"
sensors = "ideal"
duration_s = 2.0
rate_hz = 60.0

[sampling]
kind = "grid"

[[parameter]]
name = "sensors.tracker.position_noise_m"
unit = "mm"
values = [0.0, 1.0]
"""

RANDOM_STUDY = STUDY.replace('kind = "grid"', 'kind = "random"\nsamples = 3').replace(
    "values = [0.0, 1.0]", "low = 0.5\nhigh = 2.0\nlog = true"
)

SENSORS = """name = "fuzz-rig"
description = "every section"
[tracker]
position_noise_m = 0.002
orientation_noise_rad = 0.004
transmitter_pos = [0.0, 0.0, 0.5]
transmitter_axis = [0.0, 0.0, 1.0]
latency_s = 0.01
dropout_rate = 0.01
unit_scale = 1.0
[[tracker.distortion]]
center = [1.0, 0.5, 0.0]
radius_m = 0.3
position_gain_m = 0.02
[imu]
accel_noise_density = 0.0006
gyro_bias = 0.001
accel_range = 160.0
[magnetic]
strength_ut = 50.0
inclination_deg = 60.0
[[magnetic.disturbance]]
position = [0.5, 0.0, 1.0]
moment_am2 = [0.0, 0.0, 2.0]
[[magnetic.attached]]
sensor = "forearm_l"
start_s = 0.2
stop_s = 0.8
field_ut = [10.0, 0.0, 5.0]
ramp_s = 0.1
[skin]
sta_amplitude_m = 0.002
sta_by_sensor = { head = 0.003 }
laxity_by_joint = { forearm_l = 0.002 }
[[skin.slip]]
sensor = "forearm_l"
time_s = 0.5
offset_m = [0.0, 0.01, 0.0]
[skin.pack]
sensor = "chest"
pushed_by = "head"
flexion_axis = [0.0, -1.0, 0.0]
threshold_rad = 0.5
gain_m_per_rad = 0.05
direction = [0.0, 0.0, 1.0]
[[skin.girdle]]
joint = "upper_arm_l"
pivot_m = [0.0, -0.15, 0.0]
axis = [1.0, 0.0, 0.0]
limb_axis = [-1.0, 0.0, 0.0]
ratio = 0.3
[joints]
play_m = 0.0005
"""

PROGRAM = """name = "fuzz"
root = "carry"
[[phase]]
start_s = 0.0
end_s = 1.0
[phase.joints.neck]
amplitude_rad = [0.3, 0.2, 0.1]
frequency_hz = [0.5, 0.7, 0.9]
"""

MJCF_ONE_BODY = """<mujoco model="one">
  <worldbody>
    <body name="only" pos="0 0 1"><freejoint/><geom size="0.05"/></body>
  </worldbody>
</mujoco>
"""


def _markers(rec):
    """Four markers rigidly on each sensor of a recording: labels and ``(F, M, 3)`` positions."""
    offsets = np.array([[0.04, 0, 0], [0, 0.04, 0], [0, 0, 0.04], [0.03, 0.03, 0.0]])
    labels, xyz = [], []
    for k, name in enumerate(rec.names):
        for i, o in enumerate(offsets):
            labels.append(f"{name}_{i}")
            xyz.append(rec.p_w_s[:, k] + rec.R_w_s[:, k] @ o)
    return labels, np.stack(xyz, axis=1)


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    """A folder of valid inputs: a pose CSV, a dataset, a C3D file and its cluster spec, a wide
    export and its spec, a study, a sensor configuration, a motion program, a hierarchy JSON and
    a calibration JSON."""
    import json

    from simbench.io.c3d import write_c3d_markers
    from simbench.io.dataset import truth_calibration_dict, write_dataset
    from simbench.io.poses import PoseRecording, write_pose_csv
    from simbench.io.wide_csv import read_wide_spec, write_wide_csv
    from simbench.sim.session import SessionConfig, run_session
    from simbench.sim.synthetic import linkage, simulate_motion

    folder = tmp_path_factory.mktemp("base")
    cap = simulate_motion(
        linkage(), n_frames=360, rate_hz=120.0, rng=np.random.default_rng(3), position_noise_m=0.001
    )
    rec = PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones((360, 6), bool))
    write_pose_csv(folder / "good.csv", rec, digits=8)
    ds = run_session(SessionConfig(duration_s=1.0))
    write_dataset(folder / "good.h5", ds)
    (folder / "cal.json").write_text(json.dumps(truth_calibration_dict(ds), indent=2))
    (folder / "hier.json").write_text(
        json.dumps(
            {
                "head": "chest",
                "upper_arm_l": "chest",
                "forearm_l": "upper_arm_l",
                "upper_arm_r": "chest",
                "forearm_r": "upper_arm_r",
            }
        )
    )
    labels, xyz = _markers(rec)
    write_c3d_markers(folder / "good.c3d", labels, xyz, 120.0)
    (folder / "clusters.toml").write_text(
        "[clusters]\n" + "".join(f'{n} = ["{n}_0", "{n}_1", "{n}_2", "{n}_3"]\n' for n in rec.names)
    )
    spec = WIDE_SPEC + "".join(
        f'[wide.sensors.{n}]\nposition = ["{n}_X", "{n}_Y", "{n}_Z"]\n'
        f'quaternion = ["{n}_W", "{n}_QX", "{n}_QY", "{n}_QZ"]\n'
        for n in rec.names
    )
    (folder / "wide.toml").write_text(spec)
    write_wide_csv(folder / "wide.csv", rec, read_wide_spec(folder / "wide.toml"))
    (folder / "study.toml").write_text(STUDY)
    (folder / "sensors.toml").write_text(SENSORS)
    (folder / "program.toml").write_text(PROGRAM)
    return folder


# ---------------------------------------------------------------------------------------------
# Makers: how a case's input files come about.
# ---------------------------------------------------------------------------------------------

Maker = Callable[[Path, Path], None]  # (base folder, destination) -> None


def raw(content: str | bytes) -> Maker:
    def make(base: Path, dest: Path) -> None:
        if isinstance(content, bytes):
            dest.write_bytes(content)
        else:
            dest.write_text(content, encoding="utf-8")

    return make


def edited(name: str, edit: Callable[[str], str | bytes]) -> Maker:
    """A base file's text changed by ``edit``."""

    def make(base: Path, dest: Path) -> None:
        raw(edit((base / name).read_text(encoding="utf-8")))(base, dest)

    return make


def lines(edit: Callable[[list[str]], list[str]], end: str = "\n") -> Callable[[str], str]:
    return lambda text: end.join(edit(text.splitlines())) + end


def cell(row: int, col: int, value: str) -> Callable[[str], str]:
    """Line ``row`` (0 = the header), field ``col`` set to ``value``."""

    def edit(rows: list[str]) -> list[str]:
        fields = rows[row].split(",")
        fields[col] = value
        return [*rows[:row], ",".join(fields), *rows[row + 1 :]]

    return lines(edit)


def column(col: int, value: str) -> Callable[[str], str]:
    """Field ``col`` of every data row set to ``value``."""
    return lines(lambda rows: [rows[0]] + [",".join(_set(r.split(","), col, value)) for r in rows[1:]])


def _set(fields: list[str], col: int, value: str) -> list[str]:
    fields[col] = value
    return fields


def cut(name: str, fraction: float) -> Maker:
    """A base file cut to ``fraction`` of its bytes."""

    def make(base: Path, dest: Path) -> None:
        data = (base / name).read_bytes()
        dest.write_bytes(data[: int(len(data) * fraction)])

    return make


def directory(base: Path, dest: Path) -> None:
    dest.mkdir()


def dangling(base: Path, dest: Path) -> None:
    dest.symlink_to(dest.with_name("nowhere"))


def loop(base: Path, dest: Path) -> None:
    dest.symlink_to(dest.name)


def h5(damage: Callable) -> Maker:
    """The base dataset with ``damage(h5py.File)`` done to it."""

    def make(base: Path, dest: Path) -> None:
        import h5py

        shutil.copy(base / "good.h5", dest)
        with h5py.File(dest, "a") as fh:
            damage(fh)

    return make


def c3d_markers(edit: Callable[[list[str], np.ndarray], tuple[list[str], np.ndarray]]) -> Maker:
    """A C3D file of the base markers changed by ``edit(labels, xyz)``."""

    def make(base: Path, dest: Path) -> None:
        from simbench.io.c3d import read_c3d_markers, write_c3d_markers

        labels, xyz, rate = read_c3d_markers(base / "good.c3d")
        labels, xyz = edit(labels, xyz)
        write_c3d_markers(dest, labels, xyz, rate)

    return make


def replaced(name: str, old: str, new: str) -> Maker:
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)

    return edited(name, edit)


# ---------------------------------------------------------------------------------------------
# The table.
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """A bad input: its files, the command line and what the error must name.

    ``argv`` and ``named`` may hold ``{tmp}`` (the case's folder) and ``{base}`` (the valid
    inputs).
    """

    id: str
    argv: tuple[str, ...]
    named: str
    files: dict[str, Maker] = field(default_factory=dict)
    xfail: str | None = None


HEADER = "time,sensor,x,y,z,qw,qx,qy,qz"

#: Damaged pose CSVs: (id, maker, xfail); each is run through calibrate, scale and report.
POSE_CSV: list[tuple[str, Maker, str | None]] = [
    ("empty", raw(b""), None),
    ("blank lines only", raw("\n  \n\t\n"), None),
    ("header only", raw(HEADER + "\n"), None),
    ("header and blank lines", raw(HEADER + "\n\n,,,\n"), None),
    ("column qz missing", edited("good.csv", lines(lambda r: [x.rsplit(",", 1)[0] for x in r])), None),
    ("header capitalised", edited("good.csv", cell(0, 0, "Time")), None),
    (
        "column x repeated",
        edited("good.csv", lines(lambda r: [r[0] + ",x"] + [x + ",0" for x in r[1:]])),
        None,
    ),
    ("semicolon separated", edited("good.csv", lambda t: t.replace(",", ";")), None),
    (
        "a row one field short",
        edited("good.csv", lines(lambda r: [*r[:5], r[5].rsplit(",", 1)[0], *r[6:]])),
        None,
    ),
    ("a row one field long", edited("good.csv", lines(lambda r: [*r[:5], r[5] + ",1", *r[6:]])), None),
    ("x not a number", edited("good.csv", cell(7, 2, "abc")), None),
    ("decimal comma in a quoted field", edited("good.csv", cell(7, 3, '"0,5"')), None),
    ("time a clock reading", edited("good.csv", cell(3, 0, "12:00:01")), None),
    ("time empty", edited("good.csv", cell(3, 0, "")), None),
    ("time inf", edited("good.csv", cell(9, 0, "inf")), None),
    ("time nan", edited("good.csv", cell(9, 0, "nan")), None),
    ("time -inf", edited("good.csv", cell(9, 0, "-inf")), None),
    ("a sensor row repeated", edited("good.csv", lines(lambda r: [*r[:10], r[9], *r[10:]])), None),
    (
        "the rows appended again (time restarts)",
        edited("good.csv", lambda t: t + "".join(t.splitlines(True)[1:])),
        None,
    ),
    (
        "a second header in the middle",
        edited("good.csv", lambda t: t + HEADER + "\n" + t.splitlines(True)[1]),
        None,
    ),
    (
        "zero quaternion",
        edited(
            "good.csv",
            lines(lambda r: [*r[:12], ",".join([*r[12].split(",")[:5], "0", "0", "0", "0"]), *r[13:]]),
        ),
        None,
    ),
    (
        "every quaternion nan",
        edited(
            "good.csv", lines(lambda r: [r[0]] + [",".join(x.split(",")[:5] + ["nan"] * 4) for x in r[1:]])
        ),
        None,
    ),
    ("every position nan", edited("good.csv", column(2, "nan")), None),
    ("empty sensor name", edited("good.csv", cell(4, 1, " ")), None),
    ("one frame only", edited("good.csv", lines(lambda r: r[:7])), None),
    (
        "times 1e-12 of seconds",
        edited(
            "good.csv",
            lines(
                lambda r: (
                    [r[0]]
                    + [",".join([repr(float(x.split(",")[0]) * 1e-12), *x.split(",")[1:]]) for x in r[1:]]
                )
            ),
        ),
        None,
    ),
    ("a coordinate of 1e30", edited("good.csv", cell(20, 3, "1e30")), None),
    ("a coordinate of -1e30", edited("good.csv", cell(30, 4, "-1e30")), None),
    ("every x 1e300", edited("good.csv", column(2, "1e300")), None),
    ("two BOMs", edited("good.csv", lambda t: ("\ufeff\ufeff" + t).encode()), None),
    (
        "BOM then Latin-1",
        edited("good.csv", lambda t: b"\xef\xbb\xbf" + t.replace("chest", "ch\xe9st").encode("latin-1")),
        None,
    ),
    ("UTF-16", edited("good.csv", lambda t: t.encode("utf-16")), None),
    ("CRLF with a bad row", edited("good.csv", lambda t: cell(8, 2, "x1")(t).replace("\n", "\r\n")), None),
    (
        "CR line endings with a short row",
        edited("good.csv", lambda t: lines(lambda r: [*r[:6], "0.1,chest", *r[6:]])(t).replace("\n", "\r")),
        None,
    ),
    (
        "Latin-1 sensor name",
        edited("good.csv", lambda t: t.replace("head", "t\xeate").encode("latin-1")),
        None,
    ),
    ("gzip-compressed", edited("good.csv", lambda t: gzip.compress(t.encode())), None),
    ("random bytes", raw(np.random.default_rng(5).integers(0, 256, 3000, dtype=np.uint8).tobytes()), None),
    ("a NUL byte in a row", edited("good.csv", lambda t: t.replace("head", "he\0ad", 1)), None),
    ("a field of 200 kB", edited("good.csv", cell(5, 1, "s" * 200_000)), None),
    ("an unclosed quote", edited("good.csv", cell(40, 1, '"chest')), None),
]

POSE_PATHS: list[tuple[str, str, Maker | None]] = [
    ("a directory named .csv", "{tmp}/dir.csv", directory),
    ("no such file", "{tmp}/missing.csv", None),
    ("a path through a file", "{tmp}/file.csv/x.csv", raw("x")),
    ("a dangling symlink", "{tmp}/link.csv", dangling),
    ("a symlink loop", "{tmp}/loop.csv", loop),
    ("a name too long", "{tmp}/" + "n" * 300 + ".csv", None),
    ("an unknown suffix", "{tmp}/poses.dat", edited("good.csv", lambda t: t)),
    ("no suffix", "{tmp}/poses", edited("good.csv", lambda t: t)),
]


def _pose_cases() -> list[Case]:
    out = []
    commands = {
        "calibrate": ("calibrate", "{path}"),
        "scale": ("scale", "{path}", "--sensors", "chest", "head", "--distance", "0.3"),
        "report": ("report", "{path}"),
    }
    for cmd, argv in commands.items():
        for name, maker, xfail in POSE_CSV:
            if xfail and xfail.split(":", 1)[0] in commands:  # a failure of one command only
                xfail = xfail.split(":", 1)[1] if xfail.startswith(f"{cmd}:") else None
            out.append(
                Case(
                    f"{cmd}: pose CSV: {name}",
                    tuple(a.replace("{path}", "{tmp}/in.csv") for a in argv),
                    "{tmp}/in.csv",
                    {"in.csv": maker},
                    xfail,
                )
            )
        for name, path, maker in POSE_PATHS:
            files = {} if maker is None else {path.split("/", 1)[1].split("/")[0]: maker}
            named = path if "file.csv/" not in path else "{tmp}/file.csv/x.csv"
            if "n" * 300 in path:
                named = "nnnn.csv"
            out.append(Case(f"{cmd}: {name}", tuple(a.replace("{path}", path) for a in argv), named, files))
    return out


def _sensor_spec(n: str) -> str:
    return (
        f'[wide.sensors.{n}]\nposition = ["{n}_X", "{n}_Y", "{n}_Z"]\n'
        f'quaternion = ["{n}_W", "{n}_QX", "{n}_QY", "{n}_QZ"]\n'
    )


def _euler_sensor(n: str) -> str:
    return (
        f'[wide.sensors.{n}]\nposition = ["{n}_X", "{n}_Y", "{n}_Z"]\neuler = ["{n}_A", "{n}_B", "{n}_C"]\n'
    )


TWO = _sensor_spec("chest") + _sensor_spec("head")

#: Damaged wide-export specs: (id, spec text or maker).
WIDE_SPECS: list[tuple[str, Maker]] = [
    ("not TOML", raw("[wide\ntime = 'Time'\n")),
    ("Latin-1", raw("[wide]\ntime = '\xe9'\n".encode("latin-1"))),
    ("binary", raw(bytes(range(256)))),
    ("no [wide] table", raw("time = 'Time'\n")),
    ("wide a number", raw("wide = 5\n")),
    ("an unknown key", raw(WIDE_SPEC + "rate = 120\n" + TWO)),
    ("orientation matrix", raw(WIDE_SPEC.replace('"quaternion"', '"matrix"') + TWO)),
    ("no time and no rate", raw(WIDE_SPEC.replace('time = "Time"\n', "") + TWO)),
    ("rate_hz = 0", raw(WIDE_SPEC.replace('time = "Time"\n', "rate_hz = 0\n") + TWO)),
    ("rate_hz = -120", raw(WIDE_SPEC.replace('time = "Time"\n', "rate_hz = -120\n") + TWO)),
    ("rate_hz = nan", raw(WIDE_SPEC.replace('time = "Time"\n', "rate_hz = nan\n") + TWO)),
    ("rate_hz = inf", raw(WIDE_SPEC.replace('time = "Time"\n', "rate_hz = inf\n") + TWO)),
    ("rate_hz a string", raw(WIDE_SPEC.replace('time = "Time"\n', 'rate_hz = "120"\n') + TWO)),
    ("rate_hz = true", raw(WIDE_SPEC.replace('time = "Time"\n', "rate_hz = true\n") + TWO)),
    ("time and rate_hz both", raw(WIDE_SPEC + "rate_hz = 120\n" + TWO)),
    ("time a number", raw(WIDE_SPEC.replace('"Time"', "5") + TWO)),
    ("angle_units grad", raw(WIDE_SPEC + 'angle_units = "grad"\n' + TWO)),
    ("repeated yes", raw(WIDE_SPEC.replace('"keep"', '"yes"') + TWO)),
    ("units furlong", raw(WIDE_SPEC.replace('"cm"', '"furlong"') + TWO)),
    ("units a number", raw(WIDE_SPEC.replace('"cm"', "100") + TWO)),
    ("no sensors", raw(WIDE_SPEC)),
    ("sensors a number", raw(WIDE_SPEC + "sensors = 5\n")),
    ("a sensor a number", raw(WIDE_SPEC + "sensors = { chest = 5 }\n")),
    ("position two columns", raw(WIDE_SPEC + TWO.replace('"chest_X", ', "", 1))),
    ("position numbers", raw(WIDE_SPEC + TWO.replace('["chest_X", "chest_Y", "chest_Z"]', "[1, 2, 3]"))),
    (
        "quaternion missing",
        raw(WIDE_SPEC + TWO.replace('quaternion = ["head_W", "head_QX", "head_QY", "head_QZ"]\n', "")),
    ),
    ("an euler key under quaternion", raw(WIDE_SPEC + TWO + 'euler = ["a", "b", "c"]\n')),
    (
        "euler sequence XYZW",
        raw(
            WIDE_SPEC.replace('"quaternion"', '"euler"')
            + 'euler = "XYZW"\n'
            + "".join(_euler_sensor(n) for n in ("chest", "head"))
        ),
    ),
    (
        "euler sequence a number",
        raw(
            WIDE_SPEC.replace('"quaternion"', '"euler"')
            + "euler = 5\n"
            + "".join(_euler_sensor(n) for n in ("chest", "head"))
        ),
    ),
    ("a column in two places", raw(WIDE_SPEC + TWO.replace('"head_X"', '"chest_X"'))),
]

#: Damaged wide exports with the valid spec.
WIDE_CSVS: list[tuple[str, Maker, str | None]] = [
    ("empty", raw(""), None),
    ("header only", edited("wide.csv", lambda t: t.splitlines(True)[0]), None),
    ("a column missing", edited("wide.csv", lambda t: t.replace("head_QZ", "head_Q")), None),
    (
        "a row one field short",
        edited("wide.csv", lines(lambda r: [*r[:4], r[4].rsplit(",", 1)[0], *r[5:]])),
        None,
    ),
    ("not a number", edited("wide.csv", cell(6, 3, "abc")), None),
    ("times decreasing", edited("wide.csv", cell(6, 0, "-1.0")), None),
    ("a time repeated", edited("wide.csv", lines(lambda r: [*r[:6], r[5], *r[7:]])), None),
    ("a time nan", edited("wide.csv", cell(6, 0, "nan")), None),
    (
        "zero quaternion",
        edited(
            "wide.csv",
            lines(
                lambda r: [*r[:9], ",".join(r[9].split(",")[:4] + ["0"] * 4 + r[9].split(",")[8:]), *r[10:]]
            ),
        ),
        None,
    ),
    ("a coordinate of 1e30", edited("wide.csv", cell(9, 2, "1e30")), None),
    (
        "every value nan",
        edited(
            "wide.csv",
            lines(
                lambda r: (
                    [r[0]] + [",".join([x.split(",")[0]] + ["nan"] * (len(x.split(",")) - 1)) for x in r[1:]]
                )
            ),
        ),
        None,
    ),
    ("Latin-1", edited("wide.csv", lambda t: (t + "0,\xe9\n").encode("latin-1")), None),
    ("a field of 200 kB", edited("wide.csv", cell(5, 1, "1" * 200_000)), None),
    (
        "times 1e-12 of seconds",
        edited(
            "wide.csv",
            lines(
                lambda r: (
                    [r[0]]
                    + [",".join([repr(float(x.split(",")[0]) * 1e-12), *x.split(",")[1:]]) for x in r[1:]]
                )
            ),
        ),
        None,
    ),
    ("a directory", directory, None),
]


def _wide_cases() -> list[Case]:
    out = []
    for cmd in ("calibrate", "report"):
        for name, maker in WIDE_SPECS:
            out.append(
                Case(
                    f"{cmd}: wide spec: {name}",
                    (cmd, "{base}/wide.csv", "--wide", "{tmp}/spec.toml"),
                    "{tmp}/spec.toml",
                    {"spec.toml": maker},
                )
            )
        for name, maker, xfail in WIDE_CSVS:
            out.append(
                Case(
                    f"{cmd}: wide export: {name}",
                    (cmd, "{tmp}/wide.csv", "--wide", "{base}/wide.toml"),
                    "{tmp}/wide.csv",
                    {"wide.csv": maker},
                    xfail,
                )
            )
        out.append(
            Case(
                f"{cmd}: wide spec: no such file",
                (cmd, "{base}/wide.csv", "--wide", "{tmp}/no.toml"),
                "{tmp}/no.toml",
            )
        )
        out.append(
            Case(
                f"{cmd}: wide spec: a directory",
                (cmd, "{base}/wide.csv", "--wide", "{tmp}/d.toml"),
                "{tmp}/d.toml",
                {"d.toml": directory},
            )
        )
    return out


def c3d_bytes(edit: Callable[[bytes], bytes]) -> Maker:
    def make(base: Path, dest: Path) -> None:
        dest.write_bytes(edit((base / "good.c3d").read_bytes()))

    return make


C3D_FILES: list[tuple[str, Maker]] = [
    ("cut in half", cut("good.c3d", 0.5)),
    ("cut to 90 percent", cut("good.c3d", 0.9)),
    ("cut inside the header", c3d_bytes(lambda b: b[:300])),
    ("cut inside the parameters", c3d_bytes(lambda b: b[:700])),
    ("empty", raw(b"")),
    ("random bytes", raw(np.random.default_rng(7).integers(0, 256, 4096, dtype=np.uint8).tobytes())),
    ("zeros", raw(bytes(2048))),
    ("text", raw("time,sensor\n" * 100)),
    ("parameter block past the end", c3d_bytes(lambda b: bytes([200]) + b[1:])),
    ("parameter block 0", c3d_bytes(lambda b: bytes([0]) + b[1:])),
    ("parameters zeroed", c3d_bytes(lambda b: b[:512] + bytes(512) + b[1024:])),
    ("every marker invalid", c3d_markers(lambda labels, xyz: (labels, np.full_like(xyz, np.nan)))),
    ("markers of one segment only", c3d_markers(lambda labels, xyz: (labels[:4], xyz[:, :4]))),
    ("a directory", directory),
]


def _c3d_cases() -> list[Case]:
    out = []
    for cmd in ("calibrate", "report"):
        for name, maker in C3D_FILES:
            out.append(Case(f"{cmd}: C3D: {name}", (cmd, "{tmp}/m.c3d"), "{tmp}/m.c3d", {"m.c3d": maker}))
        out.append(
            Case(
                f"{cmd}: C3D: a real file cut in half",
                (cmd, "{tmp}/hip.c3d"),
                "{tmp}/hip.c3d",
                {"hip.c3d": _real_c3d_half},
            )
        )
    out.append(
        Case(
            "scale: C3D: cut in half",
            ("scale", "{tmp}/m.c3d", "--sensors", "a", "b", "--distance", "1"),
            "{tmp}/m.c3d",
            {"m.c3d": cut("good.c3d", 0.5)},
        )
    )
    return out


def _real_c3d_half(base: Path, dest: Path) -> None:
    if not REAL_C3D.is_file():
        pytest.skip("../shared/data/biobuddy_right_hip.c3d is not beside the repository")
    data = REAL_C3D.read_bytes()
    dest.write_bytes(data[: len(data) // 2])


#: Damaged cluster specs: (id, maker[, what the error names: the spec unless said]).
CLUSTER_SPECS: list[tuple] = [
    ("not TOML", raw("[clusters\n")),
    ("Latin-1", raw('[clusters]\nchest = ["\xe9", "b", "c"]\n'.encode("latin-1"))),
    ("no [clusters]", raw('chest = ["chest_0", "chest_1", "chest_2"]\n')),
    ("clusters a number", raw("clusters = 5\n")),
    ("clusters empty", raw("[clusters]\n")),
    (
        "two labels",
        replaced("clusters.toml", '"chest_0", "chest_1", "chest_2", "chest_3"', '"chest_0", "chest_1"'),
    ),
    ("labels numbers", replaced("clusters.toml", '"chest_0", "chest_1", "chest_2", "chest_3"', "1, 2, 3")),
    (
        "a cluster a string",
        replaced("clusters.toml", '["chest_0", "chest_1", "chest_2", "chest_3"]', '"chest_0"'),
    ),
    ("a marker not in the file", replaced("clusters.toml", '"chest_0"', '"LASIS"'), "{base}/good.c3d"),
    ("a marker in two clusters", replaced("clusters.toml", '"head_0"', '"chest_0"')),
    ("a marker twice in one cluster", replaced("clusters.toml", '"chest_1"', '"chest_0"')),
    ("one cluster only", raw('[clusters]\nchest = ["chest_0", "chest_1", "chest_2"]\n'), "{base}/good.c3d"),
    ("an unknown key", edited("clusters.toml", lambda t: "units = 'mm'\n" + t)),
    ("a directory", directory),
]


def _cluster_cases() -> list[Case]:
    out = []
    for cmd in ("calibrate", "report"):
        for name, maker, *named in CLUSTER_SPECS:
            out.append(
                Case(
                    f"{cmd}: cluster spec: {name}",
                    (cmd, "{base}/good.c3d", "--clusters", "{tmp}/c.toml"),
                    named[0] if named else "{tmp}/c.toml",
                    {"c.toml": maker},
                )
            )
        out.append(
            Case(
                f"{cmd}: cluster spec: no such file",
                (cmd, "{base}/good.c3d", "--clusters", "{tmp}/no.toml"),
                "{tmp}/no.toml",
            )
        )
    return out


def _del(*names: str) -> Callable:
    def damage(fh) -> None:
        for name in names:
            del fh[name]

    return damage


def _put(name: str, value, **kwargs) -> Callable:
    def damage(fh) -> None:
        data = value(fh) if callable(value) else value
        del fh[name]
        fh.create_dataset(name, data=data, **kwargs)

    return damage


def _attr(name: str, value) -> Callable:
    def damage(fh) -> None:
        if value is None:
            del fh.attrs[name]
        else:
            fh.attrs[name] = value

    return damage


def _measured_group_a_dataset(fh) -> None:
    del fh["measured"]
    fh["measured"] = np.zeros(3)


def _shape(name: str, shape_of: Callable) -> Callable:
    return _put(name, lambda fh: np.ones(shape_of(fh[name].shape)))


def _times(edit: Callable[[np.ndarray], np.ndarray]) -> Callable:
    return _put("time_s", lambda fh: edit(np.array(fh["time_s"][()])))


def _at(name: str, index, value) -> Callable:
    def damage(fh) -> None:
        a = np.array(fh[name][()])
        a[index] = value
        del fh[name]
        fh[name] = a

    return damage


DATASETS: list[tuple[str, Maker]] = [
    ("empty", raw(b"")),
    ("random bytes", raw(np.random.default_rng(9).integers(0, 256, 4096, dtype=np.uint8).tobytes())),
    ("cut in half", cut("good.h5", 0.5)),
    ("cut to 99 percent", cut("good.h5", 0.99)),
    ("text", raw(HEADER + "\n")),
    ("a directory", directory),
    ("not a simbench dataset", h5(_attr("format", None))),
    ("a newer format version", h5(_attr("format_version", 99))),
    ("format version a string", h5(_attr("format_version", "one"))),
    ("no meta", h5(_attr("meta", None))),
    ("meta not JSON", h5(_attr("meta", "{oops"))),
    ("no sensors", h5(_del("sensors"))),
    ("no measured group", h5(_del("measured"))),
    ("measured a dataset", h5(_measured_group_a_dataset)),
    ("no measured/valid", h5(_del("measured/valid"))),
    ("no measured/acc", h5(_del("measured/acc"))),
    (
        "positions as strings",
        h5(_put("measured/p_w_s", lambda fh: np.full(fh["measured/p_w_s"].shape, b"x"))),
    ),
    ("positions of the wrong shape", h5(_shape("measured/p_w_s", lambda s: (*s[:2], 2)))),
    ("valid as strings", h5(_put("measured/valid", lambda fh: np.full(fh["measured/valid"].shape, b"yes")))),
    ("quaternions 1-D", h5(_shape("measured/q_w_s", lambda s: (s[0],)))),
    ("time 2-D", h5(_shape("time_s", lambda s: (s[0], 2)))),
    ("time decreasing", h5(_times(lambda t: t[::-1].copy()))),
    ("a time nan", h5(_times(lambda t: np.where(np.arange(t.size) == 5, np.nan, t)))),
    ("time one sample short", h5(_times(lambda t: t[:-1]))),
    ("a sensor name missing", h5(_put("sensors", lambda fh: fh["sensors"][()][:-1]))),
    ("position unit scale -1", h5(_attr("position_unit_scale", -1.0))),
    ("position unit scale a string", h5(_attr("position_unit_scale", "big"))),
    ("a position of 1e30", h5(_at("measured/p_w_s", (3, 1, 0), 1e30))),
    ("no valid sample", h5(_put("measured/valid", lambda fh: np.zeros(fh["measured/valid"].shape, bool)))),
    ("zero quaternions", h5(_put("measured/q_w_s", lambda fh: np.zeros(fh["measured/q_w_s"].shape)))),
    ("no truth/joint_w", h5(_del("truth/joint_w"))),
    ("truth of another length", h5(_shape("truth/p_w_s", lambda s: (s[0] - 1, *s[1:])))),
]


def _dataset_cases() -> list[Case]:
    out = []
    commands = {
        "calibrate": ("calibrate", "{path}"),
        "report": ("report", "{path}"),
        "orient": ("orient", "{path}"),
        "scale": ("scale", "{path}", "--sensors", "chest", "head", "--distance", "0.3"),
    }
    imu_blind = {
        "no valid sample",
        "a position of 1e30",
        "positions as strings",
        "positions of the wrong shape",
        "zero quaternions",
        "no truth/joint_w",
        "truth of another length",
        "position unit scale -1",
    }
    for cmd, argv in commands.items():
        for name, maker in DATASETS:
            if cmd == "orient" and name in imu_blind:
                continue  # orient reads the inertial data, not these
            if cmd == "scale" and name.startswith(("no truth", "truth")):
                continue  # scale reads the measured poses only
            out.append(
                Case(
                    f"{cmd}: dataset: {name}",
                    tuple(a.replace("{path}", "{tmp}/d.h5") for a in argv),
                    "{tmp}/d.h5",
                    {"d.h5": maker},
                )
            )
    out += [
        Case(
            "calibrate: dataset with --units mm",
            ("calibrate", "{base}/good.h5", "--units", "mm"),
            "{base}/good.h5",
        ),
        Case("orient: a pose CSV", ("orient", "{base}/good.csv"), "{base}/good.csv"),
        Case(
            "orient: BROAD without imu_mag",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(drop="imu_mag")},
        ),
        Case(
            "orient: BROAD without sampling_rate",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(rate=None)},
        ),
        Case(
            "orient: BROAD sampling_rate 0",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(rate=0.0)},
        ),
        Case(
            "orient: BROAD sampling_rate a string",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(rate="fast")},
        ),
        Case(
            "orient: BROAD lengths differ",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(short="imu_gyr")},
        ),
        Case(
            "orient: BROAD acc as strings",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(strings="imu_acc")},
        ),
        Case(
            "orient: BROAD movement of another length",
            ("orient", "{tmp}/b.hdf5"),
            "{tmp}/b.hdf5",
            {"b.hdf5": _broad(short="movement")},
        ),
        Case("orient: BROAD empty", ("orient", "{tmp}/b.hdf5"), "{tmp}/b.hdf5", {"b.hdf5": _broad(frames=0)}),
    ]
    return out


def _broad(
    drop: str | None = None,
    rate=100.0,
    short: str | None = None,
    strings: str | None = None,
    frames: int = 200,
) -> Maker:
    """A small BROAD-like trial, damaged."""

    def make(base: Path, dest: Path) -> None:
        import h5py

        rng = np.random.default_rng(0)
        data = {
            "imu_acc": rng.normal(0, 1, (frames, 3)) + np.array([0, 0, 9.81]),
            "imu_gyr": rng.normal(0, 0.1, (frames, 3)),
            "imu_mag": rng.normal(0, 1, (frames, 3)) + np.array([0, 20, -40]),
            "opt_quat": np.tile([1.0, 0, 0, 0], (frames, 1)),
            "movement": np.ones(frames, bool),
        }
        if short:
            data[short] = data[short][:-1]
        if strings:
            data[strings] = np.full(data[strings].shape, b"x")
        with h5py.File(dest, "w") as fh:
            for k, v in data.items():
                if k != drop:
                    fh[k] = v
            if rate is not None:
                fh.attrs["sampling_rate"] = rate

    return make


#: Damaged sensor configurations (simulate --sensors): (id, TOML text or maker, named key).
SENSOR_CONFIGS: list[tuple[str, Maker]] = [
    ("not TOML", raw("[tracker\n")),
    ("Latin-1", raw('name = "\xe9"\n'.encode("latin-1"))),
    ("binary", raw(bytes(range(256)))),
    ("an unknown top-level key", raw("[trackers]\nposition_noise_m = 0.1\n")),
    ("tracker a number", raw("tracker = 5\n")),
    ("name a table", raw("[name]\nx = 1\n")),
    ("tracker noise a string", raw('[tracker]\nposition_noise_m = "big"\n')),
    ("tracker noise negative", raw("[tracker]\nposition_noise_m = -0.001\n")),
    ("tracker noise nan", raw("[tracker]\nposition_noise_m = nan\n")),
    ("tracker noise true", raw("[tracker]\nposition_noise_m = true\n")),
    ("tracker noise a list", raw("[tracker]\nposition_noise_m = [0.1]\n")),
    ("tracker noise a table", raw("[tracker]\nposition_noise_m = { a = 1 }\n")),
    ("tracker latency inf", raw("[tracker]\nlatency_s = inf\n")),
    ("tracker latency 1e9 s", raw("[tracker]\nlatency_s = 1e9\n")),
    ("tracker unit scale 0", raw("[tracker]\nunit_scale = 0\n")),
    ("tracker dropout 1", raw("[tracker]\ndropout_rate = 1.0\n")),
    ("tracker sample rate -1", raw("[tracker]\nsample_rate_hz = -1\n")),
    ("tracker reference distance 0", raw("[tracker]\nreference_distance_m = 0\n")),
    ("tracker transmitter two numbers", raw("[tracker]\ntransmitter_pos = [1, 2]\n")),
    ("tracker transmitter strings", raw('[tracker]\ntransmitter_pos = ["a", "b", "c"]\n')),
    ("tracker transmitter a number", raw("[tracker]\ntransmitter_pos = 1.0\n")),
    ("tracker transmitter nested lists", raw("[tracker]\ntransmitter_pos = [[1], [2], [3]]\n")),
    ("tracker unknown key", raw("[tracker]\nposition_noise = 0.1\n")),
    ("distortion a number", raw("[tracker]\ndistortion = 5\n")),
    ("distortion a list of numbers", raw("[tracker]\ndistortion = [1, 2]\n")),
    ("distortion radius 0", raw("[[tracker.distortion]]\nradius_m = 0\n")),
    ("distortion axis zero", raw("[[tracker.distortion]]\naxis = [0, 0, 0]\n")),
    ("distortion unknown key", raw("[[tracker.distortion]]\nstrength = 1\n")),
    ("imu noise negative", raw("[imu]\naccel_noise_density = -1\n")),
    ("imu bias a string", raw('[imu]\ngyro_bias = "x"\n')),
    ("imu range nan", raw("[imu]\naccel_range = nan\n")),
    ("imu unknown key", raw("[imu]\naccel_noise = 0.1\n")),
    ("imu a list", raw("imu = [1, 2]\n")),
    ("magnetic strength negative", raw("[magnetic]\nstrength_ut = -5\n")),
    ("magnetic inclination 100", raw("[magnetic]\ninclination_deg = 100\n")),
    ("disturbance two numbers", raw("[[magnetic.disturbance]]\nposition = [1, 2]\nmoment_am2 = [0, 0, 1]\n")),
    (
        "disturbance moment nan",
        raw("[[magnetic.disturbance]]\nposition = [1, 2, 3]\nmoment_am2 = [nan, 0, 1]\n"),
    ),
    ("disturbance missing moment", raw("[[magnetic.disturbance]]\nposition = [1, 2, 3]\n")),
    (
        "disturbance unknown key",
        raw("[[magnetic.disturbance]]\nposition = [1, 2, 3]\nmoment_am2 = [0, 0, 1]\nsize = 2\n"),
    ),
    (
        "attached sensor a number",
        raw("[[magnetic.attached]]\nsensor = 5\nstart_s = 0\nstop_s = 1\nfield_ut = [1, 0, 0]\n"),
    ),
    (
        "attached an unknown sensor",
        raw('[[magnetic.attached]]\nsensor = "thigh_l"\nstart_s = 0\nstop_s = 1\nfield_ut = [1, 0, 0]\n'),
    ),
    (
        "attached off before its ramps",
        raw(
            '[[magnetic.attached]]\nsensor = "head"\nstart_s = 0\nstop_s = 1\n'
            "field_ut = [1, 0, 0]\nramp_s = 0.6\n"
        ),
    ),
    (
        "attached start negative",
        raw('[[magnetic.attached]]\nsensor = "head"\nstart_s = -1\nstop_s = 1\nfield_ut = [1, 0, 0]\n'),
    ),
    (
        "attached field two numbers",
        raw('[[magnetic.attached]]\nsensor = "head"\nstart_s = 0\nstop_s = 1\nfield_ut = [1, 0]\n'),
    ),
    ("attached missing field", raw('[[magnetic.attached]]\nsensor = "head"\nstart_s = 0\nstop_s = 1\n')),
    ("skin amplitude negative", raw("[skin]\nsta_amplitude_m = -0.01\n")),
    ("skin by sensor a string value", raw('[skin]\nsta_by_sensor = { head = "a" }\n')),
    ("skin by sensor negative", raw("[skin]\nsta_by_sensor = { head = -1 }\n")),
    ("skin by sensor an unknown sensor", raw("[skin]\nsta_by_sensor = { thigh_l = 0.01 }\n")),
    ("skin laxity a list", raw("[skin]\nlaxity_by_joint = [1, 2]\n")),
    ("skin laxity an unknown joint", raw("[skin]\nlaxity_by_joint = { shank_l = 0.01 }\n")),
    ("skin mount mass 0", raw("[skin]\nmount_stiffness_n_per_m = 2000.0\nmount_mass_kg = 0\n")),
    ("skin damping negative", raw("[skin]\nmount_damping_ratio = -1\n")),
    ("skin unknown key", raw("[skin]\nsta = 0.01\n")),
    ("slip sensor a number", raw("[[skin.slip]]\nsensor = 5\ntime_s = 0.5\noffset_m = [0, 0, 0.01]\n")),
    (
        "slip an unknown sensor",
        raw('[[skin.slip]]\nsensor = "thigh_l"\ntime_s = 0.5\noffset_m = [0, 0, 0.01]\n'),
    ),
    ("slip time negative", raw('[[skin.slip]]\nsensor = "head"\ntime_s = -1\noffset_m = [0, 0, 0.01]\n')),
    ("slip offset two numbers", raw('[[skin.slip]]\nsensor = "head"\ntime_s = 0.5\noffset_m = [0, 0.01]\n')),
    ("slip missing offset", raw('[[skin.slip]]\nsensor = "head"\ntime_s = 0.5\n')),
    (
        "slip a table not an array",
        raw('[skin.slip]\nsensor = "head"\ntime_s = 0.5\noffset_m = [0, 0, 0.01]\n'),
    ),
    ("pack a number", raw("[skin]\npack = 5\n")),
    ("pack missing fields", raw('[skin.pack]\nsensor = "chest"\n')),
    ("pack pushed by itself", replaced("sensors.toml", 'pushed_by = "head"', 'pushed_by = "chest"')),
    ("pack an unknown sensor", replaced("sensors.toml", 'pushed_by = "head"', 'pushed_by = "thigh_r"')),
    ("pack threshold 10", replaced("sensors.toml", "threshold_rad = 0.5", "threshold_rad = 10")),
    ("girdle ratio 2", replaced("sensors.toml", "ratio = 0.3", "ratio = 2")),
    ("girdle an unknown joint", replaced("sensors.toml", 'joint = "upper_arm_l"', 'joint = "upper_arm_x"')),
    ("girdle axis zero", replaced("sensors.toml", "axis = [1.0, 0.0, 0.0]", "axis = [0.0, 0.0, 0.0]")),
    ("joints play 0.1", raw("[joints]\nplay_m = 0.1\n")),
    ("joints play a string", raw('[joints]\nplay_m = "loose"\n')),
    ("joints unknown key", raw("[joints]\nplay = 0.001\n")),
    ("a directory", directory),
]


def _sensor_cases() -> list[Case]:
    out = [
        Case(
            f"simulate: sensor config: {name}",
            ("simulate", "--duration", "1", "--sensors", "{tmp}/s.toml", "-o", "{tmp}/o.h5"),
            "{tmp}/s.toml",
            {"s.toml": maker},
        )
        for name, maker in SENSOR_CONFIGS
    ]
    out += [
        Case(
            "simulate: sensor preset unknown",
            ("simulate", "--duration", "1", "--sensors", "nosuch", "-o", "{tmp}/o.h5"),
            "nosuch",
        ),
        Case(
            "simulate: sensor preset empty",
            ("simulate", "--duration", "1", "--sensors", "", "-o", "{tmp}/o.h5"),
            "--sensors",
        ),
        Case(
            "simulate: sensor config missing",
            ("simulate", "--duration", "1", "--sensors", "{tmp}/no.toml", "-o", "{tmp}/o.h5"),
            "{tmp}/no.toml",
        ),
    ]
    return out


MODELS: list[tuple[str, str, Maker | None]] = [
    ("not XML", "bad.xml", raw("<mujoco><worldbody><body></mujoco>")),
    ("empty", "empty.xml", raw("")),
    ("binary", "bin.xml", raw(bytes(range(256)))),
    ("Latin-1", "l1.xml", raw('<mujoco model="\xe9"><worldbody/></mujoco>'.encode("latin-1"))),
    ("no bodies", "none.xml", raw("<mujoco><worldbody/></mujoco>")),
    ("one body", "one.xml", raw(MJCF_ONE_BODY)),
    ("an unknown element", "elem.xml", raw("<mujoco><worldbody><bodyy/></worldbody></mujoco>")),
    ("an include of a missing file", "inc.xml", raw('<mujoco><include file="nowhere.xml"/></mujoco>')),
    ("a directory", "dir.xml", directory),
    ("missing", "missing.xml", None),
]


def _model_cases() -> list[Case]:
    out = [
        Case(
            f"simulate: model: {name}",
            ("simulate", "--duration", "1", "--model", "{tmp}/" + path, "-o", "{tmp}/o.h5"),
            "{tmp}/" + path,
            {} if maker is None else {path: maker},
        )
        for name, path, maker in MODELS
    ]
    out += [
        Case(
            "simulate: model: an unknown name",
            ("simulate", "--duration", "1", "--model", "nosuch", "-o", "{tmp}/o.h5"),
            "nosuch",
        ),
        Case(
            "simulate: model: a .txt file",
            ("simulate", "--duration", "1", "--model", "{tmp}/m.txt", "-o", "{tmp}/o.h5"),
            "{tmp}/m.txt",
            {"m.txt": raw("x")},
        ),
        Case(
            "simulate: sensors on an unknown body",
            ("simulate", "--duration", "1", "--sensors-on", "chest,tail", "-o", "{tmp}/o.h5"),
            "tail",
        ),
        Case(
            "simulate: sensors on one body",
            ("simulate", "--duration", "1", "--sensors-on", "chest", "-o", "{tmp}/o.h5"),
            "--sensors-on",
        ),
        Case(
            "simulate: sensors on a body twice",
            ("simulate", "--duration", "1", "--sensors-on", "chest,head,head", "-o", "{tmp}/o.h5"),
            "--sensors-on",
        ),
        Case(
            "simulate: sensors on commas only",
            ("simulate", "--duration", "1", "--sensors-on", ",,", "-o", "{tmp}/o.h5"),
            "--sensors-on",
        ),
        Case(
            "simulate: output a directory",
            ("simulate", "--duration", "1", "-o", "{tmp}/out.h5"),
            "{tmp}/out.h5",
            {"out.h5": directory},
        ),
        Case(
            "simulate: csv into a missing folder",
            ("simulate", "--duration", "1", "-o", "{tmp}/o.h5", "--csv", "{tmp}/no/o.csv"),
            "{tmp}/no/o.csv",
        ),
        Case(
            "simulate: rate above the physics rate",
            ("simulate", "--duration", "1", "--rate", "100000", "-o", "{tmp}/o.h5"),
            "100000 Hz",
        ),
        Case(
            "simulate: a rate of 1e-300 Hz",
            ("simulate", "--rate", "1e-300", "-o", "{tmp}/o.h5"),
            "1e-300 Hz",
        ),
        Case(
            "simulate: a duration of 1e308 s",
            ("simulate", "--duration", "1e308", "-o", "{tmp}/o.h5"),
            "duration 1e+308 s",
        ),
        Case(
            "simulate: duration too short for 2 samples",
            ("simulate", "--duration", "0.001", "-o", "{tmp}/o.h5"),
            "duration 0.001 s",
        ),
    ]
    return out


PROGRAMS: list[tuple[str, Maker]] = [
    ("not TOML", raw("[[phase]\n")),
    ("Latin-1", raw('name = "\xe9"\n'.encode("latin-1"))),
    ("an unknown key", edited("program.toml", lambda t: "speed = 2\n" + t)),
    ("root unknown", replaced("program.toml", '"carry"', '"fly"')),
    ("no phase", raw('name = "x"\n')),
    ("phase a list of numbers", raw("phase = [1, 2]\n")),
    ("phase a table", raw("[phase]\nstart_s = 0\nend_s = 1\n")),
    ("start after end", replaced("program.toml", "end_s = 1.0", "end_s = -1.0")),
    ("start a string", replaced("program.toml", "start_s = 0.0", 'start_s = "now"')),
    ("start true", replaced("program.toml", "start_s = 0.0", "start_s = true")),
    ("joints a number", raw("[[phase]]\nstart_s = 0\nend_s = 1\njoints = 5\n")),
    ("a joint a number", raw("[[phase]]\nstart_s = 0\nend_s = 1\njoints = { neck = 5 }\n")),
    ("an unknown joint", replaced("program.toml", "joints.neck", "joints.knee")),
    ("two amplitudes for a ball joint", replaced("program.toml", "[0.3, 0.2, 0.1]", "[0.3, 0.2]")),
    ("amplitude nan", replaced("program.toml", "[0.3, 0.2, 0.1]", "[0.3, nan, 0.1]")),
    ("frequency negative", replaced("program.toml", "[0.5, 0.7, 0.9]", "[0.5, -0.7, 0.9]")),
    ("frequency missing", replaced("program.toml", "frequency_hz = [0.5, 0.7, 0.9]\n", "")),
    ("a joint unknown key", edited("program.toml", lambda t: t + "speed = 1\n")),
    ("a directory", directory),
]


def _motion_cases() -> list[Case]:
    out = [
        Case(
            f"simulate: motion program: {name}",
            ("simulate", "--duration", "1", "--motion", "{tmp}/p.toml", "-o", "{tmp}/o.h5"),
            "{tmp}/p.toml",
            {"p.toml": maker},
        )
        for name, maker in PROGRAMS
    ]
    out += [
        Case(
            "simulate: motion unknown",
            ("simulate", "--duration", "1", "--motion", "dance", "-o", "{tmp}/o.h5"),
            "dance",
        ),
        Case(
            "simulate: motion program missing",
            ("simulate", "--duration", "1", "--motion", "{tmp}/no.toml", "-o", "{tmp}/o.h5"),
            "{tmp}/no.toml",
        ),
    ]
    return out


def _study_text(old: str, new: str) -> Maker:
    return replaced("study.toml", old, new)


def _study_append(text: str) -> Maker:
    return edited("study.toml", lambda t: t + text)


def _study_prepend(text: str) -> Maker:
    return edited("study.toml", lambda t: text + t)


STUDIES: list[tuple[str, Maker]] = [
    ("not TOML", raw("[base\n")),
    ("Latin-1", raw('name = "\xe9"\n'.encode("latin-1"))),
    ("binary", raw(bytes(range(256)))),
    ("empty", raw("")),
    ("an unknown key", _study_prepend("workers = 4\n")),
    ("name a list", _study_text('name = "fuzz"', 'name = ["fuzz"]')),
    ('duration_s = "two"', _study_text("duration_s = 2.0", 'duration_s = "two"')),
    ("duration_s negative", _study_text("duration_s = 2.0", "duration_s = -2.0")),
    ("duration_s nan", _study_text("duration_s = 2.0", "duration_s = nan")),
    ("duration_s true", _study_text("duration_s = 2.0", "duration_s = true")),
    ("duration_s 0.001 (under 2 samples)", _study_text("duration_s = 2.0", "duration_s = 0.001")),
    ("rate_hz 0", _study_text("rate_hz = 60.0", "rate_hz = 0")),
    ("rate above the physics rate", _study_text("rate_hz = 60.0", "rate_hz = 100000.0")),
    ('seed = "one"', _study_text("seed = 1", 'seed = "one"')),
    ("seed negative", _study_text("seed = 1", "seed = -1")),
    ("seed 1.5", _study_text("seed = 1", "seed = 1.5")),
    ("seed true", _study_text("seed = 1", "seed = true")),
    ("seeds_per_cell 0", _study_text("seeds_per_cell = 1", "seeds_per_cell = 0")),
    ("seeds_per_cell a string", _study_text("seeds_per_cell = 1", 'seeds_per_cell = "3"')),
    ("seeds_per_cell true", _study_text("seeds_per_cell = 1", "seeds_per_cell = true")),
    ("estimators a string", _study_text('estimators = ["calibration"]', 'estimators = "calibration"')),
    ("estimators a number", _study_text('estimators = ["calibration"]', "estimators = [1]")),
    ("estimators empty", _study_text('estimators = ["calibration"]', "estimators = []")),
    ("estimator unknown", _study_text('estimators = ["calibration"]', 'estimators = ["kalman"]')),
    (
        "orientation method unknown",
        _study_text('estimators = ["calibration"]', 'estimators = ["orientation:foo"]'),
    ),
    (
        "metrics a string",
        _study_text(
            'metrics = ["joint_centre_error_m", "limb_length_error_m"]', 'metrics = "joint_centre_error_m"'
        ),
    ),
    (
        "metrics numbers",
        _study_text('metrics = ["joint_centre_error_m", "limb_length_error_m"]', "metrics = [1, 2]"),
    ),
    ("metric unknown", _study_text('"limb_length_error_m"]', '"accuracy"]')),
    (
        "base a number",
        edited(
            "study.toml",
            lambda t: "base = 5\n" + t.split("[base]")[0] + "[sampling]" + t.split("[sampling]")[1],
        ),
    ),
    ("base unknown key", _study_text("[base]\n", "[base]\nsubject = 'me'\n")),
    ("base model unknown", _study_text('model = "linkage"', 'model = "octopus"')),
    ("base model a number", _study_text('model = "linkage"', "model = 3")),
    ("base motion a number", _study_text('motion = "exercise"', "motion = 1")),
    ("base sensors a list", _study_text('sensors = "ideal"', 'sensors = ["ideal"]')),
    ("base rate a string", _study_text("rate_hz = 60.0", 'rate_hz = "60"')),
    ("base model a missing MJCF", _study_text('model = "linkage"', 'model = "nowhere.xml"')),
    ("base motion unknown", _study_text('motion = "exercise"', 'motion = "dance"')),
    ("base motion a missing program", _study_text('motion = "exercise"', 'motion = "nowhere.toml"')),
    ("base preset unknown", _study_text('sensors = "ideal"', 'sensors = "nosuch"')),
    ("base preset a path out", _study_text('sensors = "ideal"', 'sensors = "../../etc/passwd"')),
    ("base sensors a missing file", _study_text('sensors = "ideal"', 'sensors = "nowhere.toml"')),
    (
        "sampling a number",
        edited("study.toml", lambda t: "sampling = 5\n" + t.replace('[sampling]\nkind = "grid"\n', "")),
    ),
    ("sampling kind unknown", _study_text('kind = "grid"', 'kind = "sobol"')),
    ("sampling kind a number", _study_text('kind = "grid"', "kind = 1")),
    ('samples = "ten"', _study_text('kind = "grid"', 'kind = "random"\nsamples = "ten"')),
    ("samples 0", edited("study.toml", lambda t: RANDOM_STUDY.replace("samples = 3", "samples = 0"))),
    ("samples negative", edited("study.toml", lambda t: RANDOM_STUDY.replace("samples = 3", "samples = -3"))),
    ("samples 1.5", edited("study.toml", lambda t: RANDOM_STUDY.replace("samples = 3", "samples = 1.5"))),
    ("sampling unknown key", _study_text('kind = "grid"', 'kind = "grid"\nsample = 10')),
    ("no parameter", edited("study.toml", lambda t: t.split("[[parameter]]")[0])),
    (
        "parameter a number",
        edited(
            "study.toml", lambda t: t.split("[[parameter]]")[0].replace("[base]", "parameter = 5\n[base]")
        ),
    ),
    (
        "parameter a list of numbers",
        edited(
            "study.toml",
            lambda t: t.split("[[parameter]]")[0].replace("[base]", "parameter = [1, 2]\n[base]"),
        ),
    ),
    ("parameter unknown key", _study_append("step = 1\n")),
    ("parameter name missing", _study_text('name = "sensors.tracker.position_noise_m"\n', "")),
    ("parameter name a number", _study_text('name = "sensors.tracker.position_noise_m"', "name = 5")),
    ("parameter section unknown", _study_text("sensors.tracker.position", "sensors.trackers.position")),
    ("parameter field unknown", _study_text("position_noise_m", "position_noise")),
    (
        "parameter field not numeric",
        _study_text("sensors.tracker.position_noise_m", "sensors.tracker.distortion"),
    ),
    (
        "parameter placement axis w",
        _study_text('name = "sensors.tracker.position_noise_m"', 'name = "placement.head.w_m"'),
    ),
    (
        "parameter placement unknown sensor",
        _study_text(
            'name = "sensors.tracker.position_noise_m"\nunit = "mm"',
            'name = "placement.tail.x_m"\nunit = "mm"',
        ),
    ),
    ("unit unknown", _study_text('unit = "mm"', 'unit = "furlong"')),
    ("unit of another kind", _study_text('unit = "mm"', 'unit = "s"')),
    ("unit a number", _study_text('unit = "mm"', "unit = 5")),
    ("values empty (an empty grid)", _study_text("values = [0.0, 1.0]", "values = []")),
    ("values strings", _study_text("values = [0.0, 1.0]", 'values = ["a", "b"]')),
    ("values a number", _study_text("values = [0.0, 1.0]", "values = 1.0")),
    ("values booleans", _study_text("values = [0.0, 1.0]", "values = [true, false]")),
    ("values nan", _study_text("values = [0.0, 1.0]", "values = [0.0, nan]")),
    ("values negative noise", _study_text("values = [0.0, 1.0]", "values = [0.0, -1.0]")),
    (
        "a grid of 10^12 cells",
        edited(
            "study.toml",
            lambda t: (
                t
                + "".join(
                    f'[[parameter]]\nname = "sensors.imu.{f}"\nvalues = [{", ".join(["0.0"] * 1000)}]\n'
                    for f in ("accel_bias", "gyro_bias", "mag_noise", "gyro_noise_density")
                )
            ),
        ),
    ),
    ("random low above high", edited("study.toml", lambda t: RANDOM_STUDY.replace("low = 0.5", "low = 5.0"))),
    ("random low a string", edited("study.toml", lambda t: RANDOM_STUDY.replace("low = 0.5", 'low = "0.5"'))),
    (
        "random high a list",
        edited("study.toml", lambda t: RANDOM_STUDY.replace("high = 2.0", "high = [2.0]")),
    ),
    ("random log with low 0", edited("study.toml", lambda t: RANDOM_STUDY.replace("low = 0.5", "low = 0.0"))),
    (
        "random log a string",
        edited("study.toml", lambda t: RANDOM_STUDY.replace("log = true", 'log = "yes"')),
    ),
    ("random high inf", edited("study.toml", lambda t: RANDOM_STUDY.replace("high = 2.0", "high = inf"))),
    (
        "duration parameter 0",
        _study_text(
            'name = "sensors.tracker.position_noise_m"\nunit = "mm"\nvalues = [0.0, 1.0]',
            'name = "duration_s"\nunit = "s"\nvalues = [1.0, 0.0]',
        ),
    ),
    (
        "rate parameter above the physics rate",
        _study_text(
            'name = "sensors.tracker.position_noise_m"\nunit = "mm"\nvalues = [0.0, 1.0]',
            'name = "rate_hz"\nunit = "hz"\nvalues = [60.0, 1e6]',
        ),
    ),
    ("a directory", directory),
]


def _study_cases() -> list[Case]:
    out = [
        Case(
            f"sweep: study: {name}",
            ("sweep", "{tmp}/s.toml", "--workers", "1", "--no-progress"),
            "{tmp}/s.toml",
            {"s.toml": maker},
        )
        for name, maker in STUDIES
    ]
    out += [
        Case("sweep: study: missing", ("sweep", "{tmp}/no.toml", "--no-progress"), "{tmp}/no.toml"),
        Case(
            "sweep: --out in a missing folder",
            ("sweep", "{base}/study.toml", "--out", "{tmp}/no/out", "--no-progress"),
            "{tmp}/no/out",
        ),
        Case(
            "sweep: --out a file",
            ("sweep", "{base}/study.toml", "--out", "{tmp}/f", "--no-progress"),
            "{tmp}/f",
            {"f": raw("x")},
        ),
    ]
    return out


HIERARCHIES: list[tuple[str, Maker]] = [
    ("not JSON", raw('{"head": "chest",}')),
    ("empty", raw("")),
    ("Latin-1", raw('{"t\xeate": "chest"}'.encode("latin-1"))),
    ("a list", raw('["head", "chest"]')),
    ("a parent a number", raw('{"head": 1}')),
    ("a child twice", raw('{"head": "chest", "head": "upper_arm_l"}')),
    ("an unknown sensor", raw('{"tail": "chest"}')),
    ("an unknown parent", raw('{"head": "tail"}')),
    ("a cycle", raw('{"head": "upper_arm_l", "upper_arm_l": "head"}')),
    ("its own parent", raw('{"head": "head"}')),
    ("a directory", directory),
]


def _hierarchy_cases() -> list[Case]:
    out = [
        Case(
            f"calibrate: hierarchy JSON: {name}",
            ("calibrate", "{base}/good.csv", "--hierarchy", "{tmp}/h.json"),
            "{tmp}/h.json",
            {"h.json": maker},
        )
        for name, maker in HIERARCHIES
    ]
    out += [
        Case(
            "calibrate: hierarchy JSON missing",
            ("calibrate", "{base}/good.csv", "--hierarchy", "{tmp}/no.json"),
            "{tmp}/no.json",
        ),
        Case(
            "calibrate: --root unknown",
            ("calibrate", "{base}/good.csv", "--root", "tail"),
            "--root",
        ),
        Case(
            "calibrate: --json into a missing folder",
            ("calibrate", "{base}/good.csv", "--json", "{tmp}/no/c.json"),
            "{tmp}/no/c.json",
        ),
    ]
    return out


def _caljson(edit: Callable[[dict], object]) -> Maker:
    def make(base: Path, dest: Path) -> None:
        import json

        doc = json.loads((base / "cal.json").read_text())
        doc = edit(doc) or doc
        dest.write_text(json.dumps(doc) if not isinstance(doc, str) else doc)

    return make


def _joint(key: str, value) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        doc["joints"][1][key] = value

    return edit


CALIBRATIONS: list[tuple[str, Maker]] = [
    ("not JSON", raw("{")),
    ("empty", raw("")),
    ("Latin-1", raw('{"joints": "\xe9"}'.encode("latin-1"))),
    ("a list", raw("[]")),
    ("no joints", _caljson(lambda d: d.pop("joints") and None)),
    ("joints an object", _caljson(lambda d: d.update(joints={}))),
    ("no joints at all", _caljson(lambda d: d.update(joints=[]))),
    ("a joint a number", _caljson(lambda d: d["joints"].append(5))),
    ("a joint without a parent", _caljson(lambda d: d["joints"][0].pop("parent") and None)),
    ("joint_in_parent two numbers", _caljson(_joint("joint_in_parent", [0.1, 0.2]))),
    ("joint_in_child strings", _caljson(_joint("joint_in_child", ["a", "b", "c"]))),
    ("joint_in_parent NaN", _caljson(lambda d: json_nan(d))),
    ("joint_in_parent 1e300", _caljson(_joint("joint_in_parent", [1e300, 0, 0]))),
    ("single_axis a string", _caljson(_joint("single_axis", "yes"))),
    ("an unknown sensor", _caljson(_joint("child", "tail"))),
    ("a joint twice", _caljson(lambda d: d["joints"].append(dict(d["joints"][0])))),
    ("a cycle", _caljson(lambda d: d["joints"][1].update(parent="forearm_l"))),
    ("a sensor joined with itself", _caljson(_joint("parent", "upper_arm_l"))),
    ("units mm", _caljson(lambda d: d.update(units="mm"))),
    ("warnings a number", _caljson(lambda d: d.update(warnings=5))),
    ("a directory", directory),
]


def json_nan(doc: dict) -> str:
    import json

    doc["joints"][0]["joint_in_parent"] = [float("nan"), 0.0, 0.0]
    return json.dumps(doc)


def _calibration_cases() -> list[Case]:
    out = [
        Case(
            f"report: calibration JSON: {name}",
            ("report", "{base}/good.h5", "--calibration", "{tmp}/c.json"),
            "{tmp}/c.json",
            {"c.json": maker},
        )
        for name, maker in CALIBRATIONS
    ]
    out += [
        Case(
            "report: calibration JSON missing",
            ("report", "{base}/good.h5", "--calibration", "{tmp}/no.json"),
            "{tmp}/no.json",
        ),
        Case(
            "report: --out a file",
            ("report", "{base}/good.h5", "--out", "{tmp}/f"),
            "{tmp}/f",
            {"f": raw("x")},
        ),
        Case(
            "report: --out in a missing folder",
            ("report", "{base}/good.h5", "--out", "{tmp}/no/r"),
            "{tmp}/no/r",
        ),
    ]
    return out


BASELINES: list[tuple[str, Maker | None]] = [
    ("missing", None),
    ("not JSON", raw("{")),
    ("empty", raw("")),
    ("Latin-1", raw('{"scenarios": "\xe9"}'.encode("latin-1"))),
    ("a list", raw("[]")),
    ("no scenarios", raw('{"figures": {}}')),
    ("scenarios a list", raw('{"scenarios": [1, 2]}')),
    ("a figure a string", raw('{"scenarios": {"linkage": {"max_error_m": "small"}}}')),
    ("a figure set a number", raw('{"scenarios": {"linkage": 5}}')),
    ("a directory", directory),
]


def _baseline_cases() -> list[Case]:
    out = [
        Case(
            f"baseline: file: {name}",
            ("baseline", "--file", "{tmp}/b.json"),
            "{tmp}/b.json",
            {} if maker is None else {"b.json": maker},
        )
        for name, maker in BASELINES
    ]
    out += [
        Case(
            "baseline: --update into a missing folder",
            ("baseline", "--update", "--file", "{tmp}/no/b.json"),
            "{tmp}/no/b.json",
        ),
        Case(
            "validate: --out a file", ("validate", "--quick", "--out", "{tmp}/f"), "{tmp}/f", {"f": raw("x")}
        ),
        Case(
            "validate: --physics-cache a file",
            ("validate", "--quick", "--physics-cache", "{tmp}/f", "--out", "{tmp}/r"),
            "{tmp}/f",
            {"f": raw("x")},
        ),
        Case(
            "validate: --out in a missing folder",
            ("validate", "--quick", "--out", "{tmp}/no/r"),
            "{tmp}/no/r",
        ),
    ]
    return out


CASES: list[Case] = (
    _pose_cases()
    + _wide_cases()
    + _c3d_cases()
    + _cluster_cases()
    + _dataset_cases()
    + _sensor_cases()
    + _model_cases()
    + _motion_cases()
    + _study_cases()
    + _hierarchy_cases()
    + _calibration_cases()
    + _baseline_cases()
)


def _run(args: list[str]) -> int:
    try:
        return main(args)
    except SystemExit as exc:  # argparse refuses a bad option value itself
        return int(exc.code)


def _tree(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")} | {p for p in folder.rglob(".*")}


def _params():
    for case in CASES:
        marks = [pytest.mark.xfail(strict=True, reason=case.xfail)] if case.xfail else []
        yield pytest.param(case, id=case.id, marks=marks)


@pytest.mark.parametrize("case", list(_params()))
def test_bad_input(case: Case, base: Path, tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # default outputs (report/, a study's folder, MuJoCo's log) land here
    for name, make in case.files.items():
        make(base, tmp_path / name)
    before = _tree(tmp_path)

    def fill(text: str) -> str:
        return text.replace("{tmp}", str(tmp_path)).replace("{base}", str(base))

    status = _run([fill(a) for a in case.argv])
    lines_ = capsys.readouterr().err.strip().splitlines()
    assert status == 2, lines_
    assert not any("Traceback" in line for line in lines_), lines_
    errors = [line for line in lines_ if line.startswith("simbench: error:") or ": error: " in line]
    assert len(errors) == 1 and errors[0] == lines_[-1], lines_
    assert "internal error" not in errors[0], errors[0]
    assert fill(case.named) in errors[0], errors[0]
    assert _tree(tmp_path) == before, sorted(map(str, _tree(tmp_path) - before))


def test_the_table_has_at_least_120_distinct_bad_inputs() -> None:
    """At least 120 distinct bad inputs (issue 14; each run through every command that reads
    that kind of file), every case id once."""
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids))
    kinds = (
        len(POSE_CSV)
        + len(POSE_PATHS)
        + len(WIDE_SPECS)
        + len(WIDE_CSVS)
        + len(C3D_FILES)
        + len(CLUSTER_SPECS)
        + len(DATASETS)
        + len(SENSOR_CONFIGS)
        + len(MODELS)
        + len(PROGRAMS)
        + len(STUDIES)
        + len(HIERARCHIES)
        + len(CALIBRATIONS)
        + len(BASELINES)
    )
    assert kinds >= 120 and len(CASES) >= kinds


def test_valid_inputs_are_accepted(base: Path, tmp_path: Path, capsys, monkeypatch) -> None:
    """The files every case damages are themselves fine (so each case tests its damage), and a
    BOM or CRLF line endings are not damage."""
    monkeypatch.chdir(tmp_path)
    text = (base / "good.csv").read_text()
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.replace("\n", "\r\n").encode())
    assert main(["calibrate", str(tmp_path / "bom.csv"), "--no-slip"]) == 0
    assert main(["calibrate", str(base / "wide.csv"), "--wide", str(base / "wide.toml"), "--no-slip"]) == 0
    assert (
        main(["calibrate", str(base / "good.c3d"), "--clusters", str(base / "clusters.toml"), "--no-slip"])
        == 0
    )
    assert (
        main(["calibrate", str(base / "good.csv"), "--hierarchy", str(base / "hier.json"), "--no-slip"]) == 0
    )
    assert main(["report", str(base / "good.h5"), "--calibration", str(base / "cal.json"), "--out", "r"]) == 0
    from simbench.experiments.study import check_study, load_study
    from simbench.sim.sensor_config import load_sensor_config

    sim = ["simulate", "--duration", "1", "--sensors", str(base / "sensors.toml"), "-o", "s.h5"]
    assert main([*sim, "--motion", str(base / "program.toml")]) == 0
    check_study(load_study(base / "study.toml"))
    (tmp_path / "random.toml").write_text(RANDOM_STUDY)
    check_study(load_study(tmp_path / "random.toml"))
    load_sensor_config(str(base / "sensors.toml"))
    capsys.readouterr()


# ---------------------------------------------------------------------------------------------
# Property-based: mutations of valid files through the parsers.
# ---------------------------------------------------------------------------------------------

FIELD_VALUES = st.one_of(
    st.text(max_size=12),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(
        ["1e308", "-1e308", "1e30", "-1", "-0", "0", "nan", "inf", "-inf", "1e-320", "", " ", '"', "x"]
    ),
    st.integers(min_value=-(10**25), max_value=10**25).map(str),
)

TOML_VALUES = st.one_of(
    st.sampled_from(
        [
            "0",
            "-1",
            "1e308",
            "-1e308",
            "1e-320",
            "nan",
            "inf",
            "-inf",
            "true",
            "false",
            '""',
            '"x"',
            "[]",
            "[1, 2]",
            "[0, 0, 0]",
            "[nan, 1, 2]",
            '["a", "b", "c"]',
            "{}",
            "{ a = 1 }",
            "9223372036854775807",
            "-9223372036854775808",
            '"../../etc/passwd"',
            '"ideal"',
            "2024-01-01",
            "[[1]]",
            "[1e308, -1e308, 0]",
        ]
    ),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.integers(min_value=-(2**63), max_value=2**63 - 1).map(str),
    st.text(max_size=10).map(lambda s: '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'),
)


@st.composite
def mutated(draw, text: str, *, separator: str, values) -> bytes:
    """``text`` with 1 to 3 random mutations: bytes inserted or deleted, a field replaced, a line
    dropped, duplicated or swapped with another."""
    data = text
    for _ in range(draw(st.integers(1, 3))):
        rows = data.split("\n")
        kind = draw(st.sampled_from(["field"] * 5 + ["insert", "delete", "drop", "duplicate", "swap"]))
        if kind == "insert":
            at = draw(st.integers(0, len(data)))
            junk = draw(
                st.one_of(st.text(max_size=8), st.binary(max_size=8).map(lambda b: b.decode("latin-1")))
            )
            data = data[:at] + junk + data[at:]
        elif kind == "delete":
            at = draw(st.integers(0, max(len(data) - 1, 0)))
            data = data[:at] + data[at + draw(st.integers(1, 20)) :]
        elif kind == "field":
            k = draw(st.integers(0, len(rows) - 1))
            if separator == "=":
                if " = " in rows[k]:
                    rows[k] = rows[k].split(" = ", 1)[0] + " = " + draw(values)
            else:
                parts = rows[k].split(separator)
                parts[draw(st.integers(0, len(parts) - 1))] = draw(values)
                rows[k] = separator.join(parts)
            data = "\n".join(rows)
        elif kind == "drop":
            k = draw(st.integers(0, len(rows) - 1))
            data = "\n".join(rows[:k] + rows[k + 1 :])
        elif kind == "duplicate":
            k = draw(st.integers(0, len(rows) - 1))
            data = "\n".join(rows[: k + 1] + rows[k:])
        else:
            i, j = draw(st.integers(0, len(rows) - 1)), draw(st.integers(0, len(rows) - 1))
            rows[i], rows[j] = rows[j], rows[i]
            data = "\n".join(rows)
    raw_bytes = data.encode("utf-8", "surrogatepass")
    if draw(st.integers(0, 9)) == 0:  # now and then a byte that is not UTF-8
        at = draw(st.integers(0, len(raw_bytes)))
        raw_bytes = raw_bytes[:at] + bytes([draw(st.integers(0x80, 0xFF))]) + raw_bytes[at:]
    return raw_bytes


SMALL_CSV = (
    HEADER
    + "\n"
    + "".join(
        f"{t / 60!r},{name},{0.1 * k + 0.01 * t!r},{0.2 * k!r},{1.0 + 0.001 * t!r},1.0,0.0,0.0,0.0\n"
        for t in range(6)
        for k, name in enumerate(("a", "b", "c"))
    )
)

#: Examples per property; ``SIMBENCH_FUZZ_EXAMPLES=5000`` for a long hunt.
EXAMPLES = int(os.environ.get("SIMBENCH_FUZZ_EXAMPLES", "300"))
PROPERTY = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,  # nothing written beside the tests
    derandomize="SIMBENCH_FUZZ_EXAMPLES" not in os.environ,  # the same examples on every run
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _only_input_errors(path: Path, call: Callable[[], object]) -> object | None:
    """``call()``'s result, or None when it raised an InputError naming ``path``; any other
    exception fails the test."""
    try:
        return call()
    except InputError as exc:
        assert str(path) in str(exc), f"{exc} does not name {path}"
        return None


@PROPERTY
@given(data=mutated(SMALL_CSV, separator=",", values=FIELD_VALUES))
def test_pose_csv_parser_returns_a_recording_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.poses import PoseRecording, read_pose_csv

    path = tmp_path_factory.mktemp("csv") / "m.csv"
    path.write_bytes(data)
    rec = _only_input_errors(path, lambda: read_pose_csv(path))
    if rec is not None:
        assert isinstance(rec, PoseRecording) and rec.n_frames >= 1 and len(rec.names) >= 1
        assert np.all(np.diff(rec.time_s) > 0) and np.isfinite(rec.time_s).all()
        ok = rec.valid
        assert np.isfinite(rec.p_w_s[ok]).all() and np.isfinite(rec.R_w_s[ok]).all()


def _wide_spec_text() -> str:
    return WIDE_SPEC + _sensor_spec("a") + _sensor_spec("b")


SMALL_WIDE = (
    "Time,"
    + ",".join(f"{n}_X,{n}_Y,{n}_Z,{n}_W,{n}_QX,{n}_QY,{n}_QZ" for n in ("a", "b"))
    + "\n"
    + "".join(
        f"{t / 60!r}," + ",".join(f"{k + 0.01 * t!r},0.5,1.0,1.0,0.0,0.0,0.0" for k in range(2)) + "\n"
        for t in range(6)
    )
)


@PROPERTY
@given(data=mutated(_wide_spec_text(), separator="=", values=TOML_VALUES))
def test_wide_spec_parser_returns_a_spec_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.wide_csv import WideSpec, read_wide_csv, read_wide_spec

    folder = tmp_path_factory.mktemp("wide")
    path = folder / "spec.toml"
    path.write_bytes(data)
    spec = _only_input_errors(path, lambda: read_wide_spec(path))
    if spec is not None:
        assert isinstance(spec, WideSpec)
        csv_path = folder / "w.csv"
        csv_path.write_text(SMALL_WIDE)
        try:  # the spec is valid: reading with it fails only naming the export (or the spec)
            read_wide_csv(csv_path, spec)
        except InputError as exc:
            assert str(csv_path) in str(exc) or str(path) in str(exc), str(exc)


@PROPERTY
@given(data=mutated(SMALL_WIDE, separator=",", values=FIELD_VALUES))
def test_wide_export_reader_returns_a_recording_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.wide_csv import read_wide_csv, read_wide_spec

    folder = tmp_path_factory.mktemp("widecsv")
    (folder / "spec.toml").write_text(_wide_spec_text())
    path = folder / "w.csv"
    path.write_bytes(data)
    rec = _only_input_errors(path, lambda: read_wide_csv(path, read_wide_spec(folder / "spec.toml")))
    if rec is not None:
        assert np.all(np.diff(rec.time_s) > 0)


CLUSTERS = (
    '[clusters]\npelvis = ["LASIS", "RASIS", "LPSIS", "RPSIS"]\nthigh_r = ["RTHI1", "RTHI2", "RTHI3"]\n'
)


@PROPERTY
@given(data=mutated(CLUSTERS, separator="=", values=TOML_VALUES))
def test_cluster_spec_parser_returns_clusters_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.c3d import read_cluster_spec

    path = tmp_path_factory.mktemp("clusters") / "c.toml"
    path.write_bytes(data)
    clusters = _only_input_errors(path, lambda: read_cluster_spec(path))
    if clusters is not None:
        assert clusters and all(
            isinstance(k, str) and len(v) >= 3 and all(isinstance(x, str) for x in v)
            for k, v in clusters.items()
        )


@PROPERTY
@given(data=mutated(SENSORS, separator="=", values=TOML_VALUES))
def test_sensor_config_parser_returns_a_config_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.sim.sensor_config import SensorConfig, load_sensor_config

    path = tmp_path_factory.mktemp("sensors") / "s.toml"
    path.write_bytes(data)
    config = _only_input_errors(path, lambda: load_sensor_config(str(path)))
    if config is not None:
        assert isinstance(config, SensorConfig)


@PROPERTY
@given(
    data=st.one_of(
        mutated(STUDY, separator="=", values=TOML_VALUES),
        mutated(RANDOM_STUDY, separator="=", values=TOML_VALUES),
    )
)
def test_study_parser_returns_a_checked_study_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    """Every study :func:`load_study` returns passes :func:`check_study` or fails it naming the
    file too: nothing about the file is found only when its trials run."""
    from simbench.experiments.study import Study, check_study, load_study, trials

    path = tmp_path_factory.mktemp("study") / "s.toml"
    path.write_bytes(data)
    study = _only_input_errors(path, lambda: load_study(path))
    if study is not None:
        assert isinstance(study, Study)
        if len(trials(study)) <= 50:
            _only_input_errors(path, lambda: check_study(study))


SMALL_BVH = """HIERARCHY
ROOT hips
{
  OFFSET 0.0 90.0 0.0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT knee
  {
    OFFSET 0.0 -40.0 0.0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0.0 -40.0 0.0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.01
0.0 90.0 0.0 0.0 0.0 0.0 10.0 20.0 30.0
0.5 90.0 0.0 1.0 2.0 3.0 11.0 21.0 31.0
1.0 90.0 0.0 2.0 4.0 6.0 12.0 22.0 32.0
"""


@PROPERTY
@given(data=mutated(SMALL_BVH, separator=" ", values=FIELD_VALUES))
def test_bvh_reader_returns_a_motion_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.bvh import read_bvh

    path = tmp_path_factory.mktemp("bvh") / "clip.bvh"
    path.write_bytes(data)
    got = _only_input_errors(path, lambda: read_bvh(path))
    if got is not None:
        R = got.R_parent_joint
        assert R.shape == (got.n_frames, len(got.names), 3, 3) and np.isfinite(R).all()
        np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
        assert np.isfinite(got.offset_m).all() and got.frame_time_s > 0


SMALL_QPOS_CSV = """time_s,j1.qw,j1.qx,j1.qy,j1.qz
0.00,1.0,0.0,0.0,0.0
0.01,0.9998,0.02,0.0,0.0
0.02,0.9992,0.04,0.0,0.0
0.03,0.9982,0.06,0.0,0.0
"""


@functools.cache
def _linkage_base() -> tuple[object, str]:
    import mujoco

    from simbench.sim.mjcf import compile_spec, read_spec

    m = compile_spec(read_spec("linkage"), "linkage")
    ball = next(
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        for j in range(m.njnt)
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL
    )
    return m, ball


@PROPERTY
@given(data=mutated(SMALL_QPOS_CSV, separator=",", values=FIELD_VALUES))
def test_qpos_csv_reader_returns_a_motion_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.qpos import read_qpos_csv

    m, ball = _linkage_base()
    path = tmp_path_factory.mktemp("qpos") / "motion.csv"
    path.write_bytes(data.replace(b"j1", ball.encode()))
    got = _only_input_errors(path, lambda: read_qpos_csv(path, m))
    if got is not None:
        assert got.frame_time_s > 0 and got.valid.shape == (got.n_frames,)
        for track in got.tracks:
            assert np.isfinite(track.values).all()
            q = track.quaternion_columns
            if q is not None:
                np.testing.assert_allclose(np.linalg.norm(track.values[:, q], axis=1), 1.0, atol=1e-9)


@PROPERTY
@given(data=mutated(SMALL_CSV, separator=",", values=FIELD_VALUES))
def test_pose_csv_motion_returns_tracks_or_names_the_file(tmp_path_factory, data: bytes) -> None:
    from simbench.io.read import read_poses
    from simbench.sim.pose_model import poses_recorded

    path = tmp_path_factory.mktemp("poses") / "poses.csv"
    path.write_bytes(data)
    got = _only_input_errors(path, lambda: poses_recorded(read_poses(path)))
    if got is not None:
        assert got.frame_time_s > 0 and all(np.isfinite(t.values).all() for t in got.tracks)
