"""Optical marker clusters on a simulated session's segments, from the exact segment poses.

Every segment that carries a sensor gets a cluster of 3 or 4 markers at fixed offsets in its
segment (body) frame: a plate centred on the sensor's placement, laid out in the sensor's frame
(:data:`CLUSTER_LAYOUT_S`, asymmetric so that no marker can be mistaken for another). The exact
marker positions come from the truth's segment poses ``p_w_b``, ``q_w_b``:
``x_w = R_w_b @ offset_b + p_w_b``. Optionally (:class:`MarkerConfig`):

- **skin motion**: the skin carries each segment's cluster over the bone, and deforms it a
  little. Each cluster slides on its segment by one smooth random displacement shared by its
  markers (the sums of sines of :func:`simbench.sim.markers.smooth_noise`, in the segment frame),
  of standard deviation ``skin_sd_m`` per coordinate; each marker moves by its own smooth
  displacement of :data:`SKIN_DEFORMATION` times that (the deformation). The split is measured on
  real recordings (``studies/marker_deformation.py``): on 73 moving clusters of 13 real
  recordings (C3D and TRC: the kinetics toolkit, pyomeca, biobuddy, OpenSim's gait and running
  trials) the rigid fit's residual -- the deformation, the common motion taken out -- is 0.79 mm
  per coordinate (median; quartiles 0.49-1.57), 1.13 % of the cluster's radius (quartiles
  0.65-2.05 %). On the 38 mm radius of :data:`CLUSTER_LAYOUT_S` that is 0.43 mm, 0.22 of
  the 2 mm skin motion of the sessions issue 42 measures cluster finding on (``--marker-skin 2``,
  docs/cluster-finding.md);
- **camera noise**: white Gaussian noise of standard deviation ``camera_noise_m`` on every
  coordinate (:data:`simbench.sim.markers.CAMERA_NOISE_M` is a typical value).

The random draws come from their own stream of the session seed (spawn key
:data:`MARKER_STREAM`, beside the session's five), so adding markers changes nothing else of a
session, and the same seed gives identical markers.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from calibration.clusters import reference_shape, rigid_fit
from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.dataset import Dataset
from simbench.io.marker_data import MarkerData
from simbench.sim.markers import smooth_noise
from simbench.sim.skin import relative_rotvecs, soft_tissue_offsets

#: The marker stream's spawn key under the session seed (:func:`simbench.sim.plan.plan_session`
#: spawns keys 0-4).
MARKER_STREAM = 5

#: Marker offsets from the sensor in the sensor's frame, m: a plate of 4 markers (the first 3 for
#: clusters of 3), all distances between them different, the fourth 1 cm off the plate's plane.
CLUSTER_LAYOUT_S = np.array(
    [
        [0.040, 0.000, 0.000],
        [0.000, 0.030, 0.000],
        [-0.035, -0.010, 0.000],
        [0.010, -0.045, 0.010],
    ]
)


#: A cluster's deformation over its skin motion: each marker's own smooth displacement has
#: ``SKIN_DEFORMATION * skin_sd_m`` per coordinate, the cluster's shared one ``skin_sd_m``. The
#: median relative deformation of real clusters (0.0113 of the radius, module docstring) times
#: the plate's radius (38.1 mm) over 2 mm of skin motion.
SKIN_DEFORMATION = 0.22


@dataclass(frozen=True)
class MarkerConfig:
    """Simulated marker clusters (module docstring).

    Attributes:
        per_segment: markers on each segment, 3 or 4.
        skin_sd_m: standard deviation of each cluster's skin motion per coordinate, m (0: none);
            its markers deform it by :data:`SKIN_DEFORMATION` times that.
        camera_noise_m: standard deviation of the white camera noise per coordinate, m (0: none).
        skin_hz: about how often the skin motion changes direction, Hz.
    """

    per_segment: int = 4
    skin_sd_m: float = 0.0
    camera_noise_m: float = 0.0
    skin_hz: float = 0.5

    def __post_init__(self) -> None:
        if self.per_segment not in (3, 4) or isinstance(self.per_segment, bool):
            raise InputError(f"Expected 3 or 4 markers per segment, got {self.per_segment!r}")
        for name in ("skin_sd_m", "camera_noise_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise InputError(f"Expected {name} to be a finite number >= 0 (metres), got {value!r}")
        if not (isinstance(self.skin_hz, int | float) and math.isfinite(self.skin_hz) and self.skin_hz > 0):
            raise InputError(f"Expected skin_hz to be a finite number > 0, got {self.skin_hz!r}")

    def as_dict(self) -> dict[str, float]:
        """The configuration as the dataset's metadata records it."""
        return dataclasses.asdict(self)


