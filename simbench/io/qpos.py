"""MuJoCo ``qpos`` series: a recorded motion for any MJCF model.

**NumPy archive** (``.npz``): ``qpos`` ``(F, nq)`` (every coordinate of the model, in MuJoCo's
order) or, with ``joints`` (a list of joint names), ``(F, sum of their widths)`` (the named joints'
coordinates one after the other; the others stay at the model's ``qpos0``); ``time_s`` ``(F,)``
s, or ``rate_hz`` (a number, Hz, the first frame at 0 s); optionally ``model`` (the model it was
recorded on, e.g. ``humanoid``, used when no model is given).

**CSV** (``.csv``): a header ``time_s`` then one column per coordinate: a hinge's or slide's is
named after its joint (rad or m), a ball joint's ``<joint>.qw``, ``.qx``, ``.qy``, ``.qz``, a free
joint's ``<joint>.x``, ``.y``, ``.z`` (m, world) then its four quaternion columns; one row per frame.
Joints without columns stay at ``qpos0``; a column naming no joint of the model is an error.

Units are MuJoCo's (SI, radians, quaternions wxyz); quaternions are normalised (one off unit norm
by more than 1e-3 is an error: not a rotation). :func:`write_qpos_npz` writes the archive.
"""

from __future__ import annotations

import csv
import io
import os

import mujoco
import numpy as np

from simbench.errors import InputError, read_text
from simbench.io.atomic import atomic_open
from simbench.io.recorded import WIDTH, RecordedMotion, Track, on_frame_grid

#: The coordinates of each joint kind, as CSV column suffixes (a hinge's or slide's: none).
COLUMNS = {
    "free": ("x", "y", "z", "qw", "qx", "qy", "qz"),
    "ball": ("qw", "qx", "qy", "qz"),
    "hinge": ("",),
    "slide": ("",),
}

#: A quaternion off unit norm by more than this is not a rotation.
QUAT_NORM_TOLERANCE = 1e-3

_KINDS = {
    mujoco.mjtJoint.mjJNT_FREE: "free",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
}


def model_joints(m: mujoco.MjModel) -> list[tuple[str, str, int]]:
    """``(name, kind, qpos address)`` of every joint of ``m``, in MuJoCo's order."""
    return [
        (
            mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}",
            _KINDS[mujoco.mjtJoint(int(m.jnt_type[j]))],
            int(m.jnt_qposadr[j]),
        )
        for j in range(m.njnt)
    ]


def npz_model(path: str | os.PathLike[str]) -> str | None:
    """The ``model`` an archive names, or ``None``."""
    with _open_npz(path) as z:
        return str(np.asarray(z["model"]).item()) if "model" in z.files else None


def _open_npz(path: str | os.PathLike[str]) -> np.lib.npyio.NpzFile:
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{path}: not a NumPy .npz archive: {exc}") from None


def _check_quaternions(path: str, name: str, q: np.ndarray, lines: np.ndarray | None) -> np.ndarray:
    with np.errstate(over="ignore"):  # a component of 1e308 has an infinite norm: not a rotation
        norm = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(~(np.abs(norm - 1) <= QUAT_NORM_TOLERANCE))
    if bad.size:
        where = f"line {lines[bad[0]]}" if lines is not None else f"frame {bad[0]}"
        raise InputError(
            f"{path}, {where}: joint {name!r}'s quaternion has norm {norm[bad[0]]:.6g} (expected 1 within "
            f"{QUAT_NORM_TOLERANCE:g}; {bad.size} such frame(s))"
        )
    return q / norm[:, None]


def _tracks(
    path: str, m: mujoco.MjModel, columns: dict[str, np.ndarray], lines: np.ndarray | None
) -> list[Track]:
    """Tracks from ``{column name: (F,) values}`` named as in the module docstring (``lines``: each
    frame's line in the file, or ``None`` for an archive)."""
    used: set[str] = set()
    tracks = []
    for name, kind, _ in model_joints(m):
        names = [f"{name}.{c}" if c else name for c in COLUMNS[kind]]
        have = [c in columns for c in names]
        if not any(have):
            continue
        if not all(have):
            missing = [c for c, h in zip(names, have, strict=True) if not h]
            raise InputError(f"{path}: {kind} joint {name!r} needs columns {names}; missing {missing}")
        values = np.stack([columns[c] for c in names], axis=1)
        q = {"free": slice(3, 7), "ball": slice(0, 4)}.get(kind)
        if q is not None:
            values[:, q] = _check_quaternions(path, name, values[:, q], lines)
        tracks.append(Track(name, kind, values))
        used.update(names)
    unknown = [c for c in columns if c not in used]
    if unknown:
        joints = [f"{n} ({k})" for n, k, _ in model_joints(m)]
        raise InputError(
            f"{path}: column(s) {unknown} name no coordinate of the model; its joints: {', '.join(joints)} "
            "(a ball joint's columns are <joint>.qw .qx .qy .qz, a free joint's <joint>.x .y .z .qw .qx "
            ".qy .qz)"
        )
    if not tracks:
        raise InputError(f"{path}: no column names a joint of the model")
    return tracks


