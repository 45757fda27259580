"""OpenSim joint angles (``.mot``, ``.sto``) as a recorded motion.

**The file** is an OpenSim Storage, as the IK tool writes a ``.mot`` and OpenSim 4 a ``.sto``::

    Coordinates
    version=1
    nRows=211
    nColumns=24
    inDegrees=yes
    endheader
    time    pelvis_tilt    pelvis_list    ...
    0.5     4.76281529     0.40342044     ...

Header lines up to ``endheader``: ``key=value`` (other lines, a name or free text, are skipped).
``inDegrees=yes``: rotational coordinates in degrees (``no``, or no such key: radians, OpenSim's
default); translations are metres either way. ``nRows`` and ``nColumns`` (``time`` included) are
checked against the table when given; a ``DataType`` other than ``double`` (OpenSense's
``Quaternion`` orientations) is refused. Then one line of column labels, the first ``time`` (s),
tab-separated (or whitespace-separated), and one row per frame, every value a finite number, the
time stamps on one constant period (:func:`~simbench.io.recorded.frame_grid`; dropped frames are
filled). A state column as Moco and the Forward tool name it, ``/jointset/<joint>/<coordinate>/value``,
is the coordinate ``<coordinate>``; other state columns (``.../speed``, ``/forceset/...``) are
skipped. Errors name the file and line.

**On the humanoid** (``humanoid``, ``humanoid-female``: any model with the humanoid's joints and
body frames) the columns are the coordinates of OpenSim's standard gait models -- gait2392/2354,
Hamner 2010 full body, Rajagopal 2016 (and its OpenSense and Lai-Uhlrich 2023 versions) -- and
:data:`HUMANOID_COORDINATES` maps them onto the humanoid's joints:

=================== =========== ================ ===========================================
coordinate          joint       axis             positive
=================== =========== ================ ===========================================
pelvis_tilt         root        +z (-y)          pelvis turns front up (about the right)
pelvis_list         root        +x (+x)          right side drops
pelvis_rotation     root        +y (+z)          front turns to the left
pelvis_tx, _ty, _tz root        x, y, z          position (x, -z, y - 0.94 m + standing height)
hip_flexion_r/_l    hip_r/_l    +z (-y)          thigh forward
hip_adduction_r/_l  hip_r/_l    +x / -x          thigh towards the midline
hip_rotation_r/_l   hip_r/_l    +y / -y          internal rotation
knee_angle_r/_l     knee_r/_l   +z (-y)          extension (gait2392: flexion negative; below)
ankle_angle_r/_l    ankle_r/_l  talocrural       dorsiflexion (toes up)
lumbar_extension    lumbar      +z (-y)          trunk leans back
lumbar_bending      lumbar      +x (+x)          trunk leans right
lumbar_rotation     lumbar      +y (+z)          trunk turns left
arm_flex_r/_l       shoulder    +z (-y)          arm forward
arm_add_r/_l        shoulder    +x / -x          arm towards the midline (abduction negative)
arm_rot_r/_l        shoulder    +y / -y          internal rotation
elbow_flex_r/_l     elbow       humero-ulnar     flexion
pro_sup_r/_l        elbow       radio-ulnar      pronation (0: palm forward, supinated)
wrist_flex_r/_l     wrist       +z (-y)          flexion (towards the palm)
wrist_dev_r/_l      wrist       +x / -x          ulnar deviation
=================== =========== ================ ===========================================

Axes map into simbench's frame (x forward, y to the left, z up) by ``v -> C v``, ``C``
:data:`~simbench.io.bvh.Y_UP_TO_Z_UP`. At all coordinates zero both bodies stand in their
reference pose (OpenSim's: upright, arms hanging, palms forward; the humanoid's: the same, every
body frame parallel to the world's), so each OpenSim body frame maps onto its humanoid segment's
by ``C``.

- **Composition.** A humanoid joint's rotation is its coordinates' rotations composed in the
  table's order, each about the axis as turned by the ones before (OpenSim's ``CustomJoint``:
  ``R = R(a1, q1) R(a2, q2) R(a3, q3)``, body-fixed), as a quaternion of ``C R C^T``. The elbow
  composes OpenSim's elbow and radio-ulnar joints (the humanoid's forearm turns with the radius);
  thoracic and neck have no coordinate and stay at their reference.
- **Axes** (the table's column: OpenSim's frame, x forward, y up, z right, a left side's after
  the slash; simbench's in brackets) are the models' own: principal where gait2392, Hamner and
  Rajagopal turn about a principal axis, else the oblique axes the three share, talocrural
  :data:`ANKLE_AXIS_R` (11.8 deg off z), humero-ulnar :data:`ELBOW_AXIS_R` (13.2 deg off z) and
  radio-ulnar :data:`PRO_SUP_AXIS_R` (3.3 deg off y), a left side's with x and y negated. So a
  segment turns in the humanoid as in those models: OpenSim 4.6 posing them at random
  coordinates, every segment of gait2392 and Hamner is the humanoid's to 2e-14 deg, every one of
  Rajagopal's but the shank to 2e-4 deg (its frames are written to 6 digits). Not carried:
  Rajagopal's walker knee turns about an axis 4 deg off z and couples tibial rotation and
  adduction to flexion (the humanoid's shank is off its by 2.8, 6.8, 10.0 and 11.2 deg at 10, 30,
  60 and 90 deg of flexion), the knees' coupled translations, and the joint centres and segment
  lengths (the humanoid's are its own).
- **Knee sign.** gait2392/2354, gait10dof18musc and Hamner turn the knee about +z: flexion is
  negative (range -120..10 deg); the Rajagopal models turn it the other way: flexion positive
  (0..120 deg). A file with Rajagopal's patella coordinates ``knee_angle_r_beta``/``_l_beta`` is
  Rajagopal's; else one whose knee angles pass +10 deg is, and one whose pass -10 deg is
  gait2392's (a knee hyperextends neither way beyond 10 deg); both is an error; knee angles
  within +-10 deg are taken as gait2392's. :attr:`RecordedMotion.notes` says which.
- **Pelvis.** Its rotations give the root's orientation in the world, its translations (in
  OpenSim's ground) the root's position: the OpenSim pelvis standing at ``pelvis_ty`` =
  :data:`PELVIS_STANDING_HEIGHT_M` (0.94 m, Rajagopal 2016's default; gait2392's is 0.95) puts the
  humanoid's pelvis at its own standing height (its ``qpos0``: 1.05 m, the female 1.024 m), so
  ``z = pelvis_ty - 0.94 m + standing height``, ``x = pelvis_tx``, ``y = -pelvis_tz``; a scaled
  subject's pelvis sits that much higher or lower. The OpenSim pelvis origin (midway between
  the anterior superior iliac spines, 5.6-7.1 cm in front of and 6.6-7.8 cm above the hip
  centres) is placed at the humanoid's (8 cm above the hip centres, over them).
- Coordinates in :data:`IGNORED` (subtalar, metatarsophalangeal, Rajagopal's patella) have no
  humanoid counterpart: skipped, named in the notes. Any other column is an error (a file for
  another model). A joint no column moves stays at its reference pose.

**On any other model** the columns name the model's own joints, as
:mod:`simbench.io.skeleton_osim` names an exported skeleton's coordinates (so IK results on that
``.osim`` play on the exported MJCF): a hinge ``<joint>`` or, for a joint ``<stem>_joint``,
``<stem>_angle`` (rad, or deg); a slide ``<joint>`` (m); a ball joint ``<stem>_rx``, ``_ry``,
``_rz`` (OpenSim's ``BallJoint``: body-fixed X-Y-Z angles); a free joint those and ``<stem>_tx``,
``_ty``, ``_tz`` (``FreeJoint``: position in the parent, m). No frame is converted: the model's
own. A joint's coordinates come all or none. :func:`storage_text` writes a file.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import mujoco
import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_write_text
from simbench.io.bvh import Y_UP_TO_Z_UP
from simbench.io.qpos import model_joints
from simbench.io.recorded import RecordedMotion, Track, on_frame_grid

#: ``C``: OpenSim's ground (x forward, y up, z right) into simbench's world (x forward, y left, z up).
C = Y_UP_TO_Z_UP

#: The OpenSim pelvis height (``pelvis_ty``, m) that is the humanoid's standing height.
PELVIS_STANDING_HEIGHT_M = 0.94

#: Knee angles beyond this (deg) either way are flexion in one convention, hyperextension in the other.
KNEE_HYPEREXTENSION_DEG = 10.0

_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
_NX, _NY = (-1.0, 0.0, 0.0), (0.0, -1.0, 0.0)
#: The oblique axes gait2392, Hamner and Rajagopal share (right side; the left's mirrors x and y):
#: the talocrural axis in the tibia, the elbow's in the humerus, the radio-ulnar in the ulna.
ANKLE_AXIS_R = (-0.10501355, -0.17402245, 0.97912632)
ELBOW_AXIS_R = (0.22604696, 0.022269, 0.97386183)
PRO_SUP_AXIS_R = (0.05639803, 0.99840646, 0.001952)


def _left(axis: tuple[float, float, float]) -> tuple[float, float, float]:
    return (-axis[0], -axis[1], axis[2])


@dataclass(frozen=True)
class Coordinate:
    """Where an OpenSim coordinate goes on the humanoid.

    Attributes:
        joint: the humanoid's joint.
        axis: ``(3,)`` axis in OpenSim's frame (normalised where used): a rotation's, or a
            translation's direction.
        translation: a pelvis translation (m), not a rotation.
    """

    joint: str
    axis: tuple[float, float, float]
    translation: bool = False


#: OpenSim coordinate -> the humanoid's joint (module docstring); a joint's coordinates compose in
#: this order.
HUMANOID_COORDINATES: dict[str, Coordinate] = {
    "pelvis_tilt": Coordinate("root", _Z),
    "pelvis_list": Coordinate("root", _X),
    "pelvis_rotation": Coordinate("root", _Y),
    "pelvis_tx": Coordinate("root", _X, translation=True),
    "pelvis_ty": Coordinate("root", _Y, translation=True),
    "pelvis_tz": Coordinate("root", _Z, translation=True),
    "hip_flexion_r": Coordinate("hip_r", _Z),
    "hip_adduction_r": Coordinate("hip_r", _X),
    "hip_rotation_r": Coordinate("hip_r", _Y),
    "hip_flexion_l": Coordinate("hip_l", _Z),
    "hip_adduction_l": Coordinate("hip_l", _NX),
    "hip_rotation_l": Coordinate("hip_l", _NY),
    "knee_angle_r": Coordinate("knee_r", _Z),
    "knee_angle_l": Coordinate("knee_l", _Z),
    "ankle_angle_r": Coordinate("ankle_r", ANKLE_AXIS_R),
    "ankle_angle_l": Coordinate("ankle_l", _left(ANKLE_AXIS_R)),
    "lumbar_extension": Coordinate("lumbar", _Z),
    "lumbar_bending": Coordinate("lumbar", _X),
    "lumbar_rotation": Coordinate("lumbar", _Y),
    "arm_flex_r": Coordinate("shoulder_r", _Z),
    "arm_add_r": Coordinate("shoulder_r", _X),
    "arm_rot_r": Coordinate("shoulder_r", _Y),
    "arm_flex_l": Coordinate("shoulder_l", _Z),
    "arm_add_l": Coordinate("shoulder_l", _NX),
    "arm_rot_l": Coordinate("shoulder_l", _NY),
    "elbow_flex_r": Coordinate("elbow_r", ELBOW_AXIS_R),
    "pro_sup_r": Coordinate("elbow_r", PRO_SUP_AXIS_R),
    "elbow_flex_l": Coordinate("elbow_l", _left(ELBOW_AXIS_R)),
    "pro_sup_l": Coordinate("elbow_l", _left(PRO_SUP_AXIS_R)),
    "wrist_flex_r": Coordinate("wrist_r", _Z),
    "wrist_dev_r": Coordinate("wrist_r", _X),
    "wrist_flex_l": Coordinate("wrist_l", _Z),
    "wrist_dev_l": Coordinate("wrist_l", _NX),
}

#: Coordinates of the standard gait models with no humanoid counterpart: skipped, and why.
IGNORED: dict[str, str] = {
    **{f"subtalar_angle_{s}": "the humanoid's foot is one body" for s in "rl"},
    **{f"mtp_angle_{s}": "the humanoid's foot has no toes" for s in "rl"},
    **{f"knee_angle_{s}_beta": "Rajagopal's patella, coupled to the knee" for s in "rl"},
    **{f"knee_angle_pat_{s}": "the patella, coupled to the knee" for s in "rl"},
}

#: The humanoid's joints and their kinds: a model with all of them (and body frames parallel to
#: their parents' at ``qpos0``) takes :data:`HUMANOID_COORDINATES`.
HUMANOID_JOINTS = {
    "root": "free",
    **{
        j: "ball"
        for j in (
            "lumbar thoracic neck shoulder_l shoulder_r elbow_l elbow_r wrist_l wrist_r hip_l hip_r "
            "knee_l knee_r ankle_l ankle_r"
        ).split()
    },
}

#: The models that take the mapping table, for messages.
MAPPED_MODELS = "humanoid, humanoid-female (a model with the humanoid's joints)"

_STATE_VALUE = re.compile(r"^/jointset/[^/]+/([^/]+)/value$")


@dataclass(frozen=True)
class Storage:
    """An OpenSim Storage file's table as written.

    Attributes:
        source: the file.
        header: every ``key=value`` of the header.
        labels: ``(C,)`` the column labels after ``time``.
        time_s: ``(F,)`` s.
        values: ``(F, C)`` as written (degrees where :attr:`in_degrees`).
        in_degrees: ``inDegrees=yes``.
        labels_line: the line of the column labels (1-based).
        row_lines: ``(F,)`` the line of each row.
    """

    source: str
    header: dict[str, str]
    labels: tuple[str, ...]
    time_s: np.ndarray
    values: np.ndarray
    in_degrees: bool
    labels_line: int
    row_lines: tuple[int, ...]

    @property
    def first_line(self) -> int:
        """The line of the first row."""
        return self.row_lines[0]


def _int_key(src: str, header: dict[str, tuple[str, int]], key: str) -> tuple[int, int] | None:
    if key not in header:
        return None
    text, line = header[key]
    try:
        value = int(text)
    except ValueError:
        raise InputError(f"{src}, line {line}: {key}={text!r} is not a whole number") from None
    return value, line


def read_storage(path: str | os.PathLike[str]) -> Storage:
    """The table of an OpenSim Storage file (module docstring).

    Raises:
        InputError: naming file and line: no ``endheader``, a ``DataType`` that is not ``double``,
            ``inDegrees`` neither ``yes`` nor ``no``, no column labels or a first one not ``time``,
            labels named twice, a row with another count of fields, a value that is not a finite
            number, ``nRows``/``nColumns`` that do not count the table.
    """
    src = str(path)
    lines = read_text(path).splitlines()
    if not any(line.strip() for line in lines):
        raise InputError(
            f"{src}: empty file; expected an OpenSim storage (a header, endheader, column labels, rows)"
        )
    end = next((k for k, line in enumerate(lines) if line.strip() == "endheader"), None)
    if end is None:
        raise InputError(
            f"{src}: not an OpenSim storage file: no line 'endheader' in its {len(lines)} lines (expected a "
            "header such as inDegrees=yes, then endheader, then the column labels)"
        )
    header: dict[str, tuple[str, int]] = {}
    for k, line in enumerate(lines[:end]):
        if "=" in line:
            key, value = line.split("=", 1)
            header[key.strip()] = (value.strip(), k + 1)
    if "DataType" in header and header["DataType"][0].lower() not in ("double", "float"):
        kind, line = header["DataType"]
        hint = " (OpenSense's sensor orientations, not joint angles)" if kind == "Quaternion" else ""
        raise InputError(
            f"{src}, line {line}: DataType={kind}{hint}: expected a table of coordinates (double)"
        )
    in_degrees = False
    if "inDegrees" in header:
        flag, line = header["inDegrees"]
        if flag.lower() not in ("yes", "no"):
            raise InputError(f"{src}, line {line}: inDegrees={flag!r}; expected yes or no")
        in_degrees = flag.lower() == "yes"
    at = next((k for k in range(end + 1, len(lines)) if lines[k].strip()), None)
    if at is None:
        raise InputError(f"{src}, line {end + 1}: no column labels after endheader")
    text = lines[at].strip()
    labels = [x.strip() for x in text.split("\t")] if "\t" in text else text.split()
    if "" in labels:
        raise InputError(f"{src}, line {at + 1}: an empty column label in {labels}")
    if labels[0].lower() != "time":
        raise InputError(f"{src}, line {at + 1}: expected the first column 'time', got {labels[0]!r}")
    twice = sorted({x for x in labels if labels.count(x) > 1})
    if twice:
        raise InputError(f"{src}, line {at + 1}: columns named twice: {twice}")
    numbers = [(k + 1, line.split()) for k, line in enumerate(lines[at + 1 :], start=at + 1) if line.strip()]
    for number, fields in numbers:
        if len(fields) != len(labels):
            raise InputError(
                f"{src}, line {number}: {len(fields)} fields; the column labels (line {at + 1}) name "
                f"{len(labels)}"
            )
    rows = _table(src, numbers, labels)
    counts = {"nRows": (len(numbers), "rows"), "nColumns": (len(labels), "columns (time included)")}
    for key, (actual, what) in counts.items():
        given = _int_key(src, header, key)
        if given is not None and given[0] != actual:
            raise InputError(f"{src}, line {given[1]}: {key}={given[0]}, but the table has {actual} {what}")
    if not numbers:
        raise InputError(f"{src}, line {at + 1}: no rows after the column labels")
    return Storage(
        source=src,
        header={k: v for k, (v, _) in header.items()},
        labels=tuple(labels[1:]),
        time_s=rows[:, 0],
        values=rows[:, 1:],
        in_degrees=in_degrees,
        labels_line=at + 1,
        row_lines=tuple(number for number, _ in numbers),
    )


def _table(src: str, numbers: list[tuple[int, list[str]]], labels: list[str]) -> np.ndarray:
    """The rows' numbers ``(F, C)``; naming the first field that is not a finite number."""
    try:
        rows = np.array([fields for _, fields in numbers], dtype=float).reshape(len(numbers), len(labels))
    except ValueError:
        for number, fields in numbers:
            for label, x in zip(labels, fields, strict=True):
                try:
                    float(x)
                except ValueError:
                    raise InputError(
                        f"{src}, line {number}, column {label!r}: {x!r} is not a number"
                    ) from None
        raise InputError(f"{src}: the rows are not a table of numbers") from None
    bad = np.argwhere(~np.isfinite(rows))
    if bad.size:
        i, c = bad[0]
        raise InputError(
            f"{src}, line {numbers[i][0]}, column {labels[c]!r}: {numbers[i][1][c]!r} is not a finite number "
            f"({len(bad)} such value(s))"
        )
    return rows