def cluster_offsets(p_b_s: np.ndarray, q_b_s: np.ndarray, per_segment: int = 4) -> np.ndarray:
    """Marker offsets in each segment frame: the layout placed at each sensor.

    Args:
        p_b_s: ``(N, 3)`` sensor positions in their segment frames, m.
        q_b_s: ``(N, 4)`` sensor orientations in their segment frames (wxyz).
        per_segment: 3 or 4.

    Returns:
        ``(N, per_segment, 3)`` marker offsets in the segment frames, m.
    """
    p_b_s, q_b_s = np.asarray(p_b_s, dtype=float), np.asarray(q_b_s, dtype=float)
    if p_b_s.ndim != 2 or p_b_s.shape[1] != 3 or q_b_s.shape != (p_b_s.shape[0], 4):
        raise InputError(f"Expected p_b_s (N, 3) and q_b_s (N, 4), got {p_b_s.shape} and {q_b_s.shape}")
    layout = CLUSTER_LAYOUT_S[:per_segment]
    return np.einsum("nij,kj->nki", quat_to_matrix(q_b_s), layout) + p_b_s[:, None]


def simulate_markers(ds: Dataset, config: MarkerConfig, rng: np.random.Generator) -> MarkerData:
    """Marker clusters on every sensor's segment of a simulated session (module docstring).

    Args:
        ds: a session with truth (segment poses ``truth.p_w_b``, ``truth.q_w_b`` ``(F, N, 3/4)``).
        config: markers per segment, skin motion, camera noise.
        rng: the only source of randomness.

    Returns:
        ``N * per_segment`` markers labelled ``<sensor>_M<k>`` (``k`` from 1), positions in
        metres in world; ``xyz_true`` the exact positions, ``offset_b`` the offsets.
    """
    if ds.truth is None:
        raise InputError("simulated markers need a dataset with truth (segment poses); this one has none")
    t = ds.truth
    k = config.per_segment
    n = len(ds.sensors)
    frames = ds.time_s.size
    offset_b = cluster_offsets(t.p_b_s, t.q_b_s, k).reshape(n * k, 3)
    segment = np.repeat(np.arange(n), k)
    R_w_b = quat_to_matrix(t.q_w_b)[:, segment]  # (F, M, 3, 3)
    p_w_b = t.p_w_b[:, segment]
    xyz_true = np.einsum("fmij,mj->fmi", R_w_b, offset_b) + p_w_b
    duration = float(ds.time_s[-1] - ds.time_s[0]) if frames > 1 else 0.0
    cycles = max(duration * config.skin_hz, 1.0)
    shared_b = smooth_noise(rng, frames, (n, 3), cycles)[:, segment]
    own_b = smooth_noise(rng, frames, (n * k, 3), cycles)
    slide_b = shared_b + SKIN_DEFORMATION * own_b
    noise = rng.standard_normal((frames, n * k, 3))
    xyz = (
        xyz_true
        + config.skin_sd_m * np.einsum("fmij,fmj->fmi", R_w_b, slide_b)
        + config.camera_noise_m * noise
    )
    return MarkerData(
        labels=tuple(f"{ds.sensors[s]}_M{j + 1}" for s in range(n) for j in range(k)),
        segment=tuple(ds.sensors[s] for s in segment),
        xyz=xyz,
        xyz_true=xyz_true,
        offset_b=offset_b,
    )


