"""The estimator registry: what an estimator is, and the one list of those simbench knows.

An :class:`Estimator` has a **kind** (:data:`KINDS`), a function, the **parameters** it takes
(:class:`Param`: name, unit, default; the one place each default lives) and what it **needs**
beyond its data (a hierarchy, a sample rate). Its function's contract depends on the kind:

- ``joints``: ``fn(poses, *, hierarchy=None, **params)`` with ``poses`` a
  :class:`simbench.io.poses.PoseRecording` (positions in ``poses.unit``) and ``hierarchy`` a
  ``{child: parent}`` of sensor names or ``None`` (infer it); returns the joints in both sensors'
  frames, in the poses' unit: a :class:`JointsResult`, a :class:`calibration.Calibration`, a
  :class:`simbench.io.calibration_json.CalibrationJoints` or a calibration document (the dict of
  ``simbench calibrate --json``: ``joints`` with ``parent``, ``child``, ``joint_in_parent``,
  ``joint_in_child``; ``units``).
- ``orientation``: ``fn(imu, **params)`` with ``imu`` a :class:`simbench.io.imu.ImuRecording`;
  returns ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` in ENU (NaN where not estimated), or
  an :class:`OrientationResult`.

Built-ins register themselves (:mod:`simbench.estimators.builtin`); :func:`resolve` finds any other
estimator from a *spec* (:mod:`simbench.estimators.spec`): a Python callable, an installed
plugin (entry-point group :data:`ENTRY_POINT_GROUP`) or an external command.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from calibration import Calibration
from calibration.diagnostics import JointResiduals
from simbench.errors import InputError
from simbench.estimators.catalog import DATA, KINDS, NEEDS
from simbench.estimators.catalog import ENTRY_POINT_GROUP as ENTRY_POINT_GROUP
from simbench.estimators.catalog import Param as Param
from simbench.io.calibration_json import CalibrationJoints


@dataclass(frozen=True)
class Estimator:
    """An estimator of one kind, with its parameters and needs.

    Attributes:
        name: the registry's name, or the spec it was resolved from.
        kind: one of :data:`KINDS`.
        fn: the function (contract by kind: module docstring).
        params: its parameters; the values it gets are their defaults updated with those given.
        needs: what it needs beyond its data, from :data:`NEEDS`.
        summary: one line on what it is (the method and its reference).
        origin: ``builtin``, ``python`` (a callable named by a spec), ``plugin`` or ``command``.
        data: what a joints estimator's first argument is (:data:`DATA`); orientation estimators
            take an IMU recording.
        takes_hierarchy: a joints estimator whose function takes ``hierarchy`` (a built-in, or a
            callable with that parameter); one that does not always infers its own tree.
        takes_skeleton: an orientation estimator whose function takes ``skeleton`` (a
            :class:`calibration.orientation.Skeleton` of a calibration, or ``None``).
    """

    name: str
    kind: str
    fn: Callable[..., Any]
    params: tuple[Param, ...] = ()
    needs: frozenset[str] = frozenset()
    summary: str = ""
    origin: str = "builtin"
    data: str = "poses"
    takes_hierarchy: bool = True
    takes_skeleton: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"estimator {self.name!r}: kind must be one of {list(KINDS)}, got {self.kind!r}")
        unknown = sorted(set(self.needs) - set(NEEDS))
        if unknown:
            raise InputError(
                f"estimator {self.name!r}: needs {unknown} unknown; expected some of {list(NEEDS)}"
            )
        if self.data not in DATA:
            raise InputError(f"estimator {self.name!r}: data must be one of {list(DATA)}, got {self.data!r}")
        if self.kind == "orientation":
            object.__setattr__(self, "data", "imu")
        names = [p.name for p in self.params]
        if len(set(names)) != len(names):
            raise InputError(f"estimator {self.name!r}: a parameter declared twice in {names}")

    @property
    def defaults(self) -> dict[str, Any]:
        """``{parameter: default}``."""
        return {p.name: p.default for p in self.params}

    def param(self, name: str) -> Param:
        """The parameter ``name``.

        Raises:
            InputError: the estimator has no such parameter (its parameters named).
        """
        for p in self.params:
            if p.name == name:
                return p
        raise InputError(
            f"{self.name}: no parameter {name!r}; its parameters: {[p.name for p in self.params] or 'none'}"
        )

    def arguments(self, given: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The defaults updated with ``given``, each value checked.

        Raises:
            InputError: an unknown parameter or a value it does not take.
        """
        out = self.defaults
        for name, value in (given or {}).items():
            out[name] = self.param(name).check(value, self.name)
        return out


@dataclass(frozen=True)
class JointsResult:
    """What a joints estimator found, in the unit of the poses it was given.

    Attributes:
        joints: the joints (:class:`simbench.io.calibration_json.CalibrationJoints`; a hinge's
            centre is a point of its axis).
        calibration: the built-in O'Brien methods' whole :class:`calibration.Calibration` (joint
            residuals, conditioning, warnings), or ``None``.
        notes: what the estimator could not do (a joint it could not fit is left out and named).
        residuals: for an estimator other than O'Brien's variants, run on poses: how its joints
            fit them (:class:`calibration.diagnostics.JointResiduals`, the poses' unit), else
            ``None`` (O'Brien's are in ``calibration``).
        warnings: with ``residuals``: joints whose residual stands far above the others' or
            explains almost nothing of their sensors' motion
            (:func:`calibration.diagnostics.residual_warnings`, as O'Brien's calibration warns).
        unit: the length unit of the centres and residuals (the poses').
    """

    joints: CalibrationJoints
    calibration: Calibration | None = None
    notes: tuple[str, ...] = ()
    residuals: JointResiduals | None = None
    warnings: tuple[str, ...] = ()
    unit: str = "m"