def _some(names: list[str], k: int = 6) -> str:
    """The first ``k`` names, and how many more."""
    more = f" and {len(names) - k} more" if len(names) > k else ""
    return f"{names[:k]}{more}"


def _axis_quaternion(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``(F, 4)`` wxyz of rotations by ``angle`` ``(F,)`` rad about the unit ``axis`` ``(3,)``."""
    half = 0.5 * np.asarray(angle, dtype=float)
    return np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis[None, :]], axis=1)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products ``a b`` of quaternions ``(F, 4)`` wxyz (the rotation ``R_a R_b``)."""
    aw, av = a[:, :1], a[:, 1:]
    bw, bv = b[:, :1], b[:, 1:]
    w = aw * bw - np.sum(av * bv, axis=1, keepdims=True)
    return np.concatenate([w, aw * bv + bw * av + np.cross(av, bv)], axis=1)


def _compose(axes: list[np.ndarray], angles: list[np.ndarray], n: int) -> np.ndarray:
    """``(n, 4)`` wxyz of ``R(a1, q1) R(a2, q2) ...`` (body-fixed, in order)."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    for axis, angle in zip(axes, angles, strict=True):
        q = _quat_mul(q, _axis_quaternion(axis, angle))
    return q


def is_humanoid(m: mujoco.MjModel) -> bool:
    """``m`` has the humanoid's joints (:data:`HUMANOID_JOINTS`), each on a body whose frame is
    parallel to its parent's at ``qpos0``: :data:`HUMANOID_COORDINATES` applies."""
    kinds = {name: kind for name, kind, _ in model_joints(m)}
    if any(kinds.get(j) != k for j, k in HUMANOID_JOINTS.items()):
        return False
    for j in HUMANOID_JOINTS:
        body = int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)])
        if not np.allclose(m.body_quat[body], [1.0, 0.0, 0.0, 0.0], atol=1e-12):
            return False
    return True