@dataclass(frozen=True)
class MessyMarkers:
    """Marker clusters as messy as real ones on a simulated session (:func:`messy_markers`).

    Attributes:
        xyz: ``(F, M, 3)`` marker positions in world, m.
        labels: ``(M,)`` ``<segment>_M<k>`` for measured markers, ``<segment>_V<k>`` for virtual ones.
        segment: ``(M,)`` the segment each marker sits on (a virtual marker: the cluster it is
            computed from).
        clusters: index lists of the segments that carry three markers or more (a pose), sorted.
        pairs: index lists of the segments that carry fewer (no pose), sorted.
        virtual: index lists of the virtual markers, one list per cluster they are computed from.
        virtual_host: for each list of ``virtual``, the index in ``clusters`` of that cluster.
    """

    xyz: np.ndarray
    labels: tuple[str, ...]
    segment: tuple[str, ...]
    clusters: list[list[int]]
    pairs: list[list[int]]
    virtual: list[list[int]]
    virtual_host: list[int]


def messy_markers(
    ds: Dataset,
    rng: np.random.Generator,
    *,
    per_segment: tuple[int, int] = (2, 4),
    skin_sd_m: float = 0.002,
    sta_m: float = 0.004,
    camera_noise_m: float = 0.0002,
    virtual: int = 0,
) -> MessyMarkers:
    """Marker clusters with the mess of real recordings, for testing cluster finding.

    Each sensor's segment carries ``per_segment[0]`` to ``per_segment[1]`` markers (drawn per
    segment; fewer than three give no pose), on a plate of +-4.5 cm (1.3 cm deep) laid out in
    the sensor's frame around its placement. Each marker moves on its segment by

    - a soft-tissue artefact that follows the adjacent joints' rotations ``A tanh(W phi)``
      (:func:`simbench.sim.skin.soft_tissue_offsets`): one shared by the segment's markers (the
      skin carrying the cluster over the bone, amplitude ``2 sta_m``) and one of its own
      (:data:`SKIN_DEFORMATION` times that: the distances within the cluster change with the
      joint angles);
    - smooth random skin motion (about one period every two seconds,
      :func:`simbench.sim.markers.smooth_noise`): shared by the segment's markers, of standard
      deviation ``skin_sd_m`` per coordinate, and each marker's own, :data:`SKIN_DEFORMATION`
      times that -- the split of :func:`simulate_markers`, measured on real clusters;
    - white camera noise ``camera_noise_m`` per coordinate.

    ``virtual`` clusters of three markers or more (drawn) each get two or three virtual markers:
    fixed points 5-15 cm from the cluster's centre in its frame, placed every frame by the
    least-squares pose of the cluster's measured markers -- landmarks as a probing-based export
    computes them (acromion, epicondyles, styloids).

    Args:
        ds: a session with truth (segment poses).
        rng: the only source of randomness.
        per_segment: fewest and most markers on a segment (1 to 8).
        skin_sd_m, sta_m, camera_noise_m: the motions' sizes, m (>= 0).
        virtual: clusters that get virtual markers (>= 0; at most those with three markers).

    Raises:
        InputError: a dataset without truth, or arguments out of range.
    """
    if ds.truth is None:
        raise InputError("messy markers need a dataset with truth (segment poses); this one has none")
    lo, hi = per_segment
    if not (isinstance(lo, int) and isinstance(hi, int) and 1 <= lo <= hi <= 8):
        raise InputError(
            f"Expected per_segment (fewest, most) with 1 <= fewest <= most <= 8, got {per_segment!r}"
        )
    for name, value in (("skin_sd_m", skin_sd_m), ("sta_m", sta_m), ("camera_noise_m", camera_noise_m)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
            raise InputError(f"Expected {name} to be a finite number >= 0 (metres), got {value!r}")
    if not (isinstance(virtual, int) and virtual >= 0):
        raise InputError(f"Expected virtual to be a whole number >= 0, got {virtual!r}")
    t = ds.truth
    names = list(ds.sensors)
    n, frames = len(names), ds.time_s.size
    parent = [names.index(s) for s in t.parent]
    child = [names.index(s) for s in t.child]
    phi = relative_rotvecs(t.q_w_b, parent, child)
    R_w_b = quat_to_matrix(t.q_w_b)
    R_b_s = quat_to_matrix(t.q_b_s)
    duration = float(ds.time_s[-1] - ds.time_s[0]) if frames > 1 else 0.0
    xs, segment, labels = [], [], []
    for s in range(n):
        k = int(rng.integers(lo, hi + 1))
        plate = rng.uniform(-0.045, 0.045, (k, 3)) * np.array([1.0, 1.0, 0.3])
        offset = t.p_b_s[s] + plate @ R_b_s[s].T
        amp = np.zeros(n)
        amp[s] = 2.0 * sta_m
        shared = soft_tissue_offsets(phi, parent, child, amp, rng)[:, s]
        amp[s] = SKIN_DEFORMATION * 2.0 * sta_m
        own = np.stack([soft_tissue_offsets(phi, parent, child, amp, rng)[:, s] for _ in range(k)], axis=1)
        cycles = max(duration * 0.5, 1.0)
        slide = skin_sd_m * (
            smooth_noise(rng, frames, (1, 3), cycles)
            + SKIN_DEFORMATION * smooth_noise(rng, frames, (k, 3), cycles)
        )
        local = offset[None] + shared[:, None] + own + slide
        xs.append(np.einsum("fij,fkj->fki", R_w_b[:, s], local) + t.p_w_b[:, s, None])
        segment += [names[s]] * k
        labels += [f"{names[s]}_M{j + 1}" for j in range(k)]
    x = np.concatenate(xs, axis=1)
    x = x + camera_noise_m * rng.standard_normal(x.shape)
    seg = np.array(segment)
    clusters = sorted(np.flatnonzero(seg == s).tolist() for s in names if (seg == s).sum() >= 3)
    pairs = sorted(np.flatnonzero(seg == s).tolist() for s in names if 0 < (seg == s).sum() < 3)
    hosts = sorted(rng.choice(len(clusters), min(virtual, len(clusters)), replace=False).tolist())
    extra, groups = [], []
    for h in hosts:
        members = clusters[h]
        fit = rigid_fit(reference_shape(x[:, members]), x[:, members])
        kv = int(rng.integers(2, 4))
        direction = rng.standard_normal((kv, 3))
        points = (
            direction / np.linalg.norm(direction, axis=1, keepdims=True) * rng.uniform(0.05, 0.15, (kv, 1))
        )
        extra.append(np.einsum("fij,kj->fki", fit.R_w_c, points) + fit.p_w_c[:, None])
        start = len(labels)
        groups.append(list(range(start, start + kv)))
        host = str(seg[members[0]])
        segment += [host] * kv
        labels += [f"{host}_V{j + 1}" for j in range(kv)]
    if extra:
        x = np.concatenate([x, *extra], axis=1)
    return MessyMarkers(
        xyz=x,
        labels=tuple(labels),
        segment=tuple(segment),
        clusters=clusters,
        pairs=pairs,
        virtual=groups,
        virtual_host=hosts,
    )


def marker_rng(seed: int) -> np.random.Generator:
    """The markers' random stream of a session seed (:data:`MARKER_STREAM`)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(MARKER_STREAM,)))


def add_markers(ds: Dataset, config: MarkerConfig | None = None, *, seed: int | None = None) -> Dataset:
    """The dataset with simulated marker clusters (``config`` default: 4 per segment, no skin
    motion, no camera noise), drawn from the marker stream of ``seed`` (default: the session's
    ``meta["seed"]``); the configuration is recorded in ``meta["markers"]``."""
    config = MarkerConfig() if config is None else config
    if seed is None:
        seed = ds.meta.get("seed")
        if not isinstance(seed, int):
            raise InputError("the dataset's meta has no integer seed: pass seed=")
    markers = simulate_markers(ds, config, marker_rng(seed))
    meta = {**ds.meta, "markers": {**config.as_dict(), "seed": seed, "stream": MARKER_STREAM}}
    return dataclasses.replace(ds, markers=markers, meta=meta)


__all__ = [
    "CLUSTER_LAYOUT_S",
    "MARKER_STREAM",
    "SKIN_DEFORMATION",
    "MarkerConfig",
    "MessyMarkers",
    "add_markers",
    "cluster_offsets",
    "marker_rng",
    "messy_markers",
    "simulate_markers",
]