@dataclass(frozen=True)
class OrientationResult:
    """What an orientation estimator found.

    Attributes:
        q_enu: ``(F, N, 4)`` scalar-first quaternions of ``R_w_s`` in ENU, NaN where not estimated.
        ok: ``(F, N)`` estimated.
        field_strength_ut, inclination_deg: the reference field a built-in used (NaN otherwise).
    """

    q_enu: np.ndarray
    ok: np.ndarray
    field_strength_ut: float = math.nan
    inclination_deg: float = math.nan


#: The built-in estimators by name (:mod:`simbench.estimators.builtin` fills it).
REGISTRY: dict[str, Estimator] = {}


def register(estimator: Estimator) -> Estimator:
    """Add a built-in estimator to :data:`REGISTRY` (its name must be new); returns it.

    Raises:
        InputError: the name is taken.
    """
    if estimator.name in REGISTRY:
        raise InputError(f"an estimator named {estimator.name!r} is registered already")
    REGISTRY[estimator.name] = estimator
    return estimator


@dataclass(frozen=True)
class _Declared:
    kind: str | None
    params: tuple[Param, ...] | None
    needs: frozenset[str] | None
    summary: str


def estimator(
    *,
    kind: str | None = None,
    params: tuple[Param, ...] | None = None,
    needs: tuple[str, ...] | None = None,
    summary: str = "",
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorate a user's function with what simbench cannot read off its signature: its kind,
    its parameters' units, what it needs. Optional: undecorated, the kind is read from the first
    parameter's name (``poses`` or ``imu``), the parameters from its keyword arguments with
    defaults, and a joints function needs a hierarchy when its ``hierarchy`` has no default.

    Example::

        @simbench.estimator(kind="joints", params=(Param("tolerance_m", 1e-3, unit="m"),))
        def fit(poses, *, hierarchy=None, tolerance_m=1e-3): ...
    """

    def mark(fn: Callable[..., Any]) -> Callable[..., Any]:
        fn.__simbench_estimator__ = _Declared(
            kind, params, None if needs is None else frozenset(needs), summary
        )
        return fn

    return mark


#: Units read off a parameter's name suffix when it declares none.
SUFFIX_UNITS = (("_m", "m"), ("_s", "s"), ("_hz", "hz"), ("_rad", "rad"), ("_deg", "deg"))


def from_callable(fn: Callable[..., Any], name: str, origin: str, kind: str | None = None) -> Estimator:
    """An :class:`Estimator` of a plain function (or an :class:`Estimator` itself, returned as is),
    its kind, parameters and needs read off its signature and :func:`estimator` declaration.

    Args:
        fn: the function.
        name: the spec that named it (messages and score rows use it).
        origin: ``python`` or ``plugin``.
        kind: the kind the caller expects; ``None`` takes the function's own.

    Raises:
        InputError: not callable; its kind cannot be told, or is not ``kind``.
    """
    if isinstance(fn, Estimator):
        if kind is not None and fn.kind != kind:
            raise InputError(f"{name} estimates {fn.kind}, not {kind}")
        return fn
    if not callable(fn):
        raise InputError(f"{name}: expected a function, got {type(fn).__name__}")
    declared = getattr(fn, "__simbench_estimator__", None) or _Declared(None, None, None, "")
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        raise InputError(f"{name}: its signature cannot be read (a builtin?); wrap it in a def") from None
    positional = [
        p for p in sig.parameters.values() if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]
    first = positional[0].name if positional else None
    own = declared.kind or {"poses": "joints", "imu": "orientation"}.get(first or "")
    if own is None:
        if kind is None:
            raise InputError(
                f"{name}: cannot tell what kind of estimator it is: name its first parameter 'poses' "
                "(joint centres) or 'imu' (orientation), or declare it with @simbench.estimator(kind=...)"
            )
        own = kind
    if kind is not None and own != kind:
        raise InputError(f"{name} estimates {own} (its first parameter is {first!r}), not {kind}")
    if first is None:
        raise InputError(f"{name}: expected a function of the data ({'poses' if own == 'joints' else 'imu'})")
    hierarchy = sig.parameters.get("hierarchy")
    skip = {first, "hierarchy", "skeleton"}
    if declared.params is not None:
        params = declared.params
    else:
        params = tuple(
            Param(
                p.name,
                p.default,
                unit=next((u for s, u in SUFFIX_UNITS if p.name.endswith(s)), "1"),
            )
            for p in sig.parameters.values()
            if p.name not in skip and p.default is not p.empty and p.kind is not p.VAR_KEYWORD
        )
    if declared.needs is not None:
        needs = declared.needs
    else:
        needs = (
            frozenset({"hierarchy"})
            if hierarchy is not None and hierarchy.default is hierarchy.empty
            else frozenset()
        )
    return Estimator(
        name=name,
        kind=own,
        fn=fn,
        params=params,
        needs=needs,
        summary=declared.summary or (inspect.getdoc(fn) or "").split("\n", 1)[0],
        origin=origin,
        takes_hierarchy=hierarchy is not None,
        takes_skeleton="skeleton" in sig.parameters,
    )


@dataclass(frozen=True)
class Failure:
    """An estimator that did not give a usable result, and why (in words)."""

    estimator: str
    error: str


__all__ = [
    "ENTRY_POINT_GROUP",
    "KINDS",
    "NEEDS",
    "REGISTRY",
    "Estimator",
    "Failure",
    "JointsResult",
    "OrientationResult",
    "Param",
    "estimator",
    "from_callable",
    "register",
]
