"""simbench's pytest plugin: the benchmark suite's scenarios and regression checks in a user's tests.

Installed with simbench (entry point ``pytest11``: ``simbench``), it gives every test these
fixtures (``docs/pytest-plugin.md`` has a complete example):

- ``simbench_scenario``: a factory, ``ds = simbench_scenario("linkage-paper", seed=1)``, the
  suite's scenario (:mod:`simbench.experiments.suite`) simulated with exact truth; simulated once
  per session for each ``(name, seed)`` and shared by every test that asks (do not modify it).
- ``simbench_scenarios``: the suite's scenario names.
- ``simbench_score``: ``simbench_score(estimator, ds_or_name, seed=1)``, an estimator (a spec, an
  :class:`simbench.estimators.Estimator` or a plain function) scored against the truth
  (:func:`score`: :func:`simbench.experiments.metrics.joint_method_metrics` or
  :func:`~simbench.experiments.metrics.orientation_metrics` by the estimator's kind).
- ``simbench_regression``: ``simbench_regression.check(key, figures, rel_tol=0.1, abs_tol=0.0)``
  compares "lower is better" figures with those accepted in a JSON file of the user's repository
  (:class:`Regression`); ``pytest --simbench-update`` accepts the new ones.

The file (``simbench_regression.json`` beside the test file, the ini option
``simbench_regression_file`` or ``check(path=...)``) holds, per key, its figures with the suite
version and simbench version they were accepted with: figures of another suite version are not
comparable and fail until they are accepted again.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from simbench.estimators import Estimator, resolve
from simbench.estimators.registry import from_callable
from simbench.experiments.metrics import joint_method_metrics, orientation_metrics
from simbench.experiments.suite import SCENARIOS, SEEDS, SUITE_VERSION, scenario, scenario_dataset
from simbench.io.atomic import atomic_write_text
from simbench.io.dataset import Dataset
from simbench.versions import __version__

try:  # POSIX: concurrent --simbench-update writers (pytest-xdist workers) take turns
    import fcntl
except ImportError:  # pragma: no cover - Windows: no lock
    fcntl = None

#: The regression file's name beside a test file (when neither the ini option nor ``path=`` names one).
DEFAULT_FILE = "simbench_regression.json"
#: The ini option naming the regression file (relative to the ini file's folder or the rootdir).
INI_FILE = "simbench_regression_file"
#: The command-line option that accepts the new figures.
UPDATE_OPTION = "--simbench-update"
#: The regression file's format.
FORMAT = 1
#: The keys accepted in this run (the terminal summary lists them).
_UPDATED = pytest.StashKey[list[str]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("simbench", "simbench regression figures")
    group.addoption(
        UPDATE_OPTION,
        action="store_true",
        default=False,
        help="accept the figures simbench_regression.check is given: write them to the regression file",
    )
    parser.addini(
        INI_FILE,
        help=f"the regression figures' JSON file (default: {DEFAULT_FILE} beside each test file)",
        default="",
    )


# ---- scenarios and scores -----------------------------------------------------------------------


class ScenarioCache:
    """The suite's scenarios simulated once per ``(name, seed)``: call it as
    ``cache(name, seed=1)``; ``cache.datasets`` holds those simulated so far."""

    def __init__(self) -> None:
        self.datasets: dict[tuple[str, int], Dataset] = {}

    def __call__(self, name: str, seed: int = SEEDS[0]) -> Dataset:
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise TypeError(f"simbench_scenario: seed must be an int, got {seed!r}")
        key = (scenario(name).name, seed)
        if key not in self.datasets:
            self.datasets[key] = scenario_dataset(key[0], seed)
        return self.datasets[key]


def estimator_of(estimator: str | Estimator | Callable[..., Any]) -> Estimator:
    """An estimator from a spec (:func:`simbench.estimators.resolve`), an :class:`Estimator` or a
    plain function (its kind read off its first parameter, ``poses`` or ``imu``)."""
    if isinstance(estimator, str | Estimator):
        return resolve(estimator)
    name = f"{getattr(estimator, '__module__', '?')}:{getattr(estimator, '__qualname__', repr(estimator))}"
    return from_callable(estimator, name, "python")


def score(estimator: str | Estimator | Callable[..., Any], ds: Dataset) -> dict[str, float]:
    """An estimator's figures on a dataset with truth, all "lower is better": a joints estimator's
    :func:`~simbench.experiments.metrics.joint_method_metrics` (``joint_centre_error_m``,
    ``limb_length_error_m``, ``failed_joints``), an orientation estimator's
    :func:`~simbench.experiments.metrics.orientation_metrics` (``total_rmse_deg``,
    ``heading_rmse_deg``, ``inclination_rmse_deg``)."""
    est = estimator_of(estimator)
    if est.kind == "joints":
        return joint_method_metrics(ds, est)
    return orientation_metrics(ds, est)


@pytest.fixture(scope="session")
def simbench_scenario() -> ScenarioCache:
    """``simbench_scenario(name, seed=1)``: the suite's scenario simulated with exact truth, once
    per session for each ``(name, seed)`` (shared: do not modify it)."""
    return ScenarioCache()


@pytest.fixture(scope="session")
def simbench_scenarios() -> list[str]:
    """The suite's scenario names, in its order."""
    return [sc.name for sc in SCENARIOS]


