"""Walk trials for the hierarchy: O'Brien et al.'s walk failure, its suspected cause, two trees.

In three of the paper's five walk trials the minimum spanning tree made one thigh the child of
the other; the paper suspects its pelvis sensor, which sat on the battery pack worn on the hip and
moved when the thigh rotated upwards. :func:`walk_trial` runs one seeded humanoid walk with the
paper-like preset (``skin-paper-human``, whose ``[skin.pack]`` models that mount), with the pack
or without it (switched off, everything else the same, same seed), calibrates it with both
hierarchy methods of :mod:`calibration.hierarchy` (``"mst"``, the paper's, and ``"misfit"``) and
returns JSON-ready figures: the wrong and missed edges of each tree, whether one thigh became the
other's child, and the three pairs between pelvis and thighs (rms residual, its noise part, the
misfit left, and how close the pair's relative rotation is to one axis).

Two hip motions (``hips``):

- ``"walk"``: the built-in walk program (:mod:`simbench.sim.programs`, the validation's walk):
  every joint at once, the hips through flexion, abduction and rotation alike;
- ``"sagittal"``: the same program with the hips' abduction and rotation at a quarter of their
  amplitude, so that both hips turn nearly about one common lateral axis, as a human walk does
  (and the thigh-thigh pair then nearly fits a hinge on that axis).

Three trackers (``tracker``, :data:`TRACKERS`): the preset's (its transmitter at the centre of
the walk), the same with the transmitter on ``ascension-flock``'s stand in front of the capture
area (the walk's far end 2 m away: several centimetres of noise there, more on some sensors than
on others), and a quiet one (no noise, no resolution).

``studies/walk_hierarchy.py`` runs many seeds and summarises.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from calibration import calibrate, pair_noise_variance, pair_statistics, solve_pairs
from simbench.errors import InputError
from simbench.io.poses import PoseRecording
from simbench.score import compare_trees
from simbench.sim.models import CaptureModel
from simbench.sim.programs import builtin_program
from simbench.sim.sensor_config import SensorConfig, load_sensor_config
from simbench.sim.session import SessionConfig, load_session_model, run_session

#: The paper-like human preset, with the pack.
PRESET = "skin-paper-human"

#: The validation's walk seeds start here (``simbench.experiments.validate``: seed 100 + trial).
FIRST_SEED = 101

#: Hip motions of :func:`walk_trial` (module docstring).
HIP_STYLES = ("walk", "sagittal")

#: In the ``"sagittal"`` walk, the hips' abduction and rotation amplitudes relative to the walk's.
SAGITTAL_OFF_AXIS = 0.25

#: The pairs between pelvis and thighs whose fits :func:`walk_trial` reports.
HIP_PAIRS = (("pelvis", "thigh_l"), ("pelvis", "thigh_r"), ("thigh_l", "thigh_r"))

METHODS = ("mst", "misfit")

#: The trackers of :func:`walk_trial`: the preset's; the same with its transmitter on the stand
#: where ``ascension-flock`` puts it (:data:`STAND_TRANSMITTER_POS`), 1.3 m from the walk's centre,
#: so that the far end of the walk is about 2 m away and the r^4 noise law gives several
#: centimetres there; the preset's without noise and resolution (``quiet``).
TRACKERS = ("preset", "stand", "quiet")

#: ``ascension-flock``'s transmitter: on a stand 0.8 m in front of the capture area, waist high, m.
STAND_TRANSMITTER_POS = (0.0, -0.8, 1.0)


def walk_sensors(pack: bool = True, tracker: str = "preset") -> SensorConfig:
    """The paper-like preset, with its pack or without it, and one of :data:`TRACKERS`; all
    else the same.

    Raises:
        InputError: an unknown ``tracker``.
    """
    if tracker not in TRACKERS:
        raise InputError(f"tracker must be one of {list(TRACKERS)}, got {tracker!r}")
    config = load_sensor_config(PRESET)
    if not pack:
        config = dataclasses.replace(
            config, name=f"{config.name} without pack", skin=dataclasses.replace(config.skin, pack=None)
        )
    if tracker == "stand":
        stand = dataclasses.replace(config.tracker, transmitter_pos=STAND_TRANSMITTER_POS)
        config = dataclasses.replace(config, name=f"{config.name}, transmitter on the stand", tracker=stand)
    elif tracker == "quiet":
        quiet = dataclasses.replace(
            config.tracker,
            position_noise_m=0.0,
            orientation_noise_rad=0.0,
            resolution_m=0.0,
            resolution_rad=0.0,
        )
        config = dataclasses.replace(config, name=f"{config.name}, quiet tracker", tracker=quiet)
    return config


def sagittal_walk_toml(cm: CaptureModel, seed: int, duration_s: float) -> str:
    """A program TOML: the built-in walk of ``cm`` (phases drawn from ``seed``) with the hips'
    abduction and rotation (their x and z rotation-vector components) scaled by
    :data:`SAGITTAL_OFF_AXIS`."""
    program = builtin_program("walk", cm, duration_s, np.random.default_rng(seed))

    def row(values: np.ndarray) -> str:
        return "[" + ", ".join(f"{float(v):.9g}" for v in np.atleast_1d(values)) + "]"

    lines = [
        f'name = "sagittal walk {seed}"',
        'root = "walk"',
        "[[phase]]",
        "start_s = 0.0",
        f"end_s = {duration_s!r}",
    ]
    for joint, motion in program.phases[0].joints.items():
        amplitude = motion.amplitude.copy()
        if joint in ("hip_l", "hip_r"):
            amplitude[[0, 2]] *= SAGITTAL_OFF_AXIS
        lines += [
            f"[phase.joints.{joint}]",
            f"amplitude_rad = {row(amplitude)}",
            f"frequency_hz = {row(motion.frequency)}",
            f"phase_rad = {row(motion.phase)}",
            f"offset_rad = {row(program.neutral[joint])}",
        ]
    return "\n".join(lines) + "\n"


def _hip_pairs(rec: PoseRecording, metres_per_unit: float) -> dict[str, dict[str, float]]:
    """rms residual, its noise part and the misfit left (cm, the misfit signed: negative where the
    noise estimate exceeds the residual) and ``s_min / s_max`` of the pairs between pelvis and
    thighs."""
    stats = pair_statistics(rec.R_w_s, rec.p_w_s, valid=rec.valid)
    index = {name: k for k, name in enumerate(rec.names)}
    par = np.array([index[a] for a, _ in HIP_PAIRS])
    chi = np.array([index[b] for _, b in HIP_PAIRS])
    sol = solve_pairs(stats, par, chi)
    nu = pair_noise_variance(
        rec.R_w_s, rec.p_w_s, par, chi, sol.joint_in_parent, sol.joint_in_child, valid=rec.valid
    )
    misfit_sq = sol.rms_residual**2 - nu
    cm = 100.0 * metres_per_unit
    return {
        f"{a}-{b}": {
            "rms_residual_cm": float(sol.rms_residual[k] * cm),
            "noise_cm": float(np.sqrt(nu[k]) * cm),
            "misfit_cm": float(np.sign(misfit_sq[k]) * np.sqrt(abs(misfit_sq[k])) * cm),
            "weak_ratio": float(sol.singular_values[k, -1] / sol.singular_values[k, 0]),
        }
        for k, (a, b) in enumerate(HIP_PAIRS)
    }


def _tree(parent_of: dict[str, str], truth: dict[str, str]) -> dict[str, Any]:
    """A tree against the truth: right or not, the wrong and missed edges, the thighs' parents."""
    score = compare_trees(parent_of, truth)
    thighs = {t: parent_of.get(t) for t in ("thigh_l", "thigh_r")}
    return {
        "correct": bool(score.correct),
        "wrong_edges": list(score.wrong_edges),
        "missed_edges": list(score.missed_edges),
        "thigh_parents": thighs,
        "thigh_child_of_thigh": thighs["thigh_l"] == "thigh_r" or thighs["thigh_r"] == "thigh_l",
    }


