"""The benchmark suite: a versioned, fixed set of seeded scenarios every estimator is scored on.

A :class:`SuiteScenario` is a simulated session (a :class:`simbench.sim.session.SessionConfig`
whose seed is replaced by each of the suite's seeds), or a real recording the package ships
(:data:`DATA_DIR`, scored against its optical reference), and the kind of estimator it scores
(``joints`` or ``orientation``). :data:`SUITE_VERSION` changes whenever a scenario, a seed or a
metric changes, and :func:`scenario_fingerprint` hashes what makes a scenario's data (its
session and simbench's version), so two scorecards say whether they can be compared.

``simbench bench`` (:mod:`simbench.experiments.bench`) runs the suite; the pytest plugin
(:mod:`simbench.pytest_plugin`) hands its scenarios to a user's tests.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from simbench.errors import InputError
from simbench.io.dataset import Dataset
from simbench.io.imu import ImuRecording, read_broad
from simbench.sim.sensor_config import parse_sensor_config
from simbench.sim.session import SessionConfig, load_session_model, run_session
from simbench.versions import __version__

#: The suite's version: bump it when a scenario, its seeds or a metric changes.
SUITE_VERSION = "2"

#: The real recordings the package ships (``simbench/data/README.md``: sources and licences).
DATA_DIR = Path(__file__).resolve().parents[1] / "data"

#: The seeds each scenario is run with (``--quick``: the first ones, :data:`QUICK_SEEDS`: three,
#: the fewest the scorecard's paired test is run on).
SEEDS = (1, 2, 3, 4, 5)
QUICK_SEEDS = 3


@dataclass(frozen=True)
class SuiteScenario:
    """One scenario of the suite.

    Attributes:
        name: its name (scorecard rows and the pytest plugin's fixtures use it).
        kind: the kind of estimator it scores (``joints`` or ``orientation``).
        config: the session; its ``seed`` is replaced by each of the suite's seeds.
        about: one line on what it tests.
        quick: part of ``--quick`` (a shorter duration is not used: the data is the suite's).
        recording: for a real recording, its file in :data:`DATA_DIR` (``config`` is then unused):
            one recording, scored against its own reference, the same for every seed.
    """

    name: str
    kind: str
    config: SessionConfig
    about: str
    quick: bool = True
    recording: str | None = None

    @property
    def real(self) -> bool:
        """A real recording, not a simulation."""
        return self.recording is not None


def _session(
    model: str, motion: str, sensors: str, duration_s: float, rate_hz: float = 120.0
) -> SessionConfig:
    return SessionConfig(model=model, motion=motion, sensors=sensors, duration_s=duration_s, rate_hz=rate_hz)


#: The scenarios, in the order a scorecard lists them.
SCENARIOS: tuple[SuiteScenario, ...] = (
    SuiteScenario(
        "linkage-paper",
        "joints",
        _session("linkage", "exercise", "ascension-flock-paper", 20.0),
        "O'Brien et al.'s wooden linkage: five ball joints, the paper-like Flock of Birds",
    ),
    SuiteScenario(
        "linkage-single-axis",
        "joints",
        _session("linkage", "single-axis", "polhemus-liberty", 20.0),
        "the linkage moved about one axis per joint (hinge-like motion)",
    ),
    SuiteScenario(
        "linkage-slip",
        "joints",
        SessionConfig(
            model="linkage",
            motion="exercise",
            duration_s=20.0,
            sensors=parse_sensor_config(
                {
                    "name": "linkage-slip",
                    "tracker": {"position_noise_m": 0.002, "transmitter_pos": [0.0, -0.8, 1.0]},
                    "skin": {"slip": [{"sensor": "forearm_l", "time_s": 10.0, "offset_m": [0.0, 0.03, 0.0]}]},
                },
                "the suite's slip scenario",
            ),
        ),
        "a slip: the left forearm's sensor moves 3 cm on its segment halfway through",
        quick=False,
    ),
    SuiteScenario(
        "humanoid-skin-exercise",
        "joints",
        _session("humanoid", "exercise", "skin-paper-human", 20.0),
        "O'Brien et al.'s human subjects: skin, centimetre slip, laxity, the pelvis pack",
        quick=False,
    ),
    SuiteScenario(
        "humanoid-gait-small-range",
        "joints",
        _session("humanoid", "gait", "ascension-flock", 20.0),
        "a person's gait: hips, shoulders and spine move little (small range of motion)",
        quick=False,
    ),
    SuiteScenario(
        "humanoid-gait-imu",
        "orientation",
        _session("humanoid", "gait", "mems-industrial", 20.0, 100.0),
        "industrial MEMS IMUs on a walking person",
    ),
    SuiteScenario(
        "humanoid-exercise-consumer-imu",
        "orientation",
        _session("humanoid", "exercise", "mems-consumer", 20.0, 100.0),
        "consumer-grade IMUs: bias, scale, misalignment, hard and soft iron",
        quick=False,
    ),
    SuiteScenario(
        "linkage-magnet",
        "orientation",
        _session("linkage", "exercise", "imu-lab-magnet", 20.0, 100.0),
        "a laboratory IMU beside a permanent magnet (BROAD's disturbed trials)",
        quick=False,
    ),
    SuiteScenario(
        "broad-02-undisturbed",
        "orientation",
        SessionConfig(),
        "real: BROAD trial 02's first 60 s, slow rotation, undisturbed field; optical reference",
        recording="broad_02_undisturbed_slow_rotation_B_60s.hdf5",
    ),
    SuiteScenario(
        "broad-30-magnet",
        "orientation",
        SessionConfig(),
        "real: BROAD trial 30's first 60 s, a magnet beside the path; optical reference",
        quick=False,
        recording="broad_30_disturbed_stationary_magnet_C_60s.hdf5",
    ),
)


def scenario(name: str) -> SuiteScenario:
    """The scenario ``name``.

    Raises:
        InputError: no such scenario (the suite's named).
    """
    for sc in SCENARIOS:
        if sc.name == name:
            return sc
    raise InputError(
        f"no scenario {name!r} in the suite (version {SUITE_VERSION}): {[s.name for s in SCENARIOS]}"
    )


def scenario_config(sc: SuiteScenario, seed: int) -> SessionConfig:
    """The session of one seed of a scenario."""
    return dataclasses.replace(sc.config, seed=int(seed))


def scenario_dataset(sc: SuiteScenario | str, seed: int) -> Dataset | ImuRecording:
    """Simulate one seed of a scenario (with exact truth); a real recording is read (the same for
    every seed), with its reference as ``q_true`` and the samples to score as ``evaluate``."""
    sc = scenario(sc) if isinstance(sc, str) else sc
    if sc.real:
        return read_broad(DATA_DIR / sc.recording)
    config = scenario_config(sc, seed)
    return run_session(config, load_session_model(config))


def scenario_fingerprint(sc: SuiteScenario) -> str:
    """A hash of what makes the scenario's data: its session (but the seed), the suite's seeds and
    version, and simbench's version (the simulation may change between versions)."""
    if sc.real:  # the recording's own bytes
        config: dict | str = hashlib.sha256((DATA_DIR / sc.recording).read_bytes()).hexdigest()
    else:
        config = dataclasses.asdict(dataclasses.replace(sc.config, seed=0))
    doc = {"suite": SUITE_VERSION, "simbench": __version__, "seeds": SEEDS, "kind": sc.kind, "config": config}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]
