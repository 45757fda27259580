"""Sensor configurations: TOML files and named presets, into frozen dataclasses.

A configuration has up to six tables; every key is optional (default: ideal) and every
unknown key or out-of-range value is an error naming the file and key::

    name = "my-rig"
    [tracker]                       # simbench.sim.sensor_models.TrackerConfig fields
    position_noise_m = 0.004
    unit_scale = 0.94
    [[tracker.distortion]]          # simbench.sim.sensor_models.Distortion fields
    center = [1.0, 0.5, 0.0]
    radius_m = 0.3
    position_gain_m = 0.02
    [imu]                           # simbench.sim.sensor_models.ImuConfig fields
    accel_noise_density = 0.0006
    [magnetic]
    strength_ut = 50.0              # Earth field, uT
    inclination_deg = 60.0
    [[magnetic.disturbance]]        # ferromagnetic objects as magnetic dipoles
    position = [0.5, 0.0, 1.0]
    moment_am2 = [0.0, 0.0, 2.0]
    [[magnetic.attached]]           # AttachedMagnet: a magnet riding on a sensor for a while
    sensor = "forearm_l"
    start_s = 10.0
    stop_s = 20.0
    field_ut = [15.0, -12.0, 16.0]  # in the sensor's frame
    ramp_s = 1.0
    [skin]                          # SkinConfig fields
    sta_amplitude_m = 0.005
    sta_by_sensor = { thigh_l = 0.03 }
    laxity_by_joint = { shank_l = 0.007 }   # keyed by the joint's child sensor
    mount_stiffness_n_per_m = 2000.0
    [[skin.slip]]
    sensor = "forearm_l"
    time_s = 10.0
    offset_m = [0.0, 0.03, 0.0]
    [skin.pack]                     # simbench.sim.skin.SkinPack: a sensor on a pushed pack
    sensor = "pelvis"
    pushed_by = "thigh_r"
    flexion_axis = [0.0, -1.0, 0.0]
    threshold_rad = 0.5
    gain_m_per_rad = 0.05
    direction = [0.0, 0.0, 1.0]
    [[skin.girdle]]                 # simbench.sim.skin.SkinGirdle: a shoulder girdle
    joint = "upper_arm_l"
    pivot_m = [0.0, -0.15, 0.0]
    axis = [1.0, 0.0, 0.0]
    limb_axis = [0.0, 0.0, -1.0]
    ratio = 0.33
    [joints]                        # JointConfig fields: the subject's mechanics
    play_m = 0.0005                 # free play of every joint, m (simbench.sim.play)

Presets ship in ``simbench/sim/presets/<name>.toml`` (``ideal``, ``ascension-flock``,
``ascension-flock-paper``, ``polhemus-liberty``, ``mems-consumer``, ``mems-industrial``,
``imu-lab``, ``imu-lab-magnet``, ``skin-markers``, ``skin-paper-human``); each file says where its
numbers come from, and which are fitted to what.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simbench.errors import InputError, load_toml
from simbench.sim.sensor_models import Distortion, ImuConfig, TrackerConfig
from simbench.sim.skin import SkinGirdle, SkinPack, SkinSlip

PRESETS_DIR = Path(__file__).resolve().parent / "presets"


@dataclass(frozen=True)
class Disturbance:
    """A ferromagnetic object as a magnetic dipole at ``position`` (m) with ``moment_am2``."""

    position: tuple[float, float, float]
    moment_am2: tuple[float, float, float]

    def __post_init__(self) -> None:
        for name in ("position", "moment_am2"):
            v = getattr(self, name)
            if len(v) != 3 or not np.all(np.isfinite(v)):
                raise InputError(f"disturbance.{name} must be 3 finite numbers, got {v}")


@dataclass(frozen=True)
class AttachedMagnet:
    """A magnet that rides on a sensor for a while (BROAD's attached-magnet trials): a field
    fixed in the sensor's frame, ``field_ut`` (uT, the sensor's axes), from ``start_s`` to
    ``stop_s``, put on and taken off over ``ramp_s`` (the field growing and shrinking linearly
    as the magnet comes near and goes)."""

    sensor: str
    start_s: float
    stop_s: float
    field_ut: tuple[float, float, float]
    ramp_s: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.sensor, str) or not self.sensor:
            raise InputError(f"attached.sensor must be a sensor name, got {self.sensor!r}")
        if len(self.field_ut) != 3 or not np.all(np.isfinite(self.field_ut)):
            raise InputError(f"attached.field_ut must be 3 finite numbers, got {self.field_ut}")
        times = (self.start_s, self.stop_s, self.ramp_s)
        if not (np.all(np.isfinite(times)) and 0 <= self.start_s and self.ramp_s >= 0):
            raise InputError(
                f"attached.start_s and ramp_s must be >= 0, got start_s {self.start_s}, ramp_s {self.ramp_s}"
            )
        if self.stop_s - self.start_s < 2 * self.ramp_s:
            raise InputError(
                f"attached: the magnet must stay on for its two ramps, got start_s {self.start_s}, "
                f"stop_s {self.stop_s}, ramp_s {self.ramp_s}"
            )

    def share(self, time_s: np.ndarray) -> np.ndarray:
        """``(F,)`` how much of ``field_ut`` is on at each time, 0 to 1."""
        t = np.asarray(time_s, dtype=float)
        if self.ramp_s == 0:
            return ((t >= self.start_s) & (t < self.stop_s)).astype(float)
        up = (t - self.start_s) / self.ramp_s
        down = (self.stop_s - t) / self.ramp_s
        return np.clip(np.minimum(up, down), 0.0, 1.0)


@dataclass(frozen=True)
class FieldConfig:
    """The magnetic field: the Earth's, plus disturbances in the room, plus magnets that ride on
    sensors for a while (``[[magnetic.attached]]``)."""

    strength_ut: float = 50.0
    inclination_deg: float = 60.0
    disturbance: tuple[Disturbance, ...] = ()
    attached: tuple[AttachedMagnet, ...] = ()

    def __post_init__(self) -> None:
        if not (np.isfinite(self.strength_ut) and self.strength_ut >= 0):
            raise InputError(f"field.strength_ut must be >= 0, got {self.strength_ut}")
        if not (np.isfinite(self.inclination_deg) and -90 <= self.inclination_deg <= 90):
            raise InputError(f"field.inclination_deg must be in [-90, 90], got {self.inclination_deg}")


@dataclass(frozen=True)
class SkinConfig:
    """Skin slip and non-ideal joints (see :mod:`simbench.sim.skin` and :mod:`simbench.sim.mounts`).

    Attributes:
        sta_amplitude_m: soft-tissue artefact amplitude of every sensor, m.
        sta_by_sensor: per-sensor amplitudes overriding it, m.
        laxity_by_joint: joint-centre laxity amplitude by the joint's child sensor, m.
        slip: slip events.
        pack: a sensor on a pack another segment pushes (``[skin.pack]``), or ``None``.
        girdle: joints whose centre a girdle carries (``[[skin.girdle]]``: the shoulders).
        mount_stiffness_n_per_m: translational stiffness of the soft-tissue mount (0: the
            sensor is rigid on the bone, no mount).
        mount_rot_stiffness_nm_per_rad: rotational stiffness of the mount (0: rigid in rotation
            when the mount is on).
        mount_damping_ratio: damping ratio of the mount's springs.
        mount_mass_kg: mass of sensor and moving tissue on the mount, kg.
    """

    sta_amplitude_m: float = 0.0
    sta_by_sensor: dict[str, float] = field(default_factory=dict)
    laxity_by_joint: dict[str, float] = field(default_factory=dict)
    slip: tuple[SkinSlip, ...] = ()
    pack: SkinPack | None = None
    girdle: tuple[SkinGirdle, ...] = ()
    mount_stiffness_n_per_m: float = 0.0
    mount_rot_stiffness_nm_per_rad: float = 0.0
    mount_damping_ratio: float = 0.3
    mount_mass_kg: float = 0.03

    def __post_init__(self) -> None:
        for name in (
            "sta_amplitude_m",
            "mount_stiffness_n_per_m",
            "mount_rot_stiffness_nm_per_rad",
            "mount_damping_ratio",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"skin.{name} must be a finite number >= 0, got {v!r}")
        if not (np.isfinite(self.mount_mass_kg) and self.mount_mass_kg > 0):
            raise InputError(f"skin.mount_mass_kg must be > 0, got {self.mount_mass_kg!r}")
        for table in ("sta_by_sensor", "laxity_by_joint"):
            if not isinstance(getattr(self, table), dict):
                raise InputError(
                    f"skin.{table} must be a table of sensor = metres, e.g. {{ thigh_l = 0.015 }}, "
                    f"got {getattr(self, table)!r}"
                )
            for key, v in getattr(self, table).items():
                if not isinstance(v, int | float) or not np.isfinite(v) or v < 0:
                    raise InputError(f"skin.{table}.{key} must be a number >= 0, got {v!r}")

    @property
    def has_mount(self) -> bool:
        """A soft-tissue mount is modelled in the physics."""
        return self.mount_stiffness_n_per_m > 0


@dataclass(frozen=True)
class JointConfig:
    """The captured subject's joints as built: free play (:mod:`simbench.sim.play`).

    Attributes:
        play_m: half the clearance of every joint along each axis of the child's frame, m
            (0: perfect joints).
    """

    play_m: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.play_m) and 0 <= self.play_m < 0.05):
            raise InputError(f"joints.play_m must be a number of metres in [0, 0.05), got {self.play_m!r}")


@dataclass(frozen=True)
class SensorConfig:
    """All sensor imperfections of a session."""

    name: str = "ideal"
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    magnetic: FieldConfig = field(default_factory=FieldConfig)
    skin: SkinConfig = field(default_factory=SkinConfig)
    joints: JointConfig = field(default_factory=JointConfig)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready copy (tuples as lists)."""
        return dataclasses.asdict(self)