def read_qpos_npz(path: str | os.PathLike[str], m: mujoco.MjModel) -> RecordedMotion:
    """A ``qpos`` archive (module docstring) as a recorded motion of ``m``.

    Raises:
        InputError: naming the file: a missing array, shapes that do not fit the model, values that are
            not finite, time stamps off a constant rate.
    """
    src = str(path)
    with _open_npz(path) as z:
        if "qpos" not in z.files:
            raise InputError(f"{src}: no array 'qpos' (arrays: {', '.join(z.files) or 'none'})")
        qpos = np.asarray(z["qpos"])
        joints_given = [str(x) for x in np.asarray(z["joints"]).ravel()] if "joints" in z.files else None
        time = np.asarray(z["time_s"], dtype=float) if "time_s" in z.files else None
        rate = np.asarray(z["rate_hz"], dtype=float) if "rate_hz" in z.files else None
    if qpos.ndim != 2 or not np.issubdtype(qpos.dtype, np.number):
        raise InputError(
            f"{src}: qpos must be a (frames, coordinates) array of numbers, got {qpos.dtype} {qpos.shape}"
        )
    qpos = qpos.astype(float)
    bad = np.argwhere(~np.isfinite(qpos))
    if bad.size:
        i, c = bad[0]
        raise InputError(f"{src}: qpos[{i}, {c}] is {qpos[i, c]} ({len(bad)} values not finite)")
    joints = model_joints(m)
    if joints_given is None:
        if qpos.shape[1] != m.nq:
            raise InputError(f"{src}: qpos has {qpos.shape[1]} columns; the model has nq = {m.nq}")
        chosen = joints
    else:
        by_name = {n: (n, k, a) for n, k, a in joints}
        unknown = [j for j in joints_given if j not in by_name]
        if unknown:
            raise InputError(
                f"{src}: joints {unknown} are not in the model; its joints: {', '.join(by_name)}"
            )
        chosen = [by_name[j] for j in joints_given]
        width = sum(WIDTH[k] for _, k, _ in chosen)
        if qpos.shape[1] != width:
            raise InputError(f"{src}: qpos has {qpos.shape[1]} columns; the joints named take {width}")
    columns, col = {}, 0
    for name, kind, adr in chosen:
        for c in COLUMNS[kind]:
            at = col if joints_given is not None else adr + COLUMNS[kind].index(c)
            columns[f"{name}.{c}" if c else name] = qpos[:, at]
            col += 1
    if time is None:
        if rate is None or rate.size != 1 or not (np.isfinite(rate.item()) and rate.item() > 0):
            raise InputError(f"{src}: give 'time_s' (frames,) s or 'rate_hz' (one number > 0)")
        time = np.arange(qpos.shape[0]) / rate.item()
    if time.shape != (qpos.shape[0],):
        raise InputError(f"{src}: time_s has shape {time.shape}; qpos has {qpos.shape[0]} frames")
    return on_frame_grid(src, time, _tracks(src, m, columns, None), "qpos")


def read_qpos_csv(path: str | os.PathLike[str], m: mujoco.MjModel) -> RecordedMotion:
    """A ``qpos`` CSV (module docstring) as a recorded motion of ``m``.

    Raises:
        InputError: naming file and line: a header without ``time_s``, a row of another length, a
            value that is not a finite number, time stamps off a constant rate, unknown columns.
    """
    src = str(path)
    reader = csv.reader(io.StringIO(read_text(path)))
    numbered = [(reader.line_num, r) for r in reader]
    numbered = [(n, r) for n, r in numbered if r and any(x.strip() for x in r)]
    rows = [r for _, r in numbered]
    line_of = np.array([n for n, _ in numbered])
    if not rows:
        raise InputError(f"{src}: empty file; expected a header time_s,<coordinates>")
    header = [h.strip().lstrip("\ufeff") for h in rows[0]]
    if "time_s" not in header:
        raise InputError(f"{src}, line {line_of[0]}: no column 'time_s' in the header {header}")
    if len(set(header)) != len(header):
        raise InputError(f"{src}, line {line_of[0]}: columns named twice in {header}")
    data = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(f"{src}, line {line_of[i + 1]}: {len(row)} fields; the header has {len(header)}")
        for c, x in enumerate(row):
            try:
                data[i, c] = float(x)
            except ValueError:
                where = f"{src}, line {line_of[i + 1]}, column {header[c]!r}"
                raise InputError(f"{where}: {x!r} is not a number") from None
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        i, c = bad[0]
        raise InputError(
            f"{src}, line {line_of[i + 1]}, column {header[c]!r}: {data[i, c]} is not a finite number"
        )
    columns = {h: data[:, c] for c, h in enumerate(header) if h != "time_s"}
    lines = line_of[1:]
    return on_frame_grid(src, data[:, header.index("time_s")], _tracks(src, m, columns, lines), "qpos", lines)


def write_qpos_npz(
    path: str | os.PathLike[str], qpos: np.ndarray, time_s: np.ndarray, model: str | None = None
) -> None:
    """Write ``qpos`` ``(F, nq)`` at ``time_s`` ``(F,)`` s (and the model's name) as an archive,
    atomically."""
    arrays = {"qpos": np.asarray(qpos, dtype=float), "time_s": np.asarray(time_s, dtype=float)}
    if model is not None:
        arrays["model"] = np.array(model)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())