def _coordinate_columns(st: Storage) -> tuple[dict[str, np.ndarray], list[str]]:
    """``{coordinate: (F,) as written}`` and the state columns skipped (not coordinate values)."""
    columns, skipped = {}, []
    for c, label in enumerate(st.labels):
        if label.startswith("/"):
            match = _STATE_VALUE.match(label)
            if match is None:
                skipped.append(label)
                continue
            label = match.group(1)
            if label in columns:
                raise InputError(f"{st.source}, line {st.labels_line}: coordinate {label!r} named twice")
        columns[label] = st.values[:, c]
    return columns, skipped


def _check_half_turn(st: Storage, columns: dict[str, np.ndarray]) -> None:
    """Refuse a joint angle (the pelvis's aside) beyond half a turn: no joint of the humanoid turns
    that far, and OpenSim's analyses write degrees under ``inDegrees=no``."""
    half = 180.0 if st.in_degrees else math.pi
    for name, values in columns.items():
        coord = HUMANOID_COORDINATES.get(name)
        if coord is None or coord.translation or coord.joint == "root":
            continue
        beyond = np.flatnonzero(np.abs(values) > half)
        if beyond.size:
            k = int(beyond[0])
            unit = "deg" if st.in_degrees else "rad"
            hint = "" if st.in_degrees else " (inDegrees=no: if the angles are degrees, say inDegrees=yes)"
            raise InputError(
                f"{st.source}, line {st.row_lines[k]}, column {name!r}: {values[k]:.6g} {unit} is beyond "
                f"half a turn, which no joint turns{hint}"
            )