def walk_trial(
    seed: int, duration_s: float = 45.0, pack: bool = True, hips: str = "walk", tracker: str = "preset"
) -> dict[str, Any]:
    """One seeded humanoid walk, calibrated with both hierarchy methods (module docstring).

    Args:
        seed: the session's seed.
        duration_s: the walk's length, s.
        pack: the pelvis sensor on the pushed pack (the preset's ``[skin.pack]``), or not.
        hips: ``"walk"`` or ``"sagittal"`` (:data:`HIP_STYLES`).
        tracker: ``"preset"``, ``"stand"`` or ``"quiet"`` (:data:`TRACKERS`).

    Returns:
        JSON-ready: the settings, ``methods`` (``mst``, ``misfit``: ``correct``,
        ``wrong_edges``, ``missed_edges``, ``thigh_parents``, ``thigh_child_of_thigh``),
        ``hip_pairs`` (see :func:`_hip_pairs`, lengths in cm) and the pelvis sensor's largest
        distance from its bone placement (mount, soft-tissue artefact and pack), cm.

    Raises:
        InputError: an unknown ``hips`` or ``tracker``.
    """
    if hips not in HIP_STYLES:
        raise InputError(f"hips must be one of {list(HIP_STYLES)}, got {hips!r}")
    sensors = walk_sensors(pack, tracker)
    config = SessionConfig(model="humanoid", motion="walk", duration_s=duration_s, seed=seed, sensors=sensors)
    cm = load_session_model(config)
    with tempfile.TemporaryDirectory() as tmp:
        if hips == "sagittal":
            program = Path(tmp) / "sagittal_walk.toml"
            program.write_text(sagittal_walk_toml(cm, seed, duration_s))
            config = dataclasses.replace(config, motion=str(program))
        ds = run_session(config, cm)
    rec = ds.poses()
    truth = ds.truth.parent_of
    methods = {}
    for method in METHODS:
        cal = calibrate(
            rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid, root="pelvis", hierarchy_method=method
        )
        methods[method] = _tree(cal.parent_of, truth)
    pelvis = list(ds.sensors).index("pelvis")
    off_bone = np.linalg.norm(ds.truth.actual.p_w_s[:, pelvis] - ds.truth.rigid.p_w_s[:, pelvis], axis=1)
    return {
        "seed": seed,
        "duration_s": duration_s,
        "pack": pack,
        "hips": hips,
        "tracker": tracker,
        "preset": sensors.name,
        "methods": methods,
        "hip_pairs": _hip_pairs(rec, ds.position_unit_scale),
        "pelvis_sensor_off_bone_max_cm": float(off_bone.max() * 100.0),
    }
