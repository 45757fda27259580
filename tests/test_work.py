"""Progress by work done (issue 44): a run's steps weighted by their expected cost and credited as
their jobs end, and ``simbench validate``'s bar counted in those units."""

from __future__ import annotations

import contextlib
import os
import threading
from concurrent.futures import CancelledError, ThreadPoolExecutor

import pytest

from simbench.cli import main
from simbench.experiments.validate import STEPS, expected_cost, expected_jobs
from simbench.experiments.work import Work


def _square(x: int) -> int:
    return x * x


def _fail() -> None:
    raise RuntimeError("broken job")


def test_steps_are_credited_by_their_cost_as_their_jobs_end():
    seen: list[float] = []
    with ThreadPoolExecutor(1) as pool:
        work = Work(pool, {"long": 9.0, "short": 1.0}, seen.append)
        assert work.total == 10.0 and work.done == 0.0
        assert list(work.map("long")(_square, [1, 2, 3])) == [1, 4, 9]
        assert work.done == pytest.approx(9.0)  # three jobs of the long step: 3 each
        assert seen == pytest.approx([3.0, 6.0, 9.0])
        assert work.submit("short", _square, 4).result() == 16
    assert work.done == pytest.approx(10.0)
    # one job of a step of cost 1 moved the bar by 1, one of a step of cost 9 by 3: weighted, not
    # counted (three steps' worth of jobs is not 3/4 of the way)
    assert [b - a for a, b in zip([0.0, *seen], seen, strict=False)] == pytest.approx([3, 3, 3, 1])
    assert [j.step for j in work.jobs] == ["long"] * 3 + ["short"]
    assert all(j.pid == os.getpid() and j.end >= j.start and j.cpu_s >= 0 for j in work.jobs)


def _gated_jobs():
    """``(gate, started, order, job)``: ``job(name)`` appends ``name`` to ``order``; the job named
    "blocker" first sets ``started`` and waits for ``gate``, holding its pool slot until then."""
    gate, started, order = threading.Event(), threading.Event(), []

    def job(name: str) -> None:
        if name == "blocker":
            started.set()
            gate.wait(10)
        order.append(name)

    return gate, started, order, job


def test_credit_never_goes_back_and_close_gives_the_whole_cost():
    with ThreadPoolExecutor(1) as pool:
        work = Work(pool, {"a": 4.0, "b": 2.0})
        assert work.call("a", _square, 3) == 9  # 1 of 1 handed out: the whole of a
        assert work.done == pytest.approx(4.0)
        list(work.map("a")(_square, [1, 2, 3]))  # 3 more handed out later: a keeps its 4
        assert work.done == pytest.approx(4.0)
        work.close("b")
        assert work.done == pytest.approx(work.total) == 6.0


def test_expected_jobs_share_a_steps_cost_and_rank_its_jobs():
    gate, started, order, job = _gated_jobs()

    with ThreadPoolExecutor(2) as pool:
        # "many": 6 s over 6 jobs (1 s a job); "few": 4 s in 2 jobs (2 s a job): its jobs go first
        work = Work(pool, {"many": 6.0, "few": 4.0}, slots=1, jobs={"many": 6, "few": 2})
        blocker = work.submit("many", job, "blocker")
        assert started.wait(10)
        futures = [work.submit(step, job, step) for step in ("many", "few")]
        gate.set()
        for f in (blocker, *futures):
            f.result(timeout=10)
        # 2 of many's 6 expected jobs ended (the blocker and one more), 1 of few's 2
        assert work.done == pytest.approx(6.0 * 2 / 6 + 4.0 / 2)
    assert order == ["blocker", "few", "many"]
    with pytest.raises(ValueError, match="at least 1 job"):
        Work(pool, {"a": 1.0}, jobs={"a": 0})


def test_a_failing_job_raises_where_its_result_is_asked_for_and_still_ends():
    with ThreadPoolExecutor(1) as pool:
        work = Work(pool, {"a": 1.0})
        future = work.submit("a", _fail)
        with pytest.raises(RuntimeError, match="broken job"):
            future.result()
    assert work.done == pytest.approx(1.0) and work.jobs == []