def _knee_sign(st: Storage, columns: dict[str, np.ndarray]) -> tuple[float, str]:
    """``(+1, note)`` for gait2392's knee convention (flexion negative), ``(-1, note)`` for
    Rajagopal's (module docstring)."""
    knees = [k for k in ("knee_angle_r", "knee_angle_l") if k in columns]
    if not knees:
        return 1.0, ""
    beta = [k for k in ("knee_angle_r_beta", "knee_angle_l_beta") if k in columns]
    rajagopal = "knee_angle: Rajagopal's convention (flexion positive)"
    if beta:
        return -1.0, f"{rajagopal}: the file has {beta[0]}"
    deg = np.concatenate([columns[k] for k in knees])
    deg = deg if st.in_degrees else np.rad2deg(deg)
    lo, hi, limit = float(deg.min()), float(deg.max()), KNEE_HYPEREXTENSION_DEG
    if hi > limit and lo < -limit:
        raise InputError(
            f"{st.source}: knee angles from {lo:.4g} to {hi:.4g} deg: neither gait2392's (flexion negative, "
            f"at most +{limit:g}) nor Rajagopal's (flexion positive, at least -{limit:g}) convention"
        )
    if hi > limit:
        return -1.0, f"{rajagopal}: knee angles up to {hi:.4g} deg"
    gait2392 = "knee_angle: gait2392's convention (flexion negative)"
    if lo < -limit:
        return 1.0, f"{gait2392}: knee angles down to {lo:.4g} deg"
    return 1.0, f"{gait2392}, taken: knee angles within +-{limit:g} deg say neither"


