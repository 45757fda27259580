"""How much of each pair's joint-fit residual is measurement noise (for the misfit hierarchy).

A pair's residual (O'Brien eq. 13) mixes two things: the *misfit* of the joint model -- zero for
an ideal joint, centimetres between two bodies that share no joint -- and the *noise* of both
sensors. Trackers are not equally noisy everywhere: a magnetic tracker's position noise grows as
about the fourth power of the distance to its transmitter (docs/conventions.md), so in a walk the sensors
furthest out carry several times the noise of the others. A minimum spanning tree of raw residuals
then favours the quiet sensors: their pairs fit "well" whether or not they are joints.

The noise is read off the residual itself. A joint's misfit follows the motion, which is smooth at
the capture rate; the noise changes from frame to frame. The third difference of the residual
series, ``e[f+3] - 3 e[f+2] + 3 e[f+1] - e[f]``, is zero for anything quadratic over four frames
and keeps ``1 + 9 + 9 + 1 = 20`` times the variance of white noise, so

    noise variance  =  mean over frames of |third difference of e|^2  /  20,

in the same unit as the mean square residual (length squared): the two compare without any
scale. Noise that is correlated from frame to frame (a tracker's own filter, a tracker sampling
slower than the capture) is underestimated; the misfit then keeps part of it, and the misfit tree
moves towards O'Brien's tree, never past it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from calibration.poses import CHUNK_FRAMES, check_poses, iter_chunks

#: The sum of the third difference's squared coefficients (1, -3, 3, -1): the variance of the
#: third difference of white noise over the noise's own variance.
THIRD_DIFFERENCE_GAIN = 20.0

#: Bytes of residuals worked on at a time (a chunk of frames is cut shorter when many pairs are
#: asked for).
WORK_BYTES = 2 << 20


def pair_noise_variance(
    R_w_s: Any,
    p_w_s: Any,
    parent: np.ndarray,
    child: np.ndarray,
    joint_in_parent: np.ndarray,
    joint_in_child: np.ndarray,
    *,
    valid: Any = None,
    chunk_frames: int = CHUNK_FRAMES,
) -> np.ndarray:
    """The white-noise variance of each given joint's residual, from its third differences.

    One pass over the data, chunk by chunk (the last three frames of a chunk carry over to the
    next); a third difference is used where both sensors are valid in all four of its frames.

    Args:
        R_w_s: ``(frames, sensors, 3, 3)`` rotations, sensor to world.
        p_w_s: ``(frames, sensors, 3)`` positions in world, metres (any length unit).
        parent: ``(P,)`` parent sensor index of each pair.
        child: ``(P,)`` child sensor index of each pair.
        joint_in_parent: ``(P, 3)`` each pair's fitted joint centre in the parent sensor frame,
            in the unit of ``p_w_s``.
        joint_in_child: ``(P, 3)`` the same centre in the child sensor frame.
        valid: optional ``(frames, sensors)`` bool mask; non-finite poses are always invalid.
        chunk_frames: frames per chunk.

    Returns:
        ``(P,)`` noise variance of the 3-D residual (the expected ``|e|^2`` noise adds), in the
        unit of ``p_w_s`` squared; 0 for a pair with no four consecutive valid frames.
    """
    _, n = check_poses(R_w_s, p_w_s, valid)
    parent = np.asarray(parent, dtype=np.int64)
    child = np.asarray(child, dtype=np.int64)
    n_pairs = parent.shape[0]
    rotated = _Rotated(n, parent, child, joint_in_parent, joint_in_child)
    # frames a slice at a time, so that the work arrays stay near WORK_BYTES however many pairs
    # (the 496 pairs of 32 sensors are 1,488 residual components a frame)
    step = max(4, WORK_BYTES // (24 * max(n_pairs, 1)))
    total = np.zeros(n_pairs)
    used = np.zeros(n_pairs)
    carry: tuple[np.ndarray, np.ndarray] | None = None  # residuals and validity of the last 3 frames
    for _, R_chunk, p_chunk, ok_chunk in iter_chunks(R_w_s, p_w_s, valid, chunk_frames=chunk_frames):
        for start in range(0, R_chunk.shape[0], step):
            R, p, ok = (x[start : start + step] for x in (R_chunk, p_chunk, ok_chunk))
            # O'Brien eq. 8 for each pair, pair-major: R_p l_p + p_p - R_c l_c - p_c, (P, c, 3)
            e = rotated(R)
            p_t, ok_t = p.transpose(1, 0, 2), ok.T
            e += p_t[parent]
            e -= p_t[child]
            both = ok_t[parent] & ok_t[child]  # (P, c)
            if carry is not None:
                e, both = np.concatenate([carry[0], e], axis=1), np.concatenate([carry[1], both], axis=1)
            if e.shape[1] >= 4:
                d3 = np.diff(e, n=3, axis=1)  # (P, c - 3, 3)
                usable = both[:, :-3] & both[:, 1:-2] & both[:, 2:-1] & both[:, 3:]
                d3[~usable] = 0.0
                total += np.einsum("pfk,pfk->p", d3, d3)
                used += np.count_nonzero(usable, axis=1)
            carry = (e[:, -3:], both[:, -3:])
    return np.where(used > 0, total / np.maximum(used, 1.0) / THIRD_DIFFERENCE_GAIN, 0.0)


class _Rotated:
    """``R_p l_p - R_c l_c`` of every pair from a slice of rotations, pair-major ``(P, c, 3)``.

    Each sensor's rotations multiply the centres of all its pairs at once (one batched product
    over the sensors, the centres padded to the most pairs a sensor has), and each pair then
    takes its two rows: no product with a dense operator that is almost all zeros, no scatter.
    """

    def __init__(
        self,
        n: int,
        parent: np.ndarray,
        child: np.ndarray,
        joint_in_parent: np.ndarray,
        joint_in_child: np.ndarray,
    ) -> None:
        lp = np.asarray(joint_in_parent, dtype=float).reshape(-1, 3)
        lc = np.asarray(joint_in_child, dtype=float).reshape(-1, 3)
        count = np.zeros(n, dtype=np.int64)
        self.slot = np.zeros((2, parent.size), dtype=np.int64)  # each pair's row in its sensors' products
        for side, sensors in enumerate((parent, child)):
            for k, s in enumerate(sensors):
                self.slot[side, k] = count[s]
                count[s] += 1
        self.centres = np.zeros((n, max(int(count.max(initial=0)), 1), 3))  # (n, m, 3), signed
        self.centres[parent, self.slot[0]] = lp
        self.centres[child, self.slot[1]] = -lc
        self.parent, self.child = parent, child

    def __call__(self, R: np.ndarray) -> np.ndarray:
        c, n = R.shape[:2]
        by_sensor = R.transpose(1, 3, 0, 2).reshape(n, 3, 3 * c)  # [s, b, (f, a)] = R[f, s, a, b]
        products = self.centres @ by_sensor  # (n, m, 3c): each sensor's R l for all its pairs
        out = products[self.parent, self.slot[0]] + products[self.child, self.slot[1]]  # (P, 3c)
        return out.reshape(-1, c, 3)
