"""The built-in estimators as data: their names, kinds, parameters and needs, in plain Python.

The one list of simbench's own methods: :mod:`simbench.estimators.builtin` registers each entry of
:data:`BUILTINS` with its function, in this order, and the command line reads the names, defaults
and choices it lists from here, so that ``simbench calibrate --help`` loads neither numpy nor the
methods (issue 44: the light start). Entries whose parameters are read off their function (the
one-pair methods) or need the core's code to state a default (the skeleton estimator's priors)
leave ``params`` to :mod:`simbench.estimators.builtin`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from calibration.defaults import HIERARCHY_METHODS, JOINT_METHOD_NAMES, LOSSES, SINGLE_AXIS_RATIO
from simbench.errors import InputError

#: The kinds of estimator, each with its contract (:mod:`simbench.estimators.registry`).
KINDS = ("joints", "orientation")

#: What an estimator may need beyond its data: ``hierarchy`` (a joints estimator that fits the
#: joints of a given tree and cannot infer one), ``rate`` (a sample rate from the time stamps),
#: ``gyro`` (gyroscope readings).
NEEDS = ("hierarchy", "rate", "gyro")

#: The data a joints estimator takes: ``poses`` (a pose recording) or ``imu`` (an IMU recording).
DATA = ("poses", "imu")

#: The entry-point group of installed estimator plugins (``pyproject.toml``:
#: ``[project.entry-points."simbench.estimators"] name = "package.module:function"``).
ENTRY_POINT_GROUP = "simbench.estimators"

#: The default joints estimator (``simbench calibrate``, ``sb.calibrate``).
DEFAULT_JOINTS = "obrien"
#: The default orientation estimator (``simbench orient``, ``sb.orient``).
DEFAULT_ORIENTATION = "skeleton"

#: A user's estimator's time limit per call unless one is given (``--time-limit``), s.
TIME_LIMIT_S = 600.0


@dataclass(frozen=True)
class Param:
    """One parameter of an estimator.

    Attributes:
        name: the keyword its function takes.
        default: its value when none is given (the one place the default lives).
        unit: the unit of a number (a key of :data:`simbench.units.UNITS`, ``"1"`` for none).
        help: one line on what it does.
        choices: the values allowed, or ``None`` for any value of the default's type.
    """

    name: str
    default: Any
    unit: str = "1"
    help: str = ""
    choices: tuple[Any, ...] | None = None

    def check(self, value: Any, owner: str) -> Any:
        """``value`` as the parameter takes it (an int for a float default becomes a float).

        Raises:
            InputError: naming the estimator, the parameter, what it takes and what arrived.
        """
        if self.choices is not None:
            if value not in self.choices:
                raise InputError(
                    f"{owner}: parameter {self.name!r} takes one of {list(self.choices)}, got {value!r}"
                )
            return value
        default = self.default
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise InputError(f"{owner}: parameter {self.name!r} takes true or false, got {value!r}")
            return value
        if isinstance(default, int | float) or (default is None and self.unit != "1"):
            if value is None and default is None:
                return None
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise InputError(
                    f"{owner}: parameter {self.name!r} takes a finite number"
                    f"{'' if self.unit == '1' else f' in {self.unit}'}, got {value!r}"
                )
            return type(default)(value) if isinstance(default, int | float) else float(value)
        return value


@dataclass(frozen=True)
class Builtin:
    """A built-in estimator without its function (:class:`simbench.estimators.registry.Estimator`'s
    fields of the same names).

    Attributes:
        params: its parameters; ``None``: :mod:`simbench.estimators.builtin` gives them (read off
            the function, or a default the core's code states).
        summary: one line on what it is; ``""``: the function's docstring's first line.
    """

    name: str
    kind: str
    params: tuple[Param, ...] | None = ()
    needs: frozenset[str] = frozenset()
    summary: str = ""
    data: str = "poses"
    takes_skeleton: bool = False

    def __post_init__(self) -> None:
        if self.kind == "orientation":  # an orientation estimator takes an IMU recording
            object.__setattr__(self, "data", "imu")

    def param(self, name: str) -> Param:
        """The parameter ``name`` (of those the catalog gives).

        Raises:
            InputError: no such parameter here (the catalog's parameters named).
        """
        for p in self.params or ():
            if p.name == name:
                return p
        raise InputError(
            f"{self.name}: no parameter {name!r} in the catalog; its parameters there: "
            f"{[p.name for p in self.params or ()] or 'none'}"
        )


_HIERARCHY_METHOD = Param(
    "hierarchy_method",
    HIERARCHY_METHODS[0],
    help="how an inferred tree weighs each pair: misfit = the joint-fit residual less its noise, "
    "mst = the residual itself (O'Brien et al.'s minimum spanning tree)",
    choices=HIERARCHY_METHODS,
)
_SINGLE_AXIS_RATIO = Param(
    "single_axis_ratio",
    SINGLE_AXIS_RATIO,
    help="hard floor of s_min/s_max below which a direction is always undetermined",
)
_ROOT = Param("root", None, help="root sensor (default: the centre of the inferred tree)")
_INTERVALS = Param("intervals", False, help="95 % regions of every centre and intervals of limb lengths")
_DROP_NOISY = Param(
    "drop_noisy_frames", False, help="leave out each sensor's frames whose position noise drowns its others"
)
#: The parameters of O'Brien's whole-recording estimators.
OBRIEN_PARAMS = (_HIERARCHY_METHOD, _SINGLE_AXIS_RATIO, _ROOT, _INTERVALS, _DROP_NOISY)

_WEIGHTING = Param("weighting", True, help="Fontaine's disturbance weighting of the accelerometer")
#: The orientation built-ins' magnetometer calibration.
CALIBRATE_MAG = Param(
    "calibrate_mag",
    True,
    help="fit each magnetometer's hard and soft iron to the recording's own samples first, applied "
    "where the samples determine it and it steadies the field strength",
)
_SMOOTH = Param("smooth_hz", None, unit="hz", help="zero-phase low-pass cutoff of the inputs (none: none)")

_RATE = frozenset({"rate"})
_GYRO = frozenset({"rate", "gyro"})

#: The built-ins, in registration order (the order every list of them takes).
BUILTINS: tuple[Builtin, ...] = (
    Builtin(
        DEFAULT_JOINTS,
        "joints",
        OBRIEN_PARAMS,
        summary="O'Brien et al. 2000: least-squares joint fits, single-axis test, spanning tree",
    ),
    Builtin(
        "obrien-eiv",
        "joints",
        OBRIEN_PARAMS,
        summary="O'Brien's fits corrected for the rotations' noise (errors in variables)",
    ),
    Builtin(
        "obrien-robust",
        "joints",
        (*OBRIEN_PARAMS, Param("robust", LOSSES[0], help="the IRLS loss", choices=LOSSES)),
        summary="O'Brien's fits by iteratively reweighted least squares (slip, bursts)",
    ),
    # the one-pair methods of calibration.methods (O'Brien's are the whole-recording ones above)
    *(
        Builtin(name, "joints", None, frozenset({"hierarchy"}))
        for name in JOINT_METHOD_NAMES
        if name not in (DEFAULT_JOINTS, "obrien-eiv")
    ),
    Builtin(
        "inertial",
        "joints",
        (Param("hinge", False, help="the joints are hinges: their axes from the gyroscopes"),),
        frozenset({"hierarchy", "rate", "gyro"}),
        "Seel et al. 2012/2014: joints from gyroscopes and accelerometers, no poses",
        data="imu",
    ),
    Builtin(
        DEFAULT_ORIENTATION,
        "orientation",
        None,
        _RATE,
        "every sensor over the whole recording at once, on the calibrated skeleton when given",
        takes_skeleton=True,
    ),
    Builtin("triad", "orientation", (CALIBRATE_MAG, _SMOOTH), _RATE, "TRIAD: the two-vector fix per sample"),
    Builtin(
        "fontaine",
        "orientation",
        (CALIBRATE_MAG, _WEIGHTING, _SMOOTH),
        _RATE,
        "Fontaine et al.: Gauss-Newton per sample",
    ),
    Builtin(
        "wahba",
        "orientation",
        (CALIBRATE_MAG, _WEIGHTING, _SMOOTH),
        _RATE,
        "Wahba's problem per sample (closed form)",
    ),
    Builtin(
        "mahony", "orientation", (CALIBRATE_MAG, _SMOOTH), _GYRO, "Mahony's complementary filter (gyro-aided)"
    ),
    Builtin(
        "vqf",
        "orientation",
        (CALIBRATE_MAG, _SMOOTH),
        _GYRO,
        "VQF (Laidig and Seel 2023), offline (gyro-aided reference)",
    ),
)


def builtin(name: str) -> Builtin:
    """The built-in ``name``.

    Raises:
        InputError: no built-in of that name (the built-ins named).
    """
    for b in BUILTINS:
        if b.name == name:
            return b
    raise InputError(f"no built-in estimator {name!r}; the built-ins: {', '.join(b.name for b in BUILTINS)}")


@cache
def plugin_entry_points() -> dict[str, EntryPoint]:
    """The installed plugins' entry points by name (looked up once per process)."""
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def names(kind: str | None = None, *, plugins: bool = True) -> tuple[str, ...]:
    """The names :func:`simbench.estimators.resolve` takes as they are: the built-ins of ``kind``
    (or all) in registration order, then the installed plugins (whose kind is known once loaded:
    all are listed).

    Raises:
        InputError: an unknown kind.
    """
    if kind is not None and kind not in KINDS:
        raise InputError(f"kind must be one of {list(KINDS)}, got {kind!r}")
    own = tuple(b.name for b in BUILTINS if kind is None or b.kind == kind)
    every = {b.name for b in BUILTINS}
    return own + (tuple(sorted(set(plugin_entry_points()) - every)) if plugins else ())


__all__ = [
    "BUILTINS",
    "CALIBRATE_MAG",
    "DATA",
    "DEFAULT_JOINTS",
    "DEFAULT_ORIENTATION",
    "ENTRY_POINT_GROUP",
    "KINDS",
    "NEEDS",
    "OBRIEN_PARAMS",
    "TIME_LIMIT_S",
    "Builtin",
    "Param",
    "builtin",
    "names",
    "plugin_entry_points",
]