def _humanoid_tracks(
    st: Storage, m: mujoco.MjModel, model: str, columns: dict[str, np.ndarray]
) -> tuple[list[Track], list[str]]:
    unknown = [c for c in columns if c not in HUMANOID_COORDINATES and c not in IGNORED]
    if unknown:
        raise InputError(
            f"{st.source}, line {st.labels_line}: column(s) {_some(unknown)} name no coordinate of the "
            f"mapping table onto the {model} model (OpenSim's gait2392, Hamner and Rajagopal coordinates: "
            "docs/recorded-motion.md); a file for another model plays on a model whose joints it names"
        )
    _check_half_turn(st, columns)
    sign, knee_note = _knee_sign(st, columns)
    notes = [knee_note] if knee_note else []
    ignored = [c for c in columns if c in IGNORED]
    if ignored:
        notes.append(
            "skipped (no humanoid counterpart): " + ", ".join(f"{c} ({IGNORED[c]})" for c in ignored)
        )
    n = st.time_s.size
    qpos0 = np.asarray(m.qpos0, dtype=float)
    tracks = []
    for joint, kind, adr in model_joints(m):
        mine = [(c, HUMANOID_COORDINATES[c]) for c in HUMANOID_COORDINATES if c in columns]
        mine = [(c, k) for c, k in mine if k.joint == joint]
        if not mine:
            continue
        axes, angles = [], []
        offset = np.zeros((n, 3))
        for name, coord in mine:
            value = columns[name]
            if coord.translation:
                ref = PELVIS_STANDING_HEIGHT_M if name == "pelvis_ty" else 0.0
                offset += np.outer(value - ref, C @ np.array(coord.axis))
                continue
            angle = np.deg2rad(value) if st.in_degrees else np.array(value, dtype=float)
            axes.append(C @ np.array(coord.axis) / np.linalg.norm(coord.axis))
            angles.append(sign * angle if name.startswith("knee_angle") else angle)
        q = _compose(axes, angles, n)
        if kind == "free":
            values = np.concatenate([qpos0[adr : adr + 3] + offset, q], axis=1)
        else:
            values = q
        tracks.append(Track(joint, kind, values))
    if not tracks:
        raise InputError(f"{st.source}, line {st.labels_line}: no column moves a joint of the {model} model")
    return tracks, notes


