"""Optical marker recordings (C3D) as segment poses, for the same calibration.

Markers are read and written with ezc3d (the C3D library of the field's tools); positions are
converted to metres from the file's ``POINT:UNITS``; samples the file marks invalid (negative
residual) and samples at exactly (0, 0, 0) (an exporter's gap) are missing; a file shorter than
its header announces is an error. Markers are grouped into rigid clusters -- by a specification
naming the markers of each segment (TOML ``[clusters] thigh_r = ["RTHI1", "RTHI2", "RTHI3"]``), or
automatically from the steadiness of their mutual distances relative to motion, with groups that
barely move set apart as still -- and each cluster's pose at every frame comes from a
least-squares rigid fit (:mod:`calibration.clusters`). The resulting :class:`PoseRecording`
feeds the calibration like any tracker's poses; its notes say what was read: clusters, frames,
rate, gaps (the zeros dropped among them) and each cluster's rigidity residual.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import ezc3d
import numpy as np

from calibration.clusters import (
    DOUBT_FALSE_ALARM,
    RIGID_FALSE_ALARM,
    SPREAD_FALSE_ALARM,
    ZERO_SPREAD,
    find_clusters,
    reference_shape,
    rigid_fit,
)
from calibration.errors import CalibrationError
from simbench.errors import InputError, load_toml
from simbench.io.atomic import atomic_path
from simbench.io.marker_data import MarkerData
from simbench.io.poses import PoseRecording
from simbench.io.trc import read_trc
from simbench.units import LENGTH_UNITS


def _header_frames(path: Path) -> tuple[int, int]:
    """Frames the C3D header announces and the frames the file's bytes can hold.

    The header (first 512-byte block) gives, in 16-bit words: the parameter block (byte 0), the
    number of points (word 2), analog values per frame (word 3), first and last frame (words 4,
    5), the point scale (float, words 7-8: negative means float storage) and the first data block
    (word 9). The processor type (fourth byte of the parameter section) gives the byte order.
    """
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(512)
        if len(head) < 512:
            raise InputError(f"{path}: not a C3D file: {size} bytes, shorter than its header")
        if head[1] != 0x50:
            raise InputError(
                f"{path}: not a C3D file: its second byte is 0x{head[1]:02x}, a C3D file's is 0x50"
            )
        if head[0] < 2:
            raise InputError(f"{path}: not a C3D file: its header puts the parameters in block {head[0]}")
        if (head[0] - 1) * 512 + 4 > size:
            raise InputError(
                f"{path}: truncated C3D file: the header puts the parameters at byte "
                f"{(head[0] - 1) * 512}, the "
                f"file has {size} bytes"
            )
        fh.seek((head[0] - 1) * 512)
        param = fh.read(4)
    order = ">" if len(param) == 4 and param[3] == 86 else "<"  # 86: MIPS (big-endian)
    points, analogs, first, last = struct.unpack(order + "4H", head[2:10])
    if param[3:] == b"\x55":  # 85: DEC, whose float keeps its sign in bit 7 of the second byte
        scale = -1.0 if head[13] & 0x80 else 1.0
    else:
        (scale,) = struct.unpack(order + "f", head[12:16])
    (data_block,) = struct.unpack(order + "H", head[16:18])
    word = 4 if scale < 0 else 2
    frame_bytes = (4 * points + analogs) * word
    announced = last - first + 1
    available = (size - (data_block - 1) * 512) // frame_bytes if frame_bytes else announced
    return announced, available


@dataclass(frozen=True)
class C3DMarkers:
    """The markers of a C3D file, as read by :func:`read_c3d`.

    Attributes:
        labels: the ``M`` marker labels (``POINT:LABELS``).
        xyz_m: ``(F, M, 3)`` positions, m (NaN where missing).
        rate_hz: ``POINT:RATE``, Hz.
        units: the unit the file's values were read in (``POINT:UNITS``).
        notes: what was read as missing beyond NaN and invalid samples, for the recording's notes.
    """

    labels: list[str]
    xyz_m: np.ndarray
    rate_hz: float
    units: str
    notes: tuple[str, ...]


def read_c3d(path: str | os.PathLike[str], *, units: str | None = None) -> C3DMarkers:
    """A C3D file's markers in metres (NaN where missing), rate and notes.

    Read with ezc3d. Units from ``POINT:UNITS`` (``mm``, ``cm``, ``m``, ``in``), or ``units``
    when given: it overrides the file's (an exporter that wrote the wrong label), with a note
    naming both; a sample is
    missing when its residual is negative (C3D's mark for invalid; ezc3d also gives it NaN), a
    coordinate is not finite, or it is exactly ``(0, 0, 0)``: many exporters write a gap as
    zeros, and a real marker is never at the origin to the last bit in all three coordinates;
    the notes say how many such samples were dropped. The rate is ``POINT:RATE``. ANALOG
    parameters without analog channels are fine.

    Raises:
        InputError: unreadable or truncated file (fewer frames than its header announces), a
            unit (given or the file's) not in :data:`simbench.units.LENGTH_UNITS`.
    """
    path, units_given = Path(path), units
    if units is not None and units not in LENGTH_UNITS:
        raise InputError(f"Expected the units to be one of {sorted(LENGTH_UNITS)}, got {units!r}")
    if path.is_dir():
        raise InputError(f"{path}: expected a file, got a directory")
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    announced, available = _header_frames(path)
    if available < announced:
        raise InputError(
            f"{path}: truncated C3D file: the header announces {announced} frames, "
            f"the file holds {max(available, 0)}"
        )
    try:
        c = ezc3d.c3d(str(path), extract_forceplat_data=False)
        point = c["parameters"]["POINT"]
        labels = [str(label).strip() for label in point["LABELS"]["value"]]
        units_value = point["UNITS"]["value"] if "UNITS" in point else ["mm"]
        units = (units_value[0] if len(units_value) else "mm").strip().lower()
        rate = float(np.ravel(point["RATE"]["value"])[0])
        data = np.asarray(c["data"]["points"], dtype=float)  # (4, M, F): x, y, z, 1
        residual = np.asarray(c["data"]["meta_points"]["residuals"], dtype=float)  # (1, M, F)
    except Exception as exc:  # ezc3d raises assorted errors on damaged files
        raise InputError(f"{path}: not a readable C3D file ({type(exc).__name__}: {exc})") from None
    notes = []
    if units_given is not None:
        if units_given != units:
            notes.append(
                f"positions read in {units_given} as asked (--units), not in the file's POINT:UNITS {units!r}"
            )
        units = units_given
    elif units not in LENGTH_UNITS:
        raise InputError(
            f"{path}: POINT:UNITS is {units!r}; expected one of {sorted(LENGTH_UNITS)} "
            "(or give the unit: --units)"
        )
    if data.shape[2] == 0:
        raise InputError(f"{path}: no frames")
    if data.shape[2] < announced:
        raise InputError(f"{path}: truncated C3D file: {data.shape[2]} of {announced} frames read")
    if not rate > 0:
        raise InputError(f"{path}: POINT:RATE is {rate}; expected a positive rate in Hz")
    raw = np.transpose(data[:3], (2, 1, 0))  # (F, M, 3) in the file's unit
    bad = (residual[0].T < 0) | ~np.isfinite(raw).all(axis=2)
    zero = ~bad & (raw == 0.0).all(axis=2)
    if zero.any():
        frames = int(zero.any(axis=1).sum())
        markers = int(zero.any(axis=0).sum())
        notes.append(
            f"{int(zero.sum())} sample(s) of {markers} marker(s) in {frames} frame(s) at exactly (0, 0, 0) "
            "read as missing (many exporters write a gap as zeros)"
        )
    xyz = raw * LENGTH_UNITS[units]
    xyz[bad | zero] = np.nan
    return C3DMarkers(labels[: xyz.shape[1]], xyz, rate, units, tuple(notes))


def read_c3d_markers(path: str | os.PathLike[str]) -> tuple[list[str], np.ndarray, float]:
    """Marker labels, positions ``(F, M, 3)`` in metres (NaN where missing) and the rate (Hz).

    :func:`read_c3d` without its notes.

    Raises:
        InputError: unreadable or truncated file (fewer frames than its header announces).
    """
    markers = read_c3d(path)
    return markers.labels, markers.xyz_m, markers.rate_hz


def read_cluster_spec(path: str | os.PathLike[str]) -> dict[str, list[str]]:
    """``{segment: [marker labels]}`` from a TOML file with a ``[clusters]`` table.

    Raises:
        InputError: naming the file and key: no ``[clusters]`` table or other keys beside it,
            fewer than 2 clusters (calibration needs 2 segments), a cluster of fewer than 3
            labels, a label twice (in one cluster or two).
    """
    path = Path(path)
    doc = load_toml(path)
    clusters = doc.get("clusters")
    if not isinstance(clusters, dict) or not clusters:
        raise InputError(f'{path}: expected a [clusters] table: segment = ["MARKER1", "MARKER2", "MARKER3"]')
    unknown = sorted(set(doc) - {"clusters"})
    if unknown:
        raise InputError(f"{path}: unknown keys {unknown}; expected only a [clusters] table")
    owner: dict[str, str] = {}
    for name, labels in clusters.items():
        if not isinstance(labels, list) or len(labels) < 3 or not all(isinstance(x, str) for x in labels):
            raise InputError(
                f"{path}, key clusters.{name}: expected a list of at least 3 marker labels, got {labels!r}"
            )
        for label in labels:
            if label in owner:
                where = "twice in it" if owner[label] == name else f"also in clusters.{owner[label]}"
                raise InputError(
                    f"{path}, key clusters.{name}: marker {label!r} is {where}; a marker belongs to one "
                    "rigid cluster"
                )
            owner[label] = name
    return clusters


def _group_name(labels: list[str]) -> str:
    return "+".join(labels) if len(labels) <= 4 else f"{labels[0]}+{len(labels) - 1}"


def auto_clusters(
    labels: list[str], xyz: np.ndarray, *, still_deg: float = 10.0
) -> tuple[dict[str, list[str]], list[str]]:
    """``{name: [labels]}`` found by :func:`calibration.clusters.find_clusters`, and notes.

    Moving clusters first (named by their markers), then still groups (``still``, ``still2``...);
    the notes name the markers seen too little to group, then those left out of the groups and why.
    """
    found = find_clusters(xyz, still_deg=still_deg)
    clusters = {_group_name([labels[k] for k in g]): [labels[k] for k in g] for g in found.clusters}
    for i, g in enumerate(found.still):
        name = "still" if i == 0 else f"still{i + 1}"
        clusters[name] = [labels[k] for k in g]
    rot = found.rotation_deg
    notes = [
        f"clusters found automatically: {len(found.clusters)} moving"
        + (
            f" (rotating {', '.join(f'{a:.0f}' for a in rot[: len(found.clusters)])} deg)"
            if found.clusters
            else ""
        )
        + f", {len(found.still)} still; cuts on the distance spread at "
        f"{found.cut_m[0] * 1e3:.3g} mm (still/moving groups) and {found.cut_m[1] * 1e3:.3g} mm (segments)"
    ]
    for i, g in enumerate(found.still):
        notes.append(
            f"{'still' if i == 0 else f'still{i + 1}'}: {len(g)} markers whose distances are steady "
            f"but which rotate only {rot[len(found.clusters) + i]:.1f} deg (< {still_deg:g}): rigidity not "
            f"proven by "
            f"motion, treated as one body: {', '.join(labels[k] for k in g)}"
        )
    names = list(clusters)
    for g, host, most in zip(found.virtual, found.virtual_with, found.virtual_spread, strict=True):
        notes.append(
            f"virtual markers set aside: {', '.join(labels[k] for k in g)} keep their distances to each "
            f"other exactly (distance spread at most {most * 1e3:.2g} mm, below {ZERO_SPREAD:g} of the "
            f"recording's marker noise {found.marker_noise * 1e3:.3g} mm; no two measured markers are that "
            "steady): landmarks computed from a cluster's pose, as probing-based exports write them, not "
            "measured; "
            + (f"they move with {names[host]}" if host is not None else "they move with no group found")
        )
    for r in found.splits:
        a, b = _group_name([labels[k] for k in r.part]), _group_name([labels[k] for k in r.other])
        if r.test == "spread":
            why = (
                f"the distances between them vary {r.ratio:.3g} times as much as within them (median "
                f"distance spread; {r.value:.3g} robust standard deviations of a within pair's log spread > "
                f"{r.limit:.3g}, exceeded by one rigid body's top union 1 time in {1 / r.false_alarm:.0f})"
            )
        else:
            why = (
                f"they move against each other (median frame's misfit ratio F {r.value:.3g} > {r.limit:.3g}, "
                f"exceeded by one rigid body in 1 frame in {1 / RIGID_FALSE_ALARM:.0f})"
            )
        notes.append(f"not one rigid body, split: {a} and {b}: {why}")
    for a, b, f, z, n in found.doubtful:
        notes.append(
            f"cluster {_group_name([labels[k] for k in sorted(a + b)])} may be two bodies: "
            f"{_group_name([labels[k] for k in a])} and {_group_name([labels[k] for k in b])} misfit as one "
            f"(median frame's misfit ratio F {f:.3g}) {z:.1f} robust standard deviations (log F) beyond the "
            f"same union in {n} subsets of the other clusters (a one-body cluster goes that far 1 time in "
            f"{1 / DOUBT_FALSE_ALARM:.0f}); kept as one: if they are on two segments, name the clusters "
            "(--clusters SPEC.toml)"
        )
    for r in found.doubtful_spread:
        notes.append(
            f"cluster {_group_name([labels[k] for k in sorted(r.part + r.other)])} may be two bodies: "
            f"{_group_name([labels[k] for k in r.part])} and {_group_name([labels[k] for k in r.other])}: "
            f"the distances between them vary {r.ratio:.3g} times as much as within them ({r.value:.3g} "
            f"robust standard deviations > {r.limit:.3g}, exceeded by one rigid body's top union 1 time in "
            f"{1 / r.false_alarm:.0f}; split beyond 1 in {1 / SPREAD_FALSE_ALARM:.0f}); kept as one: if they "
            "are on two segments, name the clusters (--clusters SPEC.toml)"
        )
    for d in found.doubtful_partner:
        notes.append(
            f"cluster {_group_name([labels[k] for k in sorted([d.marker, *d.rest])])} may be two bodies: "
            f"{labels[d.marker]} and {_group_name([labels[k] for k in d.rest])}: {labels[d.marker]} joined "
            f"it last, and it is the steadiest partner of {', '.join(labels[k] for k in d.pair)}, left out "
            f"(median distance spread {d.to_pair * 1e3:.3g} mm to them, {d.to_rest * 1e3:.3g} mm to the "
            "cluster): if it is on their segment, name the clusters (--clusters SPEC.toml)"
        )
    if found.unseen:
        notes.append(
            "not seen enough to group, left out: "
            + "; ".join(f"{labels[k]} ({found.left_out[k]})" for k in found.unseen)
        )
    virtual = {k for g in found.virtual for k in g}
    judged = {k: why for k, why in found.left_out.items() if k not in found.unseen and k not in virtual}
    if judged:
        notes.append("left out: " + "; ".join(f"{labels[k]} ({why})" for k, why in judged.items()))
    return clusters, notes


def cluster_fits(
    labels: list[str] | tuple[str, ...], xyz: np.ndarray, clusters: dict[str, list[str]], where: str
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Each cluster's pose per frame by a least-squares rigid fit of its markers (Kabsch), and notes.

    Args:
        labels: ``(M,)`` marker names.
        xyz: ``(F, M, 3)`` positions in world, any length unit (NaN where not seen).
        clusters: ``{name: [labels]}``.
        where: the source, for messages.

    Returns:
        ``(names, R (F, N, 3, 3), p (F, N, 3), valid (F, N), notes)``: a frame with fewer than
        three of a cluster's markers has no pose (never interpolated); the notes give each
        cluster's rigidity residual and flag one far above the others'.
    """
    index = {label: k for k, label in enumerate(labels)}
    names = tuple(clusters)
    f = xyz.shape[0]
    R = np.full((f, len(names), 3, 3), np.nan)
    p = np.full((f, len(names), 3), np.nan)
    valid = np.zeros((f, len(names)), dtype=bool)
    residual = np.zeros(len(names))
    notes = []
    for k, (name, marker_labels) in enumerate(clusters.items()):
        x = xyz[:, [index[m] for m in marker_labels]]
        try:
            shape = reference_shape(x)
        except CalibrationError as exc:
            raise InputError(f"{where}: cluster {name}: {exc}") from None
        fit = rigid_fit(shape, x)
        R[:, k], p[:, k], valid[:, k] = fit.R_w_c, fit.p_w_c, fit.valid
        residual[k] = np.nanmedian(fit.rms_residual)
        gaps = int((~fit.valid).sum())
        notes.append(
            f"cluster {name} ({', '.join(marker_labels)}): rigidity residual median "
            f"{residual[k] * 1e3:.2f} mm, {gaps} of {f} frames without a pose"
        )
    for k, name in enumerate(names):
        others = np.delete(residual, k)
        if len(others) and residual[k] > 2 * np.median(others):
            notes.append(
                f"high rigidity residual: cluster {name} {residual[k] * 1e3:.2f} mm, more than twice the "
                f"others' median {np.median(others) * 1e3:.2f} mm: markers moving on skin or not one body"
            )
    return names, R, p, valid, notes


def c3d_poses(
    path: str | os.PathLike[str],
    *,
    clusters: dict[str, list[str]] | None = None,
    still_deg: float = 10.0,
    units: str | None = None,
) -> PoseRecording:
    """Segment poses from the marker clusters of a C3D file (module docstring).

    Args:
        path: the C3D file.
        units: the positions' unit, overriding the file's ``POINT:UNITS`` (:func:`read_c3d`);
            ``None``: the file's.
        clusters: ``{segment: [labels]}``; ``None`` to find clusters automatically.
        still_deg: automatic grouping: a group rotating less than this is still, degrees.
    """
    return marker_poses(read_c3d(path, units=units), path, clusters=clusters, still_deg=still_deg)


def trc_poses(
    path: str | os.PathLike[str],
    *,
    clusters: dict[str, list[str]] | None = None,
    still_deg: float = 10.0,
    units: str | None = None,
) -> PoseRecording:
    """Segment poses from the marker clusters of a TRC file (:func:`simbench.io.trc.read_trc`), as
    :func:`c3d_poses` makes them from a C3D file.

    Args:
        path: the TRC file.
        units: the positions' unit, overriding the file's ``Units``; ``None``: the file's.
        clusters: ``{segment: [labels]}``; ``None`` to find clusters automatically.
        still_deg: automatic grouping: a group rotating less than this is still, degrees.

    Raises:
        InputError: an unreadable TRC file (:func:`simbench.io.trc.read_trc`), or ``units`` not a
            length unit.
    """
    trc = read_trc(path)
    xyz, unit, notes = trc.xyz, trc.units, ()
    if units is not None and units != trc.units:
        if units not in LENGTH_UNITS:
            raise InputError(f"units {units!r}: expected one of {sorted(LENGTH_UNITS)}")
        xyz = xyz / LENGTH_UNITS[trc.units] * LENGTH_UNITS[units]
        unit, notes = units, (f"units {units} given; the file says {trc.units}",)
    read = C3DMarkers(list(trc.labels), xyz, trc.rate_hz, unit, notes)
    return marker_poses(read, path, clusters=clusters, still_deg=still_deg)


def marker_poses(
    read: C3DMarkers,
    path: str | os.PathLike[str],
    *,
    clusters: dict[str, list[str]] | None = None,
    still_deg: float = 10.0,
) -> PoseRecording:
    """Segment poses from the marker clusters of markers read from ``path`` (a C3D or TRC file):
    :func:`c3d_poses`, :func:`trc_poses`."""
    labels, xyz, rate = read.labels, read.xyz_m, read.rate_hz
    index = {label: k for k, label in enumerate(labels)}
    notes: list[str] = []
    if not np.isfinite(xyz).all(axis=2).any():
        raise InputError(
            f"{path}: no marker seen in any of its {xyz.shape[0]} frame(s) ({len(labels)} marker(s))"
            + "".join(f"; {n}" for n in read.notes)
        )
    if clusters is None:
        clusters, notes = auto_clusters(labels, xyz, still_deg=still_deg)
        if len(clusters) < 2:
            raise InputError(
                f"{path}: found {len(clusters)} rigid marker group(s); calibration needs 2 or more. "
                + "; ".join([*read.notes, *notes])
            )
    missing = sorted({m for ms in clusters.values() for m in ms} - index.keys())
    if missing:
        raise InputError(f"{path}: no markers named {missing}; markers: {labels}")
    if len(clusters) < 2:
        raise InputError(
            f"{path}: {len(clusters)} marker cluster given ({list(clusters)}); calibration needs 2 or more"
        )
    names, R, p, valid, fitted = cluster_fits(labels, xyz, clusters, str(path))
    notes += fitted
    f = xyz.shape[0]
    notes[:0] = [
        f"read {len(labels)} markers in {read.units}, {f} frames at {rate:g} Hz; {len(names)} clusters",
        *read.notes,
    ]
    return PoseRecording(
        names=names,
        time_s=np.arange(f) / rate,
        R_w_s=R,
        p_w_s=p,
        valid=valid,
        source=str(path),
        notes=tuple(notes),
    )


def dataset_marker_poses(markers: MarkerData, time_s: np.ndarray, where: str = "dataset") -> PoseRecording:
    """The poses of a dataset's optical markers: one cluster per segment (the markers' ``segment``),
    each segment's pose per frame by :func:`cluster_fits` (in the cluster's own frame, not the
    sensor's: its joint centres are compared in the world).

    Raises:
        InputError: fewer than two segments with three or more markers.
    """
    clusters: dict[str, list[str]] = {}
    for label, segment in zip(markers.labels, markers.segment, strict=True):
        clusters.setdefault(segment, []).append(label)
    clusters = {name: labels for name, labels in clusters.items() if len(labels) >= 3}
    if len(clusters) < 2:
        raise InputError(
            f"{where}: its markers make {len(clusters)} cluster(s) of 3 or more; calibration needs 2"
        )
    names, R, p, valid, notes = cluster_fits(list(markers.labels), np.asarray(markers.xyz), clusters, where)
    return PoseRecording(
        names=names,
        time_s=np.asarray(time_s, dtype=float),
        R_w_s=R,
        p_w_s=p,
        valid=valid,
        source=f"{where} (markers)",
        notes=(f"poses of the {len(names)} marker clusters ({len(markers.labels)} markers)", *notes),
    )


def write_c3d_markers(
    path: str | os.PathLike[str], labels: list[str], xyz_m: np.ndarray, rate_hz: float
) -> None:
    """Write markers ``(F, M, 3)`` (metres; NaN = not seen) to a C3D file in mm with ezc3d, atomically.

    Missing samples get residual -1 (C3D's invalid mark); others residual 0.
    """
    xyz = np.asarray(xyz_m, dtype=float)
    if xyz.ndim != 3 or xyz.shape[1] != len(labels) or xyz.shape[2] != 3:
        raise InputError(f"Expected markers of shape (frames, {len(labels)}, 3), got {xyz.shape}")
    if not rate_hz > 0:
        raise InputError(f"Expected a positive rate in Hz, got {rate_hz}")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    seen = np.isfinite(xyz).all(axis=2)  # (F, M)
    points = np.ones((4, xyz.shape[1], xyz.shape[0]))
    points[:3] = np.transpose(np.where(seen[..., None], xyz * 1000.0, 0.0), (2, 1, 0))
    c["data"]["points"] = points
    c["data"]["meta_points"]["residuals"] = np.where(seen.T, 0.0, -1.0)[None]
    with atomic_path(path) as tmp:
        named = tmp.with_name(tmp.name + ".c3d")  # ezc3d appends ".c3d" to any other name
        try:
            c.write(str(named))
            check_c3d_written(named, path, points)
            os.replace(named, tmp)
        finally:
            named.unlink(missing_ok=True)


def check_c3d_written(
    written: str | os.PathLike[str], path: str | os.PathLike[str], points: np.ndarray
) -> None:
    """Check a C3D file ezc3d wrote: its size, then what ezc3d reads back from it.

    ezc3d's ``write`` reports no error: on a full disk it leaves a truncated file (384 of 600
    frames) that crashes ezc3d when read. So the file's size is checked first against what its
    header says it must hold (the data's start block, then 16 bytes a marker a frame of float
    data), and only then is it read back: the marker and frame counts, and the positions to
    float32 precision.

    Args:
        written: the file ezc3d wrote.
        path: the destination it stands for (named in the error).
        points: ``(4, M, F)`` the homogeneous positions given to ezc3d, mm.

    Raises:
        InputError: naming ``path`` and what is wrong (a full disk, most likely).
    """
    _, n_markers, n_frames = points.shape
    size = os.path.getsize(written)
    with open(written, "rb") as fh:
        head = fh.read(24)
    if len(head) < 24:
        raise InputError(
            f"cannot write {path}: the C3D written is {size} bytes, short of its header (disk full?)"
        )
    start_block = struct.unpack("<h", head[16:18])[0]
    need = 512 * (start_block - 1) + 16 * n_markers * n_frames
    if start_block < 2 or size < need:
        raise InputError(
            f"cannot write {path}: the C3D written is {size} bytes, {need} expected for {n_frames} frames of "
            f"{n_markers} markers (disk full?)"
        )
    try:
        back = ezc3d.c3d(str(written), extract_forceplat_data=False)["data"]["points"]
    except Exception as exc:  # ezc3d raises assorted errors on damaged files
        raise InputError(f"cannot write {path}: ezc3d cannot read back the C3D it wrote ({exc})") from exc
    seen = np.isfinite(back[:3])  # ezc3d gives NaN for the samples marked invalid
    if back.shape != points.shape or not np.allclose(back[:3][seen], points[:3][seen], rtol=1e-6, atol=1e-3):
        raise InputError(
            f"cannot write {path}: the C3D read back holds {back.shape[2]} frames of {back.shape[1]} "
            f"markers, not the {n_frames} of {n_markers} written, or other positions; "
            "the file was not written whole"
        )
