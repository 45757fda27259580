"""Motion programs: what the body is asked to do during a capture session.

A program is a set of phases; in each phase some joints follow sums of sines (per degree of
freedom: amplitude, frequency, phase, offset), faded in and out over a raised-cosine ramp so
that nothing jerks, plus a root motion style. It becomes actuator set-points (the rotation-vector
components of ball joints, the angles of hinges) and a mocap pose for the root at every physics
step; the physics decides what actually happens.

Built-in programs (seeded: the phases of the sines come from the ``numpy.random.Generator``):

- ``exercise``: each joint in turn through its range in all its degrees of freedom at once, as
  O'Brien et al.'s subjects moved, while the root is carried (the linkage twisted through space
  by hand) or sways (a standing person).
- ``walk``: O'Brien's "chicken walk": every joint at once while the root walks an ellipse through
  the capture volume (1.6 m x 1.0 m, 0.5 m/s: a magnetic tracker's working volume).
- ``gait``: a person walking at 1 m/s on a 1.2 m circle (humanoid models only): the joint angles
  of normal gait as the first two harmonics of the stride (hip flexion -0.15..0.45 rad, knee
  0.05..1.05 rad with its loading bump, ankle +-0.2 rad, arms swinging +-0.25 rad against the
  legs, trunk counter-rotating) and the pelvis's step-synchronous bob (+-2 cm at twice the stride
  rate), sway, rotation and obliquity. Unlike ``walk`` it moves as a person does: limb and head
  accelerations are those of human gait (see :func:`gait_program`).
- ``single-axis``: each joint in turn about one axis only (the degenerate case of section 3.2).
- ``static``: the neutral pose, root still.

User programs are TOML files (``--motion FILE.toml``)::

    name = "arm waves"
    root = "sway"                 # still | sway | carry | walk | gait
    [[phase]]
    start_s = 0.0
    end_s = 10.0
    [phase.joints.shoulder_l]     # an MJCF joint name of the model
    amplitude_rad = [0.8, 0.5, 0.3]   # one value per degree of freedom: 3 for a ball joint, 1 for a hinge
    frequency_hz = [0.5, 0.7, 0.9]
    phase_rad = [0.0, 0.0, 0.0]       # optional, default 0
    offset_rad = [0.0, 0.0, 0.0]      # optional, default 0
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calibration.rotations import matrix_to_quat, quat_to_matrix, rotvec_to_matrix
from simbench.errors import InputError, load_toml
from simbench.sim.instrument import tracking_response
from simbench.sim.models import CaptureModel

BUILTIN_PROGRAMS = ("exercise", "walk", "gait", "single-axis", "static")
ROOT_STYLES = ("still", "sway", "carry", "walk", "gait")

# Anatomical motion of the built-in humanoid, per ball joint: amplitude about the joint's
# (x forward, y left, z up) axes and a neutral offset, rad. Sources: typical active ranges of
# motion (shoulder flexion ~160 deg, elbow flexion ~145 deg, hip flexion ~120 deg, knee
# flexion ~135 deg, neck rotation ~80 deg), kept inside the joints' cones.
HUMANOID_MOTION: dict[str, tuple[tuple[float, float, float], tuple[float, float, float], int]] = {
    # joint: (amplitude xyz, offset xyz, primary axis for single-axis motion)
    "lumbar": ((0.30, 0.45, 0.35), (0.0, 0.1, 0.0), 1),
    "thoracic": ((0.25, 0.35, 0.40), (0.0, 0.0, 0.0), 1),
    "neck": ((0.45, 0.60, 0.80), (0.0, 0.0, 0.0), 1),
    "shoulder_l": ((0.90, 1.20, 0.60), (-0.5, 0.0, 0.0), 1),
    "shoulder_r": ((0.90, 1.20, 0.60), (0.5, 0.0, 0.0), 1),
    "elbow_l": ((0.10, 0.95, 0.60), (0.0, -1.1, 0.0), 1),
    "elbow_r": ((0.10, 0.95, 0.60), (0.0, -1.1, 0.0), 1),
    "wrist_l": ((0.40, 0.70, 0.35), (0.0, 0.0, 0.0), 1),
    "wrist_r": ((0.40, 0.70, 0.35), (0.0, 0.0, 0.0), 1),
    "hip_l": ((0.45, 0.90, 0.45), (0.0, -0.5, 0.0), 1),
    "hip_r": ((0.45, 0.90, 0.45), (0.0, -0.5, 0.0), 1),
    "knee_l": ((0.08, 0.80, 0.30), (0.0, 0.9, 0.0), 1),
    "knee_r": ((0.08, 0.80, 0.30), (0.0, 0.9, 0.0), 1),
    "ankle_l": ((0.25, 0.40, 0.20), (0.0, 0.0, 0.0), 1),
    "ankle_r": ((0.25, 0.40, 0.20), (0.0, 0.0, 0.0), 1),
}


#: Normal gait of the humanoid (x forward, y left, z up), per ball joint and degree of freedom:
#: ``(mean, (amplitude, phase) of the stride's 1st harmonic, (amplitude, phase) of its 2nd)``,
#: rad, as ``mean + a1 cos(s - p1) + a2 cos(2 s - p2)`` with ``s`` the left leg's stride phase
#: (0 at its heel strike). Sagittal angles: two-harmonic fits (within 0.06 rad) to Winter's
#: normative gait data (The Biomechanics and Motor Control of Human Gait, 1991): hip flexion
#: 0.5 rad before heel strike to 0.16 rad of extension near toe-off, knee 0.1 rad at heel strike,
#: a 0.35 rad loading bump, 1.08 rad in swing; ankle 0.17 rad of dorsiflexion to 0.3 rad of
#: plantar flexion; arms swinging +-0.25 rad against the legs, elbows at 0.35 +- 0.15 rad;
#: the thorax counter-rotating against the pelvis, the head held steady. Hip and arm flexion are
#: rotations about -y, knee flexion about +y, elbow flexion about -y (the model's joint frames).
_LEFT_GAIT: dict[str, tuple[tuple[float, tuple[float, float], tuple[float, float]], ...]] = {
    "hip": (
        (0.0, (0.05, 1.6), (0.0, 0.0)),
        (-0.17, (-0.33, 5.78), (0.0, 0.0)),
        (0.0, (0.06, 0.0), (0.0, 0.0)),
    ),
    "knee": (
        (0.0, (0.0, 0.0), (0.0, 0.0)),
        (0.42, (0.355, -1.72), (0.285, 2.53)),
        (0.0, (0.04, 0.0), (0.0, 0.0)),
    ),
    "ankle": (
        (0.0, (0.04, 0.0), (0.0, 0.0)),
        (0.0, (-0.135, 1.65), (-0.129, -1.43)),
        (0.0, (0.03, 0.0), (0.0, 0.0)),
    ),
    "shoulder": (
        (0.12, (0.03, 0.0), (0.0, 0.0)),
        (0.0, (0.25, 5.78), (0.0, 0.0)),
        (0.0, (0.05, np.pi), (0.0, 0.0)),
    ),
    "elbow": (
        (0.0, (0.0, 0.0), (0.0, 0.0)),
        (-0.35, (0.15, 5.78), (0.0, 0.0)),
        (0.0, (0.03, 0.0), (0.0, 0.0)),
    ),
    "wrist": ((0.0, (0.03, 0.0), (0.0, 0.0)), (0.0, (0.06, 0.5), (0.0, 0.0)), (0.0, (0.02, 0.0), (0.0, 0.0))),
}
#: Trunk and head, (mean, 1st, 2nd) per degree of freedom as above: the lumbar and thoracic
#: joints turn the thorax against the pelvis's rotation; the neck keeps the head steady.
_TRUNK_GAIT: dict[str, tuple[tuple[float, tuple[float, float], tuple[float, float]], ...]] = {
    "lumbar": (
        (0.0, (0.03, -1.57), (0.0, 0.0)),
        (0.0, (0.0, 0.0), (0.02, np.pi)),
        (0.0, (0.06, 0.0), (0.0, 0.0)),
    ),
    "thoracic": (
        (0.0, (0.02, -1.57), (0.0, 0.0)),
        (0.0, (0.0, 0.0), (0.01, np.pi)),
        (0.0, (0.05, 0.0), (0.0, 0.0)),
    ),
    "neck": (
        (0.0, (0.01, 0.0), (0.0, 0.0)),
        (0.0, (0.0, 0.0), (0.005, 0.0)),
        (0.0, (0.04, np.pi), (0.0, 0.0)),
    ),
}
#: The gait's stride rate (Hz, a stride is two steps) and stride length (m): 1.15 m strides at 0.87
#: strides/s (1.0 m/s, about 104 steps a minute), a normal walking pace; sessions draw the rate
#: from 0.82-0.92 Hz.
GAIT_STRIDE_HZ = 0.87
GAIT_STRIDE_M = 1.15
#: Radius of the circle walked, m: around a 5 m room, turning at 0.4 rad/s (the stance foot hardly
#: skates: the pelvis is carried, not pushed off the ground).
GAIT_RADIUS_M = 2.5


@dataclass(frozen=True)
class JointMotion:
    """Sines of one MJCF joint: each ``(dof,)``; angles in rad, frequency in Hz."""

    amplitude: np.ndarray
    frequency: np.ndarray
    phase: np.ndarray
    offset: np.ndarray


@dataclass(frozen=True)
class Phase:
    """Joint motions active from ``start_s`` to ``end_s`` (faded in and out)."""

    start_s: float
    end_s: float
    joints: dict[str, JointMotion]


@dataclass(frozen=True)
class Program:
    """A motion program.

    Attributes:
        name: its name.
        phases: the phases.
        root: root motion style (``still``, ``sway``, ``carry``, ``walk``, ``gait``).
        neutral: ``{joint: (dof,) offset}`` held throughout (the resting pose), rad.
        stride_hz: the stride rate of the ``gait`` root style, Hz (a stride is two steps).
        stride_phase: the stride's phase at ``t = 0``, rad (0: left heel strike).
    """

    name: str
    phases: tuple[Phase, ...]
    root: str
    neutral: dict[str, np.ndarray]
    stride_hz: float = GAIT_STRIDE_HZ
    stride_phase: float = 0.0


def _dof_count(cm: CaptureModel) -> dict[str, int]:
    out = {}
    for art in cm.articulations:
        for joint, kind in zip(art.joints, art.kinds, strict=True):
            out[joint] = 3 if kind == "ball" else 1
    return out


def _default_motion(cm: CaptureModel, art_index: int, joint: str) -> tuple[np.ndarray, np.ndarray, int]:
    """Amplitude, neutral offset and primary axis of one joint for the built-in programs."""
    art = cm.articulations[art_index]
    if joint in HUMANOID_MOTION and cm.source == "humanoid":
        amp, off, primary = HUMANOID_MOTION[joint]
        return np.array(amp), np.array(off), primary
    k = art.joints.index(joint)
    if art.kinds[k] == "ball":
        # three sines of amplitude a reach sqrt(3) a together: keep that inside 70 % of the cone
        a = min(0.8, 0.4 * art.cone) if art.cone > 0 else 0.8
        return np.full(3, a), np.zeros(3), 0
    h = sum(1 for kind in art.kinds[:k] if kind == "hinge")
    lo, hi = art.hinge_range[h]
    if np.isfinite(lo) and np.isfinite(hi):
        return np.array([min(1.2, 0.45 * (hi - lo))]), np.array([0.5 * (lo + hi)]), 0
    return np.array([0.8]), np.zeros(1), 0


def builtin_program(name: str, cm: CaptureModel, duration_s: float, rng: np.random.Generator) -> Program:
    """One of :data:`BUILTIN_PROGRAMS` for a model and a duration."""
    if name not in BUILTIN_PROGRAMS:
        raise InputError(
            f"unknown motion {name!r}: expected one of {', '.join(BUILTIN_PROGRAMS)} or a .toml file"
        )
    neutral: dict[str, np.ndarray] = {}
    motions: list[tuple[int, str, np.ndarray, int]] = []
    for i, art in enumerate(cm.articulations):
        for joint in art.joints:
            amp, off, primary = _default_motion(cm, i, joint)
            neutral[joint] = off
            motions.append((i, joint, amp, primary))
    phases: list[Phase] = []
    carry = "carry" if cm.source == "linkage" else "sway"
    if name == "static":
        return Program(name, (), "still", neutral)
    if name == "gait":
        return gait_program(cm, duration_s, rng)
    if name == "walk":
        joints = {}
        for _, joint, amp, _ in motions:
            n = amp.size
            joints[joint] = JointMotion(
                amplitude=0.7 * amp,
                frequency=rng.uniform(0.45, 1.1, n),
                phase=rng.uniform(0, 2 * np.pi, n),
                offset=np.zeros(n),
            )
        return Program(name, (Phase(0.0, duration_s, joints),), "walk", neutral)
    # exercise and single-axis: one slot per articulation, in sensor order
    n_slots = len(cm.articulations)
    slot = duration_s / max(n_slots, 1)
    base_f = float(np.clip(2.5 / slot, 0.3, 0.6))  # about 2.5 cycles a slot, at human speeds
    for i in range(n_slots):
        joints = {}
        hinge_seen = 0
        for _, joint, amp, primary in (m for m in motions if m[0] == i):
            n = amp.size
            amplitude = amp.copy()
            if name == "single-axis":
                if n == 3:
                    amplitude = np.where(np.arange(3) == primary, amp, 0.0)
                else:
                    amplitude = amp if hinge_seen == 0 else np.zeros(1)
                    hinge_seen += 1
            joints[joint] = JointMotion(
                amplitude=amplitude,
                frequency=base_f * np.array([1.0, 1.37, 1.73])[:n] * rng.uniform(0.9, 1.1, n),
                phase=rng.uniform(0, 2 * np.pi, n),
                offset=np.zeros(n),
            )
        phases.append(Phase(i * slot, (i + 1) * slot, joints))
    return Program(name, tuple(phases), carry, neutral)


def gait_program(cm: CaptureModel, duration_s: float, rng: np.random.Generator) -> Program:
    """Normal gait (module docstring) for a model with the humanoid's joints.

    The stride rate is drawn from 0.82-0.92 Hz and the stride's phase at ``t = 0`` uniformly;
    the joint angles are :data:`_LEFT_GAIT` (the right side half a stride later, its abduction
    and rotation mirrored) and :data:`_TRUNK_GAIT`, the pelvis follows the ``gait`` root style.

    Raises:
        InputError: when the model lacks a joint the gait moves (the linkage, a non-human MJCF).
    """
    dofs = _dof_count(cm)
    needed = [*_TRUNK_GAIT, *(f"{j}_{side}" for j in _LEFT_GAIT for side in "lr")]
    missing = [j for j in needed if dofs.get(j) != 3]
    if missing:
        raise InputError(
            f"motion 'gait' needs the humanoid's ball joints; the model {cm.source} lacks "
            f"{', '.join(missing)}: use exercise, walk, single-axis or a program .toml"
        )
    f = float(rng.uniform(0.82, 0.92))
    s0 = float(rng.uniform(0, 2 * np.pi))
    harmonics: list[dict[str, JointMotion]] = [{}, {}]
    # the set-points that the actuators' lag turns into the gait's angles
    response = [tracking_response(cm.model, k * f) for k in (1, 2)]
    actuators = {
        joint: list(art.actuators[3 * i : 3 * i + 3])
        for art in cm.articulations
        for i, joint in enumerate(art.joints)
        if art.kinds == ("ball",) * len(art.joints)
    }
    table = {**_TRUNK_GAIT, **{f"{j}_l": v for j, v in _LEFT_GAIT.items()}}
    table |= {f"{j}_r": v for j, v in _LEFT_GAIT.items()}
    for joint, spec in table.items():
        right = joint.endswith("_r")
        shift = np.pi if right else 0.0  # the right leg half a stride later
        mirror = np.array([-1.0, 1.0, -1.0]) if right else np.ones(3)  # abduction and rotation
        mean = np.array([d[0] for d in spec]) * mirror
        for k in (1, 2):
            gain = response[k - 1][actuators[joint]]
            amp = np.array([d[k][0] for d in spec]) * mirror / abs(gain)
            lag = np.array([d[k][1] for d in spec]) + np.angle(gain)
            # a cos(k s - p) with s = 2 pi f t + s0 (+ pi on the right) is a sine of phase
            # k (s0 + shift) - p + pi / 2
            harmonics[k - 1][joint] = JointMotion(
                amplitude=amp,
                frequency=np.full(3, k * f),
                phase=k * (s0 + shift) - lag + np.pi / 2,
                offset=mean if k == 1 else np.zeros(3),
            )
    phases = tuple(Phase(0.0, duration_s, h) for h in harmonics)
    neutral = {j: np.zeros(n) for j, n in dofs.items()}
    return Program("gait", phases, "gait", neutral, stride_hz=f, stride_phase=s0)


def _floats(doc: dict, key: str, where: str, n: int, default: float | None = None) -> np.ndarray:
    if key not in doc:
        if default is None:
            raise InputError(f"{where}: missing {key!r}")
        return np.full(n, default)
    value = doc[key]
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value]
    if not isinstance(value, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    ):
        raise InputError(f"{where}.{key}: expected a list of numbers, got {value!r}")
    if len(value) != n:
        raise InputError(
            f"{where}.{key}: expected {n} value(s) (one per degree of freedom), got {len(value)}"
        )
    out = np.array(value, dtype=float)
    if not np.all(np.isfinite(out)):
        raise InputError(f"{where}.{key}: values must be finite")
    return out


def load_program(path: str | Path, cm: CaptureModel) -> Program:
    """Read a user program from TOML (format in the module docstring), checked against the model.

    Raises:
        InputError: naming the file and key: unknown keys, joints the model lacks, wrong counts,
            empty or reversed phases, negative frequencies.
    """
    path = Path(path)
    doc = load_toml(path)
    unknown = sorted(set(doc) - {"name", "root", "phase"})
    if unknown:
        raise InputError(f"{path}: unknown keys {unknown}; expected name, root, phase")
    root = doc.get("root", "still")
    if not isinstance(doc.get("name", ""), str):
        raise InputError(f"{path}: name must be a string, got {doc['name']!r}")
    if root not in ROOT_STYLES:
        raise InputError(f"{path}: root must be one of {', '.join(ROOT_STYLES)}, got {root!r}")
    dofs = _dof_count(cm)
    phases = []
    raw_phases = doc.get("phase", [])
    if not isinstance(raw_phases, list) or not raw_phases:
        raise InputError(f"{path}: expected at least one [[phase]]")
    for k, ph in enumerate(raw_phases):
        where = f"{path}: phase[{k}]"
        if not isinstance(ph, dict):
            raise InputError(f"{where}: expected a table ([[phase]]), got {ph!r}")
        extra = sorted(set(ph) - {"start_s", "end_s", "joints"})
        if extra:
            raise InputError(f"{where}: unknown keys {extra}; expected start_s, end_s, joints")
        start, end = _floats(ph, "start_s", where, 1)[0], _floats(ph, "end_s", where, 1)[0]
        if not 0 <= start < end:
            raise InputError(f"{where}: need 0 <= start_s < end_s, got {start} and {end}")
        joints = {}
        table = ph.get("joints", {})
        if not isinstance(table, dict):
            raise InputError(
                f"{where}.joints: expected a table of joints ([phase.joints.<name>]), got {table!r}"
            )
        for joint, spec in table.items():
            if joint not in dofs:
                raise InputError(
                    f"{where}: the model {cm.source} has no joint {joint!r}; joints: {', '.join(dofs)}"
                )
            jw = f"{where}.joints.{joint}"
            if not isinstance(spec, dict):
                raise InputError(f"{jw}: expected a table (amplitude_rad, frequency_hz, ...), got {spec!r}")
            extra = sorted(set(spec) - {"amplitude_rad", "frequency_hz", "phase_rad", "offset_rad"})
            if extra:
                raise InputError(f"{jw}: unknown keys {extra}")
            n = dofs[joint]
            freq = _floats(spec, "frequency_hz", jw, n)
            if np.any(freq < 0):
                raise InputError(f"{jw}.frequency_hz: frequencies must be >= 0")
            joints[joint] = JointMotion(
                amplitude=_floats(spec, "amplitude_rad", jw, n),
                frequency=freq,
                phase=_floats(spec, "phase_rad", jw, n, 0.0),
                offset=_floats(spec, "offset_rad", jw, n, 0.0),
            )
        phases.append(Phase(float(start), float(end), joints))
    neutral = {j: np.zeros(n) for j, n in dofs.items()}
    return Program(str(doc.get("name", path.stem)), tuple(phases), root, neutral)


def _window(t: np.ndarray, start: float, end: float) -> np.ndarray:
    """Raised-cosine fade in and out over ``min(0.5 s, 20 %)`` of the phase; 0 outside."""
    ramp = min(0.5, 0.2 * (end - start))
    up = np.clip((t - start) / ramp, 0.0, 1.0)
    down = np.clip((end - t) / ramp, 0.0, 1.0)
    w = 0.5 * (1 - np.cos(np.pi * up)) * 0.5 * (1 - np.cos(np.pi * down))
    return np.where((t >= start) & (t < end), w, 0.0)


def joint_targets(program: Program, cm: CaptureModel, t: np.ndarray) -> np.ndarray:
    """Actuator set-points at times ``t``: ``(len(t), nu)``, rad.

    Ball joints' three set-points are the rotation-vector components of the target rotation;
    the total angle is kept inside 85 % of the joint's cone (tracking overshoot stays off the
    limit, whose impacts would shake the sensors).
    """
    nu = cm.model.nu
    out = np.zeros((t.size, nu))
    # each phase's samples and window once (not once per joint); a joint's motion is added only
    # there: the window is 0 elsewhere
    active = []
    for ph in program.phases:
        at = np.flatnonzero((t >= ph.start_s) & (t < ph.end_s))
        if at.size and at[-1] - at[0] + 1 == at.size:  # a run of samples (sorted times): a view
            at = slice(int(at[0]), int(at[-1]) + 1)
        active.append((at, _window(t[at], ph.start_s, ph.end_s)[:, None], t[at, None] - ph.start_s))
    for art in cm.articulations:
        col = 0
        for joint, kind in zip(art.joints, art.kinds, strict=True):
            n = 3 if kind == "ball" else 1
            acts = list(art.actuators[col : col + n])
            col += n
            value = np.tile(program.neutral.get(joint, np.zeros(n)), (t.size, 1))
            for ph, (at, w, since) in zip(program.phases, active, strict=True):
                motion = ph.joints.get(joint)
                if motion is None or not w.size:
                    continue
                arg = 2 * np.pi * motion.frequency[None, :] * since + motion.phase[None, :]
                value[at] += w * (motion.offset[None, :] + motion.amplitude[None, :] * np.sin(arg))
            if kind == "ball" and art.cone > 0:
                angle = np.linalg.norm(value, axis=1, keepdims=True)
                limit = 0.85 * art.cone
                value = np.where(angle > limit, value * limit / np.maximum(angle, 1e-12), value)
            elif kind == "hinge":
                h = sum(1 for k in art.kinds[: art.joints.index(joint)] if k == "hinge")
                lo, hi = art.hinge_range[h]
                value = np.clip(value, lo, hi)
            out[:, acts] = value
    return out


def root_pose(
    program: Program, p0: np.ndarray, q0: np.ndarray, t: np.ndarray, rng_phases: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Root driver pose at times ``t``: positions ``(len(t), 3)`` m, quaternions ``(len(t), 4)``.

    Args:
        program: gives the style.
        p0: ``(3,)`` initial root position, m. q0: ``(4,)`` initial root orientation (wxyz).
        t: times, s.
        rng_phases: ``(12,)`` phases (rad) drawn once per session.
    """
    n = t.size
    R0 = quat_to_matrix(q0)
    fade = np.clip(t / 1.0, 0.0, 1.0)
    fade = 0.5 * (1 - np.cos(np.pi * fade))[:, None]
    ph = rng_phases
    if program.root == "still":
        return np.tile(p0, (n, 1)), np.tile(q0, (n, 1))
    if program.root in ("sway", "carry"):
        trans, rot = (0.05, 0.12) if program.root == "sway" else (0.25, 0.7)
        f = np.array([0.11, 0.17, 0.13])
        shift = trans * np.sin(2 * np.pi * f * t[:, None] + ph[:3]) * fade
        rotvec = rot * np.sin(2 * np.pi * (f * 1.3) * t[:, None] + ph[3:6]) * fade
        R = rotvec_to_matrix(rotvec) @ R0
        return p0 + shift, matrix_to_quat(R)
    if program.root == "gait":
        return _gait_root(program, p0, R0, t, fade[:, 0])
    # walk: an ellipse through the volume at 0.5 m/s, heading along the path, a little bob
    a, b, speed = 0.8, 0.5, 0.5
    s = speed * t * fade[:, 0]
    theta = s / (0.5 * (a + b))
    pos = p0 + np.stack([a * np.sin(theta), b * (1 - np.cos(theta)), 0.02 * np.sin(4 * theta)], axis=1)
    heading = np.arctan2(b * np.sin(theta), a * np.cos(theta))
    yaw = np.zeros((n, 3))
    yaw[:, 2] = heading
    sway = 0.08 * np.sin(2 * np.pi * np.array([0.9, 0.45, 0.3]) * t[:, None] + ph[7:10]) * fade
    R = rotvec_to_matrix(yaw) @ rotvec_to_matrix(sway) @ R0
    return pos, matrix_to_quat(R)


