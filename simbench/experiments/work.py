"""Progress by work done: a run's steps weighted by their expected cost, credited as their jobs end.

A step of a run (``simbench validate``'s :data:`~simbench.experiments.validate.STEPS`) hands jobs
to a process pool (:meth:`Work.map`, :meth:`Work.submit`) or does some of its work in this process
(:meth:`Work.call`). Each step has an expected cost (CPU seconds of a reference run) and an
expected number of jobs; the work done is, over the steps, ``cost * jobs ended / max(jobs
expected, jobs handed out)``, never decreasing, and the whole cost when the step is
:meth:`closed <Work.close>`. A progress bar fed with it moves as the CPU is spent, so that its
rate, and the time left it shows, mean something; counting the steps announced would show half of
them "done" in the first second, as they are handed to the pool, and the ETA minutes off.

With ``slots`` the jobs wait here and go to the pool ``slots`` at a time (its workers), in an order
of their own rather than the order they came in: the jobs of the steps the run waits on to go on
(``first``) before the others, then the longest jobs first (a step's cost over its jobs). A pool
alone runs its jobs first come, first served: a run that hands out its independent work first, so
that it fills the cores while the run waits, would starve the steps it waits on, and end on a tail
of one long job.

Every job's process, start and end (wall clock, s since the epoch) and CPU seconds are kept
(:attr:`Work.jobs`): where a run's time goes, step by step and process by process.
"""

from __future__ import annotations

import functools
import heapq
import itertools
import os
import threading
import time
from collections.abc import Callable, Collection, Iterator, Mapping
from concurrent.futures import Executor, Future
from dataclasses import dataclass
from typing import Any

__all__ = ["Job", "Work"]


@dataclass(frozen=True)
class Job:
    """One job of a step: the process that ran it, its start and end (wall clock, s since the
    epoch) and the CPU seconds it used (its process's; a job run on a thread of this process: the
    thread's)."""

    step: str
    pid: int
    start: float
    end: float
    cpu_s: float


def _timed(
    fn: Callable[..., Any], /, *args: Any, **kwargs: Any
) -> tuple[Any, tuple[int, float, float, float]]:
    """``fn(*args, **kwargs)`` and ``(pid, start, end, CPU s)`` of the call (a pool's job)."""
    t0, c0 = time.time(), time.process_time()
    out = fn(*args, **kwargs)
    return out, (os.getpid(), t0, time.time(), time.process_time() - c0)


