"""simbench: a physics-simulation validation testbed for motion-capture skeleton calibration."""

import os

__version__ = "0.1.0"

# MuJoCo picks its OpenGL backend when it is first imported: without a display, offscreen EGL
# (Mesa) renders the report's pictures; a caller's own MUJOCO_GL choice (e.g. osmesa) wins.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"
