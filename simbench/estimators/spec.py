"""Estimators named by a *spec*: the one string the command line, study files, baseline files and
``simbench bench`` take.

- a built-in's name (``obrien``, ``skeleton``, ...: :func:`names`);
- an installed plugin's name: an entry point of the group ``simbench.estimators``;
- a Python callable: ``package.module:function`` (importable) or ``path/to/file.py:function``
  (a file, relative to the working directory);
- an external command: ``cmd:COMMAND ARGS...`` with placeholders (:mod:`simbench.estimators.command`).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path
from typing import Any

from simbench.errors import InputError
from simbench.estimators import catalog
from simbench.estimators.builtin import DEFAULT_JOINTS, DEFAULT_ORIENTATION  # fills REGISTRY
from simbench.estimators.catalog import names as names  # the built-ins' and the plugins' names
from simbench.estimators.command import PREFIX, command_estimator
from simbench.estimators.registry import REGISTRY, Estimator, from_callable


def default(kind: str) -> str:
    """The default estimator of a kind."""
    return {"joints": DEFAULT_JOINTS, "orientation": DEFAULT_ORIENTATION}[kind]


def resolve(spec: str, kind: str | None = None) -> Estimator:
    """The estimator a spec names (module docstring).

    Args:
        spec: the spec.
        kind: the kind the caller needs (:data:`simbench.estimators.registry.KINDS`); ``None``
            accepts any.

    Raises:
        InputError: naming the spec: not found (the built-ins of the kind listed), a module or
            file that cannot be loaded (with the reason), no such attribute, or another kind.
    """
    if isinstance(spec, Estimator):
        return from_callable(spec, spec.name, spec.origin, kind)
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"Expected an estimator spec (a name, module:function or cmd:...), got {spec!r}")
    spec = spec.strip()
    if spec in REGISTRY:
        est = REGISTRY[spec]
        if kind is not None and est.kind != kind:
            raise InputError(
                f"{spec!r} estimates {est.kind}, not {kind}; estimators of {kind}: {', '.join(names(kind))}"
            )
        return est
    if spec.startswith(PREFIX):
        return command_estimator(spec, kind)
    plugin = catalog.plugin_entry_points().get(spec)
    if plugin is not None:
        try:
            obj = plugin.load()
        except Exception as exc:  # a broken plugin is named, whatever it raised
            raise InputError(
                f"plugin {spec!r} ({plugin.value}) cannot be loaded: {type(exc).__name__}: {exc}"
            ) from None
        return from_callable(obj, spec, "plugin", kind)
    if ":" not in spec:
        known = ", ".join(names(kind))
        raise InputError(
            f"unknown estimator {spec!r}: expected one of {known}, package.module:function, "
            "path/to/file.py:function or cmd:COMMAND"
        )
    where, attr = spec.rsplit(":", 1)
    module = (
        _load_file(spec, where)
        if where.endswith(".py") or "/" in where or "\\" in where
        else _import(spec, where)
    )
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise InputError(f"{spec!r}: {where} has no {attr!r}")
        obj = getattr(obj, part)
    return from_callable(obj, spec, "python", kind)


def _import(spec: str, name: str) -> Any:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        raise InputError(
            f"{spec!r}: no module {exc.name!r} (is it installed, or is its folder on PYTHONPATH? a file "
            "is named path/to/file.py:function)"
        ) from None
    except Exception as exc:  # its code failed on import: say what it raised
        raise InputError(f"{spec!r}: importing {name} raised {type(exc).__name__}: {exc}") from None


def _load_file(spec: str, where: str) -> Any:
    path = Path(where).expanduser().resolve()
    if not path.is_file():
        raise InputError(f"{spec!r}: no file {where} (from {Path.cwd()})")
    # one module per file, named after its path, so two estimators' files never collide
    name = "simbench_user_" + hashlib.sha1(str(path).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    loader = importlib.util.spec_from_file_location(name, path)
    if loader is None or loader.loader is None:
        raise InputError(f"{spec!r}: {where} is not a Python file")
    module = importlib.util.module_from_spec(loader)
    sys.modules[name] = module
    try:
        loader.loader.exec_module(module)
    except SyntaxError as exc:
        del sys.modules[name]
        raise InputError(f"{spec!r}: {where}, line {exc.lineno}: invalid Python: {exc.msg}") from None
    except Exception as exc:
        del sys.modules[name]
        raise InputError(f"{spec!r}: running {where} raised {type(exc).__name__}: {exc}") from None
    return module
