"""Skin-mounted optical marker sets on a moving chain, with the true grouping (analytic motion).

Used to check automatic cluster finding (:func:`calibration.clusters.find_clusters`): a chain of
4-6 segments turning about random axes (smooth in time) carries 3-4 markers per segment; each
marker slides on the skin with smooth random motion sized so that the distances within a
cluster vary by 2-7 mm (standard deviation, drawn per cluster, as measured on real skin
clusters, docs/conventions.md); a few static markers (the lab, a body at rest) carry camera noise only.
"""

from __future__ import annotations

import numpy as np

from calibration.rotations import rotvec_to_matrix

#: Standard deviation of the white camera noise on every marker coordinate, m.
CAMERA_NOISE_M = 0.0002


def smooth_noise(rng: np.random.Generator, frames: int, shape: tuple[int, ...], cycles: float) -> np.ndarray:
    """``(frames, *shape)`` smooth zero-mean unit-variance random signals: sums of four random sines.

    ``cycles`` is about the number of periods over the recording.
    """
    t = np.linspace(0.0, 1.0, frames)[:, None]
    out = np.zeros((frames, *shape))
    for _ in range(4):
        f = rng.uniform(0.5, 1.5, shape).ravel() * cycles
        phase = rng.uniform(0, 2 * np.pi, f.shape)
        out += np.sin(2 * np.pi * f * t + phase).reshape(frames, *shape)
    return out / np.sqrt(2.0)  # four unit sines: variance 4 * 1/2


def simulate_marker_chain(
    rng: np.random.Generator, *, frames: int = 600, n_static: int = 3, markers: tuple[int, int] = (3, 5)
) -> tuple[np.ndarray, list[list[int]], list[int]]:
    """Markers of a moving chain with skin motion, the true clusters and the static markers.

    Args:
        rng: the only source of randomness.
        frames: samples.
        n_static: markers that do not move (camera noise only).
        markers: markers per segment, drawn from ``[low, high)``.

    Returns:
        ``(frames, M, 3)`` marker positions in metres (markers in shuffled order); the true
        clusters (index lists, each sorted, sorted); the static markers' indices (sorted).
    """
    n_seg = int(rng.integers(4, 7))
    length = rng.uniform(0.25, 0.45, n_seg)
    # root: translates and turns; each joint: rotations of about +-35 degrees about random axes
    R = rotvec_to_matrix(0.6 * smooth_noise(rng, frames, (3,), 2.0))
    p = 0.3 * smooth_noise(rng, frames, (3,), 1.5) + np.array([0.0, 0.0, 1.0])
    parts, sizes = [], []
    for s in range(n_seg):
        if s > 0:
            R = R @ rotvec_to_matrix(0.6 * smooth_noise(rng, frames, (3,), 2.0))
        k = int(rng.integers(*markers))
        local = np.column_stack(
            [rng.uniform(-0.05, 0.05, k), rng.uniform(-0.05, 0.05, k), -rng.uniform(0.3, 0.7, k) * length[s]]
        )
        local[:, :2] += 0.06 * rng.standard_normal((k, 2))  # cluster plate off the bone axis
        skin_sd = rng.uniform(0.002, 0.007)  # distance spread within this cluster, m
        slide = smooth_noise(rng, frames, (k, 3), 3.0) * skin_sd / np.sqrt(2.0)
        parts.append(np.einsum("fij,kj->fki", R, local) + p[:, None] + slide)
        sizes.append(k)
        p = p + np.einsum("fij,j->fi", R, np.array([0.0, 0.0, -length[s]]))
    static = rng.uniform(-1.0, 1.0, (n_static, 3)) + np.array([0.0, 0.0, 1.0])
    parts.append(np.broadcast_to(static, (frames, n_static, 3)).copy())
    x = np.concatenate(parts, axis=1)
    x += rng.normal(0.0, CAMERA_NOISE_M, x.shape)
    order = rng.permutation(x.shape[1])
    where = np.argsort(order)  # original index -> shuffled index
    starts = np.cumsum([0, *sizes])
    clusters = sorted(sorted(where[starts[i] : starts[i + 1]].tolist()) for i in range(n_seg))
    static_idx = sorted(where[starts[-1] :].tolist())
    return x[:, order], clusters, static_idx