def _stem(joint: str) -> str:
    return joint.removesuffix("_joint") if joint.endswith("_joint") and joint != "_joint" else joint


def _model_tracks(st: Storage, m: mujoco.MjModel, model: str, columns: dict[str, np.ndarray]) -> list[Track]:
    """Tracks of a model whose joints the columns name (module docstring)."""
    used: set[str] = set()
    tracks = []
    n = st.time_s.size

    def angle(c: str) -> np.ndarray:
        return np.deg2rad(columns[c]) if st.in_degrees else np.array(columns[c], dtype=float)

    for joint, kind, _ in model_joints(m):
        stem = _stem(joint)
        if kind in ("hinge", "slide"):
            names = [joint] if kind == "slide" or stem == joint else [joint, f"{stem}_angle"]
            names = [x for x in names if x in columns]
            if len(names) > 1:
                raise InputError(
                    f"{st.source}, line {st.labels_line}: hinge {joint!r} is named twice: {names}"
                )
            if names:
                value = angle(names[0]) if kind == "hinge" else np.array(columns[names[0]], dtype=float)
                tracks.append(Track(joint, kind, value[:, None]))
                used.update(names)
            continue
        rot = [f"{stem}_r{a}" for a in "xyz"]
        names = rot + ([f"{stem}_t{a}" for a in "xyz"] if kind == "free" else [])
        have = [x in columns for x in names]
        if not any(have):
            continue
        if not all(have):
            missing = [x for x, h in zip(names, have, strict=True) if not h]
            raise InputError(
                f"{st.source}, line {st.labels_line}: {kind} joint {joint!r} needs coordinates {names}; "
                f"missing {missing}"
            )
        q = _compose([np.eye(3)[i] for i in range(3)], [angle(x) for x in rot], n)
        if kind == "free":
            q = np.concatenate([np.stack([columns[x] for x in names[3:]], axis=1), q], axis=1)
        tracks.append(Track(joint, kind, q))
        used.update(names)
    unknown = [c for c in columns if c not in used]
    if unknown:
        gait = [c for c in unknown if c in HUMANOID_COORDINATES or c in IGNORED]
        hint = (
            f"; {gait[0]!r} is a coordinate of OpenSim's gait models: they map onto {MAPPED_MODELS} only"
            if gait
            else f"; OpenSim's gait-model coordinates map onto {MAPPED_MODELS} only"
        )
        joints = [f"{j} ({k})" for j, k, _ in model_joints(m)]
        raise InputError(
            f"{st.source}, line {st.labels_line}: column(s) {_some(unknown)} name no coordinate of the model "
            f"{model}; its joints: {', '.join(joints)} (a hinge's or slide's coordinate is its name or "
            f"<stem>_angle, a ball joint's <stem>_rx _ry _rz, a free joint's those and <stem>_tx _ty _tz)"
            f"{hint}"
        )
    if not tracks:
        raise InputError(
            f"{st.source}, line {st.labels_line}: no column names a coordinate of the model {model}"
        )
    return tracks


