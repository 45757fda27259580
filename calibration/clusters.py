"""Rigid marker clusters: their poses from optical markers, and finding them automatically.

An optical system sees markers, not sensors. Three or more markers rigidly fixed to one segment
(a cluster) give that segment's pose at every frame by a least-squares rigid fit of the
cluster's reference shape onto the markers seen (Soderkvist and Wedin 1993; Kabsch 1976):
``min_R,t sum_k |R r_k + t - x_k|^2`` over the visible markers, solved by the SVD of the
centred cross-covariance with the reflection guard. The fit's rms residual measures how rigid the
cluster really is (skin moves markers against each other). Frames with fewer than three visible
markers of a cluster give no pose (marked missing, never interpolated).

:func:`group_markers` finds clusters without a specification: markers whose mutual distances stay
constant over the recording (standard deviation below a tolerance) belong together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.errors import CalibrationError, CalibrationInputError


@dataclass(frozen=True)
class ClusterFit:
    """Poses of one cluster over time.

    Attributes:
        R_w_c: ``(F, 3, 3)`` cluster frame to world (NaN where missing).
        p_w_c: ``(F, 3)`` cluster origin (the reference shape's centroid) in world, m.
        valid: ``(F,)`` a pose was fitted (at least 3 markers seen).
        rms_residual: ``(F,)`` rms distance of the visible markers from the fitted shape, m.
        reference: ``(K, 3)`` the cluster's shape in its own frame, m.
    """

    R_w_c: np.ndarray
    p_w_c: np.ndarray
    valid: np.ndarray
    rms_residual: np.ndarray
    reference: np.ndarray


def rigid_fit(reference: np.ndarray, markers: np.ndarray, visible: np.ndarray | None = None) -> ClusterFit:
    """Least-squares rigid fit of a reference shape to markers at every frame (vectorised).

    Args:
        reference: ``(K, 3)`` marker positions in the cluster frame, m (K >= 3).
        markers: ``(F, K, 3)`` measured marker positions in world, m (NaN where not seen).
        visible: optional ``(F, K)`` bool; markers with NaN are never visible.
    """
    ref = np.asarray(reference, dtype=float)
    x = np.asarray(markers, dtype=float)
    if ref.ndim != 2 or ref.shape[1] != 3 or ref.shape[0] < 3:
        raise CalibrationInputError(f"Expected a reference shape of shape (K >= 3, 3), got {ref.shape}")
    if x.ndim != 3 or x.shape[1:] != ref.shape:
        raise CalibrationInputError(f"Expected markers of shape (frames, {ref.shape[0]}, 3), got {x.shape}")
    w = np.isfinite(x).all(axis=2)
    if visible is not None:
        w &= np.asarray(visible, dtype=bool)
    n = w.sum(axis=1)
    ok = n >= 3
    wf = w.astype(float)[..., None]
    xz = np.where(w[..., None], x, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (xz * wf).sum(axis=1) / n[:, None]
        cr = (ref[None] * wf).sum(axis=1) / n[:, None]
    dx = (xz - cx[:, None]) * wf
    dr = (ref[None] - cr[:, None]) * wf
    H = np.einsum("fki,fkj->fij", dr, dx)  # reference -> world cross-covariance
    H = np.where(ok[:, None, None], H, np.eye(3))
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    D = np.ones((len(x), 3))
    D[:, 2] = d
    R = np.swapaxes(Vt, -1, -2) @ (D[:, :, None] * np.swapaxes(U, -1, -2))
    t = cx - np.einsum("fij,fj->fi", R, cr)
    fitted = np.einsum("fij,kj->fki", R, ref) + t[:, None]
    err = np.where(w, np.linalg.norm(fitted - xz, axis=2), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt((err**2).sum(axis=1) / n)
    # express the pose about the reference centroid: origin at the shape's centroid
    origin = ref.mean(axis=0)
    p = t + np.einsum("fij,j->fi", R, origin)
    R[~ok] = np.nan
    p[~ok] = np.nan
    rms[~ok] = np.nan
    return ClusterFit(R, p, ok, rms, ref - origin)


def reference_shape(markers: np.ndarray, iterations: int = 3) -> np.ndarray:
    """A cluster's shape in its own frame: generalised Procrustes over the complete frames.

    Args:
        markers: ``(F, K, 3)`` marker positions in world, m (NaN where not seen).

    Raises:
        CalibrationError: when no frame shows every marker of the cluster.
    """
    x = np.asarray(markers, dtype=float)
    full = np.isfinite(x).all(axis=(1, 2))
    if not full.any():
        raise CalibrationError("no frame shows every marker of the cluster: cannot define its shape")
    shape = x[np.flatnonzero(full)[0]] - x[np.flatnonzero(full)[0]].mean(axis=0)
    for _ in range(iterations):
        fit = rigid_fit(shape, x[full])
        local = np.einsum(
            "fji,fkj->fki", fit.R_w_c, x[full] - fit.p_w_c[:, None]
        )  # back to the cluster frame
        shape = np.mean(local, axis=0)
        shape -= shape.mean(axis=0)
    return shape


def group_markers(markers: np.ndarray, *, tol_m: float = 0.002, min_size: int = 3) -> list[list[int]]:
    """Clusters of markers whose mutual distances stay constant.

    Args:
        markers: ``(F, M, 3)`` marker positions, m (NaN where not seen).
        tol_m: largest standard deviation over frames of a distance within one cluster, m.
        min_size: smallest cluster.

    Returns:
        Marker index lists, each sorted, largest cluster first.
    """
    x = np.asarray(markers, dtype=float)
    if x.ndim != 3 or x.shape[2] != 3:
        raise CalibrationInputError(f"Expected markers of shape (frames, markers, 3), got {x.shape}")
    d = np.linalg.norm(x[:, :, None] - x[:, None, :], axis=3)  # (F, M, M)
    with np.errstate(invalid="ignore"):
        spread = np.nanstd(d, axis=0)
        seen = np.isfinite(d).sum(axis=0)
    rigid = (spread < tol_m) & (seen >= 3)
    np.fill_diagonal(rigid, False)
    spread = np.where(rigid, spread, np.inf)
    # greedy cliques: seed with the steadiest remaining pair, add every marker steady with all
    # members (steadiest first), take the group out, repeat
    left = set(range(x.shape[1]))
    groups = []
    while True:
        cand = [(spread[a, b], a, b) for a in left for b in left if a < b and rigid[a, b]]
        if not cand:
            break
        _, a, b = min(cand)
        group = [a, b]
        others = sorted(left - {a, b}, key=lambda k: max(spread[k, g] for g in group))
        for k in others:
            if all(rigid[k, g] for g in group):
                group.append(k)
        left -= set(group)
        if len(group) >= min_size:
            groups.append(sorted(group))
    return sorted(groups, key=lambda g: (-len(g), g[0]))
