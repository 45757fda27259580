"""Worker processes that do not outlive their parent, and stop at once when it is interrupted.

A process pool's workers are separate processes: when the parent is killed outright (SIGKILL,
the out-of-memory killer) nothing tells them, and they stay alive as orphans, each holding a
model and its arrays. On Linux :func:`die_with_parent`, run in each worker as the pool's
initializer, asks the kernel to send the worker SIGKILL when its parent dies
(``prctl(PR_SET_PDEATHSIG)``); elsewhere it does nothing.

Each worker runs BLAS on one thread (:func:`one_blas_thread`): the work sent to a pool is many
small problems side by side, where BLAS's own threads only contend with the other workers (a
``7,200 x 6`` SVD takes 15 ms on two threads against 0.7 ms on one, on two cores).

Interrupts are the parent's to handle: a worker ignores SIGINT (a terminal's Ctrl-C reaches every
process of the group; an idle worker would print a ``KeyboardInterrupt`` traceback, a busy one would
hand its trial back as failed) and takes SIGTERM as a plain exit (not the ``Terminated`` exception a
forked worker inherits from the command line). A :class:`WorkerPool` left by an exception (Ctrl-C,
SIGTERM, an error) kills its workers rather than waiting for the work they are doing, whose
results nobody would keep.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
from concurrent.futures import ProcessPoolExecutor

from threadpoolctl import threadpool_limits

#: ``PR_SET_PDEATHSIG`` of ``<linux/prctl.h>``.
PR_SET_PDEATHSIG = 1


def one_blas_thread() -> threadpool_limits:
    """Limit BLAS (and OpenMP) in this process to one thread until the returned limiter's
    ``restore_original_limits()`` (or the end of its ``with`` block)."""
    return threadpool_limits(limits=1)


def die_with_parent(parent_pid: int) -> None:
    """In a worker: be killed when the parent dies (Linux); exit now if it already has; leave
    Ctrl-C to the parent and exit on SIGTERM; BLAS on one thread (:func:`one_blas_thread`)."""
    one_blas_thread()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


class WorkerPool(ProcessPoolExecutor):
    """A process pool whose workers die with this process (:func:`die_with_parent`) and are
    killed when a ``with`` block on it ends in an exception (:meth:`stop`)."""

    def __init__(self, workers: int) -> None:
        super().__init__(max_workers=workers, initializer=die_with_parent, initargs=(os.getpid(),))

    def stop(self) -> None:
        """Kill the workers, drop the work not started and wait for the pool's thread to reap
        them (``kill_workers`` of Python 3.14, by hand)."""
        for process in list((self._processes or {}).values()):
            with contextlib.suppress(ProcessLookupError, ValueError):  # already ended, or closed
                process.kill()
        self.shutdown(wait=True, cancel_futures=True)

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            return super().__exit__(exc_type, exc, tb)
        self.stop()
        return False


def worker_pool(workers: int) -> WorkerPool:
    """A process pool of ``workers`` whose workers die with this process and stop when it is
    interrupted (:class:`WorkerPool`)."""
    return WorkerPool(workers)
