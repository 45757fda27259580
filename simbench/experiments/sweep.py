"""Running a study (:mod:`simbench.experiments.study`): trials on any executor, one Parquet file each.

**Trials** are independent and seeded from ``(study seed, cell, replicate)``, so the results do not
depend on the number of workers or the order they finish in. They run through any
``concurrent.futures.Executor``: a local process pool by default, or a Dask distributed cluster
(:func:`dask_executor`; :func:`local_dask_executor` for one on this machine).

**Results** go to ``OUT/trials/<trial>.parquet`` (one small Parquet file per trial, written
atomically as each finishes) and are gathered into ``OUT/results.parquet``; an interrupted study
resumes where it stopped: finished trials are read back and never run or written twice.

Parquet (pyarrow) and Dask (distributed) are the optional extra ``simbench[studies]``; without them a
study stops with an :class:`InputError` saying so. Each trial runs BLAS on one thread.

**Trust.** Dask's protocol pickles: whoever can reach the scheduler can run code on the workers,
and the rows the workers send back are unpickled here. So a cluster is trusted as this process
is: :func:`dask_executor` refuses a plain ``tcp://`` scheduler off this machine unless TLS
settings are given (:func:`dask_security`: a CA, a client certificate and key, encryption
required) or the caller says the network is trusted (``insecure``). A row sent back is checked
before it is written: it must be the trial that was sent (its id, cell and replicate), a mapping
of column names to plain values, and its file name is made from the trial sent, never from what
came back (docs/dask.md).
"""

from __future__ import annotations

import ipaddress
import json
import socket
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, as_completed
from contextlib import contextmanager, nullcontext
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from calibration.errors import CalibrationError
from simbench.errors import InputError, optional_module
from simbench.estimators import TIME_LIMIT_S, EstimatorError
from simbench.experiments.metrics import calibration_metrics, joint_method_metrics, orientation_metrics
from simbench.experiments.pool import one_blas_thread, worker_pool
from simbench.experiments.study import Study, Trial, check_study, study_fingerprint, trial_config, trials
from simbench.io.atomic import atomic_path, atomic_write_text
from simbench.sim.session import load_session_model, run_session
from simbench.versions import __version__

#: The extra of the simbench distribution that installs a study's optional packages.
EXTRA = "studies"
FEATURE = "simbench sweep"


def _optional(name: str) -> ModuleType:
    return optional_module(name, EXTRA, FEATURE)


def run_trial(study: Study, trial: Trial) -> dict[str, Any]:
    """Simulate, estimate and score one trial; returns its row: ``trial``, ``cell``,
    ``replicate``, ``seed``, the parameter values (SI), the metrics (SI, degrees for orientation)
    and ``run_time_s``.

    A trial uses one core (BLAS limited to one thread): parallelism comes from running trials
    side by side, which scales; threads inside one small trial do not.

    A trial whose session or estimates cannot be made from its values (an ``InputError`` or
    ``CalibrationError``: e.g. a tracker that drops nearly every pose) is a row too, without
    metrics, its ``error`` the reason headed by the trial's id, cell and values: the study goes
    on and the summary counts it. Any other error stops the study. A user's estimator that fails
    (raises, or runs past :data:`simbench.estimators.TIME_LIMIT_S`) is an ``error:<spec>`` column
    of the row, the other estimators' metrics kept.
    """
    t0 = time.perf_counter()
    with one_blas_thread():
        try:
            return _run_trial(study, trial)
        except (InputError, CalibrationError) as exc:  # what the trial's data could not give
            values = ", ".join(f"{name} = {value:g}" for name, value in trial.params)
            row = _ids(trial)
            row["error"] = f"trial {trial.trial_id} (cell {trial.cell}: {values}): {exc}"
            row["run_time_s"] = time.perf_counter() - t0
            return row


def _ids(trial: Trial) -> dict[str, Any]:
    """The columns naming a trial: id, cell, replicate, seed, then its parameter values (SI)."""
    row: dict[str, Any] = {
        "trial": trial.trial_id,
        "cell": trial.cell,
        "replicate": trial.replicate,
        "seed": trial.seed,
    }
    row.update(dict(trial.params))
    return row


def _run_trial(study: Study, trial: Trial) -> dict[str, Any]:
    t0 = time.perf_counter()
    config = trial_config(study, trial)
    ds = run_session(config, load_session_model(config))
    row = _ids(trial)
    several = sum(e.startswith("orientation:") for e in study.estimators) > 1
    for est in study.estimators:
        if est == "calibration":
            row.update(calibration_metrics(ds))
            continue
        kind, spec = est.split(":", 1)
        try:
            if kind == "joint":
                got = joint_method_metrics(ds, spec, time_limit_s=TIME_LIMIT_S)
                row.update({f"{k}:{spec}": v for k, v in got.items()})
            else:
                key = f"orientation_rmse_deg:{spec}" if several else "orientation_rmse_deg"
                row[key] = orientation_metrics(ds, spec, time_limit_s=TIME_LIMIT_S)["total_rmse_deg"]
        except EstimatorError as exc:  # a user's estimator failed on this trial: named, the rest go on
            row[f"error:{spec}"] = str(exc)
    row["run_time_s"] = time.perf_counter() - t0
    return row


