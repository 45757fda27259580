"""Running sums of the pair statistics over a range of frames (for :mod:`calibration.pairs`).

:func:`calibration.pairs.pair_statistics` keeps one :class:`PairSums` per block of frames; the
layout of the sums and the centring of positions are described in :mod:`calibration.pairs`.
"""

from __future__ import annotations

import functools

import numpy as np

from calibration.pair_noise import THIRD_DIFFERENCE_GAIN

_ROW = np.dtype((np.void, 24))  # one row of a 3x3 float64 matrix, moved as a unit


def rows_by_world_axis(R: np.ndarray, out: np.ndarray) -> None:
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


@functools.cache
def _mean_of_sensors(n: int) -> np.ndarray:
    """``(3 n, 3)``: a frame's flattened positions times it is their mean over the sensors."""
    out = np.kron(np.ones((n, 1)) / n, np.eye(3))
    out.flags.writeable = False
    return out


def lay_out(R: np.ndarray, p: np.ndarray, XP: np.ndarray) -> np.ndarray:
    """``[X | P]`` of ``c`` frames with every pose valid, into ``XP`` ``(c, 3, 4 n)`` (returned):
    for each frame and world axis ``a``, row ``a`` of every sensor's rotation, then every sensor's
    position component ``a`` less the sensors' mean (the centring of :mod:`calibration.pairs`)."""
    c, n = R.shape[:2]
    rows_by_world_axis(R, XP[:, :, : 3 * n].reshape(c, 3, n, 3))
    centre = p.reshape(c, 3 * n) @ _mean_of_sensors(n)  # (c, 3) mean sensor position
    np.subtract(p.transpose(0, 2, 1), centre[:, :, None], out=XP[:, :, 3 * n :])
    return XP


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

    def add(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray, XP: np.ndarray) -> None:
        """Add ``c`` frames (``R`` ``(c, n, 3, 3)``, ``p`` ``(c, n, 3)``, ``ok`` ``(c, n)``);
        ``XP`` is a ``(c, 3, 4 n)`` scratch buffer."""
        n, c = self.n, R.shape[0]
        if ok.all():
            self.add_laid_out(lay_out(R, p, XP))
            return
        rows_by_world_axis(R, XP[:, :, : 3 * n].reshape(c, 3, n, 3))
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

    def add_laid_out(self, XP: np.ndarray) -> None:
        """Add ``c`` frames with every pose valid, laid out by :func:`lay_out` (``(c, 3, 4 n)``)."""
        flat = XP.reshape(-1, 4 * self.n)
        self.full += flat.T @ flat
        self.n_full += XP.shape[0]

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


def block_results(sums: list[PairSums], first: np.ndarray) -> tuple[np.ndarray, ...]:
    """:meth:`PairSums.result` of blocks of consecutive pieces, each ``(B, ...)``: block ``b`` is
    ``sums[first[b]:first[b + 1]]`` merged (none: zero), all blocks computed at once."""
    n = sums[0].n
    first = np.asarray(first, dtype=np.int64)
    empty = first[1:] == first[:-1]

    def blocks(x: np.ndarray) -> np.ndarray:  # (K, ...) per piece -> (B, ...) per block
        out = np.zeros((first.size - 1, *x.shape[1:]))
        for b in np.flatnonzero(~empty):  # (numpy.add.reduceat is slower along a first axis)
            out[b] = x[first[b] : first[b + 1]].sum(axis=0)
        return out

    full = blocks(np.stack([s.full for s in sums]))
    n_full = blocks(np.array([float(s.n_full) for s in sums]))
    gram, cross, weighted_self, dot, weighted_sq, count = (
        blocks(np.stack([getattr(s, name) for s in sums]))
        for name in ("gram", "cross", "weighted_self", "dot", "weighted_sq", "count")
    )
    fx = full[:, : 3 * n, 3 * n :]
    gram += full[:, : 3 * n, : 3 * n]
    cross += fx
    own = np.einsum("kiai->kia", fx.reshape(-1, n, 3, n))  # (B, n, 3): sum R_i^T p_i
    weighted_self += own.reshape(-1, 1, 3 * n)
    fp = full[:, 3 * n :, 3 * n :]
    dot += fp
    weighted_sq += np.diagonal(fp, axis1=1, axis2=2)[:, None, :]
    count += n_full[:, None, None]
    sq_i = weighted_sq.transpose(0, 2, 1)  # [i, j] = sum w_i w_j |p_i|^2
    return (
        gram.reshape(-1, n, 3, n, 3).transpose(0, 1, 3, 2, 4),
        cross.reshape(-1, n, 3, n).transpose(0, 1, 3, 2),
        weighted_self.reshape(-1, n, n, 3).transpose(0, 2, 1, 3),
        sq_i + weighted_sq - 2.0 * dot,
        np.rint(count).astype(np.int64),
    )


