"""Physics runs kept in a folder, so that sessions that differ only in their sensors share one run.

The validation runs the same motion many times: each paper table again with one sensor effect
switched off (noise, range law, field distortion, soft tissue...), the methods' presets on the
same seeds. Those effects act after the dynamics, on MuJoCo's sensor data, so the physics of such
sessions is the same to the bit; it is most of their cost (a humanoid second is 60 ms of
``mujoco.rollout`` at 1,200 Hz).

While :func:`physics_cache` is active (it sets :data:`ENV` to a folder, which worker processes
inherit), :func:`simbench.sim.physics.run_physics` looks its run up there by :func:`physics_key`
and stores what it computed. The key is a hash of everything the run depends on: MuJoCo's and
numpy's versions, the source of the code that makes it (:func:`code_digest`), the compiled
model's bytes (``mj_saveModel``, with the session's timestep), the motion program, the root's
phases, the step counts and the rollout's chunking; so a folder kept from one run to the next
(``simbench validate --physics-cache DIR``) never gives back a run that is no longer what the code
would make. A run read back is byte-identical to the one a fresh run gives. Writes are atomic;
two processes that compute the same run at once both write it, and either copy is the same.

A run is kept whole (every MuJoCo sensor at every sample, float64): a 45 s humanoid session is
25 MB, and a full ``simbench validate`` holds about 830 MiB in its temporary folder (under
``TMPDIR``) until it ends.

Nothing in the folder is trusted: each entry stores its key, its array's shape and dtype and a
SHA-256 of its bytes, and :func:`load_run` checks all of them (and the shape the run must have)
before a run is used. An entry that fails a check -- another key's file under this name, a
truncated or altered file, NaN, another dtype -- is named in a :class:`PhysicsCacheWarning` and
computed again (and stored again over it). A folder the runs cannot be written to is said, once,
and then only read. A temporary folder records its owner's process; a folder left by a run that
was killed (its process gone, or untouched for :data:`LEFTOVER_AGE_S`) is removed when the next
temporary cache is made, if it is the same user's.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import os
import shutil
import socket
import tempfile
import time
import warnings
import zipfile
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

import calibration.rotations
from simbench.errors import InputError
from simbench.io.atomic import atomic_path, process_running
from simbench.sim.models import CaptureModel
from simbench.sim.plan import SessionPlan

#: Environment variable naming the cache folder (unset: no cache).
ENV = "SIMBENCH_PHYSICS_CACHE"

#: Version of an entry's layout (:func:`store_run`); an entry of another version is computed again.
FORMAT = 2

#: Prefix of the temporary folders :func:`physics_cache` makes under ``TMPDIR``.
TEMP_PREFIX = "simbench-physics-"

#: File in a temporary folder naming the process that made it (JSON: ``pid``, ``host``).
OWNER_FILE = "owner.json"

#: A temporary folder of this user's untouched for this long, with no owner process known to be
#: alive on this host, is a killed run's leftover, s (a day: a run adds a file to its folder every
#: session, seconds to minutes apart).
LEFTOVER_AGE_S = 86_400.0


class PhysicsCacheWarning(UserWarning):
    """A stored run that failed a check (computed again), or a cache folder that cannot be written."""


@functools.cache
def code_digest() -> bytes:
    """SHA-256 of the source of the code a physics run is made by: every module of
    :mod:`simbench.sim` (programs, models, the rollout) and :mod:`calibration.rotations` (the
    initial pose). A folder kept between runs (``simbench validate --physics-cache``) then never
    gives back a run that changed code would make differently."""
    h = hashlib.sha256()
    sources = [*sorted(Path(__file__).parent.glob("*.py")), Path(calibration.rotations.__file__)]
    for path in sources:
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.digest()


def physics_key(cm: CaptureModel, plan: SessionPlan, timestep: float, extra: tuple = ()) -> str:
    """Hex digest naming one physics run.

    Args:
        cm: the capture model (its compiled model is hashed with ``opt.timestep = timestep``).
        plan: the session plan (program, root phases, step counts).
        timestep: the physics timestep of the run, s.
        extra: anything else the run depends on (the caller's settle time and chunk size).
    """
    m = cm.model
    saved = float(m.opt.timestep)
    m.opt.timestep = timestep
    try:
        buf = np.empty(mujoco.mj_sizeModel(m), dtype=np.uint8)
        mujoco.mj_saveModel(m, None, buf)
    finally:
        m.opt.timestep = saved
    h = hashlib.sha256(mujoco.__version__.encode())
    h.update(np.__version__.encode())  # the set-points' sines and cosines
    h.update(code_digest())
    h.update(buf.tobytes())
    plan_part = (
        plan.program,
        np.asarray(plan.root_phases).tobytes(),
        plan.steps_per_sample,
        plan.n_samples,
        timestep,
        cm.mocap_id,
        cm.articulations,
        extra,
    )
    _feed(h, plan_part)
    return h.hexdigest()


def _feed(h: hashlib._Hash, obj: object) -> None:
    """Feed ``obj`` to ``h`` by value (not ``pickle``, whose bytes depend on which equal strings
    and arrays are the same object): dataclasses, mappings, sequences, arrays and scalars."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        h.update(f"<{type(obj).__qualname__}>".encode())
        for f in dataclasses.fields(obj):
            _feed(h, f.name)
            _feed(h, getattr(obj, f.name))
    elif isinstance(obj, dict):
        h.update(b"<dict>")
        for k in sorted(obj, key=repr):
            _feed(h, k)
            _feed(h, obj[k])
    elif isinstance(obj, list | tuple):
        h.update(f"<{type(obj).__name__}{len(obj)}>".encode())
        for x in obj:
            _feed(h, x)
    elif isinstance(obj, np.ndarray):
        h.update(f"<array {obj.dtype.str} {obj.shape}>".encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    elif isinstance(obj, bytes):
        h.update(b"<bytes>" + obj)
    elif isinstance(obj, str | int | float | bool | np.generic) or obj is None:
        h.update(f"<{type(obj).__name__} {obj!r}>".encode())
    else:
        raise TypeError(f"physics_key cannot hash a {type(obj).__name__}")


def cache_folder() -> Path | None:
    """The active cache folder (:data:`ENV`), or ``None``."""
    folder = os.environ.get(ENV)
    return Path(folder) if folder else None


def _digest(data: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(data).tobytes()).hexdigest()


def check_entry(
    path: Path, key: str, shape: tuple[int, ...] | None = None
) -> tuple[np.ndarray, dict[str, int]] | str:
    """Read and check one stored run.

    Args:
        path: the entry's file.
        key: the key it must be stored under (:func:`physics_key`).
        shape: ``(n_samples, nsensordata)`` the run must have, or ``None`` (not checked).

    Returns:
        ``(sensordata, warnings)`` when every check holds, else what failed (one line).
    """
    try:
        with np.load(path, allow_pickle=False) as f:
            if "header" not in f.files or "sensordata" not in f.files:
                return f"not a run of this version (arrays {sorted(f.files)})"
            header = json.loads(str(f["header"]))
            data = f["sensordata"]
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        return f"unreadable ({type(exc).__name__}: {exc})"
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        return f"layout {header.get('format') if isinstance(header, dict) else header!r}, expected {FORMAT}"
    if header.get("key") != key:
        return f"stored under key {str(header.get('key'))[:12]}..., not this file's name"
    if data.dtype != np.float64 or header.get("dtype") != data.dtype.str:
        return f"dtype {data.dtype} (header {header.get('dtype')}), expected float64"
    if list(data.shape) != header.get("shape") or (shape is not None and data.shape != tuple(shape)):
        return f"shape {data.shape} (header {header.get('shape')}), expected {tuple(shape or data.shape)}"
    if _digest(data) != header.get("sha256"):
        return "checksum differs from the one stored with it (the file was altered)"
    if not np.isfinite(data).all():
        return "holds values that are not finite"
    runs = header.get("warnings")
    if not isinstance(runs, dict) or not all(isinstance(v, int) for v in runs.values()):
        return f"warnings {runs!r} are not a {{name: count}} table"
    return data, runs


def load_run(
    folder: Path, key: str, shape: tuple[int, ...] | None = None
) -> tuple[np.ndarray, dict[str, int]] | None:
    """``(sensordata, warnings)`` stored under ``key``, or ``None`` when there is none or it fails
    a check (:func:`check_entry`; then named in a :class:`PhysicsCacheWarning`, and the caller
    computes the run again)."""
    path = folder / f"{key}.npz"
    if not path.exists():
        return None
    got = check_entry(path, key, shape)
    if isinstance(got, str):
        warnings.warn(
            f"physics cache: {path}: {got}; computing the run again", PhysicsCacheWarning, stacklevel=2
        )
        return None
    return got


#: Folders already said to be unwritable (said once per process).
_UNWRITABLE: set[str] = set()


def _say_unwritable(folder: Path, why: str) -> None:
    if str(folder) not in _UNWRITABLE:
        _UNWRITABLE.add(str(folder))
        warnings.warn(
            f"physics cache: {folder}: cannot keep runs there ({why}); runs already there are read, new ones "
            "are computed and not kept",
            PhysicsCacheWarning,
            stacklevel=3,
        )


def store_run(folder: Path, key: str, sensordata: np.ndarray, warnings: dict[str, int]) -> bool:
    """Keep a run under ``key`` (atomically), with its key, shape, dtype and checksum; returns
    whether it was kept.

    The cache only saves time: a folder that has gone, a full disk or any other failure to
    write leaves no file (not even a partial one), is said (:class:`PhysicsCacheWarning`, once a
    folder), and the session goes on with the run it has.
    """
    if not folder.is_dir():
        return False
    data = np.ascontiguousarray(sensordata, dtype=np.float64)
    header = {
        "format": FORMAT,
        "key": key,
        "shape": list(data.shape),
        "dtype": data.dtype.str,
        "sha256": _digest(data),
        "warnings": {str(k): int(v) for k, v in warnings.items()},
    }
    try:
        with atomic_path(folder / f"{key}.npz", in_set=False) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, sensordata=data, header=np.array(json.dumps(header)))
    except (OSError, InputError) as exc:
        _say_unwritable(folder, getattr(exc, "strerror", None) or str(exc))
        return False
    return True


def writable(folder: Path) -> str | None:
    """``None`` when a file can be made in ``folder``, else why not (one line)."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".simbench-probe-")
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(name)
    return None


def sweep_leftovers(root: str | os.PathLike[str] | None = None, *, now: float | None = None) -> list[Path]:
    """Remove the temporary caches killed runs left in ``root`` (default: ``TMPDIR``).

    A folder ``simbench-physics-*`` is a leftover when it is this user's and either its owner
    file (:data:`OWNER_FILE`) names a process on this host that is gone, or it has none (or one
    of another host) and has not been touched for :data:`LEFTOVER_AGE_S`. Folders of other users,
    and of processes alive, are left alone.

    Returns:
        The folders removed.
    """
    root = Path(root if root is not None else tempfile.gettempdir())
    now = time.time() if now is None else now
    removed = []
    try:
        candidates = list(root.glob(f"{TEMP_PREFIX}*"))
    except OSError:
        return removed
    host = socket.gethostname()
    for path in candidates:
        try:
            st = path.lstat()
            if not path.is_dir() or path.is_symlink() or st.st_uid != os.getuid():
                continue
            try:
                owner = json.loads((path / OWNER_FILE).read_text())
                pid, owner_host = int(owner["pid"]), str(owner["host"])
            except (OSError, ValueError, KeyError, TypeError):
                pid, owner_host = -1, ""
            if owner_host == host and pid > 0:
                leftover = not process_running(pid)
            else:
                leftover = now - st.st_mtime > LEFTOVER_AGE_S
            if leftover:
                shutil.rmtree(path, ignore_errors=True)
                removed.append(path)
        except OSError:
            continue
    return removed


@contextlib.contextmanager
def physics_cache(folder: str | os.PathLike[str] | None = None) -> Iterator[Path | None]:
    """Share physics runs between the sessions simulated inside the ``with`` block (and the
    worker processes started inside it).

    Args:
        folder: where runs are kept (kept afterwards); ``None``: the cache already active, if
            any (a caller's, or the test run's), else a temporary folder removed at the end.

    Yields:
        The folder; ``None`` when no temporary folder can be made (no cache then).
    """
    previous = os.environ.get(ENV)
    if folder is None and previous:
        yield Path(previous)
        return
    with contextlib.ExitStack() as stack:
        if folder is None:
            sweep_leftovers()
            try:
                folder = stack.enter_context(tempfile.TemporaryDirectory(prefix=TEMP_PREFIX))
                owner = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.time()}
                (Path(folder) / OWNER_FILE).write_text(json.dumps(owner))
            except OSError:  # no writable temporary folder: every session runs its own physics
                yield None
                return
        path = Path(folder)
        path.mkdir(parents=True, exist_ok=True)
        if (why := writable(path)) is not None:
            _say_unwritable(path, why)
        os.environ[ENV] = str(path)
        try:
            yield path
        finally:
            if previous is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = previous
