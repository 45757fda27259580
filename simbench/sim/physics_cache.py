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
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

import calibration.rotations
from simbench.errors import InputError
from simbench.io.atomic import atomic_path
from simbench.sim.models import CaptureModel
from simbench.sim.plan import SessionPlan

#: Environment variable naming the cache folder (unset: no cache).
ENV = "SIMBENCH_PHYSICS_CACHE"


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


def load_run(folder: Path, key: str) -> tuple[np.ndarray, dict[str, int]] | None:
    """``(sensordata, warnings)`` stored under ``key``, or ``None`` when there is none (or it
    cannot be read: the run is then computed again)."""
    path = folder / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as f:
            return f["sensordata"], json.loads(str(f["warnings"]))
    except (OSError, KeyError, ValueError):
        return None


def store_run(folder: Path, key: str, sensordata: np.ndarray, warnings: dict[str, int]) -> bool:
    """Keep a run under ``key`` (atomically); returns whether it was kept.

    The cache only saves time: a folder that has gone, a full disk or any other failure to
    write leaves no file (not even a partial one) and the session goes on with the run it has.
    """
    if not folder.is_dir():
        return False
    try:
        with atomic_path(folder / f"{key}.npz") as tmp, open(tmp, "wb") as fh:
            np.savez(fh, sensordata=sensordata, warnings=np.array(json.dumps(warnings)))
    except (OSError, InputError):
        return False
    return True


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
            try:
                folder = stack.enter_context(tempfile.TemporaryDirectory(prefix="simbench-physics-"))
            except OSError:  # no writable temporary folder: every session runs its own physics
                yield None
                return
        path = Path(folder)
        path.mkdir(parents=True, exist_ok=True)
        os.environ[ENV] = str(path)
        try:
            yield path
        finally:
            if previous is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = previous
