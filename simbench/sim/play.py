"""Free play in a model's joints: a ball that can shift in its socket, modelled in MuJoCo.

A wooden ball-and-socket (O'Brien et al.'s linkage) or a worn hinge is not a perfect point: the
ball has clearance in its socket and moves across it whenever the load on the joint changes
direction (gravity as the piece turns, the pull of the motion when it swings). :func:`add_play`
gives each joint body three more degrees of freedom: slide joints along the body frame's axes,
free (no spring) within ``+-play_m`` and stopped at the ends by MuJoCo's joint limits, stiffened
(:data:`LIMIT_TIMECONST_S`) so that the stop holds the ball to a small fraction of the play under
the linkage's loads. The slides come after the joint's rotation, so the clearance is a box of
half-width ``play_m`` in the child's frame: the joint centre seen from the child moves by up to
``sqrt(3) play_m`` against the one seen from the parent. The slides are not driven (no
actuators): where the ball sits is up to the physics.
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np

#: Time constant of the slides' limit constraint, s: MuJoCo needs at least two physics steps
#: (1/600 s for the linkage at 1200 Hz); 2.5 ms keeps a 1 N load within about 0.1 mm of the stop.
LIMIT_TIMECONST_S = 0.0025

#: Viscous damping of the slides, N s/m: a ball in a wooden socket rubs; enough to stop it
#: rattling at the stops, small against the loads that move it.
PLAY_DAMPING_N_S_PER_M = 2.0


def add_play(spec: mujoco.MjSpec, bodies: Iterable[str], play_m: float) -> list[str]:
    """Add free play to the joints of ``bodies`` (edits ``spec`` in place).

    Args:
        spec: the model being edited.
        bodies: names of the bodies whose joint (ball or hinges) gets play.
        play_m: half the clearance along each axis of the body frame, m (> 0).

    Returns:
        the names of the slide joints added, ``<body>:play_x``, ``:play_y``, ``:play_z`` per body.
    """
    if not (np.isfinite(play_m) and play_m > 0):
        raise ValueError(f"play_m must be a finite number > 0, got {play_m!r}")
    added = []
    for body in bodies:
        for axis, label in zip(np.eye(3), "xyz", strict=True):
            name = f"{body}:play_{label}"
            joint = spec.body(body).add_joint(
                name=name,
                type=mujoco.mjtJoint.mjJNT_SLIDE,
                axis=axis,
                range=np.array([-play_m, play_m]),
                damping=np.array([PLAY_DAMPING_N_S_PER_M, 0.0, 0.0]),
            )
            joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            joint.solref_limit = np.array([LIMIT_TIMECONST_S, 1.0])
            added.append(name)
    return added
