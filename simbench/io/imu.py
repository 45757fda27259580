"""Inertial/magnetic recordings for orientation estimation: BROAD files and simbench datasets.

**BROAD** (Laidig et al. 2021, ``../shared/data/``): an HDF5 file with ``imu_acc`` (m/s^2),
``imu_gyr`` (rad/s), ``imu_mag`` (uT), each ``(F, 3)``, the optical reference ``opt_quat``
``(F, 4)`` (wxyz, IMU frame to ENU; NaN where the optical system lost the markers), the
``movement`` mask of the samples to evaluate, and the attribute ``sampling_rate`` (Hz). One
sensor, named ``imu``.

**simbench datasets**: the measured ``acc``, ``gyro``, ``mag`` of every sensor, truth the actual
sensor orientations (``truth/actual/q_w_s``; the simulated world is ENU: z up, the field's
horizontal part along +y); samples at the accelerometer's configured range are marked saturated.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from simbench.errors import InputError
from simbench.io.hdf5 import open_hdf5


@dataclass(frozen=True)
class ImuRecording:
    """Accelerometer, gyroscope and magnetometer samples of ``N`` sensors.

    Attributes:
        names: ``(N,)`` sensor names.
        time_s: ``(F,)`` s.
        acc: ``(F, N, 3)`` m/s^2. gyro: ``(F, N, 3)`` rad/s. mag: ``(F, N, 3)`` uT.
        valid: ``(F, N)`` False for samples known to be unusable (missing, saturated).
        q_true: ``(F, N, 4)`` reference orientations (``R_w_s``, ENU), or ``None``.
        evaluate: ``(F,)`` samples to score (BROAD's ``movement``), or ``None`` for all.
        rate_hz: sample rate, Hz.
        source: where it came from.
        notes: what the reader noticed (saturated or missing samples).
        saturated: ``(F, N, 3)`` True where an accelerometer axis was at its range, or ``None``
            (not known): such samples are not ``valid`` (the axis's specific force is known only
            to be beyond the range), but their other axes, magnetometer and gyroscope are good.
            The skeleton method estimates them, the clipped axis taken from the joints
            (:func:`calibration.orientation.skeleton_orientation`'s ``acc_clipped``).
    """

    names: tuple[str, ...]
    time_s: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray
    mag: np.ndarray
    valid: np.ndarray
    q_true: np.ndarray | None
    evaluate: np.ndarray | None
    rate_hz: float
    source: str
    notes: tuple[str, ...] = ()
    saturated: np.ndarray | None = None


def _field(fh: h5py.File, path: Path, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    if name not in fh:
        raise InputError(f"{path}: not a BROAD file: missing dataset {name!r} (has {sorted(fh.keys())})")
    x = fh[name][()] if isinstance(fh[name], h5py.Dataset) else None
    if not (isinstance(x, np.ndarray) and (np.issubdtype(x.dtype, np.number) or x.dtype == bool)):
        raise InputError(
            f"{path}: {name} must be an array of numbers, got {getattr(x, 'dtype', type(fh[name]).__name__)}"
        )
    if x.ndim != 1 + len(shape_tail) or x.shape[1:] != shape_tail:
        raise InputError(
            f"{path}: expected {name} of shape (frames, {', '.join(map(str, shape_tail))}), got {x.shape}"
        )
    return x


#: Median magnitudes in these ranges pass as m/s^2 and uT (gravity, moving or not; the earth's
#: field, 25-65 uT, with local iron): outside, a reading in other units (g or mg; nT or gauss)
#: is named in a note.
ACC_RANGE_MS2 = (9.81 / 2, 9.81 * 2)
MAG_RANGE_UT = (10.0, 200.0)

#: The common full range of MEMS gyroscopes, 2000 deg/s, in rad/s: a 99th-percentile rate above
#: it is most likely in deg/s (the 22 BROAD trials: at most 18.8 rad/s, fast rotation).
GYRO_TOP_RADS = np.deg2rad(2000.0)


def unit_notes(acc: np.ndarray, mag: np.ndarray, gyro: np.ndarray | None = None) -> list[str]:
    """Notes on magnitudes that suggest other units than m/s^2, uT and rad/s, from the median
    magnitudes of ``acc`` and ``mag`` and the 99th percentile of ``gyro``'s, each ``(F, 3)``
    (finite samples)."""
    checks = (
        (
            acc,
            50,
            ACC_RANGE_MS2,
            "the accelerometer's median magnitude is {:.4g}, where gravity gives about "
            "9.81 m/s^2: is it in m/s^2? (g gives about 1, mg about 1000)",
        ),
        (
            mag,
            50,
            MAG_RANGE_UT,
            "the magnetometer's median magnitude is {:.4g}, where the earth's field is "
            "25-65 uT: is it in uT? (nT gives tens of thousands, gauss below 1)",
        ),
        (
            gyro,
            99,
            (0.0, GYRO_TOP_RADS),
            "the gyroscope's 99th-percentile rate is {:.4g}, above 2000 deg/s "
            f"({GYRO_TOP_RADS:.1f} rad/s), the full range of common MEMS gyroscopes: is it in rad/s? (deg/s "
            "gives 57x)",
        ),
    )
    out = []
    for x, percentile, (lo, hi), text in checks:
        if x is not None and x.shape[0]:
            value = float(np.percentile(np.linalg.norm(x, axis=1), percentile))
            if not lo <= value <= hi:
                out.append(text.format(value))
    return out


def read_broad(path: str | os.PathLike[str]) -> ImuRecording:
    """Read a BROAD trial (module docstring)."""
    path = Path(path)
    with open_hdf5(path) as fh:
        acc = _field(fh, path, "imu_acc", (3,))
        gyro = _field(fh, path, "imu_gyr", (3,))
        mag = _field(fh, path, "imu_mag", (3,))
        n = acc.shape[0]
        if n < 2:
            raise InputError(f"{path}: imu_acc holds {n} sample(s); expected at least 2")
        if gyro.shape[0] != n or mag.shape[0] != n:
            raise InputError(
                f"{path}: imu_acc, imu_gyr and imu_mag have different lengths: {n}, {gyro.shape[0]}, "
                f"{mag.shape[0]}"
            )
        q = _field(fh, path, "opt_quat", (4,)) if "opt_quat" in fh else None
        if q is not None and q.shape[0] != n:
            raise InputError(f"{path}: opt_quat holds {q.shape[0]} samples, imu_acc {n}")
        move = _field(fh, path, "movement", ()) if "movement" in fh else None
        if move is not None and move.dtype != bool:  # 0/1 numbers; NaN marks no sample to score
            move = np.nan_to_num(move.astype(float), nan=0.0) != 0
        if move is not None and move.shape[0] != n:
            raise InputError(f"{path}: movement holds {move.shape[0]} samples, imu_acc {n}")
        if "sampling_rate" not in fh.attrs:
            raise InputError(f"{path}: missing attribute 'sampling_rate'")
        try:
            given = np.ravel(fh.attrs["sampling_rate"])
            rate = float(given[0]) if given.size == 1 else math.nan
        except (TypeError, ValueError, IndexError):
            rate = math.nan
        if not (math.isfinite(rate) and rate > 0):
            raise InputError(
                f"{path}: attribute sampling_rate must be a finite number of Hz > 0, got "
                f"{fh.attrs['sampling_rate']!r}"
            )
    finite = np.isfinite(acc).all(axis=1) & np.isfinite(mag).all(axis=1)
    notes = []
    if not finite.all():
        notes.append(f"{int((~finite).sum())} samples with NaN accelerometer or magnetometer values")
    # a vector of exactly zero is no reading (no gravity or field is that weak): not usable
    zero = finite & ~(np.any(acc != 0, axis=1) & np.any(mag != 0, axis=1))
    if zero.any():
        notes.append(
            f"{int(zero.sum())} samples whose accelerometer or magnetometer reads exactly zero: left out"
        )
    finite &= ~zero
    if q is not None and np.any(none := np.isfinite(q).all(axis=1) & ~np.any(q != 0, axis=1)):
        notes.append(f"{int(none.sum())} reference quaternions of zero (no rotation): not scored")
    notes.extend(unit_notes(acc[finite], mag[finite], gyro[np.isfinite(gyro).all(axis=1)]))
    turned = np.isfinite(gyro).all(axis=1)
    if not turned.all():
        notes.append(
            f"{int((~turned).sum())} samples with NaN gyroscope values (not estimated by the gyro-aided "
            "methods)"
        )
    return ImuRecording(
        names=("imu",),
        time_s=np.arange(n) / rate,
        acc=acc[:, None],
        gyro=gyro[:, None],
        mag=mag[:, None],
        valid=finite[:, None],
        q_true=None if q is None else q[:, None],
        evaluate=move,
        rate_hz=rate,
        source=str(path),
        notes=tuple(notes),
    )


@dataclass(frozen=True)
class OpticalPose:
    """The optical reference pose of a BROAD trial's IMU housing.

    Attributes:
        time_s: ``(F,)`` s (the IMU's samples: one clock in the file).
        p_w: ``(F, 3)`` position in world (ENU), m; NaN where the optical system lost the markers.
        q_w: ``(F, 4)`` orientation ``R_w_s`` (IMU frame to ENU), scalar-first; NaN where lost.
        source: the file.
    """

    time_s: np.ndarray
    p_w: np.ndarray
    q_w: np.ndarray
    source: str


def read_broad_pose(
    path: str | os.PathLike[str], n: int | None = None, rate_hz: float | None = None
) -> OpticalPose:
    """The optical pose (``opt_pos``, ``opt_quat``) of a BROAD-layout trial, at ``rate_hz``
    (default its ``sampling_rate``) from 0 s; ``n``: the count of IMU samples (:func:`read_broad`)
    it must have, if given.

    Raises:
        InputError: a dataset missing or of the wrong shape, or a ``sampling_rate`` that is not one
            number of Hz > 0, naming the file.
    """
    path = Path(path)
    with open_hdf5(path) as fh:
        for name in ("opt_quat", "opt_pos"):
            if name not in fh:
                raise InputError(
                    f"{path}: expected BROAD's optical pose (opt_quat, opt_pos) beside the IMU readings; "
                    f"missing dataset {name!r} (has {sorted(fh.keys())})"
                )
        q = _field(fh, path, "opt_quat", (4,)).astype(float)
        p = _field(fh, path, "opt_pos", (3,)).astype(float)
        given = np.ravel(fh.attrs.get("sampling_rate", np.nan)) if rate_hz is None else np.array([rate_hz])
    if p.shape[0] != q.shape[0]:
        raise InputError(f"{path}: opt_pos holds {p.shape[0]} samples, opt_quat {q.shape[0]}")
    if n is not None and q.shape[0] != n:
        raise InputError(f"{path}: opt_quat holds {q.shape[0]} samples, imu_acc {n}")
    try:
        rate = float(given[0]) if given.size == 1 else math.nan
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"{path}: attribute sampling_rate must be one number of Hz > 0, got {given!r}")
    return OpticalPose(np.arange(q.shape[0]) / rate, p, q, str(path))