class Work:
    """The work of a run: its steps' expected costs, and what is done of them.

    Args:
        pool: the executor the steps' jobs go to (``submit``).
        cost: ``{step: expected cost}`` (CPU seconds of a reference run; any positive unit):
            the total is their sum, and what :attr:`done` reaches.
        report: called with the work done (the same unit) each time it grows, from whichever
            thread ended a job.
        slots: how many jobs the pool holds at once (its workers): the others wait here, and go
            in the order of ``first`` and the costs (module docstring); ``None``: every job goes
            to the pool when it is handed out.
        first: steps whose jobs go before any other's (those the run waits on).
        jobs: ``{step: expected number of jobs}`` (1 for a step not named): a job's expected
            cost is its step's over it, and a step's jobs are credited as fractions of it.

    Raises:
        ValueError: a cost that is not a positive finite number, ``slots`` below 1, a step of
            ``first`` or ``jobs`` that has no cost, an expected number of jobs below 1.
    """

    def __init__(
        self,
        pool: Executor,
        cost: Mapping[str, float],
        report: Callable[[float], None] | None = None,
        *,
        slots: int | None = None,
        first: Collection[str] = (),
        jobs: Mapping[str, int] | None = None,
    ) -> None:
        bad = {s: c for s, c in cost.items() if not (isinstance(c, int | float) and 0 < c < float("inf"))}
        if bad:
            raise ValueError(f"Expected every step's cost to be a positive number, got {bad}")
        if slots is not None and slots < 1:
            raise ValueError(f"Expected slots to be None or at least 1, got {slots}")
        if set(first) - set(cost) or set(jobs or {}) - set(cost):
            raise ValueError(
                f"Expected the steps of first and jobs among the costs' {list(cost)}, got {list(first)} "
                f"and {list(jobs or {})}"
            )
        if any(n < 1 for n in (jobs or {}).values()):
            raise ValueError(f"Expected at least 1 job for each step, got {dict(jobs or {})}")
        self._expected = {s: (jobs or {}).get(s, 1) for s in cost}
        self._slots = slots
        self._first = frozenset(first)
        self._queue: list[tuple[tuple[int, float, int], Callable[[], bool]]] = []
        self._order = itertools.count()
        self._running = 0
        self._pool = pool
        self.cost = dict(cost)
        self.total = float(sum(self.cost.values()))
        self._report = report or (lambda _: None)
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)  # a slot freed or a job queued
        self._dispatcher: threading.Thread | None = None
        self._handed = dict.fromkeys(self.cost, 0)
        self._ended = dict.fromkeys(self.cost, 0)
        self._credit = dict.fromkeys(self.cost, 0.0)
        self.jobs: list[Job] = []

    @property
    def done(self) -> float:
        """The work done so far: between 0 and :attr:`total`."""
        with self._lock:
            return sum(self._credit.values())

    def _hand_out(self, step: str, n: int) -> None:
        if step not in self.cost:
            raise KeyError(f"no step {step!r}: expected one of {list(self.cost)}")
        with self._lock:
            self._handed[step] += n

    def _end(self, step: str, timing: tuple[int, float, float, float] | None) -> None:
        with self._lock:
            if timing is not None:
                self.jobs.append(Job(step, *timing))
            self._ended[step] += 1
            share = self.cost[step] * self._ended[step] / max(self._handed[step], self._expected[step])
            self._credit[step] = max(self._credit[step], share)
            done = sum(self._credit.values())
        self._report(done)

    def close(self, step: str) -> None:
        """The step has ended: the whole of its cost is done."""
        with self._lock:
            self._credit[step] = self.cost[step]
            done = sum(self._credit.values())
        self._report(done)

    def submit(self, step: str, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        """``pool.submit(fn, *args, **kwargs)``, a job of ``step``: the future of its result."""
        self._hand_out(step, 1)
        return self._submit(step, fn, *args, **kwargs)

    def _submit(self, step: str, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        outer: Future = Future()

        def ended(f: Future) -> None:
            if self._slots is not None:
                with self._wake:
                    self._running -= 1
                    self._wake.notify()
            if f.cancelled():  # the pool was stopped (an interrupt) before the job started
                self._end(step, None)
                outer.cancel()
                return
            exc = f.exception()
            if exc is not None:
                self._end(step, None)
                outer.set_exception(exc)
                return
            out, timing = f.result()
            self._end(step, timing)
            outer.set_result(out)

        def start() -> bool:
            try:
                inner = self._pool.submit(_timed, fn, *args, **kwargs)
            except RuntimeError as exc:  # the pool was shut down (the run is being stopped)
                self._end(step, None)
                outer.set_exception(exc)
                return False
            inner.add_done_callback(ended)
            return True

        if self._slots is None:
            start()
            return outer
        rank = (0 if step in self._first else 1, -self.cost[step] / self._expected[step], next(self._order))
        with self._wake:
            heapq.heappush(self._queue, (rank, start))
            if self._dispatcher is None:
                self._dispatcher = threading.Thread(target=self._dispatch, name="work-dispatch", daemon=True)
                self._dispatcher.start()
            self._wake.notify()
        return outer

    def _dispatch(self) -> None:
        """The dispatcher thread: hand the waiting jobs to the pool, first in order, while it has a
        free slot; end when none has been waiting for a second (the next job starts another).

        A thread of its own, not the callbacks of the jobs that end: a pool calls those with its
        own lock held when it is shut down (cancelling what it had not started), and handing it a
        job there would wait on that lock for ever."""
        while True:
            with self._wake:
                while not (self._queue and self._running < (self._slots or 0)):
                    if not self._wake.wait(timeout=1.0) and not self._queue:
                        self._dispatcher = None
                        return
                _, start = heapq.heappop(self._queue)
                self._running += 1
            if not start():  # no pool to go to: the slot is free again for the next (to fail too)
                with self._wake:
                    self._running -= 1

    def map(self, step: str) -> Callable[..., Iterator[Any]]:
        """An executor's ``map`` whose calls are jobs of ``step``: every call handed out at once,
        the results given in order."""

        def run(fn: Callable[..., Any], *iterables: Any) -> Iterator[Any]:
            calls = list(zip(*iterables, strict=False))  # as map
            self._hand_out(step, len(calls))  # all at once: the first to end is one of them all
            futures = [self._submit(step, fn, *args) for args in calls]
            return (f.result() for f in futures)

        return run

    def call(self, step: str, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        """``fn(*args, **kwargs)`` here (this thread), as a job of ``step``."""
        self._hand_out(step, 1)
        t0, c0 = time.time(), time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            self._end(step, (os.getpid(), t0, time.time(), time.thread_time() - c0))

    def bound(self, step: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        """``fn`` as a job of ``step`` wherever it is called (:meth:`call`): for a thread."""
        return functools.partial(self.call, step, fn)