#: The file in an output folder that names the study whose trials it holds.
STAMP = "study.json"


def _claim(out: Path, study: Study, force: bool) -> None:
    """Make ``out`` the folder of ``study`` (see :func:`run_study`)."""
    fingerprint = study_fingerprint(study)
    stamp = out / STAMP
    held = finished(out)
    if stamp.is_file():
        try:
            theirs = json.loads(stamp.read_text(encoding="utf-8"))["fingerprint"]
        except (ValueError, KeyError, TypeError):
            theirs = None
    else:
        theirs = None if held else fingerprint  # an empty folder is free
    if theirs != fingerprint:
        if not force:
            whose = f"an unknown study (no {STAMP})" if theirs is None else "another study"
            raise InputError(
                f"{out}: holds {len(held)} trial(s) of {whose}, not of {study.name!r} (its file, a value in "
                "it or the simbench version differs); use another --out, or --force to remove them and "
                "start over"
            )
        for path in (out / "trials").glob("*.parquet"):
            path.unlink()
        (out / "results.parquet").unlink(missing_ok=True)
    (out / "trials").mkdir(parents=True, exist_ok=True)
    doc = {"fingerprint": fingerprint, "study": study.name, "simbench": __version__}
    atomic_write_text(stamp, json.dumps(doc, indent=2) + "\n")


def _write_row(out: Path, row: dict[str, Any], trial: Trial) -> None:
    """Write a finished trial's row to ``out/trials/<id>.parquet``, the id the trial's own."""
    pa, pq = _optional("pyarrow"), _optional("pyarrow.parquet")
    table = pa.Table.from_pylist([checked_row(row, trial)])
    with atomic_path(out / "trials" / f"{trial.trial_id}.parquet") as tmp:
        pq.write_table(table, tmp)


def finished(out: Path) -> set[str]:
    """Trial ids already written in the output folder ``out`` (a resumed study skips them)."""
    folder = out / "trials"
    return {p.stem for p in folder.glob("*.parquet")} if folder.is_dir() else set()


def gather(out: Path, ids: set[str] | None = None) -> Any:
    """All finished trials as one ``pyarrow.Table``, sorted by trial id, also written to
    ``out/results.parquet`` (not written when no trial has finished); with ``ids``, only those
    trials' files (another file there is not the study's).

    Raises:
        InputError: a trial file that cannot be read, named (delete it to run that trial again).
    """
    pa, pq = _optional("pyarrow"), _optional("pyarrow.parquet")
    tables = []
    for path in sorted((out / "trials").glob("*.parquet")):
        if ids is not None and path.stem not in ids:
            continue
        try:
            tables.append(pq.read_table(path))
        except (OSError, pa.ArrowException) as exc:
            raise InputError(
                f"{path}: not a readable trial file ({exc}); delete it to run that trial again"
            ) from None
    if not tables:
        return pa.table({})
    table = pa.concat_tables(tables, promote_options="default").sort_by("trial")
    with atomic_path(out / "results.parquet") as tmp:
        pq.write_table(table, tmp)
    return table


def dask_security(ca_file: str | None, cert: str | None, key: str | None) -> Any:
    """Dask TLS settings from the CA file, the client certificate and its key (PEM files), each
    checked to be a readable file; encryption required. ``None`` when none is given.

    Raises:
        InputError: one or two of the three given, or a file that is not there.
    """
    given = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    if not any(given.values()):
        return None
    missing = [name for name, value in given.items() if not value]
    if missing:
        raise InputError(
            f"Dask TLS needs the CA file, the certificate and the key: {', '.join(missing)} missing"
        )
    for name, value in given.items():
        if not Path(value).is_file():
            raise InputError(f"{name} {value}: no such file (expected a PEM file)")
    distributed = optional_module("distributed", EXTRA, f"{FEATURE} --scheduler")
    return distributed.Security(
        tls_ca_file=ca_file, tls_client_cert=cert, tls_client_key=key, require_encryption=True
    )


def _loopback(host: str) -> bool:
    """Whether ``host`` is this machine's loopback (a name resolved, all its addresses)."""
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(info[4][0].split("%")[0]).is_loopback for info in infos)


def check_scheduler(address: str, security: Any = None, insecure: bool = False) -> None:
    """Refuse a scheduler this process should not trust with its pickles (module docstring): a
    ``tcp://`` (or bare) address off this machine without TLS settings, unless ``insecure``.

    Raises:
        InputError: naming the address and the ways to connect.
    """
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    host = rest.rsplit(":", 1)[0] if ":" in rest and not rest.endswith("]") else rest
    if scheme == "tls" or security is not None or insecure or _loopback(host):
        return
    raise InputError(
        f"--scheduler {address}: a plain {scheme}:// connection off this machine; Dask unpickles what the "
        "cluster sends back, so anyone on that network could run code here. Give --tls-ca-file, --tls-cert "
        "and --tls-key (and a tls:// address), or --insecure if the network is yours alone (docs/dask.md)"
    )


