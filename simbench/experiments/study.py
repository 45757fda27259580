"""Study files: seeded trials over a grid or a random sample of parameters.

A study (TOML) names a base scenario, the parameters to vary, seeds per cell, estimators and
metrics::

    name = "noise"
    seed = 1
    seeds_per_cell = 3
    estimators = ["calibration"]                  # and/or "orientation:fontaine", "joint:score",
                                                  # "joint:mylab.fit:estimate", "joint:cmd:..."
    metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]
    [base]                                        # a missing key takes SessionConfig's default
    model = "linkage"
    motion = "exercise"
    sensors = "ascension-flock"                   # a preset: the parameters change its fields
    duration_s = 10.0
    rate_hz = 120.0
    [sampling]
    kind = "grid"                                 # or "random", with samples = N
    [[parameter]]
    name = "sensors.tracker.position_noise_m"     # a field of the sensor configuration,
    unit = "mm"                                   # placement.<sensor>.x_m (y_m, z_m), duration_s
    values = [0, 2, 4, 8]                         # or rate_hz; unit converted to SI. Grid: values;
                                                  # random: low, high (, log)

:func:`load_study` checks the whole file before any work; :func:`trials` enumerates its seeded
trials and :func:`trial_config` gives the session of one. Running them is
:mod:`simbench.experiments.sweep`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simbench.errors import InputError, load_toml
from simbench.estimators import names, resolve
from simbench.experiments.metrics import CALIBRATION_METRICS
from simbench.sim.plan import plan_session, session_defaults
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.sim.session import SessionConfig, load_session_model
from simbench.units import UNITS
from simbench.versions import __version__

#: Every metric a study may name: a trial's row holds these columns (:func:`sweep.run_trial`).
METRICS = {
    **CALIBRATION_METRICS,
    "orientation_rmse_deg": "orientation RMSE over sensors and frames, degrees",
    "run_time_s": "seconds the trial took",
}
#: Keys of ``[base]``: fields of :class:`SessionConfig` (a missing one takes its default).
BASE_KEYS = {
    "model",
    "motion",
    "sensors",
    "duration_s",
    "rate_hz",
    "motion_units",
    "motion_cutoff_hz",
    "motion_clusters",
    "motion_position_cutoff_hz",
}
DEFAULT_METRICS = ("joint_centre_error_m", "limb_length_error_m", "hierarchy_correct")
STUDY_KEYS = {"name", "seed", "seeds_per_cell", "estimators", "metrics", "base", "sampling", "parameter"}
PARAMETER_KEYS = {"name", "unit", "values", "low", "high", "log"}
SAMPLING_KEYS = {"kind", "samples"}
#: The most trials a study may have (cells times seeds per cell): a grid beyond this is a
#: mistake (a million trials of seconds each is weeks of computing).
MAX_TRIALS = 1_000_000
SUFFIX_UNIT = {"_m": "m", "_rad": "rad", "_s": "s", "_hz": "hz"}


@dataclass(frozen=True)
class Parameter:
    """One varied parameter: its SI values (grid) or SI range ``[low, high)`` (random; ``log``
    samples uniformly in the logarithm)."""

    name: str
    values: tuple[float, ...] = ()
    low: float = math.nan
    high: float = math.nan
    log: bool = False
    #: The unit the file gave the values in (a key of :data:`simbench.units.UNITS`): the plots
    #: and the summary show the parameter in it.
    unit: str = "1"


@dataclass(frozen=True)
class Study:
    """A parsed study file (module docstring); ``base`` as written, with ``sensors`` filled in."""

    name: str
    seed: int
    seeds_per_cell: int
    estimators: tuple[str, ...]
    metrics: tuple[str, ...]
    base: dict[str, Any]
    kind: str
    samples: int
    parameters: tuple[Parameter, ...]
    #: The file the study was read from (messages name it); not part of the study's fingerprint.
    source: str = field(default="", compare=False)


@dataclass(frozen=True)
class Trial:
    """One seeded trial: cell index, replicate, parameter values (SI) and session seed."""

    cell: int
    replicate: int
    params: tuple[tuple[str, float], ...]
    seed: int

    @property
    def trial_id(self) -> str:
        """``c<cell>-r<replicate>``, zero-padded: sorts in trial order."""
        return f"c{self.cell:05d}-r{self.replicate:03d}"


def _is_number(value: Any) -> bool:
    """An int or float that is not a bool (TOML's ``true`` is no number)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def _field_unit(field: str) -> str:
    """SI unit of a field from its name's suffix (``1`` for a plain number, and for a compound
    unit such as ``_n_per_m`` or ``_nm_per_rad``, whose values are given in it as they are);
    ``deg`` for a field held in degrees (``_deg``)."""
    if "_per_" in field:
        return "1"
    if field.endswith("_deg"):
        return "deg"
    return next((u for suffix, u in SUFFIX_UNIT.items() if field.endswith(suffix)), "1")


def _check_parameter_name(name: str, base_sensors: SensorConfig) -> None:
    if name in ("duration_s", "rate_hz"):
        return
    parts = name.split(".")
    if parts[0] == "placement":
        if len(parts) != 3 or parts[2] not in ("x_m", "y_m", "z_m"):
            raise InputError(f"parameter {name!r}: expected placement.<sensor>.x_m, .y_m or .z_m")
        return
    if len(parts) != 3 or parts[0] != "sensors":
        raise InputError(
            f"parameter {name!r}: expected duration_s, rate_hz or sensors.<section>.<field> "
            "(section: tracker, imu, magnetic, skin)"
        )
    section = getattr(base_sensors, parts[1], None)
    if section is None or not dataclasses.is_dataclass(section):
        raise InputError(f"parameter {name!r}: no sensor section {parts[1]!r} (tracker, imu, magnetic, skin)")
    fields = {f.name: f for f in dataclasses.fields(section)}
    if parts[2] not in fields or fields[parts[2]].type != "float":
        numeric = sorted(f for f, v in fields.items() if v.type == "float")
        raise InputError(
            f"parameter {name!r}: {parts[1]} has no numeric field {parts[2]!r}; fields: {numeric}"
        )


def _parse_parameter(p: Any, where: str, kind: str, base_sensors: SensorConfig) -> Parameter:
    """One ``[[parameter]]`` table, its values converted to SI."""
    if not isinstance(p, dict):
        raise InputError(f"{where}: expected a table ([[parameter]]), got {p!r}")
    extra = sorted(set(p) - PARAMETER_KEYS)
    if extra:
        raise InputError(f"{where}: unknown keys {extra}; expected some of {sorted(PARAMETER_KEYS)}")
    name = p.get("name")
    if not isinstance(name, str):
        raise InputError(f"{where}, key name: expected the parameter's name (a string), got {name!r}")
    try:
        _check_parameter_name(name, base_sensors)
    except InputError as exc:
        raise InputError(f"{where}, key name: {exc}") from None
    where = f"{where} ({name})"
    field_unit = _field_unit(name.split(".")[-1])
    unit = p.get("unit", "deg" if field_unit == "deg" else "1")
    if not isinstance(unit, str) or unit.lower() not in UNITS:
        raise InputError(f"{where}, key unit: unknown unit {unit!r}; expected one of {sorted(UNITS)}")
    unit = unit.lower()
    si, factor = UNITS[unit]
    if field_unit == "deg":  # held in degrees: an angle in any unit, converted to degrees
        if si != "rad":
            raise InputError(f"{where}, key unit: unit {unit!r} does not fit (the field is an angle in deg)")
        factor /= UNITS["deg"][1]
    elif si != field_unit:
        given = f"unit {unit!r}" if "unit" in p else "no unit (a plain number)"
        raise InputError(
            f"{where}, key unit: {given} does not fit: the field is in {field_unit}; give its unit "
            f'(e.g. unit = "{field_unit}")'
        )
    if kind == "grid":
        values = p.get("values")
        if (
            not isinstance(values, list)
            or not values
            or not all(_is_number(v) and math.isfinite(v) for v in values)
        ):
            raise InputError(
                f"{where}, key values: grid sampling needs a non-empty list of finite numbers, got {values!r}"
            )
        extra = sorted({"low", "high", "log"} & set(p))
        if extra:
            raise InputError(f"{where}: {extra} apply to random sampling; a grid takes values")
        return Parameter(name, values=tuple(float(v) * factor for v in values), unit=unit)
    low, high = p.get("low"), p.get("high")
    if not (
        _is_number(low) and _is_number(high) and math.isfinite(low) and math.isfinite(high) and low < high
    ):
        raise InputError(
            f"{where}, keys low and high: random sampling needs low < high (finite numbers), got {low!r} "
            f"and {high!r}"
        )
    if "values" in p:
        raise InputError(f"{where}: values apply to grid sampling; random sampling takes low and high")
    log = p.get("log", False)
    if not isinstance(log, bool):
        raise InputError(f"{where}, key log: expected true or false, got {log!r}")
    if log and low <= 0:
        raise InputError(f"{where}, key low: log sampling needs low > 0, got {low!r}")
    return Parameter(name, low=float(low) * factor, high=float(high) * factor, log=log, unit=unit)


def _beside(value: Any, folder: Path) -> Any:
    """A base value naming a file (a sensor TOML, a model or motion file) as a path from
    ``folder`` (the study file's) when it lies there, else as written (a preset name, or a path
    from the working directory)."""
    if isinstance(value, str) and not Path(value).is_absolute() and (folder / value).is_file():
        return str(folder / value)
    return value


def _base_files(study: Study) -> dict[str, Any]:
    """The study's ``[base]`` with every file it names as found (:func:`_beside` the study file)."""
    folder = Path(study.source).parent if study.source else Path(".")
    return {key: _beside(value, folder) for key, value in study.base.items()}


def _parse_base(doc: dict[str, Any], path: Path) -> tuple[dict[str, Any], SensorConfig]:
    """``[base]`` as written (``sensors`` filled in from SessionConfig's default) and its sensors."""
    base = doc.get("base", {})
    if not isinstance(base, dict):
        raise InputError(f"{path}, key base: expected a table ([base]), got {base!r}")
    base = dict(base)
    bad = sorted(set(base) - BASE_KEYS)
    if bad:
        raise InputError(f"{path}: base: unknown keys {bad}; expected {sorted(BASE_KEYS)}")
    base.setdefault("sensors", SessionConfig().sensors)
    for key, value in base.items():
        numeric = key in ("duration_s", "rate_hz", "motion_cutoff_hz", "motion_position_cutoff_hz")
        if numeric and not _is_number(value):
            raise InputError(f"{path}, key base.{key}: expected a number, got {value!r}")
        if not numeric and not (isinstance(value, str) and value.strip()):
            raise InputError(f"{path}, key base.{key}: expected a string (a name), got {value!r}")
    try:
        base_sensors = load_sensor_config(_beside(base["sensors"], path.parent))
    except InputError as exc:
        raise InputError(f"{path}, key base.sensors: {exc}") from None
    return base, base_sensors


def _strings(doc: dict[str, Any], path: Path, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
    """A non-empty list of strings at ``key``."""
    value = doc.get(key, list(default))
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise InputError(f"{path}, key {key}: expected a non-empty list of names, got {value!r}")
    return tuple(value)


#: A study's estimator entries: ``calibration`` (O'Brien's whole calibration, with the hierarchy
#: inferred and given), or a kind's prefix and any spec of :func:`simbench.estimators.resolve`.
ESTIMATOR_PREFIXES = {"joint:": "joints", "orientation:": "orientation"}


def _parse_estimators(doc: dict[str, Any], path: Path) -> tuple[str, ...]:
    """The study's estimators, each resolved once here (a spec that names nothing, or a file or
    module that cannot be loaded, is refused before any trial); a ``file.py:function`` is found
    beside the study file first, as the base's files are."""
    estimators = []
    for e in _strings(doc, path, "estimators", ("calibration",)):
        if e == "calibration":
            estimators.append(e)
            continue
        prefix = next((p for p in ESTIMATOR_PREFIXES if e.startswith(p)), None)
        if prefix is None:
            raise InputError(
                f"{path}, key estimators: unknown {e!r}; expected calibration, joint:SPEC or "
                f"orientation:SPEC, SPEC one of {', '.join(names())}, package.module:function, "
                "path/to/file.py:function or cmd:COMMAND"
            )
        spec = e[len(prefix) :]
        where, _, attr = spec.rpartition(":")
        if where.endswith(".py") and not Path(where).is_absolute() and (path.parent / where).is_file():
            spec = f"{path.parent / where}:{attr}"
        try:
            resolve(spec, ESTIMATOR_PREFIXES[prefix])
        except InputError as exc:
            raise InputError(f"{path}, key estimators: {e!r}: {exc}") from None
        estimators.append(prefix + spec)
    return tuple(estimators)


def _parse_sampling(doc: dict[str, Any], path: Path) -> tuple[str, int]:
    """``(kind, samples)`` of ``[sampling]``."""
    sampling = doc.get("sampling", {"kind": "grid"})
    if not isinstance(sampling, dict):
        raise InputError(f"{path}, key sampling: expected a table ([sampling]), got {sampling!r}")
    unknown = sorted(set(sampling) - SAMPLING_KEYS)
    if unknown:
        raise InputError(f"{path}: sampling: unknown keys {unknown}; expected {sorted(SAMPLING_KEYS)}")
    kind = sampling.get("kind", "grid")
    if kind not in ("grid", "random"):
        raise InputError(f"{path}, key sampling.kind: expected 'grid' or 'random', got {kind!r}")
    samples = sampling.get("samples", 0)
    if kind == "random" and not (isinstance(samples, int) and not isinstance(samples, bool) and samples >= 1):
        raise InputError(
            f"{path}, key sampling.samples: random sampling needs an integer >= 1, got {samples!r}"
        )
    if kind == "grid" and "samples" in sampling:
        raise InputError(
            f"{path}, key sampling.samples: applies to random sampling; a grid takes every value"
        )
    return kind, int(samples)


def _integer(doc: dict[str, Any], path: Path, key: str, default: int, low: int) -> int:
    value = doc.get(key, default)
    if not (isinstance(value, int) and not isinstance(value, bool) and low <= value < 2**63):
        raise InputError(f"{path}, key {key}: {key} must be an integer >= {low} (below 2^63), got {value!r}")
    return value


def load_study(path: str | os.PathLike[str]) -> Study:
    """Read and check a study file; every problem is reported before any work starts.

    Raises:
        InputError: naming the file and key (unknown keys, parameters or estimators, empty
            ranges, wrong units, a base session that is not valid).
    """
    path = Path(path)
    doc = load_toml(path)
    unknown = sorted(set(doc) - STUDY_KEYS)
    if unknown:
        raise InputError(f"{path}: unknown keys {unknown}; expected {sorted(STUDY_KEYS)}")
    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{path}, key name: expected a name (a string), got {name!r}")
    seed = _integer(doc, path, "seed", 0, 0)
    seeds = _integer(doc, path, "seeds_per_cell", 1, 1)
    base, base_sensors = _parse_base(doc, path)
    estimators = _parse_estimators(doc, path)
    metrics = _strings(doc, path, "metrics", DEFAULT_METRICS)
    bad = sorted(set(metrics) - set(METRICS))
    if bad:
        raise InputError(f"{path}, key metrics: unknown {bad}; expected some of {sorted(METRICS)}")
    kind, samples = _parse_sampling(doc, path)
    raw = doc.get("parameter", [])
    if not isinstance(raw, list):
        raise InputError(f"{path}, key parameter: expected [[parameter]] tables, got {raw!r}")
    if not raw:
        raise InputError(f"{path}: expected at least one [[parameter]]")
    params = tuple(
        _parse_parameter(p, f"{path}, parameter[{k}]", kind, base_sensors) for k, p in enumerate(raw)
    )
    names = [p.name for p in params]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise InputError(f"{path}: parameter(s) {repeated} declared more than once; each is varied once")
    cells = math.prod(len(p.values) for p in params) if kind == "grid" else samples
    if cells * seeds > MAX_TRIALS:
        raise InputError(
            f"{path}: {cells:,} cell(s) x {seeds} seed(s) = {cells * seeds:,} trials; at most {MAX_TRIALS:,} "
            "(fewer values, samples or seeds)"
        )
    study = Study(
        name=name,
        seed=seed,
        seeds_per_cell=seeds,
        estimators=estimators,
        metrics=metrics,
        base=base,
        kind=kind,
        samples=samples,
        parameters=params,
        source=str(path),
    )
    try:
        base_session(study)
    except InputError as exc:
        raise InputError(f"{path}: base: {exc}") from None
    return study


def _cells(study: Study) -> np.ndarray:
    """Parameter values of every cell, ``(cells, parameters)``, SI: the grid's cartesian product
    (first parameter slowest) or the seeded random sample."""
    if study.kind == "grid":
        grids = np.meshgrid(*[np.array(p.values) for p in study.parameters], indexing="ij")
        return np.stack([g.ravel() for g in grids], axis=1)
    rng = np.random.default_rng([study.seed, 0xC0FFEE])
    cols = []
    for p in study.parameters:
        u = rng.random(study.samples)
        cols.append(
            np.exp(np.log(p.low) + u * np.log(p.high / p.low)) if p.log else p.low + u * (p.high - p.low)
        )
    return np.stack(cols, axis=1)


def trials(study: Study) -> list[Trial]:
    """Every trial of the study, in a fixed order; trial ``(cell, replicate)`` is seeded from
    ``(study seed, cell, replicate)`` alone."""
    out = []
    for c, row in enumerate(_cells(study)):
        for r in range(study.seeds_per_cell):
            seed = int(np.random.SeedSequence([study.seed, c, r]).generate_state(1)[0])
            params = tuple((p.name, float(v)) for p, v in zip(study.parameters, row, strict=True))
            out.append(Trial(c, r, params, seed))
    return out


def base_session(study: Study) -> SessionConfig:
    """The study's base session: ``[base]``'s keys, :class:`SessionConfig`'s defaults for the rest
    (a recorded motion: its model, rate and length, :func:`~simbench.sim.plan.session_defaults`);
    a file it names is looked up beside the study file first, then from the working directory.

    Raises:
        InputError: a base value SessionConfig refuses (duration or rate not > 0), what reading a
            recorded motion refuses.
    """
    base = _base_files(study)
    names = ("model", "motion", "sensors", "motion_units", "motion_clusters")
    given = {k: base[k] for k in names if k in base}
    given.update(
        {
            k: float(study.base[k])
            for k in ("duration_s", "rate_hz", "motion_cutoff_hz", "motion_position_cutoff_hz")
            if k in study.base
        }
    )
    motion = given.get("motion", SessionConfig().motion)
    given["model"], given["duration_s"], given["rate_hz"] = session_defaults(
        given.get("model"),
        motion,
        given.get("duration_s"),
        given.get("rate_hz"),
        given.get("motion_units"),
        given.get("motion_clusters"),
    )
    return SessionConfig(**given)


def trial_config(study: Study, trial: Trial) -> SessionConfig:
    """The session of one trial: the base session with the trial's parameter values and seed."""
    base = base_session(study)
    sensors = base.sensors if isinstance(base.sensors, SensorConfig) else load_sensor_config(base.sensors)
    timing: dict[str, float] = {}
    shifts: dict[str, list[float]] = {}
    for name, value in trial.params:
        if name in ("duration_s", "rate_hz"):
            timing[name] = value
        elif name.startswith("placement."):
            _, sensor, axis = name.split(".")
            shifts.setdefault(sensor, [0.0, 0.0, 0.0])["xyz".index(axis[0])] = value
        else:
            _, section, field = name.split(".")
            changed = dataclasses.replace(getattr(sensors, section), **{field: value})
            sensors = dataclasses.replace(sensors, **{section: changed})
    return dataclasses.replace(
        base,
        **timing,
        seed=trial.seed,
        sensors=sensors,
        placement=tuple((k, tuple(v)) for k, v in sorted(shifts.items())),
    )


def _named_files(estimator: str) -> list[str]:
    """The files an estimator entry names: a ``file.py:function``'s file, or the files a
    ``cmd:`` line's words name (from the working directory)."""
    spec = estimator.split(":", 1)[1] if ":" in estimator else estimator
    if spec.startswith("cmd:"):
        words = spec[4:].split()
    else:
        words = [spec.rpartition(":")[0]] if spec.rpartition(":")[0].endswith(".py") else []
    return sorted({w for w in words if "{" not in w and Path(w).is_file()})


def study_fingerprint(study: Study) -> str:
    """A fingerprint of the study: SHA-256 of every parsed value (the base session, the sensors,
    the parameters, seeds and estimators), the contents of the files the base names (a sensor
    TOML, a model or motion file) and of a user's estimator files, and simbench's version. Two
    files that parse to the same study share it; any changed value or named file, or another
    simbench version, gives another."""
    values = dataclasses.asdict(study)
    del values["source"]  # where the file lies is not what it asks
    # a base value naming a file (a sensor TOML, an MJCF model, a motion TOML): what it holds
    named = _base_files(study)
    values["file_contents"] = {
        key: hashlib.sha256(Path(value).read_bytes()).hexdigest()
        for key, value in named.items()
        if isinstance(value, str) and Path(value).is_file()
    }
    # a user's estimator in a file (file.py:function, or a script a cmd: line names): its code
    values["estimator_files"] = {
        word: hashlib.sha256(Path(word).read_bytes()).hexdigest()
        for est in study.estimators
        for word in _named_files(est)
    }
    doc = json.dumps(values, sort_keys=True, default=repr)
    return hashlib.sha256(f"simbench {__version__}\n{doc}".encode()).hexdigest()


def check_study(study: Study) -> None:
    """Build and check every cell's session before any trial runs: values a session refuses
    (a duration or rate not > 0, a rate above the model's physics rate, an unknown model, motion
    or preset, a sensor value out of range) are errors naming the cell and its values.

    Raises:
        InputError: the first cell that cannot run.
    """
    models: dict[tuple[str, str, float], Any] = {}
    for trial in trials(study):
        if trial.replicate:
            continue  # replicates differ only in the seed
        values = ", ".join(f"{k} = {v:g}" for k, v in trial.params) or "the base session"
        try:
            config = trial_config(study, trial)
            sensors = config.sensors  # trial_config resolves the preset
            key = (config.model, repr(sensors.skin), sensors.joints.play_m)
            if key not in models:
                models[key] = load_session_model(config)
            plan_session(config, models[key])
        except InputError as exc:
            where = f"{study.source}: study" if study.source else "study"
            raise InputError(f"{where} {study.name!r}, cell {trial.cell} ({values}): {exc}") from None