def third_difference(x: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out[f] = x[f+3] - 3 x[f+2] + 3 x[f+1] - x[f]`` along the first axis (``len(x) - 3`` rows),
    as :func:`numpy.diff` with ``n=3`` gives it, without its intermediate arrays."""
    np.subtract(x[1:-2], x[2:-1], out=out)
    out *= 3.0
    out += x[3:]
    out -= x[:-3]
    return out


class ThirdDifferenceSums:
    """Sums over frames of the third-differenced poses: the misfit hierarchy's noise
    (:mod:`calibration.pair_noise`) as a quadratic form in each pair's joint.

    The residual's third difference is linear in the joint, ``D3 e = D3 A x - D3 b``, so
    ``sum |D3 e|^2`` needs only the pair statistics of the third-differenced poses
    (:class:`PairSums`) and each sensor's own ``sum D3R_i^T D3R_i`` weighted by the pair's
    validity; a third difference counts where both sensors are valid in all four of its frames.
    Frames are added in order, in chunks of any size (three carry over to the next chunk), so the
    batch calibration fills it in its one pass over the data and the streaming one as frames come.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.sums = PairSums(n)
        self.self_gram = np.zeros((n, n, 9))  # [i, j] sum w_i w_j D3R_i^T D3R_i (chunks with gaps)
        self.carry: tuple[np.ndarray, ...] | None = None  # the last 3 frames added
        self.carry_laid: np.ndarray | None = None  # and laid out, when the last chunk was

    def add(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray, laid_out: np.ndarray | None = None) -> None:
        """Add the next ``c`` frames (``R`` ``(c, n, 3, 3)``, ``p`` ``(c, n, 3)``, ``ok`` ``(c, n)``,
        invalid poses zeroed). ``laid_out``: the frames' ``[X | P]`` (:func:`lay_out`) when every
        pose is valid and the caller has it; their third differences are then taken of it (the
        layout is linear and the centring a shift per frame, which third differences keep)."""
        chunk = (R, p, ok)
        c = R.shape[0]
        # the third differences that straddle the previous chunk (its last 3 frames, our first 3)
        # join ours in one product when both chunks were laid out; else they are added alone
        carry_laid, self.carry_laid = self.carry_laid, None
        joined = laid_out is not None and carry_laid is not None and c >= 3
        if self.carry is not None and not joined:
            self._add(*(np.concatenate([a, b[:3]]) for a, b in zip(self.carry, chunk, strict=True)))
        if c >= 3 or self.carry is None:
            self.carry = tuple(b[-3:].copy() for b in chunk)
        else:
            self.carry = tuple(np.concatenate([a, b])[-3:] for a, b in zip(self.carry, chunk, strict=True))
        if laid_out is None:
            self._add(R, p, ok)
            return
        if c >= 3:
            self.carry_laid = laid_out[-3:].copy()
        if joined:
            assert carry_laid is not None
            d3 = np.empty_like(laid_out)
            third_difference(np.concatenate([carry_laid, laid_out[:3]]), d3[:3])
            third_difference(laid_out, d3[3:])
            self.sums.add_laid_out(d3)
        elif c > 3:
            self.sums.add_laid_out(third_difference(laid_out, np.empty_like(laid_out[3:])))

    def _add(self, R: np.ndarray, p: np.ndarray, ok: np.ndarray) -> None:
        c = R.shape[0] - 3
        if c < 1:
            return
        d3R = third_difference(R, np.empty((c, *R.shape[1:])))
        d3p = third_difference(p, np.empty((c, *p.shape[1:])))
        ok4 = ok[3:] & ok[2:-1] & ok[1:-2] & ok[:-3]
        if not ok4.all():
            d3R[~ok4] = 0.0
            d3p[~ok4] = 0.0
            w = ok4.astype(float)
            own = np.einsum("fsai,fsaj->fsij", d3R, d3R).reshape(c, self.n * 9)  # invalid rows are zero
            self.self_gram += (w.T @ own).reshape(self.n, self.n, 9).transpose(1, 0, 2)
        # with every pose valid the own products are the diagonal blocks of PairSums.full
        self.sums.add(d3R, d3p, ok4, np.empty((c, 3, 4 * self.n)))

    def noise_variance(
        self, parent: np.ndarray, child: np.ndarray, joint_in_parent: np.ndarray, joint_in_child: np.ndarray
    ) -> np.ndarray:
        """``(P,)`` the noise variance of each pair's residual for the given joints (as
        :func:`calibration.pair_noise.pair_noise_variance` computes it from the frames), in the
        positions' unit squared; 0 for a pair with no four consecutive valid frames."""
        n = self.n
        gram, cross, self_cross, sq_dist, count = self.sums.result()
        self_gram = self.self_gram
        if self.sums.n_full:
            diag = self.sums.full[: 3 * n, : 3 * n].reshape(n, 3, n, 3)[np.arange(n), :, np.arange(n)]
            self_gram = self_gram + diag.reshape(n, 1, 9)  # (n, 3, 3) per sensor, every pair
        parent, child = np.asarray(parent, dtype=np.int64), np.asarray(child, dtype=np.int64)
        lp, lc = np.asarray(joint_in_parent, dtype=float), np.asarray(joint_in_child, dtype=float)
        g = gram[parent, child]  # (P, 3, 3) sum D3R_p^T D3R_c
        sp = self_gram[parent, child].reshape(-1, 3, 3)
        sc = self_gram[child, parent].reshape(-1, 3, 3)
        quad = (
            np.einsum("pi,pij,pj->p", lp, sp, lp)
            + np.einsum("pi,pij,pj->p", lc, sc, lc)
            - 2.0 * np.einsum("pi,pij,pj->p", lp, g, lc)
        )
        h_p = cross[parent, child] - self_cross[parent, child]
        h_c = cross[child, parent] - self_cross[child, parent]
        lin = np.einsum("pi,pi->p", lp, h_p) + np.einsum("pi,pi->p", lc, h_c)
        total = quad - 2.0 * lin + sq_dist[parent, child]
        used = count[parent, child].astype(float)
        return np.where(
            used > 0, np.clip(total, 0.0, None) / np.maximum(used, 1.0) / THIRD_DIFFERENCE_GAIN, 0.0
        )