@contextmanager
def dask_executor(address: str, *, security: Any = None, insecure: bool = False) -> Iterator[Executor]:
    """An executor on the Dask cluster whose scheduler is at ``address`` (``tcp://host:8786``,
    ``tls://host:8786``); the client closes when the ``with`` block ends.

    Args:
        address: the scheduler.
        security: Dask TLS settings (:func:`dask_security`), or ``None`` (Dask's configuration).
        insecure: connect by plain TCP off this machine (:func:`check_scheduler`).
    """
    distributed = optional_module("distributed", EXTRA, f"{FEATURE} --scheduler")
    check_scheduler(address, security, insecure)
    with distributed.Client(address, security=security) as client:
        yield client.get_executor()


def checked_row(row: Any, trial: Trial) -> dict[str, Any]:
    """The row a worker sent back for ``trial``, checked (module docstring).

    Raises:
        InputError: a row that is not a mapping of names to plain values (str, int, float, bool,
            None), or that names another trial.
    """
    if not isinstance(row, dict):
        raise InputError(f"trial {trial.trial_id}: a worker sent back a {type(row).__name__}, not a row")
    for name in ("trial", "cell", "replicate"):
        if row.get(name) != getattr(trial, "trial_id" if name == "trial" else name):
            raise InputError(
                f"trial {trial.trial_id}: a worker sent back a row with {name} {row.get(name)!r}; refused "
                "(not the trial that was sent)"
            )
    for name, value in row.items():
        if not isinstance(name, str) or not (
            value is None or isinstance(value, str | bool | int | float | np.number | np.bool_)
        ):
            raise InputError(
                f"trial {trial.trial_id}: a worker sent back column {name!r} = a {type(value).__name__}; "
                "expected plain values (str, int, float, bool, None, numpy numbers)"
            )
    return row


@contextmanager
def local_dask_executor(workers: int) -> Iterator[Executor]:
    """An executor on a Dask cluster of ``workers`` single-threaded worker processes on this
    machine, talking over loopback TCP as a real cluster does (tests and benchmarks); the cluster
    stops when the ``with`` block ends."""
    distributed = optional_module("distributed", EXTRA, FEATURE)
    with (
        distributed.LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            protocol="tcp",
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        dask_executor(cluster.scheduler_address) as executor,
    ):
        yield executor


def run_study(
    study: Study,
    out: Path,
    *,
    executor: Executor | None = None,
    workers: int = 1,
    progress: Callable[[int, int], None] | None = None,
    limit: int | None = None,
    force: bool = False,
) -> Any:
    """Run every unfinished trial of a study, writing each as it finishes; returns the
    ``pyarrow.Table`` of every finished trial (:func:`gather`).

    The study is checked whole before any trial runs (:func:`check_study`), and the output
    folder is claimed for it: ``out/study.json`` holds the study's fingerprint
    (:func:`study_fingerprint`). A folder that holds another study's trials (another file, an
    edited one, another simbench version) is refused unless ``force``, which removes its trials
    and starts over.

    A trial its values cannot make is written as a row with its ``error`` (:func:`run_trial`).
    Interrupted (Ctrl-C, SIGTERM) or stopped by an internal error, it runs nothing more: the default
    pool's workers are killed at once, no file is left half-written, and the trials written so
    far are kept for the next call.

    Args:
        study: the study.
        out: output folder (created); finished trials there are skipped.
        executor: where trials run; default a local process pool of ``workers``.
        workers: size of the default pool.
        progress: called with ``(done, total)`` as trials finish.
        limit: run at most this many trials now (the rest on a later call).
        force: start over in a folder that holds another study's trials.

    Raises:
        InputError: the optional packages of ``simbench[studies]`` are missing, a cell cannot
            run, or ``out`` holds another study's trials (all before any trial).
    """
    _optional("pyarrow.parquet")
    check_study(study)
    _claim(out, study, force)
    every = trials(study)
    ids = {t.trial_id for t in every}
    done = finished(out) & ids  # another file there is not one of the study's trials
    todo = [t for t in every if t.trial_id not in done][:limit]
    count = len(done)
    with worker_pool(workers) if executor is None else nullcontext(executor) as pool:
        futures = {}
        try:
            for trial in todo:
                futures[pool.submit(run_trial, study, trial)] = trial
            for fut in as_completed(futures):
                _write_row(out, fut.result(), futures[fut])
                count += 1
                if progress:
                    progress(count, len(every))
        except BaseException:  # Ctrl-C, SIGTERM, a failed trial: run no more (own pool: killed)
            if pool is executor:
                for fut in futures:
                    fut.cancel()
            raise
    return gather(out, ids)