@pytest.fixture(scope="session")
def simbench_score(simbench_scenario: ScenarioCache) -> Callable[..., dict[str, float]]:
    """``simbench_score(estimator, ds_or_scenario_name, seed=1)``: :func:`score` on a dataset, or on
    a scenario of the suite (simulated through ``simbench_scenario``)."""

    def run(
        estimator: str | Estimator | Callable[..., Any], ds: Dataset | str, seed: int = SEEDS[0]
    ) -> dict[str, float]:
        return score(estimator, simbench_scenario(ds, seed) if isinstance(ds, str) else ds)

    return run


# ---- regression figures -------------------------------------------------------------------------


def _number(value: Any) -> float | None:
    """``value`` as a float, or ``None`` when it is not a real number."""
    if isinstance(value, bool):
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _read(path: Path) -> dict[str, Any]:
    """The regression file's document (an empty one when there is no file)."""
    if not path.exists():
        return {"format": FORMAT, "figures": {}}
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        pytest.fail(f"simbench regression file {path} cannot be read: {exc}", pytrace=False)
    if not isinstance(doc, dict) or not isinstance(doc.get("figures"), dict):
        pytest.fail(
            f"simbench regression file {path}: expected an object with 'figures' (written by "
            f"{UPDATE_OPTION}), got {type(doc).__name__}",
            pytrace=False,
        )
    return doc


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Writers of the same regression file take turns (a lock file in the temporary folder)."""
    if fcntl is None:
        yield
        return
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:16]
    lock = Path(tempfile.gettempdir()) / f"simbench-regression-{digest}.lock"
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


class Regression:
    """The ``simbench_regression`` fixture: :meth:`check` a test's figures against those accepted.

    Attributes:
        path: the regression file a :meth:`check` without ``path=`` uses.
        update: ``--simbench-update`` was given: :meth:`check` accepts the figures it is given.
    """

    def __init__(self, request: pytest.FixtureRequest) -> None:
        config = request.config
        self.update: bool = bool(config.getoption("simbench_update"))
        self._folder = Path(request.path).parent
        named = str(config.getini(INI_FILE) or "").strip()
        if named:
            base = config.inipath.parent if config.inipath is not None else config.rootpath
            self.path = base / named
        else:
            self.path = self._folder / DEFAULT_FILE
        self._updated: list[str] = config.stash.setdefault(_UPDATED, [])

    def check(
        self,
        key: str,
        figures: Mapping[str, float],
        *,
        rel_tol: float = 0.1,
        abs_tol: float = 0.0,
        path: str | os.PathLike[str] | None = None,
    ) -> None:
        """Fail unless every figure is no worse than accepted: ``value <= accepted +
        |accepted| * rel_tol + abs_tol`` (all figures "lower is better").

        Args:
            key: what the figures are of, e.g. ``"my-method/linkage-paper"``.
            figures: ``{figure: value}``, finite numbers.
            rel_tol: the tolerance relative to the accepted figure.
            abs_tol: the absolute tolerance, in the figure's unit.
            path: the regression file (relative: to the test file's folder); default
                :attr:`path`.

        With ``--simbench-update`` the figures are written to the file (merged with its other
        keys) and the check passes. It fails when a figure is not finite, when the key or a figure
        has no accepted value yet, or when the key's figures were accepted with another suite
        version (not comparable).
        """
        if not isinstance(key, str) or not key:
            raise TypeError(f"simbench_regression.check: key must be a non-empty string, got {key!r}")
        for name, tol in (("rel_tol", rel_tol), ("abs_tol", abs_tol)):
            t = _number(tol)
            if t is None or not math.isfinite(t) or t < 0:
                raise ValueError(
                    f"simbench_regression.check: {name} must be a finite number >= 0, got {tol!r}"
                )
        if not isinstance(figures, Mapping) or not figures:
            raise TypeError(
                f"simbench_regression.check({key!r}): figures must be a non-empty {{name: number}}, "
                f"got {figures!r}"
            )
        values: dict[str, float] = {}
        bad = []
        for name, value in figures.items():
            v = _number(value)
            if not isinstance(name, str) or v is None or not math.isfinite(v):
                bad.append(f"  {name}: {value!r}")
            else:
                values[name] = v
        if bad:
            pytest.fail(
                f"simbench regression {key!r}: figures must be finite numbers (a regression cannot be "
                "told from NaN or infinity; did the estimator fail?):\n" + "\n".join(bad),
                pytrace=False,
            )
        file = self.path if path is None else self._folder / Path(path)
        if self.update:
            self._write(file, key, values)
            return
        self._compare(file, key, values, float(rel_tol), float(abs_tol))

    def _write(self, file: Path, key: str, values: dict[str, float]) -> None:
        with _locked(file):
            doc = _read(file)
            doc["format"] = FORMAT
            doc["figures"][key] = {
                "suite_version": SUITE_VERSION,
                "simbench_version": __version__,
                "figures": dict(sorted(values.items())),
            }
            atomic_write_text(file, json.dumps(doc, indent=2, sort_keys=True) + "\n")
        self._updated.append(f"{key} ({file})")

    def _compare(self, file: Path, key: str, values: dict[str, float], rel: float, abs_: float) -> None:
        entry = _read(file)["figures"].get(key)
        if not isinstance(entry, dict) or not isinstance(entry.get("figures"), dict):
            pytest.fail(
                f"simbench regression {key!r}: no accepted figures in {file}; run pytest with "
                f"{UPDATE_OPTION} to accept these: {values}",
                pytrace=False,
            )
        version = entry.get("suite_version")
        if version != SUITE_VERSION:
            pytest.fail(
                f"simbench regression {key!r}: the figures in {file} were accepted with suite version "
                f"{version!r} (simbench {entry.get('simbench_version')}), this is suite version "
                f"{SUITE_VERSION!r} (simbench {__version__}): the figures are not comparable; check "
                f"them and run pytest with {UPDATE_OPTION} to accept the new ones",
                pytrace=False,
            )
        accepted = entry["figures"]
        problems = []
        for name, value in values.items():
            if name not in accepted:
                problems.append(
                    f"  {name}: {value:.6g} has no accepted figure yet (run pytest with {UPDATE_OPTION})"
                )
                continue
            ref = _number(accepted[name])
            if ref is None or not math.isfinite(ref):
                problems.append(f"  {name}: the accepted figure {accepted[name]!r} is not a finite number")
                continue
            limit = ref + abs(ref) * rel + abs_
            if value > limit:
                problems.append(
                    f"  {name}: {value:.6g} is worse than the accepted {ref:.6g} (limit {limit:.6g}: "
                    f"rel_tol {rel:g}, abs_tol {abs_:g})"
                )
        if problems:
            pytest.fail(
                f"simbench regression {key!r} ({file}; lower is better):\n"
                + "\n".join(problems)
                + f"\n(if the change is intended, run pytest with {UPDATE_OPTION})",
                pytrace=False,
            )


@pytest.fixture
def simbench_regression(request: pytest.FixtureRequest) -> Regression:
    """``simbench_regression.check(key, figures, rel_tol=0.1, abs_tol=0.0, path=None)``
    (:class:`Regression`)."""
    return Regression(request)


def pytest_terminal_summary(terminalreporter: Any, config: pytest.Config) -> None:
    updated = config.stash.get(_UPDATED, [])
    if updated:
        terminalreporter.section("simbench regression figures accepted")
        for line in updated:
            terminalreporter.write_line(line)
