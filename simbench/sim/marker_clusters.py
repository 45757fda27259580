"""Optical marker clusters on a simulated session's segments, from the exact segment poses.

Every segment that carries a sensor gets a cluster of 3 or 4 markers at fixed offsets in its
segment (body) frame: a plate centred on the sensor's placement, laid out in the sensor's frame
(:data:`CLUSTER_LAYOUT_S`, asymmetric so that no marker can be mistaken for another). The exact
marker positions come from the truth's segment poses ``p_w_b``, ``q_w_b``:
``x_w = R_w_b @ offset_b + p_w_b``. Optionally (:class:`MarkerConfig`):

- **skin motion**: each marker slides on its segment by a smooth random displacement (the sums of
  sines of :func:`simbench.sim.markers.smooth_noise`, in the segment frame), of standard deviation
  ``skin_sd_m`` per coordinate -- millimetres on real skin clusters (DESIGN.md: distances within a
  cluster vary by 2-7 mm);
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

from calibration.rotations import quat_to_matrix
from simbench.errors import InputError
from simbench.io.dataset import Dataset
from simbench.io.marker_data import MarkerData
from simbench.sim.markers import smooth_noise

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


@dataclass(frozen=True)
class MarkerConfig:
    """Simulated marker clusters (module docstring).

    Attributes:
        per_segment: markers on each segment, 3 or 4.
        skin_sd_m: standard deviation of each marker's skin motion per coordinate, m (0: none).
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
    slide_b = smooth_noise(rng, frames, (n * k, 3), max(duration * config.skin_hz, 1.0))
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
    "MarkerConfig",
    "add_markers",
    "cluster_offsets",
    "marker_rng",
    "simulate_markers",
]
