"""What a capture session is asked to be, and everything about it fixed before physics runs.

A :class:`SessionConfig` names the model, motion, duration, rate, seed and sensors;
:func:`plan_session` turns it into a :class:`SessionPlan` against a loaded model: the motion
program, the root's phases, the physics timestep (the model's, or slightly finer so that the
capture period is a whole number ``k`` of steps) and the random streams of the sensor models,
all drawn from the session seed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simbench.errors import InputError
from simbench.sim.models import CaptureModel, Mount, joint_sensor_indices, load_capture_model
from simbench.sim.motion_source import (
    MotionSource,
    check_units,
    is_recorded,
    load_motion,
    motion_format,
    own_model,
)
from simbench.sim.playback import (
    DEFAULT_CUTOFF_HZ,
    Playback,
    clip_rate_hz,
    default_duration_s,
    plan_playback,
)
from simbench.sim.programs import BUILTIN_PROGRAMS, Program, builtin_program, load_program
from simbench.sim.roles import humanoid_roles
from simbench.sim.sensor_config import SensorConfig, load_sensor_config

POSES_WHAT = (
    "the bodies of a pose trajectory: give a pose CSV, a C3D file of marker clusters or a BROAD-layout trial"
)

#: The most samples a session may record (10 million: a day at 120 Hz; each sample of each sensor
#: holds some hundred numbers of truth and measurement).
MAX_SAMPLES = 10_000_000


@dataclass(frozen=True)
class SessionConfig:
    """What a capture session is asked to be.

    Attributes:
        model: model name (``linkage``, ``humanoid``, ``dm_control:NAME``, an MJCF path), or the
            model a recorded motion brings: ``bvh`` (a BVH clip's skeleton,
            :mod:`simbench.sim.bvh_model`), ``poses`` (a pose trajectory's bodies,
            :mod:`simbench.sim.pose_model`), which it must be with such a motion.
        motion: built-in program name, a program TOML path, or a recorded motion file played back
            kinematically (:mod:`simbench.sim.motion_source`: BVH, ``qpos`` series, OpenSim
            joint angles, pose trajectories; :mod:`simbench.sim.playback`).
        duration_s: session length, s (> 0).
        rate_hz: capture rate, Hz (> 0, at most the model's physics rate).
        seed: seed of the session's ``numpy.random.Generator``.
        sensor_bodies: bodies carrying a sensor, or ``None`` for the model's default.
        sensors: sensor preset name, configuration TOML path, or a :class:`SensorConfig`
            (:mod:`simbench.sim.sensor_config`).
        placement: ``((sensor, (dx, dy, dz)), ...)`` sensor shifts in their body frames, m.
        motion_units: a recorded motion's length unit (``cm``, ``m``, ``mm``, ``in``), or ``None``:
            the file's convention (BVH centimetres, a pose CSV metres, a C3D file its own).
        motion_cutoff_hz: a recorded motion's smoothing cutoff for velocities and accelerations, Hz.
        motion_position_cutoff_hz: the cutoff of its positions, Hz (``None``: ``motion_cutoff_hz``):
            accelerations are positions differentiated twice, which amplifies a recording's jitter.
        recording: a recorded motion already read (its model with it), played instead of reading
            ``motion``, which then only names it; ``None``: ``motion`` is read when it is a file.
        motion_clusters: a C3D motion's marker cluster spec (TOML), or ``None``: found automatically.
    """

    model: str = "linkage"
    motion: str = "exercise"
    duration_s: float = 20.0
    rate_hz: float = 120.0
    seed: int = 0
    sensor_bodies: tuple[str, ...] | None = None
    sensors: str | SensorConfig = "ideal"
    placement: tuple[tuple[str, tuple[float, float, float]], ...] = ()
    motion_units: str | None = None
    motion_cutoff_hz: float = DEFAULT_CUTOFF_HZ
    motion_clusters: str | None = None
    motion_position_cutoff_hz: float | None = None
    recording: MotionSource | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise InputError(f"duration must be > 0 s, got {self.duration_s}")
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise InputError(f"rate must be > 0 Hz, got {self.rate_hz}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**63:
            raise InputError(f"seed must be an integer in [0, 2^63), got {self.seed!r}")
        if self.recording is not None:
            own = self.recording.model if self.recording.make_spec is not None else None
        else:
            own = own_model(self.motion) if is_recorded(self.motion) else None
        if own is not None and self.model != own:
            raise InputError(
                f"motion {self.motion}: a {motion_format(self.motion)} recording moves its own model: leave "
                f"the model at its default or give {own!r}, got {self.model!r}"
            )
        for name, what in (("bvh", "a BVH clip's own skeleton: give a .bvh motion"), ("poses", POSES_WHAT)):
            if self.model == name and own != name:
                raise InputError(f"model {name!r} is {what}")
        check_units(self.motion_units)
        for name, cutoff in (("", self.motion_cutoff_hz), ("position ", self.motion_position_cutoff_hz)):
            if cutoff is not None and not (math.isfinite(cutoff) and cutoff > 0):
                raise InputError(f"motion {name}cutoff must be > 0 Hz, got {cutoff}")

    def as_dict(self) -> dict:
        """JSON-ready copy."""
        return {
            "model": self.model,
            "motion": self.motion,
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "seed": self.seed,
            "sensor_bodies": None if self.sensor_bodies is None else list(self.sensor_bodies),
            "sensors": self.sensors if isinstance(self.sensors, str) else self.sensors.as_dict(),
            "placement": {k: list(v) for k, v in self.placement},
            "motion_units": self.motion_units,
            "motion_cutoff_hz": self.motion_cutoff_hz,
            "motion_clusters": self.motion_clusters,
            "motion_position_cutoff_hz": self.motion_position_cutoff_hz,
        }

    def recorded(self) -> MotionSource | None:
        """The recorded motion and its model (read once per file), or ``None`` for a program."""
        if self.recording is not None:
            return self.recording
        if not is_recorded(self.motion):
            return None
        return load_motion(self.motion, self.model, self.motion_units, self.motion_clusters)


def session_defaults(
    model: str | None,
    motion: str,
    duration_s: float | None,
    rate_hz: float | None,
    motion_units: str | None = None,
    motion_clusters: str | None = None,
) -> tuple[str, float, float]:
    """``(model, duration_s, rate_hz)`` of a session, the ones not given (``None``) filled in.

    A recorded motion: the model it brings or names (:func:`simbench.sim.motion_source.default_model`;
    another model beside one it brings is refused), its own rate and the whole recording at the
    rate. Otherwise ``linkage``, 20 s, 120 Hz (:class:`SessionConfig`'s).

    Raises:
        InputError: a model beside a motion that brings its own; what reading the motion refuses.
    """
    default = SessionConfig()
    if not is_recorded(motion):
        return (
            default.model if model is None else model,
            default.duration_s if duration_s is None else duration_s,
            default.rate_hz if rate_hz is None else rate_hz,
        )
    check_units(motion_units)
    source = load_motion(motion, model, motion_units, motion_clusters)
    clip = source.recorded
    rate = clip_rate_hz(clip) if rate_hz is None else rate_hz
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"rate must be > 0 Hz, got {rate}")
    return source.model, default_duration_s(clip, rate) if duration_s is None else duration_s, rate


@dataclass(frozen=True)
class SessionPlan:
    """What a session will do, fixed before any physics runs.

    Attributes:
        program: the motion program.
        root_phases: ``(12,)`` phases of the root's motion, rad.
        steps_per_sample: physics steps per capture sample ``k``.
        timestep: physics timestep, s.
        n_samples: samples to record.
        sensor_config: the sensor configuration (resolved from a preset, file or object).
        streams: independent random generators for the ``skin``, ``tracker`` and ``imu`` models
            (so that switching one imperfection on does not change another's draws).
        notes: what was changed to fit the sensors to the model (:func:`adapt_preset`).
        playback: the recorded motion played back instead of physics, or ``None``;
            ``program`` is then only its name, one step per sample at the capture period.
    """

    program: Program
    root_phases: np.ndarray
    steps_per_sample: int
    timestep: float
    n_samples: int
    sensor_config: SensorConfig
    streams: dict[str, np.random.Generator]
    playback: Playback | None = None
    notes: tuple[str, ...] = ()


def steps_per_sample(model_timestep: float, rate_hz: float) -> tuple[int, float]:
    """``(k, dt)``: physics steps per sample and the timestep, ``dt <= model_timestep``.

    Raises:
        InputError: when the capture rate is above the model's physics rate.
    """
    period = 1.0 / rate_hz
    if not math.isfinite(period / model_timestep):
        raise InputError(
            f"capture rate {rate_hz:g} Hz: a sample period of {period:g} s is not a number of steps"
        )
    if period < model_timestep * (1 - 1e-9):
        raise InputError(
            f"capture rate {rate_hz:g} Hz is above the model's physics rate {1 / model_timestep:g} Hz"
        )
    k = max(1, math.ceil(period / model_timestep - 1e-9))
    return k, period / k


def _program(config: SessionConfig, cm: CaptureModel, rng: np.random.Generator) -> Program:
    if config.motion in BUILTIN_PROGRAMS:
        return builtin_program(config.motion, cm, config.duration_s, rng)
    if config.motion.endswith(".toml"):
        return load_program(config.motion, cm)
    raise InputError(
        f"unknown motion {config.motion!r}: expected one of {', '.join(BUILTIN_PROGRAMS)} or a .toml file"
    )


def _mount_of(sensor_config: SensorConfig) -> Mount | None:
    skin = sensor_config.skin
    if not skin.has_mount:
        return None
    return Mount(
        stiffness_n_per_m=skin.mount_stiffness_n_per_m,
        rot_stiffness_nm_per_rad=skin.mount_rot_stiffness_nm_per_rad,
        damping_ratio=skin.mount_damping_ratio,
        mass_kg=skin.mount_mass_kg,
    )


def _is_preset(config: SessionConfig) -> bool:
    return isinstance(config.sensors, str) and not config.sensors.endswith(".toml")


def _sensor_config(config: SessionConfig) -> SensorConfig:
    """The session's sensors; a built-in preset's joint play left out on a recorded motion
    (:func:`adapt_preset` says so)."""
    sc = _sensor_config_raw(config)
    recorded = config.recording is not None or is_recorded(config.motion)
    if _is_preset(config) and recorded and sc.joints.play_m > 0:
        sc = dataclasses.replace(sc, joints=dataclasses.replace(sc.joints, play_m=0.0))
    return sc


def adapt_preset(config: SessionConfig, cm: CaptureModel) -> tuple[SensorConfig, tuple[str, ...]]:
    """A built-in preset made to fit the session's model, and what was changed, in plain words.

    Presets written for the humanoid name its segments (``skin.sta_by_sensor``,
    ``laxity_by_joint``, ``slip``, ``magnetic.attached``): on another model the segments that play
    those roles (:func:`simbench.sim.roles.humanoid_roles`: a BVH clip's ``LeftUpLeg`` is the
    ``thigh_l``) take the values; a segment no role fits, and the pack and girdle (their axes are
    the humanoid's segment frames), are left out. Joint play is left out on a recorded motion.
    A user's own configuration (a TOML file or object) is never changed: its names must be the
    model's (:func:`check_sensor_names`).
    """
    sc = _sensor_config(config)
    if not _is_preset(config):
        return sc, ()
    notes = []
    if _sensor_config_raw(config).joints.play_m > 0 and sc.joints.play_m == 0:
        notes.append("joint play left out: a recorded motion sets every joint kinematically")
    sensors = list(cm.sensors)
    _, child = joint_sensor_indices(cm)
    children = [sensors[c] for c in child]
    roles = humanoid_roles(sensors)
    renamed: dict[str, str] = {}
    dropped: list[str] = []

    def rename(name: str, among: list[str], key: str) -> str | None:
        if name in among:
            return name
        to = roles.get(name)
        if to in among:
            renamed[name] = to
            return to
        dropped.append(f"{key} {name}")
        return None

    skin = sc.skin
    sta = {n: v for k, v in skin.sta_by_sensor.items() if (n := rename(k, sensors, "skin.sta_by_sensor"))}
    lax = {
        n: v for k, v in skin.laxity_by_joint.items() if (n := rename(k, children, "skin.laxity_by_joint"))
    }
    slips = tuple(
        dataclasses.replace(x, sensor=n) for x in skin.slip if (n := rename(x.sensor, sensors, "skin.slip"))
    )
    pack = skin.pack
    if pack is not None and not {pack.sensor, pack.pushed_by} <= set(sensors):
        dropped.append(f"skin.pack on {pack.sensor} (its axes are the humanoid's)")
        pack = None
    girdle = tuple(g for g in skin.girdle if g.joint in children)
    dropped += [
        f"skin.girdle {g.joint} (its axes are the humanoid's)" for g in skin.girdle if g.joint not in children
    ]
    attached = tuple(
        dataclasses.replace(a, sensor=n)
        for a in sc.magnetic.attached
        if (n := rename(a.sensor, sensors, "magnetic.attached"))
    )
    if renamed:
        pairs = ", ".join(f"{k} -> {v}" for k, v in sorted(renamed.items()))
        notes.append(f"the humanoid's segments played by this model's: {pairs}")
    if dropped:
        notes.append(f"left out, no segment of this model plays them: {'; '.join(sorted(set(dropped)))}")
    said = tuple(f"sensor preset {sc.name!r}: {n}" for n in notes)
    if not renamed and not dropped:
        return sc, said
    skin = dataclasses.replace(
        skin, sta_by_sensor=sta, laxity_by_joint=lax, slip=slips, pack=pack, girdle=girdle
    )
    magnetic = dataclasses.replace(sc.magnetic, attached=attached)
    return dataclasses.replace(sc, skin=skin, magnetic=magnetic), said


def _sensor_config_raw(config: SessionConfig) -> SensorConfig:
    return config.sensors if isinstance(config.sensors, SensorConfig) else load_sensor_config(config.sensors)


def _check_playback_sensors(config: SessionConfig, sensor_config: SensorConfig) -> None:
    """A played-back motion sets every joint: joints with play (shifted by contact forces) need a
    physics session. (Sprung mounts are integrated on top of the playback.)"""
    if sensor_config.joints.play_m > 0:
        raise InputError(
            f"{sensors_source(config)}: joint play moves by contact physics; a recorded motion "
            f"({config.motion}) sets every joint kinematically: choose sensors without joints.play_m"
        )


def load_session_model(config: SessionConfig) -> CaptureModel:
    """The capture model a session needs (with the soft-tissue mount its sensors ask for); a
    recorded motion's own model for a motion that brings one."""
    sensor_config = _sensor_config(config)
    source = config.recorded()
    spec = None
    if source is not None:
        _check_playback_sensors(config, sensor_config)
        spec = source.spec()
    return load_capture_model(
        config.motion if spec is not None else config.model,
        sensor_bodies=config.sensor_bodies,
        mount=_mount_of(sensor_config),
        placement=dict(config.placement),
        joint_play_m=sensor_config.joints.play_m,
        spec=spec,
        played_back=source is not None,
    )


def sensors_source(config: SessionConfig) -> str:
    """The sensors of a session as its messages name them: the preset or file, or the object's name."""
    if isinstance(config.sensors, SensorConfig):
        return f"sensors {config.sensors.name!r}"
    return config.sensors if config.sensors.endswith(".toml") else f"sensor preset {config.sensors!r}"


def check_sensor_names(sensor_config: SensorConfig, cm: CaptureModel, source: str) -> None:
    """The sensors and joints a configuration's skin and attached magnets name must be on the
    model: checked before any physics (the skin models would find them only after it).

    Raises:
        InputError: naming ``source`` (the preset or file), the key and the model's sensors.
    """
    skin = sensor_config.skin
    sensors = list(cm.sensors)
    _, child = joint_sensor_indices(cm)
    children = [sensors[c] for c in child]
    pack = [] if skin.pack is None else [skin.pack.sensor, skin.pack.pushed_by]
    groups = [
        ("skin.sta_by_sensor", list(skin.sta_by_sensor), sensors),
        ("skin.laxity_by_joint", list(skin.laxity_by_joint), children),
        ("skin.slip", [slip.sensor for slip in skin.slip], sensors),
        ("skin.pack", pack, sensors),
        ("skin.girdle", [g.joint for g in skin.girdle], children),
        ("magnetic.attached", [m.sensor for m in sensor_config.magnetic.attached], sensors),
    ]
    for key, names, among in groups:
        unknown = sorted(set(names) - set(among))
        if unknown:
            what = "carry no sensor" if among is sensors else "are not the child sensor of a joint"
            raise InputError(
                f"{source}: {key} names {unknown}, which {what} in the model {cm.source}; "
                f"{'sensors' if among is sensors else 'child sensors of its joints'}: {among}"
            )


def plan_session(config: SessionConfig, cm: CaptureModel) -> SessionPlan:
    """Draw everything random about a session from its seed, and check it against the model (a
    built-in preset first made to fit it: :func:`adapt_preset`)."""
    sensor_config, notes = adapt_preset(config, cm)
    if _mount_of(sensor_config) != cm.mount:
        raise InputError(
            f"sensors {config.sensors!r} need mount {_mount_of(sensor_config)}; the model was loaded with "
            f"{cm.mount} (load it with load_session_model)"
        )
    if sensor_config.joints.play_m != cm.joint_play_m:
        raise InputError(
            f"sensors {config.sensors!r} need joint play {sensor_config.joints.play_m} m; the model was "
            f"loaded with {cm.joint_play_m} m (load it with load_session_model)"
        )
    check_sensor_names(sensor_config, cm, sensors_source(config))
    samples = config.duration_s * config.rate_hz
    if samples > MAX_SAMPLES:
        raise InputError(
            f"duration {config.duration_s:g} s at {config.rate_hz:g} Hz gives {samples:.3g} samples; at most "
            f"{MAX_SAMPLES:.0e} (a session of days: is the duration in seconds?)"
        )
    n_samples = math.floor(samples + 1e-9)
    if n_samples < 2:
        raise InputError(f"duration {config.duration_s} s at {config.rate_hz} Hz gives fewer than 2 samples")
    playback = None
    source = config.recorded()
    if source is not None:
        _check_playback_sensors(config, sensor_config)
        playback = plan_playback(
            source.recorded,
            config.rate_hz,
            config.duration_s,
            config.motion_cutoff_hz,
            config.motion_position_cutoff_hz,
        )
        n_samples = playback.time_s.size
        k, dt = 1, 1.0 / config.rate_hz
    else:
        k, dt = steps_per_sample(float(cm.model.opt.timestep), config.rate_hz)
    latency = sensor_config.tracker.latency_s
    if latency >= (n_samples - 1) / config.rate_hz:
        raise InputError(
            f"{sensors_source(config)}, key tracker.latency_s: a latency of {latency:g} s is not shorter "
            f"than the session ({config.duration_s:g} s): no sample would be valid"
        )
    seeds = np.random.SeedSequence(config.seed).spawn(5)
    motion_rng = np.random.default_rng(seeds[0])
    if playback is None:
        program = _program(config, cm, motion_rng)
    else:
        name = f"{source.recorded.format}:{Path(config.motion).name}"
        program = Program(name=name, phases=(), root="still", neutral={})
    root_phases = np.random.default_rng(seeds[1]).uniform(0, 2 * np.pi, 12)
    streams = {
        name: np.random.default_rng(s) for name, s in zip(("skin", "tracker", "imu"), seeds[2:], strict=True)
    }
    return SessionPlan(program, root_phases, k, dt, n_samples, sensor_config, streams, playback, notes)
