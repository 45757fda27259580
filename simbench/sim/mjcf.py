"""MJCF files by model name: the built-in models, dm_control's suite, any path; reading, compiling.

The built-in models ship with the package in ``simbench/models/<name>/`` (``scene.xml`` includes
``<name>.xml`` and adds floor and light). ``dm_control:NAME`` names a model of dm_control's suite
(``dm_control`` is imported only then). Any other name must be a path to an ``.xml`` file.
Variants of the built-in models (:mod:`simbench.sim.variants`: ``humanoid-female``) are the
built-in file edited after reading.
"""

from __future__ import annotations

from pathlib import Path

import mujoco

from simbench.errors import InputError
from simbench.sim.variants import VARIANTS, set_limb_lengths

#: Where the built-in models lie: the package's ``simbench/models/``.
MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
BUILTIN = ("linkage", "humanoid", *VARIANTS)


def _dm_control_suite_path(source: str) -> Path:
    """The MJCF file of ``dm_control:NAME`` in dm_control's suite."""
    name = source.split(":", 1)[1]
    try:
        import dm_control
    except ImportError:
        raise InputError(f"{source}: dm_control is not installed (pip install dm-control)") from None
    suite = Path(dm_control.__file__).parent / "suite"
    path = suite / f"{name}.xml"
    if not path.is_file():
        names = sorted(p.stem for p in suite.glob("*.xml"))
        raise InputError(f"{source}: no such dm_control suite model; available: {', '.join(names)}")
    return path


def resolve_model_path(source: str) -> Path:
    """The MJCF file of a model name (built-in, ``dm_control:NAME``, or a path).

    Raises:
        InputError: naming what was expected.
    """
    if source in BUILTIN:
        folder = VARIANTS[source][0] if source in VARIANTS else source
        path = MODELS_DIR / folder / "scene.xml"
        if not path.is_file():
            raise InputError(f"built-in model {source!r} not found at {path} (is the package complete?)")
        return path
    if source.startswith("dm_control:"):
        return _dm_control_suite_path(source)
    path = Path(source)
    if path.suffix.lower() == ".xml":
        if path.is_dir():
            raise InputError(f"model file {path}: expected a file, got a directory")
        if not path.is_file():
            raise InputError(f"model file {path} does not exist")
        return path
    raise InputError(
        f"unknown model {source!r}: expected one of {', '.join(BUILTIN)}, dm_control:NAME, "
        "or a path to an MJCF .xml file"
    )


def read_spec(source: str) -> mujoco.MjSpec:
    """The editable :class:`mujoco.MjSpec` of a model name (see :func:`resolve_model_path`).

    Raises:
        InputError: unknown model, or a file MuJoCo cannot read.
    """
    path = resolve_model_path(source)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except Exception as exc:  # mujoco raises ValueError with the parser's message
        raise InputError(f"model {source}: MuJoCo could not read {path}: {exc}") from None
    if source in VARIANTS:
        set_limb_lengths(spec, VARIANTS[source][1])
    return spec


def compile_spec(spec: mujoco.MjSpec, source: str) -> mujoco.MjModel:
    """Compile a spec, naming the model (``source``) when MuJoCo refuses it.

    Raises:
        InputError: with the compiler's message.
    """
    try:
        return spec.compile()
    except Exception as exc:  # mujoco raises ValueError with the compiler's message
        raise InputError(f"model {source}: MuJoCo could not compile it: {exc}") from None