def _gait_root(
    program: Program, p0: np.ndarray, R0: np.ndarray, t: np.ndarray, fade: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The pelvis in gait: a circle of :data:`GAIT_RADIUS_M` walked at the stride's speed, heading
    along it, with the step-synchronous bob (lowest in double support, +-2 cm), sway towards the
    stance leg (+-2 cm), rotation with the swinging leg (+-0.07 rad), obliquity (+-0.05 rad, the
    swing side dropping) and tilt (+-0.03 rad); all faded in over the first second."""
    f = program.stride_hz
    s = 2 * np.pi * f * t + program.stride_phase  # the left leg's stride phase
    dist = GAIT_STRIDE_M * f * _faded_time(t)
    theta = dist / GAIT_RADIUS_M
    left = np.stack([-np.sin(theta), np.cos(theta), np.zeros_like(theta)], axis=1)
    circle = np.stack([np.sin(theta), 1 - np.cos(theta), np.zeros_like(t)], axis=1) * GAIT_RADIUS_M
    bob = np.zeros((t.size, 3))
    bob[:, 2] = -0.02 * np.cos(2 * s)
    pos = p0 + circle + fade[:, None] * (0.02 * np.sin(s)[:, None] * left + bob)
    yaw = np.zeros((t.size, 3))
    yaw[:, 2] = theta
    pelvis = fade[:, None] * np.stack([0.05 * np.sin(s), 0.03 * np.cos(2 * s), -0.07 * np.cos(s)], axis=1)
    R = rotvec_to_matrix(yaw) @ rotvec_to_matrix(pelvis) @ R0
    return pos, matrix_to_quat(R)


def _faded_time(t: np.ndarray) -> np.ndarray:
    """The integral of the first second's raised-cosine fade: the distance a path walked at unit
    speed has covered at ``t`` when the speed fades in from rest (no jump in velocity)."""
    ramp = np.clip(t, 0.0, 1.0)
    return np.where(t < 1.0, 0.5 * (ramp - np.sin(np.pi * ramp) / np.pi), t - 0.5)