def read_opensim_motion(path: str | os.PathLike[str], m: mujoco.MjModel, model: str) -> RecordedMotion:
    """An OpenSim ``.mot``/``.sto`` of coordinates as a recorded motion of ``m`` (module docstring).

    Args:
        path: the file.
        m: the model it plays on, compiled as read (no sensors, no driver).
        model: its name (for messages).

    Raises:
        InputError: naming file and line: what :func:`read_storage` refuses, a column that names no
            coordinate (of the mapping table on the humanoid, of the model's joints otherwise), a
            joint given some of its coordinates, time stamps off a constant rate.
    """
    st = read_storage(path)
    columns, skipped = _coordinate_columns(st)
    notes = []
    if skipped:
        notes.append(
            f"state columns that are not coordinate values skipped: {len(skipped)} ({skipped[0]}, ...)"
        )
    if is_humanoid(m):
        tracks, mapped = _humanoid_tracks(st, m, model, columns)
        notes = [f"OpenSim coordinates mapped onto the {model} model's joints", *mapped, *notes]
    else:
        tracks = _model_tracks(st, m, model, columns)
    unit = "degrees (inDegrees=yes)" if st.in_degrees else "radians"
    if "inDegrees" not in st.header:
        unit = "radians (no inDegrees: OpenSim's default)"
    notes.append(f"angles in {unit}")
    return on_frame_grid(
        st.source, st.time_s, tracks, "opensim", lines=np.asarray(st.row_lines), notes=tuple(notes)
    )