def _build(cls: type, table: Any, where: str) -> Any:
    """A frozen dataclass from a TOML table, naming unknown keys and bad values by their path."""
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table, got {table!r}")
    names = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - set(names))
    if unknown:
        raise InputError(f"{where}: unknown keys {unknown}; expected some of {sorted(names)}")
    kwargs: dict[str, Any] = {}
    for key, value in table.items():
        sub = {
            "distortion": Distortion,
            "disturbance": Disturbance,
            "attached": AttachedMagnet,
            "slip": SkinSlip,
            "girdle": SkinGirdle,
        }.get(key)
        if sub is not None:
            if not isinstance(value, list):
                raise InputError(f"{where}.{key}: expected an array of tables ([[{where}.{key}]])")
            kwargs[key] = tuple(_build(sub, item, f"{where}.{key}[{k}]") for k, item in enumerate(value))
        elif key == "pack" and cls is SkinConfig:
            kwargs[key] = _build(SkinPack, value, f"{where}.{key}")
        else:
            kwargs[key] = _value(value, names[key].type, f"{where}.{key}")
    try:
        return cls(**kwargs)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise InputError(f"{where}: {exc}") from None


def _value(value: Any, kind: str, where: str) -> Any:
    """A TOML value for a field of type ``kind`` (``float``, ``tuple[float, ...]``,
    ``dict[str, float]``; others, such as sensor names, as they are: their dataclass checks them),
    or an InputError naming ``where``."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if kind == "float":
        if not number:
            raise InputError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if kind.startswith("tuple"):
        if not isinstance(value, list) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value
        ):
            raise InputError(f"{where}: expected a list of numbers, got {value!r}")
        return tuple(float(v) for v in value)
    if kind.startswith("dict"):
        if not isinstance(value, dict):
            raise InputError(
                f"{where}: expected a table of sensor = value, e.g. {{ thigh_l = 0.015 }}, got {value!r}"
            )
        return dict(value)
    return value


def parse_sensor_config(doc: dict[str, Any], where: str) -> SensorConfig:
    """A :class:`SensorConfig` from a parsed TOML document (``where`` names it in errors)."""
    unknown = sorted(set(doc) - {"name", "description", "tracker", "imu", "magnetic", "skin", "joints"})
    if unknown:
        raise InputError(
            f"{where}: unknown keys {unknown}; expected name, description, tracker, imu, magnetic, "
            "skin, joints"
        )
    for key in ("name", "description"):
        if not isinstance(doc.get(key, ""), str):
            raise InputError(f"{where}, key {key}: expected a string, got {doc[key]!r}")
    return SensorConfig(
        name=str(doc.get("name", "custom")),
        tracker=_build(TrackerConfig, doc.get("tracker", {}), f"{where}: tracker"),
        imu=_build(ImuConfig, doc.get("imu", {}), f"{where}: imu"),
        magnetic=_build(FieldConfig, doc.get("magnetic", {}), f"{where}: magnetic"),
        skin=_build(SkinConfig, doc.get("skin", {}), f"{where}: skin"),
        joints=_build(JointConfig, doc.get("joints", {}), f"{where}: joints"),
    )


def preset_names() -> list[str]:
    """Names of the shipped presets."""
    return sorted(p.stem for p in PRESETS_DIR.glob("*.toml"))


def load_sensor_config(name_or_path: str) -> SensorConfig:
    """A preset by name, or a configuration TOML file by path.

    Raises:
        InputError: unknown preset, unreadable file, invalid TOML, unknown keys, bad values.
    """
    path = Path(name_or_path)
    if path.suffix.lower() != ".toml":
        path = PRESETS_DIR / f"{name_or_path}.toml"
        if not re.fullmatch(r"[A-Za-z0-9_-]+", name_or_path) or not path.is_file():
            raise InputError(
                f"unknown sensor preset {name_or_path!r}: expected one of {', '.join(preset_names())} "
                "or a .toml file"
            )
    doc = load_toml(path)
    return parse_sensor_config(doc, str(path))
