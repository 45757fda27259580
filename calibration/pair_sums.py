"""Running sums of the pair statistics over a range of frames (for :mod:`calibration.pairs`).

:func:`calibration.pairs.pair_statistics` keeps one :class:`PairSums` per block of frames; the
layout of the sums and the centring of positions are described in :mod:`calibration.pairs`.
"""

from __future__ import annotations

import numpy as np

_ROW = np.dtype((np.void, 24))  # one row of a 3x3 float64 matrix, moved as a unit


def _rows_by_world_axis(R: np.ndarray, out: np.ndarray) -> None:
    """Copy ``R[f, i, a, :]`` to ``out[f, a, i, :]`` (``(c, n, 3, 3) -> (c, 3, n, 3)``).

    Moving each 24-byte matrix row as one item is about twice as fast as numpy's element-wise
    strided copy; arrays whose rows are not contiguous take the plain path.
    """
    try:
        src = R.view(_ROW)[..., 0]
        dst = out.view(_ROW)[..., 0]
    except ValueError:
        np.copyto(out, R.transpose(0, 2, 1, 3))
        return
    np.copyto(dst, src.transpose(0, 2, 1))


class PairSums:
    """Running sums of the pair statistics over some frames (one block of
    :func:`calibration.pairs.pair_statistics`)."""

    def __init__(self, n: int) -> None:
        m = 4 * n
        self.n = n
        self.full = np.zeros((m, m))  # Gram of [X | P] over the chunks with every pose valid
        self.n_full = 0
        self.gram = np.zeros((3 * n, 3 * n))
        self.cross = np.zeros((3 * n, n))
        self.weighted_self = np.zeros((n, 3 * n))
        self.dot = np.zeros((n, n))
        self.weighted_sq = np.zeros((n, n))
        self.count = np.zeros((n, n))
        self.mean_of_sensors = np.kron(np.ones((n, 1)) / n, np.eye(3))  # (3n, 3)

    def add(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray, XP: np.ndarray) -> None:
        """Add ``c`` frames (``R`` ``(c, n, 3, 3)``, ``p`` ``(c, n, 3)``, ``ok`` ``(c, n)``);
        ``XP`` is a ``(c, 3, 4 n)`` scratch buffer."""
        n, c = self.n, R.shape[0]
        _rows_by_world_axis(R, XP[:, :, : 3 * n].reshape(c, 3, n, 3))
        if ok.all():
            centre = p.reshape(c, 3 * n) @ self.mean_of_sensors  # (c, 3) mean sensor position
            np.subtract(p.transpose(0, 2, 1), centre[:, :, None], out=XP[:, :, 3 * n :])
            flat = XP.reshape(3 * c, 4 * n)
            self.full += flat.T @ flat
            self.n_full += c
            return
        w = ok.astype(float)
        centre = p.sum(axis=1) / np.maximum(w.sum(axis=1), 1.0)[:, None]
        pc = (p - centre[:, None, :]) * w[:, :, None]
        X = XP[:, :, : 3 * n].reshape(3 * c, 3 * n)
        P = pc.transpose(0, 2, 1).reshape(3 * c, n)
        self.gram += X.T @ X
        self.cross += X.T @ P
        Rtp = np.einsum("fiab,fia->fib", R, pc)  # R_i^T p_i per frame, (c, n, 3)
        self.weighted_self += w.T @ Rtp.reshape(c, 3 * n)
        self.dot += P.T @ P
        self.weighted_sq += w.T @ np.einsum("fia,fia->fi", pc, pc)
        self.count += w.T @ w

    def merge(self, other: PairSums) -> PairSums:
        """Add the sums of ``other`` (frames of a neighbouring block) to these; returns ``self``."""
        self.full += other.full
        self.n_full += other.n_full
        self.gram += other.gram
        self.cross += other.cross
        self.weighted_self += other.weighted_self
        self.dot += other.dot
        self.weighted_sq += other.weighted_sq
        self.count += other.count
        return self

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(gram, cross, self_cross, sq_dist, count)``, laid out as
        :class:`calibration.pairs.PairStatistics` holds them."""
        n = self.n
        gram, cross, weighted_self = self.gram.copy(), self.cross.copy(), self.weighted_self.copy()
        dot, weighted_sq, count = self.dot.copy(), self.weighted_sq.copy(), self.count.copy()
        if self.n_full:
            fx = self.full[: 3 * n, 3 * n :]
            gram += self.full[: 3 * n, : 3 * n]
            cross += fx
            own = fx.reshape(n, 3, n)[np.arange(n), :, np.arange(n)]  # (n, 3): sum R_i^T p_i
            weighted_self += own.reshape(1, 3 * n)
            fp = self.full[3 * n :, 3 * n :]
            dot += fp
            weighted_sq += np.diagonal(fp)[None, :]
            count += self.n_full
        sq_i = weighted_sq.T  # [i, j] = sum w_i w_j |p_i|^2
        return (
            gram.reshape(n, 3, n, 3).transpose(0, 2, 1, 3),
            cross.reshape(n, 3, n).transpose(0, 2, 1),
            weighted_self.reshape(n, n, 3).transpose(1, 0, 2),
            sq_i + sq_i.T - 2.0 * dot,
            np.rint(count).astype(np.int64),
        )
