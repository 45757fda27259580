"""Atomic file writes: a crash never leaves a half-written result.

Output goes to a temporary file in the destination's folder, is flushed to disk, and replaces
the destination in one ``os.replace``; if anything fails the temporary file is removed and the
destination is left as it was. That includes Ctrl-C (``KeyboardInterrupt``) and SIGTERM, which
:func:`simbench.cli.main` raises as an exception for this reason. A process killed outright
(SIGKILL) cannot remove its temporary file: each one's name carries its writer's process id,
``.NAME.<pid>.<random>.tmp``, and the next write of ``NAME`` removes those whose writer is no
longer running.

A destination that is a symbolic link is written through to the file it points to (the link
stays a link); FIFOs and devices are refused. An error while writing (a full disk) is an
:class:`~simbench.errors.InputError` naming the destination.

The outputs of one command are one set (:func:`output_set`): each is written to its temporary
file as above, and only when all of them are written do they replace their destinations, so a
command that fails part way leaves none of its outputs, not the first few.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from simbench.errors import InputError


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w", **kwargs) -> Iterator[IO]:
    """Open a temporary file that replaces ``path`` when the ``with`` block ends without error.

    Args:
        path: destination file.
        mode: ``"w"`` (text) or ``"wb"`` (binary).
        **kwargs: passed to :func:`open` (e.g. ``newline=""``, ``encoding``).

    Raises:
        InputError: when the destination's folder does not exist or is not writable.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"mode must be 'w' or 'wb', got {mode!r}")
    if "b" not in mode:
        kwargs.setdefault("encoding", "utf-8")
    with atomic_path(path) as tmp, open(tmp, mode, **kwargs) as fh:
        yield fh


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    with atomic_open(path, "w") as fh:
        fh.write(text)


def check_writable(path: str | os.PathLike[str]) -> Path:
    """The file to write for ``path``: the path itself, or the file a symbolic link at it points to
    (written through, so that the link stays a link); refused when it is a folder, a FIFO or a
    device (replacing those with a file would break what uses them), or its folder does not exist
    (before anything is computed for it, or written).

    Raises:
        InputError: naming the path and what is wrong.
    """
    given = Path(path)
    dest = Path(os.path.realpath(given)) if given.is_symlink() else given
    folder = dest.parent if str(dest.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {given}: folder {folder} does not exist")
    if dest.is_dir():
        raise InputError(f"cannot write {given}: it is a folder")
    if dest.exists() and not dest.is_file():
        raise InputError(f"cannot write {given}: it exists and is not a regular file (a FIFO or a device)")
    return dest


#: The pending ``(temporary file, destination)`` pairs of the active :func:`output_set`, or None.
_PENDING: contextvars.ContextVar[list[tuple[Path, Path]] | None] = contextvars.ContextVar(
    "simbench_output_set", default=None
)


def _remove(tmp: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp)


@contextlib.contextmanager
def output_set() -> Iterator[None]:
    """Make the files written inside the ``with`` block (:func:`atomic_path`, :func:`atomic_open`,
    :func:`atomic_write_text`) one set: none replaces its destination until the block ends without
    error, and then all do; on error every one of them is removed and every destination is left as
    it was. Sets nest: an inner set's files join the outer one's."""
    if _PENDING.get() is not None:
        yield
        return
    pending: list[tuple[Path, Path]] = []
    token = _PENDING.set(pending)
    try:
        yield
    except BaseException:
        for tmp, _ in pending:
            _remove(tmp)
        raise
    finally:
        _PENDING.reset(token)
    for k, (tmp, dest) in enumerate(pending):
        try:
            os.replace(tmp, dest)
        except OSError as exc:
            for later, _ in pending[k:]:
                _remove(later)
            raise InputError(f"cannot write {dest}: {exc.strerror or exc}") from exc


@contextlib.contextmanager
def outside_output_set() -> Iterator[None]:
    """Files written inside the ``with`` block replace their destinations at once, whatever
    :func:`output_set` is active: a command's working files (an estimator program's inputs in a
    temporary folder), which other code reads before the command ends, are none of its outputs."""
    token = _PENDING.set(None)
    try:
        yield
    finally:
        _PENDING.reset(token)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], *, in_set: bool = True) -> Iterator[Path]:
    """A temporary path beside ``path`` that replaces it when the ``with`` block succeeds (or,
    inside an :func:`output_set`, when the set's block does).

    For writers that need a file name rather than a file object (HDF5). On error the temporary
    file is removed and ``path`` is left as it was; an ``OSError`` of the writer's (a full disk)
    becomes an :class:`InputError` naming ``path``.

    Args:
        path: destination file.
        in_set: join the active :func:`output_set`, if any (``False``: replace at once, for
            files that are no command's output, such as a cache's).
    """
    dest = check_writable(path)
    folder = dest.parent if str(dest.parent) else Path(".")
    sweep_stale(dest)
    umask = os.umask(0)
    os.umask(umask)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.{os.getpid()}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise InputError(f"cannot write {dest}: {exc.strerror}") from exc
    pending = _PENDING.get() if in_set else None
    try:  # from here on, any exception (Ctrl-C, SIGTERM as simbench.cli raises it) removes tmp
        os.close(fd)
        os.chmod(tmp, 0o666 & ~umask)
        try:
            yield Path(tmp)
            with open(tmp, "rb+") as fh:  # the writer has closed it: flush it to disk, then swap
                os.fsync(fh.fileno())
            if pending is None:
                os.replace(tmp, dest)
        except OSError as exc:
            raise InputError(f"cannot write {path}: {exc.strerror or exc}") from exc
    except BaseException:
        _remove(Path(tmp))
        raise
    if pending is not None:
        for k, (earlier, to) in enumerate(pending):
            if to == dest:  # written twice in one set: the last write is the one kept
                _remove(earlier)
                del pending[k]
                break
        pending.append((Path(tmp), dest))


def process_running(pid: int) -> bool:
    """Whether a process of this number runs on this machine (someone else's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def sweep_stale(dest: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files of ``dest`` left by writers that are no longer running; returns
    the paths removed."""
    dest = Path(dest)
    folder = dest.parent if str(dest.parent) else Path(".")
    removed = []
    for tmp in folder.glob(f".{glob_escape(dest.name)}.*.tmp"):
        pid = tmp.name[len(dest.name) + 2 :].split(".", 1)[0]
        if pid.isdigit() and int(pid) != os.getpid() and not process_running(int(pid)):
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
                removed.append(tmp)
    return removed


def glob_escape(name: str) -> str:
    """``name`` with glob's special characters taken literally."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)