def storage_text(
    labels: list[str] | tuple[str, ...],
    time_s: np.ndarray,
    values: np.ndarray,
    *,
    in_degrees: bool,
    name: str = "Coordinates",
) -> str:
    """An OpenSim Storage of coordinates (the IK tool's ``.mot`` layout), values to 17 digits.

    Args:
        labels: ``(C,)`` column labels after ``time``.
        time_s: ``(F,)`` s.
        values: ``(F, C)``; rotations in degrees if ``in_degrees``, else radians; translations m.
        in_degrees: written as ``inDegrees``.
        name: the first line.
    """
    time_s = np.asarray(time_s, dtype=float)
    values = np.asarray(values, dtype=float)
    labels = list(labels)
    if values.shape != (time_s.size, len(labels)):
        raise InputError(f"Expected values of shape ({time_s.size}, {len(labels)}), got {values.shape}")
    bad = [x for x in labels if not x or any(ch.isspace() for ch in x)]
    if bad or not all(math.isfinite(v) for v in values.ravel()):
        raise InputError(f"Expected labels without white space and finite values; labels {bad or labels}")
    lines = [
        name,
        "version=1",
        f"nRows={time_s.size}",
        f"nColumns={len(labels) + 1}",
        f"inDegrees={'yes' if in_degrees else 'no'}",
        "endheader",
        "\t".join(["time", *labels]),
    ]
    lines += ["\t".join(repr(float(x)) for x in (t, *row)) for t, row in zip(time_s, values, strict=True)]
    return "\n".join(lines) + "\n"


def write_storage(
    path: str | os.PathLike[str],
    labels: list[str] | tuple[str, ...],
    time_s: np.ndarray,
    values: np.ndarray,
    *,
    in_degrees: bool,
) -> None:
    """Write :func:`storage_text` atomically."""
    atomic_write_text(path, storage_text(labels, time_s, values, in_degrees=in_degrees))


__all__ = [
    "HUMANOID_COORDINATES",
    "HUMANOID_JOINTS",
    "IGNORED",
    "PELVIS_STANDING_HEIGHT_M",
    "Coordinate",
    "Storage",
    "is_humanoid",
    "read_opensim_motion",
    "read_storage",
    "storage_text",
    "write_storage",
]