def test_waiting_jobs_go_to_the_pool_critical_first_then_costliest_first():
    gate, started, order, job = _gated_jobs()

    with ThreadPoolExecutor(2) as pool:  # two threads, one slot: the order is Work's, not the pool's
        work = Work(pool, {"cheap": 1.0, "dear": 5.0, "urgent": 0.5}, slots=1, first=["urgent"])
        blocker = work.submit("cheap", job, "blocker")  # holds the one slot
        assert started.wait(10)
        futures = [work.submit(step, job, step) for step in ("cheap", "dear", "urgent", "dear")]
        gate.set()
        for f in (blocker, *futures):
            f.result(timeout=10)
    assert order == ["blocker", "urgent", "dear", "dear", "cheap"]
    with pytest.raises(ValueError, match="slots to be None or at least 1, got 0"):
        Work(pool, {"a": 1.0}, slots=0)
    with pytest.raises(ValueError, match="steps of first and jobs"):
        Work(pool, {"a": 1.0}, first=["b"])


def test_a_stopped_pool_ends_every_waiting_job_so_nothing_hangs():
    """An interrupt stops the pool (cancelling what it had not started): the jobs it held and those
    still waiting here all end, cancelled or failed, so that the threads waiting on them end too."""
    gate, started = threading.Event(), threading.Event()

    def job() -> None:
        started.set()
        gate.wait(10)

    pool = ThreadPoolExecutor(1)
    work = Work(pool, {"a": 1.0}, slots=2)
    futures = [work.submit("a", job) for _ in range(5)]  # up to 2 in the pool, the others here
    assert started.wait(10)
    pool.shutdown(wait=False, cancel_futures=True)  # the one running goes on; the other is cancelled
    gate.set()
    ends = []
    for f in futures:
        with contextlib.suppress(CancelledError, RuntimeError):
            f.result(timeout=10)  # raises TimeoutError if the job were left waiting
        ends.append("cancelled" if f.cancelled() else type(f.exception()).__name__)
    # the one the pool ran ends, the others were cancelled or found no pool to go to
    assert ends[0] == "NoneType" and set(ends[1:]) <= {"cancelled", "RuntimeError"}
    assert work.done == pytest.approx(1.0)


def test_bad_costs_and_unknown_steps_are_refused():
    with ThreadPoolExecutor(1) as pool:
        with pytest.raises(ValueError, match=r"positive number, got \{'b': 0\.0\}"):
            Work(pool, {"a": 1.0, "b": 0.0})
        with pytest.raises(KeyError, match="no step 'c'"):
            Work(pool, {"a": 1.0}).submit("c", _square, 1)


@pytest.mark.parametrize("quick", [False, True])
def test_every_step_of_validate_and_its_report_have_a_cost(quick):
    cost = expected_cost(quick)
    assert list(cost) == [*STEPS, "report"]
    assert all(c > 0 for c in cost.values())
    # weighted: the steps' costs differ (a table of equal costs would count steps again)
    assert max(cost.values()) > 5 * min(cost.values())
    jobs = expected_jobs(quick)
    assert list(jobs) == list(STEPS) and all(isinstance(n, int) and n >= 1 for n in jobs.values())


def test_validate_bar_counts_the_work_to_its_total(tmp_path, monkeypatch):
    """The bar's total is the run's expected cost; the run's reports move it, and the report's cost
    is the last stretch (a run stand-in: the bar, not the experiments, is under test)."""
    bars: list = []

    class Bar:
        def __init__(self, *, total, **kwargs):
            self.total, self.n, self.updates = total, 0, []
            bars.append(self)

        def update(self, n):
            self.n += n
            self.updates.append(self.n)

        def close(self):
            pass

    cost = expected_cost(True)
    steps = sum(cost.values()) - cost["report"]

    def run(*, quick, progress, physics_folder):
        for k in range(1, 5):
            progress(steps * k / 4)
        raise KeyboardInterrupt  # no report to write

    monkeypatch.setattr("simbench.cli.validate.tqdm", Bar)
    monkeypatch.setattr("simbench.cli.validate.run_validation", run)
    assert main(["validate", "--quick", "--out", str(tmp_path / "r")]) == 130
    (bar,) = bars
    assert bar.total == round(sum(cost.values()))
    assert bar.updates == [round(steps * k / 4) for k in range(1, 5)]
