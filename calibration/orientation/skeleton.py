"""Skeleton-aware sourceless orientation: every segment at once, over the whole recording.

Fontaine et al. name the per-sample method's limit (linear acceleration at the end of a limb)
and its remedy ("human models and constraints"). Here the orientations ``R_k(t)`` of all ``N``
sensors over all frames are the unknowns of one least-squares problem. With the skeleton from a
calibration (each joint located in its parent's and its child's sensor frame, O'Brien et al.)
the accelerometers need not point up: a joint's acceleration is the same seen from both sides,

    R_p f_p + d2/dt2 (R_p l_p)  =  R_c f_c + d2/dt2 (R_c l_c)        (world frame, m/s^2)

with ``f`` the measured specific forces and ``l_p``, ``l_c`` the joint in the parent's and the
child's sensor frame: gravity cancels, and each sensor's linear acceleration is what the chain's
motion (the second derivative of the joint positions the orientations give) makes it. Gravity
enters through the roots, whose acceleration is small (a prior). The residuals, each divided by
its prior standard deviation (:class:`Priors`):

- magnetometer: ``R_k m_k / |m_k| - b_w`` (the field's direction; 2 degrees of freedom);
- root: ``R_r f_r - g up_w`` (the root's own acceleration, a zero-mean prior);
- joint: the equation above, second derivatives by central differences;
- smoothness: the change of each sensor's angular increment ``log(R(t+1) R(t)^T)`` from one frame
  to the next (its angular acceleration, a zero-mean prior): across a span where the data say
  little (a magnetic disturbance, a gap) the orientation is carried from the span's ends.

**A sensor on its own** (a root with no children: a hand-held IMU, or every sensor when there is
no skeleton) has nothing to predict its linear acceleration, and a white prior on it (the body
root's) calls a sustained acceleration a tilt. It moves as a body does: its velocity ``V``
changes by its linear acceleration, ``(V(t) - V(t-1)) / dt = R f - g up`` (a residual of
:attr:`Priors.lone_acc`), and its speed has a zero-mean prior (:attr:`Priors.lone_speed`, 3 m/s):
a tilt error makes a velocity that grows without end, so the velocity's bound holds the tilt
over the seconds that the linear acceleration averages out. ``V`` is solved with the
orientations (three more unknowns per lone sensor and frame). Measured, against the white
prior: BROAD's 22 public trials 0.21-0.87 x TRIAD (were 0.28-0.95; the stationary-magnet trials
30 and 31 0.23 and 0.22, were 0.62 and 0.64), the fast-rotation trials 07 and 09 worse (0.35
and 0.51, were 0.28 and 0.33); humanoid without a skeleton, 30 s, ``mems-industrial``:
exercise 9.8 degrees (was 17.7), gait 16.2 (was 33.9). A body's root keeps the white prior:
with the velocity model instead, the humanoid exercise went from 1.58 to 2.42 degrees and gait
from 3.3 to 11.2 (a pelvis accelerates little). The two priors were not tuned to BROAD: with
either halved or doubled (1.5 or 6 m/s, 1 or 4 m/s^2) the 22 trials' mean ratio to TRIAD is
0.40-0.46 (0.43 as set, 0.59 with the white prior) and every magnet trial stays below its
white-prior figure; single trials move by up to 0.3 x TRIAD (the problem is not convex).

**Joint ranges.** A skeleton may carry each joint's range of motion (:attr:`Skeleton.range_rad`,
e.g. from a calibration session's tracker poses, :meth:`Skeleton.with_ranges`): a cone about a
centre rotation of the child's frame in the parent's. A joint beyond it costs its excess angle
(``log(C^T R_p^T R_c)`` scaled back to the cone's surface, :attr:`Priors.beyond_range_rad`);
inside it costs nothing. It holds on the last level only, as the hinges. Measured, 30 s, on the
skeleton calibrated from the session's tracker poses and the ranges those poses show: gait
4.07 -> 2.79 degrees, exercise 1.56 -> 1.55; the chicken walk 35 -> 52 (its starts settle in
wrong minima either way).

**Clipped accelerometers.** An accelerometer axis at its range (``acc_clipped``: a consumer
unit at +-2 g on a limb) reports the range, not the specific force, which is beyond it. Held at
the range, the axis's shortfall enters every joint of the sensor. Left out with its sample's
accelerometer, a span that clips for long is carried by the magnetometer alone. Instead the
axis is an unknown bounded by the range: at given orientations the value its rows (root, lone
velocity, joints) ask of it, where that is beyond the range (:meth:`_Problem.filled`; sensor by
sensor, so that a joint clipped on both sides is not explained twice). On the levels the axes
are taken as measured (from a start far off, the free axis lets a wrong orientation explain its
joint: on every level, an analytic chain whose tip clips 25 % of its samples was 10.7 degrees
off); after the mix of the starts the last level is solved once more with them filled.
Measured on that chain with the tip clipping 11, 25 and 45 % of its samples (1.6, 1.4 and
1.2 g): 0.97, 1.6 and 3.4 degrees overall (held at the range 2.3, 5.3 and 10.2; the
accelerometer left out where it clips 0.8, 1.2 and 19.9); ``mems-consumer`` humanoid, 30 s, on
the calibrated skeleton with ranges: exercise 8.6 -> 7.9, gait 8.9 (unchanged), the chicken
walk (17 % of its samples clip) 22.9 -> 12.2.

**Solver.** Levenberg-Marquardt on left perturbations ``R <- exp([d]x) R``. Frames couple only
to their neighbours, so with the unknowns ordered frame by frame the normal equations are a band
matrix (half-bandwidth ``9N - 1``), solved by banded Cholesky (LAPACK ``pbtrf``): the cost is
linear in the number of frames. To reach the right minimum from the per-sample estimate (which
is tens of degrees off where limbs accelerate), the problem is solved coarse to fine in time
(:data:`LEVELS_HZ`: first at 5 Hz on inputs low-passed at 2 Hz, then at 10 and 20 Hz on inputs
low-passed at 4 and 8 Hz, each level started from the previous one); the result is interpolated
(slerp) to every sample. The coarse start matters: measured on the humanoid exercise, levels
(5, 20) Hz reach 3.3 degrees, (5, 10, 20) 1.4, (10, 20) 12.3 -- the problem is not convex, and
from a poor start in a violently moving span the solve can settle in a wrong minimum.

**Several starts.** No one schedule of levels finds the right minimum on every motion. In gait
(:mod:`simbench.sim.programs`, ``gait``: the feet swing at 2-2.5 g) the legs settle 30-40
degrees off from the per-sample start at 5 Hz, and come within 5-14 degrees when the solve first
finds each segment's mean orientation at 0.625-2.5 Hz, below the stride rate; on the humanoid
exercise those coarse starts end at 3.2-3.8 degrees, the 5 Hz start at 1.6. Each start settles
right in some spans and wrong in others. So the problem is solved from each of :data:`STARTS`,
and all end on the same last level, whose cost (the criterion the estimate minimises) compares
them: in every :data:`COMBINE_S` window each sensor takes the solution that costs least on it
there (each residual's cost shared among the sensors it involves, :func:`_sensor_costs`), and
the last level is solved once more from that mix (its seams cost a few iterations). Measured,
30 s at 120 Hz, ``mems-industrial``, true skeleton: gait 17.9 (5 Hz start alone), 5.1 and 5.0
(each coarse start alone), 3.5 degrees mixed (3.4 from the truth); exercise 1.56 (unchanged);
on the calibrated skeleton, gait 18.4, 6.0 and 9.4 alone, 4.1 mixed window by window for all
sensors at once, 3.1 sensor by sensor. In the chicken ``walk`` every start settles wrong
somewhere, each in other limbs: mixed for all sensors at once 35.4 degrees (calibrated
skeleton), 51.7 (with ranges), 19.1 (true skeleton); sensor by sensor 32.7, 6.6 and 9.2 (100 Hz,
other seeds, true skeleton: 6.7 -> 5.2, 5.1 -> 4.8); ``mems-consumer``'s walk, its iron
calibrated from the session, 32.0 -> 24.5 (calibrated skeleton), 26.0 -> 24.0 (true skeleton).
A residual's cost counts at the frame of its first block (a smoothness row spans three frames):
split among its blocks' frames instead, the consumer's walk on the true skeleton was 41.9, BROAD
trial 36 16.7 (13.9). Three starts cost three times one (``starts=((),)`` for one).

**Trees.** The skeleton's trees (a root and its descendants; every sensor is one without a
skeleton) share no residual, so each is solved on its own (:meth:`Skeleton.trees`): a sensor's
estimate does not depend on what else the recording holds, and the banded solve, whose cost goes
as the cube of the sensors solved together, is the cheaper: the humanoid's 16 sensors without a
skeleton, 30 s, 19 -> 4 s. Against one solve of them all (a shared damping, starts mixed
window by window for all sensors at once) the figures moved by chance in single sensors, as a
non-convex problem does: exercise 8.1 -> 9.8 degrees (the head 26 -> 34), gait 14.7 -> 16.2
(a hand 20 -> 34), the chicken walk 64.1 -> 61.0, ``mems-consumer`` exercise 22.5 -> 22.4, gait
21.5 -> 24.0, walk 67.4 -> 65.4.

Long recordings are solved in overlapping segments (:data:`SEGMENT_S`), so memory does not grow
with the recording.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.lapack import dpbsv
from scipy.ndimage import maximum_filter1d
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee
from threadpoolctl import threadpool_limits

from calibration.errors import CalibrationInputError
from calibration.orientation.disturbance import Weighting, smooth_vectors
from calibration.orientation.gauss_newton import fontaine
from calibration.orientation.world import (
    Estimate,
    Reference,
    measured_directions,
    quat_where,
    reference_from_data,
)
from calibration.rotations import matrix_to_rotvec, quat_to_matrix, rotvec_to_matrix, skew

#: The levels' rates, Hz, coarse to fine; each level's inputs are low-passed at 0.4 times its
#: rate (0.8 of its Nyquist frequency).
LEVELS_HZ = (5.0, 10.0, 20.0)

#: The solves' coarser levels, Hz, each taken before :data:`LEVELS_HZ` (module docstring).
STARTS: tuple[tuple[float, ...], ...] = ((), (1.25, 2.5), (0.625, 1.25, 2.5))

#: Window over which the two starts' solutions are compared, s (module docstring).
COMBINE_S = 2.0

#: Longest span solved at once, s; longer recordings are cut into segments that overlap by
#: :data:`OVERLAP_S` and are joined in the middle of the overlap.
SEGMENT_S = 120.0
OVERLAP_S = 10.0

#: Fewest frames a segment holds, whatever the rate: a recording labelled with a rate far too low
#: (0.01 Hz for a 100 Hz IMU) is not cut into thousands of tiny solves.
MIN_SEGMENT_FRAMES = 512

#: BLAS threads the solve runs on (restored after it). The banded Cholesky's blocks are small
#: (half-bandwidth about 110), where a threaded BLAS only waits on itself: measured on two cores,
#: the humanoid's 16 sensors, true skeleton, 60 s at 100 Hz: 11.7 s on one thread, 22.0 s on two;
#: 20 s on the calibrated skeleton 4.0 s and 8.5 s. (The command line and the test suite ran on one
#: thread already; the Python API's callers did not.)
BLAS_THREADS = 1

#: Placements the search for a narrower order of the unknowns (:func:`_band_slots`) tries at
#: most, over all the widths it tries (the 16-sensor humanoid's takes 900; a random tree of 1,000
#: sensors gives up in 0.1 s).
NARROW_SEARCH_STEPS = 5000

#: Frames read at once by :meth:`Skeleton.with_ranges`.
RANGE_CHUNK = 65536


#: Departures of the field strength or dip beyond this many robust standard deviations of the
#: sensor's own halve a magnetometer sample's weight (a Cauchy weight): at 3, a Gaussian sample
#: loses more than half its weight once in 370.
DISTURBANCE_C = 3.0


@dataclass(frozen=True)
class Priors:
    """Standard deviations of the residuals (module docstring): what each is expected to be.

    Attributes:
        mag_rad: the measured field's direction, rad (sensor noise and small disturbances).
        joint_acc: the joint equation, m/s^2 (accelerometer noise, skin motion, a skeleton
            that is not exact).
        root_acc: a body's root's own acceleration, m/s^2, at least (a standing or walking
            person's pelvis: 0.1-0.4 m/s^2 RMS in simbench's humanoid). Each root's is raised to
            the RMS of ``|f| - g`` over its samples where that is larger. A sensor on its own
            (no children) has the velocity model instead (:attr:`lone_speed`), unless that is
            ``None``.
        angular_acc: each sensor's angular acceleration, rad/s^2 per axis (the humanoid's
            segments: 5-25 rad/s^2 RMS at 20 Hz; the prior is loose so as not to flatten real
            motion).
        hinge_rad: a hinge's axis seen from its two sensors, rad (the axis a calibration
            finds, and the play of a real hinge).
        lone_speed: a sensor on its own (a root with no children: a hand-held IMU, or every
            sensor when there is no skeleton), its speed, m/s: a zero-mean prior on the
            velocity its linear acceleration integrates to. ``None``: the root acceleration
            prior instead (:attr:`root_acc`), as for a body's root.
        lone_acc: a lone sensor's velocity change against its measured linear acceleration
            ``R f - g up``, m/s^2 (accelerometer noise and bias, vibration, taps, and the
            level's low-pass).
        beyond_range_rad: a joint's excess angle beyond its range of motion
            (:attr:`Skeleton.range_rad`), rad.
    """

    mag_rad: float = 0.05
    joint_acc: float = 0.3
    root_acc: float = 0.5
    angular_acc: float = 60.0
    hinge_rad: float = 0.02
    lone_speed: float | None = 3.0
    lone_acc: float = 2.0
    beyond_range_rad: float = 0.02

    def __post_init__(self) -> None:
        for name in (f.name for f in dataclasses.fields(self)):
            v = getattr(self, name)
            if name == "lone_speed" and v is None:
                continue
            if not (np.isfinite(v) and v > 0):
                raise CalibrationInputError(f"Priors.{name} must be > 0, got {v}")


@dataclass(frozen=True)
class Skeleton:
    """The body's tree over sensors and its joints, as a calibration gives them.

    Attributes:
        parent: ``(N,)`` parent index of each sensor, ``-1`` for a root (several roots: a
            forest; all ``-1``: no skeleton).
        joint_in_parent: ``(N, 3)`` for each child sensor, its inboard joint in the parent
            sensor's frame, m (roots' rows ignored).
        joint_in_child: ``(N, 3)`` the same joint in the child sensor's own frame, m.
        hinge_in_parent, hinge_in_child: optional ``(N, 3)``: for a child whose joint is a
            hinge (a calibration's single-axis joint), the axis in the parent's and in the
            child's sensor frame (unit vectors, ``R_p a_p = R_c a_c``); zero rows for the other
            joints. A hinge leaves the child one angle about the axis: the estimator holds the
            axis common to both sensors (a residual with :attr:`Priors.hinge_rad`).
        range_centre, range_rad: optional ``(N, 3, 3)`` and ``(N,)``: each joint's range of
            motion as a cone, the child's sensor frame in the parent's (``R_p^T R_c``) within
            ``range_rad`` of ``range_centre`` (e.g. as a calibration session's poses show it,
            :meth:`with_ranges`); ``inf`` for a joint without a range, roots' rows ignored. A
            joint beyond its range costs its excess angle over :attr:`Priors.beyond_range_rad`.
    """

    parent: np.ndarray
    joint_in_parent: np.ndarray
    joint_in_child: np.ndarray
    hinge_in_parent: np.ndarray | None = None
    hinge_in_child: np.ndarray | None = None
    range_centre: np.ndarray | None = None
    range_rad: np.ndarray | None = None

    def __post_init__(self) -> None:
        parent = np.asarray(self.parent)
        n = parent.shape[0] if parent.ndim == 1 else -1
        if parent.ndim != 1 or not np.issubdtype(parent.dtype, np.integer):
            raise CalibrationInputError(
                f"Expected parent as (N,) integers, got {parent.dtype} {parent.shape}"
            )
        if np.any((parent < -1) | (parent >= n)) or np.any(parent == np.arange(n)):
            raise CalibrationInputError(
                f"parent indices must be -1 or another sensor in [0, {n}), got {parent}"
            )
        for name in ("joint_in_parent", "joint_in_child"):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (n, 3) or not np.isfinite(arr).all():
                raise CalibrationInputError(f"Expected {name} as ({n}, 3) finite numbers, got {arr.shape}")
        hinges = (self.hinge_in_parent, self.hinge_in_child)
        if (hinges[0] is None) != (hinges[1] is None):
            raise CalibrationInputError("give both hinge_in_parent and hinge_in_child, or neither")
        if hinges[0] is not None:
            a_p, a_c = (np.asarray(h, dtype=float) for h in hinges)
            if (
                a_p.shape != (n, 3)
                or a_c.shape != (n, 3)
                or not (np.isfinite(a_p).all() and np.isfinite(a_c).all())
            ):
                raise CalibrationInputError(
                    f"Expected hinge_in_parent and hinge_in_child as ({n}, 3) finite numbers, "
                    f"got {a_p.shape} and {a_c.shape}"
                )
            norms = np.stack([np.linalg.norm(a_p, axis=1), np.linalg.norm(a_c, axis=1)])
            unit_or_zero = (np.abs(norms - 1) < 1e-6) | (norms == 0)
            if not unit_or_zero.all() or np.any((norms[0] == 0) != (norms[1] == 0)):
                raise CalibrationInputError(
                    "hinge axes must be unit vectors in both frames (or zero in both for a joint that "
                    "is no hinge)"
                )
            if np.any((norms[0] > 0) & (parent < 0)):
                raise CalibrationInputError("a root has no inboard joint, so no hinge axis")
        if (self.range_centre is None) != (self.range_rad is None):
            raise CalibrationInputError("give both range_centre and range_rad, or neither")
        if self.range_centre is not None:
            C = np.asarray(self.range_centre, dtype=float)
            r = np.asarray(self.range_rad, dtype=float)
            if C.shape != (n, 3, 3) or r.shape != (n,):
                raise CalibrationInputError(
                    f"Expected range_centre as ({n}, 3, 3) and range_rad as ({n},), got {C.shape} and "
                    f"{r.shape}"
                )
            if (
                not np.isfinite(C).all()
                or np.any(np.abs(C @ np.swapaxes(C, -1, -2) - np.eye(3)) > 1e-6)
                or np.any(np.linalg.det(C) < 0)
            ):
                raise CalibrationInputError("range_centre must hold rotation matrices")
            if np.any(np.isnan(r) | (r <= 0)):
                raise CalibrationInputError(f"range_rad must be > 0 (inf: no range), got {r}")
        # every sensor reaches a root: no cycles
        for k in range(n):
            seen, j = 0, k
            while parent[j] >= 0:
                j, seen = parent[j], seen + 1
                if seen > n:
                    raise CalibrationInputError(f"parent indices form a cycle through sensor {k}")

    def permuted(self, order: np.ndarray) -> Skeleton:
        """The same skeleton over the sensors reordered: new sensor ``i`` is old ``order[i]``.
        ``order`` may leave sensors out (e.g. one tree of a forest) if it keeps every kept
        sensor's parent."""
        order = np.asarray(order, dtype=int)
        parent = np.asarray(self.parent)
        kept = np.zeros(parent.size, dtype=bool)
        kept[order] = True
        if np.unique(order).size != order.size or not np.all(kept[parent[order][parent[order] >= 0]]):
            raise CalibrationInputError("a reordered skeleton needs distinct sensors and their parents")
        new_of_old = np.full(parent.size, -1)
        new_of_old[order] = np.arange(order.size)
        old_parent = parent[order]
        hinge = [
            None if h is None else np.asarray(h)[order] for h in (self.hinge_in_parent, self.hinge_in_child)
        ]
        ranges = [None if x is None else np.asarray(x)[order] for x in (self.range_centre, self.range_rad)]
        return Skeleton(
            np.where(old_parent >= 0, new_of_old[np.maximum(old_parent, 0)], -1),
            np.asarray(self.joint_in_parent)[order],
            np.asarray(self.joint_in_child)[order],
            hinge[0],
            hinge[1],
            ranges[0],
            ranges[1],
        )

    def with_ranges(self, R_w_s: np.ndarray, valid: np.ndarray | None = None) -> Skeleton:
        """This skeleton with each joint's range of motion as poses of its sensors show it
        (e.g. a calibration session's magnetic-tracker poses of the same sensors): the centre
        the chordal mean of ``R_p^T R_c`` over the frames where both are valid (the mean matrix
        projected onto the rotations), the radius the largest angle from it. Two passes over the
        frames, a chunk at a time (an HDF5 dataset is not read whole). The ranges are those the
        poses show: a session estimated with them should take its joints no farther (a
        calibration session that covers the motion, or the same session).

        Args:
            R_w_s: ``(F, N, 3, 3)`` the sensors' orientations, any world frame (an array or
                anything sliced like one along its frames, e.g. an h5py dataset).
            valid: optional ``(F, N)`` usable poses (default: the finite ones).
        """
        parent = np.asarray(self.parent)
        n = parent.size
        shape = tuple(R_w_s.shape)
        if len(shape) != 4 or shape[1:] != (n, 3, 3):
            raise CalibrationInputError(f"Expected R_w_s as (frames, {n}, 3, 3), got {shape}")
        if valid is not None and np.shape(valid) != shape[:2]:
            raise CalibrationInputError(f"Expected valid of shape {shape[:2]}, got {np.shape(valid)}")
        c = self.children
        p = parent[c]

        def chunks():
            for a in range(0, shape[0], RANGE_CHUNK):
                R = np.asarray(R_w_s[a : a + RANGE_CHUNK], dtype=float)
                ok = np.isfinite(R).all(axis=(-1, -2))
                if valid is not None:
                    ok &= np.asarray(valid[a : a + RANGE_CHUNK], dtype=bool)
                both = ok[:, c] & ok[:, p]
                rel = np.einsum("fkji,fkjl->fkil", np.where(both[..., None, None], R[:, p], 0.0), R[:, c])
                yield both, np.nan_to_num(rel)

        total = np.zeros((c.size, 3, 3))
        count = np.zeros(c.size)
        for both, rel in chunks():
            total += rel.sum(axis=0)
            count += both.sum(axis=0)
        u, _, vt = np.linalg.svd(total)
        flip = np.ones((c.size, 3))
        flip[:, 2] = np.linalg.det(u @ vt)
        centre = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        centre[c] = (u * flip[:, None, :]) @ vt
        largest = np.zeros(c.size)
        for both, rel in chunks():
            cos = (np.einsum("kij,fkij->fk", centre[c], rel) - 1.0) / 2.0
            angle = np.where(both, np.arccos(np.clip(cos, -1.0, 1.0)), 0.0)
            largest = np.maximum(largest, angle.max(axis=0, initial=0.0))
        radius = np.full(n, np.inf)
        radius[c] = np.where(count > 0, np.maximum(largest, 1e-6), np.inf)
        centre[c[count == 0]] = np.eye(3)
        return dataclasses.replace(self, range_centre=centre, range_rad=radius)

    def trees(self) -> list[np.ndarray]:
        """The sensors of each tree (a root and its descendants), each in :meth:`narrow_order`.
        Trees share no residual, so each is solved on its own: the banded solve's cost goes as
        the cube of the sensors solved together."""
        parent = np.asarray(self.parent)
        root = np.where(parent >= 0, parent, np.arange(parent.size))
        while np.any(root[root] != root):  # every sensor's root, by pointer jumping
            root = root[root]
        order = self.narrow_order()
        return [order[root[order] == r] for r in self.roots]

    def narrow_order(self) -> np.ndarray:
        """An order of the sensors that keeps each joint's two sensors close (reverse
        Cuthill-McKee on the tree): the normal equations' band, ``2 N`` blocks plus the largest
        index gap of a joint, narrows (16-sensor humanoid: 45 -> 37 blocks; the banded solve's
        cost goes as its square)."""
        parent = np.asarray(self.parent)
        n = parent.size
        child = np.flatnonzero(parent >= 0)
        graph = csr_matrix((np.ones(child.size), (child, parent[child])), shape=(n, n))
        return reverse_cuthill_mckee(graph + graph.T, symmetric_mode=True).astype(int)

    @classmethod
    def none(cls, n: int) -> Skeleton:
        """No skeleton: ``n`` independent sensors."""
        return cls(np.full(n, -1), np.zeros((n, 3)), np.zeros((n, 3)))

    @property
    def roots(self) -> np.ndarray:
        return np.flatnonzero(np.asarray(self.parent) < 0)

    @property
    def lone(self) -> np.ndarray:
        """Roots with no children: sensors on their own (every sensor without a skeleton)."""
        roots = self.roots
        return roots[~np.isin(roots, np.asarray(self.parent))]

    @property
    def children(self) -> np.ndarray:
        return np.flatnonzero(np.asarray(self.parent) >= 0)

    @property
    def ranged(self) -> np.ndarray:
        """Children whose joint has a range of motion."""
        if self.range_rad is None:
            return np.zeros(0, dtype=int)
        c = self.children
        return c[np.isfinite(np.asarray(self.range_rad, dtype=float)[c])]

    @property
    def hinges(self) -> np.ndarray:
        """Children whose joint is a hinge."""
        if self.hinge_in_parent is None:
            return np.zeros(0, dtype=int)
        return np.flatnonzero(np.linalg.norm(np.asarray(self.hinge_in_parent, dtype=float), axis=1) > 0)


def _narrowest_layout(neighbours: list[list[int]], width: int, budget: int) -> tuple[list[int] | None, int]:
    """An order of the graph's vertices in which every edge joins two within ``width`` places
    of each other, by depth-first search (at most ``budget`` placements; ``None`` if there is
    none or the search gave up), and the placements made."""
    n = len(neighbours)
    place = [-1] * n
    order: list[int] = []
    left = [len(x) for x in neighbours]  # each vertex's neighbours not yet placed
    steps = 0

    def feasible() -> bool:
        # each placed vertex's unplaced neighbours must fit before its deadline
        p = len(order)
        due = sorted(place[v] + width for v in order if left[v])
        return all(d - p + 1 >= i + 1 for i, d in enumerate(due)) and all(
            left[v] <= place[v] + width - p + 1 for v in order if left[v]
        )

    def search() -> bool:
        nonlocal steps
        if len(order) == n:
            return True
        p = len(order)
        urgent = [v for v in order if left[v] and place[v] + width == p]
        if len(urgent) > 1:
            return False
        pool = [u for u in neighbours[urgent[0]] if place[u] < 0] if urgent else range(n)
        for u in pool:
            if place[u] >= 0:
                continue
            steps += 1
            if steps > budget:
                return False
            place[u] = p
            order.append(u)
            for w in neighbours[u]:
                left[w] -= 1
            if feasible() and search():
                return True
            for w in neighbours[u]:
                left[w] += 1
            order.pop()
            place[u] = -1
        return False

    found = search()
    return (order if found else None), steps


def _band_slots(skeleton: Skeleton) -> np.ndarray:
    """``(N,)`` each sensor's place among a frame's unknowns: the band of the normal equations
    is ``2 N`` blocks plus the largest gap between a joint's two places (its solve's cost goes
    as the band's square). The sensors' own order (reverse Cuthill-McKee's, from
    :meth:`Skeleton.trees`) unless a search (:func:`_narrowest_layout`) finds one narrower, one
    gap at a time, down to half the busiest sensor's joints, rounded up: the 16-sensor humanoid
    37 blocks (a gap of 4) -> 34 (2), the solve 0.9 times as long. Only the linear algebra's
    order: the sensors keep theirs (the clipped axes' fill goes sensor by sensor in it)."""
    parent = np.asarray(skeleton.parent)
    n = parent.size
    child = np.flatnonzero(parent >= 0)
    slots = np.arange(n)
    if child.size == 0:
        return slots
    gap = int(np.abs(child - parent[child]).max())
    neighbours: list[list[int]] = [[] for _ in range(n)]
    for c in child.tolist():
        neighbours[c].append(int(parent[c]))
        neighbours[int(parent[c])].append(c)
    busiest = max(len(x) for x in neighbours)
    budget = NARROW_SEARCH_STEPS
    for width in range(gap - 1, (busiest + 1) // 2 - 1, -1):  # narrower until none is found
        found, steps = _narrowest_layout(neighbours, width, budget)
        budget -= steps
        if found is None:
            break
        slots[np.asarray(found, dtype=int)] = np.arange(n)
    return slots


@dataclass
class _Problem:
    """The residuals of one level (module docstring) and their Jacobian."""

    acc: np.ndarray  # (F, N, 3) m/s^2, zeros where unusable
    mag_dir: np.ndarray  # (F, N, 3) unit, zeros where unusable
    use: np.ndarray  # (F, N) usable samples
    dt: float
    skeleton: Skeleton
    ref: Reference
    priors: Priors
    clipped: np.ndarray | None = None  # (F, N, 3) accelerometer axes at their range (filled)
    slot: np.ndarray | None = None  # (N,) each sensor's place among a frame's unknowns (default: its index)
    mag_weight: np.ndarray = field(init=False)
    root_sigma: np.ndarray = field(init=False)
    lone: np.ndarray = field(init=False)  # sensors on their own: a motion of their own
    body_roots: np.ndarray = field(init=False)  # the other roots: an acceleration prior
    n_vel: int = field(init=False)
    band: dict = field(init=False, default_factory=dict)  # the normal equations' layout

    def __post_init__(self) -> None:
        self.mag_weight = self.use.astype(float)
        roots = self.skeleton.roots
        self.lone = self.skeleton.lone
        if self.priors.lone_speed is None:
            self.lone = self.lone[:0]
        self.body_roots = roots[~np.isin(roots, self.lone)]
        self.n_vel = self.lone.size
        n = self.use.shape[1]
        self.slot = np.concatenate(
            [
                np.arange(n) if self.slot is None else np.asarray(self.slot, dtype=int),
                n + np.arange(self.n_vel),
            ]
        )
        # a root's acceleration prior: at least the RMS of |f| - g, its acceleration along the
        # vertical as its own samples show it (per axis, if the acceleration is isotropic)
        roots = self.body_roots
        excess = np.linalg.norm(self.acc[:, roots], axis=-1) - self.ref.gravity
        u = self.use[:, roots]
        rms = np.sqrt(np.sum(np.where(u, excess, 0.0) ** 2, axis=0) / np.maximum(u.sum(axis=0), 1))
        self.root_sigma = np.maximum(self.priors.root_acc, rms)
        self.clipped = self._usable_clipped(self.clipped)

    def _usable_clipped(self, clipped: np.ndarray | None) -> np.ndarray | None:
        if clipped is None:
            return None
        clipped = clipped & self.use[..., None]
        return clipped if clipped.any() else None

    def with_clipped(self, clipped: np.ndarray) -> _Problem:
        """The same problem (weights as set), its clipped accelerometer axes ``(F, N, 3)``
        filled (:meth:`filled`)."""
        out = copy.copy(self)
        out.clipped = self._usable_clipped(clipped)
        return out

    def joints(self, R: np.ndarray) -> tuple[np.ndarray, ...]:
        """The joints' parent and child sensors ``(J,)`` (none with fewer than three frames),
        their places ``R_p l_p`` and ``R_c l_c`` ``(F, J, 3)`` (m) at orientations ``R``, and
        those places' second derivatives ``(F - 2, J, 3)`` (m/s^2)."""
        sk, dt = self.skeleton, self.dt
        c = sk.children if R.shape[0] > 2 else sk.children[:0]
        p = np.asarray(sk.parent)[c]
        Lp = np.einsum("fkij,kj->fki", R[:, p], np.asarray(sk.joint_in_parent, dtype=float)[c])
        Lc = np.einsum("fkij,kj->fki", R[:, c], np.asarray(sk.joint_in_child, dtype=float)[c])

        def d2(x: np.ndarray) -> np.ndarray:
            return (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2

        return p, c, Lp, Lc, d2(Lp), d2(Lc)

    def filled(self, R: np.ndarray, V: np.ndarray, joints: tuple | None = None) -> np.ndarray:
        """``(F, N, 3)`` the specific forces, each clipped axis (:attr:`clipped`, its value the
        range, a bound) at what the sensor's accelerometer rows (root, lone, joints) ask of it
        at ``R``, ``V``, where that is beyond the range. Each row ``s R_k f_k + c`` (``s`` = +-1,
        weight ``w``) asks ``f_k = -s R_k^T c``: their weighted mean is ``f_k - R_k^T sum(w^2 s
        e) / sum(w^2)`` for the rows' residuals ``e``. Sensor by sensor (Gauss-Seidel: a joint
        whose two sides clip is absorbed once, by the first, not by both), so the cost is a
        function of ``R`` and ``V`` alone. ``joints``: :meth:`joints` at ``R``, when at hand."""
        acc = self.acc
        if self.clipped is None:
            return acc
        f = acc.copy()
        frames = f.shape[0]
        dt, pri = self.dt, self.priors
        g_up = self.ref.gravity * self.ref.up_w
        Rf = np.einsum("fnij,fnj->fni", R, f)
        p, c, _, _, d2p, d2c = self.joints(R) if joints is None else joints
        w2j = (self.use[1:-1, p] & self.use[1:-1, c]) / pri.joint_acc**2
        roots, lone = list(self.body_roots), list(self.lone)
        for k in np.flatnonzero(self.clipped.any(axis=(0, 2))):
            pull = np.zeros((frames, 3))  # sum of w^2 s e, world
            weight = np.zeros(frames)  # sum of w^2
            if k in roots:
                w2 = self.use[:, k] / self.root_sigma[roots.index(k)] ** 2
                pull += w2[:, None] * (Rf[:, k] - g_up)
                weight += w2
            if k in lone and frames > 2:
                j = lone.index(k)
                e = (V[1:-1, j] - V[:-2, j]) / dt - (Rf[1:-1, k] - g_up)
                w2 = self.use[1:-1, k] / pri.lone_acc**2
                pull[1:-1] -= w2[:, None] * e
                weight[1:-1] += w2
            for j in np.flatnonzero((p == k) | (c == k)):
                e = Rf[1:-1, p[j]] - Rf[1:-1, c[j]] + d2p[:, j] - d2c[:, j]
                sign = 1.0 if p[j] == k else -1.0
                pull[1:-1] += sign * w2j[:, j, None] * e
                weight[1:-1] += w2j[:, j]
            with np.errstate(invalid="ignore", divide="ignore"):
                want = f[:, k] - np.einsum("fji,fj->fi", R[:, k], pull) / weight[:, None]
            side = np.sign(acc[:, k])
            beyond = side * np.maximum(np.abs(acc[:, k]), side * np.nan_to_num(want, nan=0.0))
            f[:, k] = np.where(self.clipped[:, k], beyond, f[:, k])
            Rf[:, k] = np.einsum("fij,fj->fi", R[:, k], f[:, k])
        return f

    def weigh_disturbance(self, mag: np.ndarray) -> np.ndarray:
        """Down-weight magnetometer samples whose field strength departs from the sensor's own:
        ``w = 1 / (1 + (x / (c s))^2)`` for the relative departure ``x`` from the reference
        strength, ``s`` its robust scale over the sensor's samples (1.4826 MAD about the
        median), ``c`` = :data:`DISTURBANCE_C`; a sample the field does not fit is then carried
        by the rest of the problem. (The dip is no test here: it is measured against the
        accelerometer, which a limb's acceleration turns.) Returns ``(F, N)`` whether a sample
        is disturbed (``w < 1/2``)."""
        x = np.linalg.norm(mag, axis=-1) / self.ref.field_strength - 1.0
        x = np.where(self.use, x, np.nan)
        w = np.ones_like(x)
        if self.use.any():
            with np.errstate(invalid="ignore"):
                med = np.nanmedian(x, axis=0)
                scale = 1.4826 * np.nanmedian(np.abs(x - med), axis=0)
            scale = np.where(np.isfinite(scale) & (scale > 0), scale, np.inf)
            w = 1.0 / (1.0 + (np.nan_to_num(x - med) / (DISTURBANCE_C * scale)) ** 2)
        self.mag_weight = np.where(self.use, w, 0.0)
        return self.use & (w < 0.5)

    @property
    def blocks_per_frame(self) -> int:
        """Unknown 3-vectors per frame: each sensor's rotation, then each root's velocity."""
        return self.use.shape[1] + self.n_vel

    def residuals(self, R: np.ndarray, V: np.ndarray, jacobian: bool = False):
        """The stacked residual vector; with ``jacobian`` also its blocks: per residual group a
        list of ``(columns, v)``, ``columns`` the block columns (frame * N + sensor) of the
        group's rows and ``v`` the derivative of each row's residual by that column's
        perturbation ``d``: every such 3 x 3 block is a cross product, ``[v]x`` with ``v``
        ``(rows..., 3)``, or a multiple of the identity, ``v I`` with ``v`` a scalar (the
        smoothness rows)."""
        r, blocks = self.evaluate(R, V)
        return (r, blocks()) if jacobian else r

    def evaluate(self, R: np.ndarray, V: np.ndarray) -> tuple[np.ndarray, Callable[[], list]]:
        """:meth:`residuals` at ``R``, ``V``, and a function that gives their Jacobian's blocks
        (``residuals(R, V, jacobian=True)[1]``) from what the residuals computed: a solver asks
        for them only where it accepts a step."""
        f, n = self.use.shape
        nb = self.blocks_per_frame
        dt, pri, sk = self.dt, self.priors, self.skeleton
        res: list[np.ndarray] = []
        builders: list[Callable[[], list[tuple[np.ndarray, np.ndarray]]]] = []

        slot = self.slot

        def col(t: np.ndarray, k: np.ndarray) -> np.ndarray:
            return t * nb + slot[k]

        frames = np.arange(f)[:, None]
        inner = frames[1:-1]
        joints = self.joints(R)
        acc = self.filled(R, V, joints)
        # magnetometer: R m - b
        Rm = np.einsum("fnij,fnj->fni", R, self.mag_dir)
        w = (self.mag_weight / pri.mag_rad)[..., None]
        res.append((w * (Rm - self.ref.field_dir_w)).reshape(-1))
        builders.append(lambda: [(col(frames, np.arange(n)[None]), -w * Rm)])
        # body roots: R f - g up, their acceleration a zero-mean prior
        Rf = np.einsum("fnij,fnj->fni", R, acc)
        roots = self.body_roots
        wr = (self.use[:, roots] / self.root_sigma)[..., None]
        res.append((wr * (Rf[:, roots] - self.ref.gravity * self.ref.up_w)).reshape(-1))
        builders.append(lambda: [(col(frames, roots[None]), -wr * Rf[:, roots])])
        # lone sensors: their velocity V (V[t] over the step t -> t + 1) changes by their
        # linear acceleration, (V[t] - V[t-1]) / dt = R f - g up at t; V a zero-mean prior
        lone = self.lone
        if lone.size and f > 2:
            e = Rf[1:-1, lone] - self.ref.gravity * self.ref.up_w
            W_lone = (self.use[1:-1, lone] / pri.lone_acc)[..., None]
            res.append((W_lone * ((V[1:-1] - V[:-2]) / dt - e)).reshape(-1))
            res.append((V / pri.lone_speed).reshape(-1))

            def lone_blocks() -> list[tuple[np.ndarray, np.ndarray]]:
                v_col = n + np.arange(lone.size)[None]
                step = (W_lone / dt)[..., None] * np.eye(3)
                return [
                    (col(inner, lone[None]), W_lone * Rf[1:-1, lone]),
                    (col(inner, v_col), step),
                    (col(inner - 1, v_col), -step),
                ]

            builders.append(lone_blocks)
            builders.append(
                lambda: [(col(frames, n + np.arange(lone.size)[None]), np.float64(1.0 / pri.lone_speed))]
            )
        # joints: R_p f_p + D2(R_p l_p) - R_c f_c - D2(R_c l_c)
        p, c, Lp, Lc, d2p, d2c = joints
        if c.size:
            wj = (self.use[1:-1, p] & self.use[1:-1, c]) / pri.joint_acc
            res.append((wj[..., None] * (Rf[1:-1, p] - Rf[1:-1, c] + d2p - d2c)).reshape(-1))

            def joint_blocks() -> list[tuple[np.ndarray, np.ndarray]]:
                W = wj[..., None]
                h = 1.0 / dt**2
                return [
                    (col(inner - 1, p[None]), -h * W * Lp[:-2]),
                    (col(inner, p[None]), -W * (Rf[1:-1, p] - 2 * h * Lp[1:-1])),
                    (col(inner + 1, p[None]), -h * W * Lp[2:]),
                    (col(inner - 1, c[None]), h * W * Lc[:-2]),
                    (col(inner, c[None]), W * (Rf[1:-1, c] - 2 * h * Lc[1:-1])),
                    (col(inner + 1, c[None]), h * W * Lc[2:]),
                ]

            builders.append(joint_blocks)
        # hinges: the axis the same from both sides, R_p a_p - R_c a_c
        hc = sk.hinges
        if hc.size:
            hp = np.asarray(sk.parent)[hc]
            Ap = np.einsum("fkij,kj->fki", R[:, hp], np.asarray(sk.hinge_in_parent, dtype=float)[hc])
            Ac = np.einsum("fkij,kj->fki", R[:, hc], np.asarray(sk.hinge_in_child, dtype=float)[hc])
            res.append(((Ap - Ac) / pri.hinge_rad).reshape(-1))
            builders.append(
                lambda: [
                    (col(frames, hp[None]), -Ap / pri.hinge_rad),
                    (col(frames, hc[None]), Ac / pri.hinge_rad),
                ]
            )
        # ranges: the excess of log(C^T R_p^T R_c) beyond the cone's radius
        rc = sk.ranged
        if rc.size:
            rp = np.asarray(sk.parent)[rc]
            C = np.asarray(sk.range_centre, dtype=float)[rc]
            M = np.einsum("kji,fklj,fklm->fkim", C, R[:, rp], R[:, rc])
            phi = _log(M)
            size = np.linalg.norm(phi, axis=-1)[..., None]
            theta = np.asarray(sk.range_rad, dtype=float)[rc][None, :, None]
            out = size > theta
            safe = np.where(out, size, 1.0)
            res.append((np.where(out, phi * (1.0 - theta / safe), 0.0) / pri.beyond_range_rad).reshape(-1))

            def range_blocks() -> list[tuple[np.ndarray, np.ndarray]]:
                # d excess / d phi, then d phi / d(delta_c) = J_r^-1(phi) R_c^T, d(delta_p) = -that
                D = np.where(
                    out[..., None],
                    (1.0 - theta / safe)[..., None] * np.eye(3)
                    + (theta / safe**3)[..., None] * phi[..., :, None] * phi[..., None, :],
                    0.0,
                )
                Jc = D @ np.swapaxes(_log_jacobian_inverse(phi), -1, -2) @ np.swapaxes(R[:, rc], -1, -2)
                Jc = Jc / pri.beyond_range_rad
                return [(col(frames, rp[None]), -Jc), (col(frames, rc[None]), Jc)]

            builders.append(range_blocks)
        # smoothness: change of the world angular increment
        if f > 2:
            s = pri.angular_acc * dt**2
            inc = _log(R[1:] @ np.swapaxes(R[:-1], -1, -2))
            res.append(((inc[1:] - inc[:-1]) / s).reshape(-1))

            def smoothness_blocks() -> list[tuple[np.ndarray, np.ndarray]]:
                k = np.arange(n)[None]
                Jl = _log_jacobian_inverse(inc) / s  # (F-1, N, 3, 3): d inc_t / d(delta_{t+1})
                Jr = np.swapaxes(Jl, -1, -2)  # -d inc_t / d(delta_t)
                return [
                    (col(inner - 1, k), Jr[:-1]),
                    (col(inner, k), -Jr[1:] - Jl[:-1]),
                    (col(inner + 1, k), Jl[1:]),
                ]

            builders.append(smoothness_blocks)
        r = np.concatenate(res)
        return r, lambda: [build() for build in builders]


def _log(M: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` of rotation matrices ``(..., 3, 3)``: ``theta`` =
    ``atan2(|w|, (tr M - 1) / 2)`` with ``w`` the vector of ``(M - M^T) / 2`` (``sin theta``
    times the axis), accurate for every angle but those within ``1e-6`` of pi, which go to
    :func:`calibration.rotations.matrix_to_rotvec` (the increments here are a frame's turn,
    far from pi; scipy's general conversion was 15 % of a solve)."""
    w = 0.5 * np.stack(
        [M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]], -1
    )
    s = np.linalg.norm(w, axis=-1)
    c = 0.5 * (np.trace(M, axis1=-2, axis2=-1) - 1.0)
    theta = np.arctan2(s, c)
    scale = np.where(s > 1e-12, theta / np.where(s > 1e-12, s, 1.0), 1.0 + theta**2 / 6.0)
    out = w * scale[..., None]
    near_pi = (s < 1e-6) & (c < 0)
    if near_pi.any():
        out[near_pi] = matrix_to_rotvec(M[near_pi])
    return out


def _log_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """``J_l^-1(phi)`` ``(..., 3, 3)``: ``log(exp(d) exp(phi)) = phi + J_l^-1(phi) d`` to first
    order in ``d`` (and ``J_r^-1 = (J_l^-1)^T`` for a perturbation on the right)."""
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    c = np.where(small, 1.0 / 12.0, 1.0 / t**2 - (1 + np.cos(t)) / (2 * t * np.sin(t)))
    return np.eye(3) - 0.5 * K + c * (K @ K)


def _frame_last(v: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """A residual block's ``v`` (rows ``shape`` = (frames, K), then its own axes) with the frames
    last and contiguous: ``(K, ..., frames)``; a scalar stays one."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 0:
        return v
    v = np.broadcast_to(v, shape + v.shape[len(shape) :])
    return np.ascontiguousarray(np.moveaxis(v, 0, -1))


def _skew_frame_last(v: np.ndarray) -> np.ndarray:
    """``[v]x`` ``(K, 3, 3, T)`` of vectors ``(K, 3, T)``."""
    out = np.zeros((v.shape[0], 3, 3, v.shape[-1]))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return out


def _as_matrix(v: np.ndarray) -> np.ndarray:
    """A block ``(K, 3, 3, T)`` whatever its kind: a matrix, a cross product's vector, a
    multiple of the identity (a scalar, broadcast)."""
    if v.ndim == 4:
        return v
    if v.ndim == 3:
        return _skew_frame_last(v)
    return np.eye(3)[None, :, :, None] * v


def _band_layout(groups: list[list[tuple[np.ndarray, np.ndarray]]], frames: int, per_frame: int) -> dict:
    """Where :func:`_normal_equations` puts each product: the residual blocks' columns are
    ``(t + s) * per_frame + k`` for the group's row ``(t, k)`` (a frame shift ``s`` per block),
    so each pair of blocks writes, for every frame, the same places of that frame's part of the
    band (``3 per_frame`` columns of ``u + 1`` entries: LAPACK lower, ``ab[row - col, col]``).
    Returns the products' rows in the work array (frames last), a sparse matrix summing them
    into the band's places and the gradient's, those places, and ``u``."""
    nb = per_frame
    specs = []  # per group: rows, K, its blocks' (frame shift, sensors)
    top = 0
    for blocks in groups:
        shape = np.broadcast_shapes(*(np.shape(c) for c, _ in blocks))
        if len(shape) != 2:
            raise ValueError(f"residual blocks' columns must be (frames, K), got {shape}")
        cols = []
        for c, _ in blocks:
            C = np.broadcast_to(np.asarray(c), shape)
            if C.size == 0:  # no rows (a tree with no body root, say): nothing to place
                cols.append((0, np.zeros(shape[1], dtype=int)))
                continue
            shift, k = np.divmod(C[0], nb)
            if np.any(shift != shift[0]) or np.any(np.diff(C, axis=0) != nb):
                raise ValueError("residual blocks' columns must be (frame + shift) * per_frame + sensor")
            cols.append((int(shift[0]), k.astype(int)))
        specs.append((shape, cols))
        for a, (sa, ka) in enumerate(cols):
            for sb, kb in cols[a:]:
                top = max(top, int(np.abs((sb - sa) * nb + kb - ka).max(initial=0)))
    u = 3 * top + 2
    i, j = np.divmod(np.arange(9), 3)
    slots, qs, weights = [], [], []
    plan = []  # per group: (pairs [(a, b, q0, first frame)], gradient [(a, q0, first frame)])
    q = 0
    n_band = 3 * nb * (u + 1)  # the gradient's places follow the band's
    for shape, cols in specs:
        K = shape[1]
        pairs, grads = [], []
        for a, (sa, ka) in enumerate(cols):
            for b in range(a, len(cols)):
                sb, kb = cols[b]
                Ca, Cb = sa * nb + ka, sb * nb + kb  # block columns at the group's first row
                first = min(sa, sb)
                base = first * nb
                ii, jj = i[None, :], j[None, :]
                below = (Ca > Cb)[:, None]  # (K, 1): the product's block is below the diagonal
                col = np.where(below, 3 * (Cb - base)[:, None] + jj, 3 * (Ca - base)[:, None] + ii)
                d = 3 * np.abs(Cb - Ca)[:, None] + np.where(below, ii - jj, jj - ii)
                w = np.ones((K, 9))
                same = (Ca == Cb)[:, None]
                if a == b:  # its own product, symmetric: the lower triangle once
                    keep = ~same | (ii >= jj)
                    col = np.where(same, 3 * (Ca - base)[:, None] + jj, col)
                    d = np.where(same, ii - jj, d)
                else:  # two blocks on one column: P + P^T, its lower triangle
                    keep = np.ones((K, 9), bool)
                    lo, hi = np.minimum(ii, jj), np.maximum(ii, jj)
                    col = np.where(same, 3 * (Ca - base)[:, None] + lo, col)
                    d = np.where(same, hi - lo, d)
                    w = np.where(same & (ii == jj), 2.0, w)
                place = col * (u + 1) + d
                qq = q + np.arange(9 * K).reshape(K, 9)
                slots.append(place[keep])
                qs.append(qq[keep])
                weights.append(w[keep])
                pairs.append((a, b, q, first))
                q += 9 * K
        for a, (sa, ka) in enumerate(cols):
            slots.append((n_band + 3 * ka[:, None] + np.arange(3)).ravel())
            qs.append(q + np.arange(3 * K))
            weights.append(np.ones(3 * K))
            grads.append((a, q, sa))
            q += 3 * K
        plan.append((shape, pairs, grads))
    slots_all = np.concatenate(slots) if slots else np.zeros(0, dtype=int)
    places, row = np.unique(slots_all, return_inverse=True)
    n_grad = int(np.sum(places >= n_band))
    S = csr_matrix(
        (np.concatenate(weights) if weights else np.zeros(0), (row, np.concatenate(qs) if qs else row)),
        shape=(places.size, q),
    )
    return {
        "plan": plan,
        "sum": S,
        "places": places[: places.size - n_grad],
        "gradient": places[places.size - n_grad :] - n_band,
        "u": u,
        "rows": q,
        "frames": frames,
        "per_frame": nb,
    }


def _normal_equations(
    r: np.ndarray,
    groups: list[list[tuple[np.ndarray, np.ndarray]]],
    frames: int,
    per_frame: int,
    cache: dict | None = None,
    out: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``J^T J`` in LAPACK's lower band layout ``(u + 1, 3 frames per_frame)``, Fortran-ordered
    (the layout ``pbtrf`` reads without a copy; lower is a third faster than upper here), and
    ``J^T r``, from the residual blocks (:meth:`_Problem.residuals`) without forming ``J``. For
    cross-product blocks ``[a]x^T [b]x = (a . b) I - b a^T`` and ``[a]x^T r = r x a``.

    Every pair of a group's blocks gives a 3 x 3 product per row, written with the frames last
    (each product entry one row of a work array over the frames); one sparse matrix, the same
    for every iteration of a problem (:func:`_band_layout`, kept in ``cache``), sums them into
    the band's places frame by frame. The band is written into ``out`` (a buffer of its shape,
    e.g. the one LAPACK factors in place; :func:`_band_again` writes it once more from the sums
    kept in ``cache``), else into the cache's buffer, which the next call overwrites."""
    nb = per_frame
    if cache is None:
        cache = {}
    if cache.get("frames") != frames or cache.get("per_frame") != nb:
        cache.clear()
        cache.update(_band_layout(groups, frames, nb))
    u = cache["u"]
    work = cache.get("work")
    if work is None:  # the products over the frames; columns no row reaches stay zero
        work = cache["work"] = np.zeros((cache["rows"], frames))
    if out is None:
        out = cache.get("band")
        if out is None:
            out = cache["band"] = np.zeros((u + 1, 3 * nb * frames), order="F")
    start = 0
    for blocks, (shape, pairs, grads) in zip(groups, cache["plan"], strict=True):
        rows, K = shape
        size = rows * K
        rg = _frame_last(r[start : start + 3 * size].reshape(rows, K, 3), shape)  # (K, 3, T)
        start += 3 * size
        vs = [_frame_last(v, shape) for _, v in blocks]
        # the blocks that a pair takes as 3 x 3 matrices (not two vectors, not a scalar's)
        mats = {
            x: _as_matrix(vs[x])
            for a, b, _, _ in pairs
            if not (vs[a].ndim == 3 and vs[b].ndim == 3)
            for x in (a, b)
            if vs[x].ndim
        }
        negated = {x: -vs[x] for x in {a for a, b, _, _ in pairs if vs[a].ndim == 3 and vs[b].ndim == 3}}
        for a, b, q0, first in pairs:
            P = work[q0 : q0 + 9 * K, first : first + rows].reshape(K, 3, 3, rows)
            va, vb = vs[a], vs[b]
            if va.ndim == 3 and vb.ndim == 3:  # -b a^T, then a . b (minus its trace) on its diagonal
                np.multiply(vb[:, :, None], negated[a][:, None, :], out=P)
                trace = P[:, 0, 0] + P[:, 1, 1]
                trace += P[:, 2, 2]
                for x in range(3):
                    P[:, x, x] -= trace
            elif va.ndim == 0 and vb.ndim == 0:
                P[...] = np.eye(3)[None, :, :, None] * (va * vb)
            elif va.ndim == 0:  # (s I)^T Mb
                np.multiply(va, mats[b], out=P)
            elif vb.ndim == 0:  # Ma^T (s I)
                np.multiply(vb, np.swapaxes(mats[a], 1, 2), out=P)
            else:  # Ma^T Mb
                np.einsum("kmit,kmjt->kijt", mats[a], mats[b], out=P)
        for a, q0, first in grads:
            G = work[q0 : q0 + 3 * K, first : first + rows].reshape(K, 3, rows)
            va = vs[a]
            if va.ndim == 3:  # [a]x^T r = r x a
                for x in range(3):
                    y, z = (x + 1) % 3, (x + 2) % 3
                    np.subtract(rg[:, y] * va[:, z], rg[:, z] * va[:, y], out=G[:, x])
            elif va.ndim == 0:
                np.multiply(va, rg, out=G)
            else:
                np.einsum("kmit,kmt->kit", va, rg, out=G)
    summed = cache["summed"] = cache["sum"] @ work  # (places, frames)
    n_band = cache["places"].size
    g = np.zeros((frames, 3 * nb))
    g[:, cache["gradient"]] = summed[n_band:].T
    return _band_again(cache, out), g.reshape(-1)


def _band_again(cache: dict, out: np.ndarray) -> np.ndarray:
    """The last :func:`_normal_equations`' band written (once more) into ``out``, ``(u + 1, 3
    frames per_frame)`` Fortran-ordered, from the sums it kept in ``cache``: zeros but for the
    places products reach (a factorisation in place fills the rest)."""
    n_band = cache["places"].size
    shape = (cache["u"] + 1, 3 * cache["per_frame"] * cache["frames"])
    if out.shape != shape or not out.flags.f_contiguous:
        raise ValueError(f"Expected a Fortran-ordered band buffer of shape {shape}, got {out.shape}")
    out.fill(0.0)
    out.T.reshape(cache["frames"], -1)[:, cache["places"]] = cache["summed"][:n_band].T
    return out


def _sensor_costs(problem: _Problem, R: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``(F, N)`` the cost (sum of squared residuals) of ``R`` ``(F, N, 3, 3)`` and ``V``
    ``(F, n_vel, 3)`` by frame and sensor: each residual row's cost at the frame of its first
    block column, shared equally among its blocks' sensors (a joint's row half to the parent,
    half to the child); a lone sensor's velocity blocks count as its own. The shares sum to the
    cost."""
    f, n = problem.use.shape
    nb = problem.blocks_per_frame
    r, groups = problem.residuals(R, V, jacobian=True)
    rows = np.sum(r.reshape(-1, 3) ** 2, axis=1)
    out = np.zeros(f * nb)
    block_of = np.argsort(problem.slot)  # the unknown at each place of a frame
    start = 0
    for blocks in groups:
        shape = np.broadcast_shapes(*(np.shape(c) for c, _ in blocks))
        size = int(np.prod(shape))
        share = rows[start : start + size] / len(blocks)
        start += size
        frame = np.broadcast_to(blocks[0][0], shape).reshape(-1) // nb
        for c, _ in blocks:
            place = frame * nb + block_of[np.broadcast_to(c, shape).reshape(-1) % nb]
            out += np.bincount(place, share, minlength=out.size)
    out = out.reshape(f, nb)
    costs = out[:, :n].copy()
    costs[:, problem.lone] += out[:, n:]
    return costs


def _mixed(
    problem: _Problem, solutions: list[tuple[np.ndarray, np.ndarray]], window: int
) -> tuple[np.ndarray, np.ndarray]:
    """A start from several solutions ``(R, V)`` of ``problem``: in each ``window`` of frames,
    each sensor from the solution that costs least on it there (:func:`_sensor_costs`), a lone
    sensor's velocity with it."""
    costs = np.stack([_sensor_costs(problem, R, V) for R, V in solutions])  # (S, F, N)
    f, n = costs.shape[1:]
    edges = np.arange(0, f, window)
    pick = np.argmin(np.add.reduceat(costs, edges, axis=1), axis=0)  # (windows, N)
    picked = np.repeat(pick, np.diff(np.append(edges, f)), axis=0)  # (F, N)
    frames = np.arange(f)[:, None]
    R = np.stack([R for R, _ in solutions])[picked, frames, np.arange(n)]
    V = np.stack([V for _, V in solutions])[picked[:, problem.lone], frames, np.arange(problem.n_vel)]
    return R, V


def _levenberg_marquardt(
    problem: _Problem, R: np.ndarray, V: np.ndarray, max_iter: int, rel_tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Minimise the problem's cost from ``R`` ``(F, N, 3, 3)`` and the roots' velocities ``V``
    ``(F, n_vel, 3)``; return them, the iterations and the final cost. The band is assembled in
    the buffer LAPACK factors in place (``pbsv``), one over the iterations; a rejected try
    writes it again from the kept sums (:func:`_band_again`) rather than each try copying it."""
    f, n = problem.use.shape
    nb = problem.blocks_per_frame
    lam = 1e-3
    r, groups = problem.residuals(R, V, jacobian=True)
    cost = float(r @ r)
    iterations = 0
    factor = None
    try:
        for iterations in range(1, max_iter + 1):
            ab, g = _normal_equations(r, groups, f, nb, problem.band, out=factor)
            factor = ab  # factored in place; a rejected try writes the band again
            diag = ab[0].copy()
            floor = 1e-12 * max(float(diag.max(initial=0.0)), 1e-300)
            tries = 0
            while True:
                if tries:
                    _band_again(problem.band, factor)
                tries += 1
                factor[0] = diag * (1 + lam) + floor
                _, x, info = dpbsv(factor, -g[:, None], lower=1, overwrite_ab=1, overwrite_b=1)
                if info < 0:
                    raise ValueError(f"LAPACK pbsv: argument {-info} is illegal")
                if info == 0:
                    d = x.reshape(f, nb, 3)[:, problem.slot]
                    R_new = rotvec_to_matrix(d[:, :n]) @ R
                    V_new = V + d[:, n:]
                    r_new, blocks_new = problem.evaluate(R_new, V_new)
                    cost_new = float(r_new @ r_new)
                    if cost_new < cost:
                        break
                if lam > 1e10:
                    return R, V, iterations, cost
                lam *= 10
            gain = (cost - cost_new) / cost
            R, V, cost = R_new, V_new, cost_new
            lam = max(lam / 3, 1e-9)
            if gain < rel_tol:
                break
            r, groups = r_new, blocks_new()  # the Jacobian where the step is accepted
    finally:  # the work buffers are large: a problem kept for later solves holds only its layout
        for key in ("work", "band", "summed"):
            problem.band.pop(key, None)
    return R, V, iterations, cost


def _interpolate(R: np.ndarray, t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """Slerp each sensor's orientations ``(Fc, N, 3, 3)`` at times ``t_from`` to ``t_to``
    (held beyond the ends): ``R_i exp(s log(R_i^T R_i+1))`` at the fraction ``s`` of the way
    from ``t_from[i]`` to ``t_from[i + 1]``, every sensor at once."""
    if R.shape[0] == 1:
        return np.broadcast_to(R, (t_to.size, *R.shape[1:])).copy()
    t = np.clip(t_to, t_from[0], t_from[-1])
    i = np.clip(np.searchsorted(t_from, t, side="right") - 1, 0, t_from.size - 2)
    s = (t - t_from[i]) / (t_from[i + 1] - t_from[i])
    turn = _log(np.swapaxes(R[:-1], -1, -2) @ R[1:])  # (Fc - 1, N, 3)
    return R[i] @ rotvec_to_matrix(s[:, None, None] * turn[i])


def _loose(skeleton: Skeleton) -> Skeleton:
    """The skeleton without its hinges and ranges (the coarser levels')."""
    return dataclasses.replace(
        skeleton, hinge_in_parent=None, hinge_in_child=None, range_centre=None, range_rad=None
    )


def _interpolate_linear(V: np.ndarray, t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """Each column of ``V`` ``(Fc, ...)`` at times ``t_from``, linearly at ``t_to`` (held beyond
    the ends)."""
    flat = V.reshape(V.shape[0], -1)
    out = np.stack([np.interp(t_to, t_from, x) for x in flat.T], axis=-1) if flat.shape[1] else None
    return np.zeros((t_to.size, *V.shape[1:])) if out is None else out.reshape(t_to.size, *V.shape[1:])


def _fill_start(q: np.ndarray) -> np.ndarray:
    """Per-sample start ``(F, N, 4)`` with NaN rows filled from the nearest earlier (else later)
    estimate of the sensor, identity where a sensor has none."""
    q = q.copy()
    for k in range(q.shape[1]):
        ok = np.isfinite(q[:, k]).all(axis=-1)
        if not ok.any():
            q[:, k] = [1.0, 0.0, 0.0, 0.0]
            continue
        idx = np.where(ok, np.arange(q.shape[0]), -1)
        idx = np.maximum.accumulate(idx)
        idx[idx < 0] = np.flatnonzero(ok)[0]
        q[:, k] = q[idx, k]
    return q


@dataclass(frozen=True)
class _Setup:
    """What every solve of one tree shares (:func:`skeleton_orientation`'s arguments)."""

    rate_hz: float
    skeleton: Skeleton
    ref: Reference
    priors: Priors
    levels_hz: tuple[float, ...]
    max_iter: int
    fine_iter: int
    weigh_disturbance: bool
    starts: tuple[tuple[float, ...], ...]
    slot: np.ndarray  # (N,) each sensor's place among a frame's unknowns (:func:`_band_slots`)


@dataclass(frozen=True)
class _Data:
    """:func:`skeleton_orientation`'s per-sample inputs: ``acc``, ``mag`` ``(F, N, 3)``, the
    usable samples ``ok`` ``(F, N)``, and the optional masks ``clipped`` ``(F, N, 3)`` and
    ``carry`` ``(F, N)``."""

    acc: np.ndarray
    mag: np.ndarray
    ok: np.ndarray
    clipped: np.ndarray | None
    carry: np.ndarray | None

    def take(self, index: slice | np.ndarray, axis: int) -> _Data:
        """The frames (``axis`` 0) or sensors (``axis`` 1) ``index``."""
        at = (index,) if axis == 0 else (slice(None), index)
        parts = (getattr(self, x.name) for x in dataclasses.fields(self))
        return _Data(*(None if x is None else x[at] for x in parts))


def _solve_span(data: _Data, setup: _Setup) -> tuple[np.ndarray, int]:
    """The coarse-to-fine solve of one span; ``(F, N, 3, 3)`` at every sample, and iterations.

    Each of ``starts`` is a solve from those coarser levels before ``levels_hz``. All end on the
    same problem, so their costs compare: window by window (:data:`COMBINE_S`) and sensor by
    sensor the solution that costs less there is taken (:func:`_mixed`), and the last level
    solved once more from that mix; kept if it costs less than the best of them."""
    f = data.acc.shape[0]
    rate_hz, ref, clipped, carry = setup.rate_hz, setup.ref, data.clipped, data.carry
    acc = np.where(data.ok[..., None], data.acc, np.nan)
    mag = np.where(data.ok[..., None], data.mag, np.nan)
    schedules = [tuple(prefix) + tuple(setup.levels_hz) for prefix in setup.starts]
    solves = []
    total = 0
    inputs: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for schedule in schedules:
        steps = [max(1, round(rate_hz / h)) for h in schedule]
        steps = [k for k in steps if not (k > 1 and f // k < 3)]
        if not steps or any(steps == s[0] for s in solves):
            continue
        *solve, it = _solve_levels(acc, mag, steps, carry, setup, inputs)
        solves.append((steps, *solve))
        total += it
    if not solves:  # too short for any level: the per-sample estimate (not where clipped)
        *_, use = measured_directions(acc, mag, ref, None if clipped is None else ~clipped.any(axis=-1))
        return quat_to_matrix(_fill_start(fontaine(acc, mag, ref, valid=use).q_w_s)), 0
    steps, R, V, t_level, problem, cost = min(solves, key=lambda s: s[-1])
    if len(solves) > 1 and all(s[0][-1] == solves[0][0][-1] for s in solves):
        # window by window and sensor by sensor, the start that costs less there; one more solve
        window = max(1, round(COMBINE_S * rate_hz / solves[0][0][-1]))
        start, start_v = _mixed(problem, [(s[1], s[2]) for s in solves], window)
        R_mix, V_mix, it, cost_mix = _levenberg_marquardt(problem, start, start_v, setup.fine_iter)
        total += it
        if cost_mix < cost:
            R, V = R_mix, V_mix
    if clipped is not None:  # the clipped axes bounded, not held at the range: a last solve
        polish = problem.with_clipped(_level_mask(clipped, steps[-1]))
        if polish.clipped is not None:
            R, V, it, _ = _levenberg_marquardt(polish, R, V, setup.fine_iter)
            total += it
    return _interpolate(R, t_level, np.arange(f, dtype=float)), total


def _level_mask(mask: np.ndarray, k: int) -> np.ndarray:
    """``mask`` ``(F, ...)`` at a level of every ``k``-th sample: set where any sample its
    low-pass reaches (about ``k`` each way) is."""
    return maximum_filter1d(mask.astype(np.uint8), size=2 * k - 1, axis=0)[::k] > 0


def _solve_levels(
    acc: np.ndarray,
    mag: np.ndarray,
    steps: list[int],
    carry: np.ndarray | None,
    setup: _Setup,
    inputs: dict[int, tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, _Problem, float, int]:
    """One coarse-to-fine solve, every ``steps[i]``-th sample at level ``i``, the first level
    started from the per-sample estimate: the last level's orientations ``(Fl, N, 3, 3)`` and
    roots' velocities ``(Fl, n_vel, 3)``, its sample indices ``(Fl,)``, its problem, its final
    cost and the iterations. ``inputs``: each step's low-passed and decimated ``acc`` and
    ``mag``, filled here as needed and kept for the other starts' solves."""
    f = acc.shape[0]
    rate_hz, ref, skeleton = setup.rate_hz, setup.ref, setup.skeleton
    R = None
    V = np.zeros((0, 0, 3))
    t_prev = np.zeros(0)
    total = 0
    cost = np.inf
    problem = None
    for i, k in enumerate(steps):
        if k not in inputs:  # the starts share their levels' inputs (read-only)
            cut = 0.4 * rate_hz / k
            a = smooth_vectors(acc, rate_hz, cut)[::k] if k > 1 else acc.copy()
            m = smooth_vectors(mag, rate_hz, cut)[::k] if k > 1 else mag.copy()
            a.flags.writeable = m.flags.writeable = False
            inputs[k] = (a, m)
        a, m = inputs[k]
        t_level = np.arange(0, f, k, dtype=float)
        _, m_dir, use = measured_directions(a, m, ref, None)
        if R is None:
            start = fontaine(a, m, ref, weighting=Weighting(), valid=use)
            R = quat_to_matrix(_fill_start(start.q_w_s))
        else:
            R = _interpolate(R, t_prev, t_level)
            V = _interpolate_linear(V, t_prev, t_level)
        # hinges and ranges hold only on the last level: from a start that breaks them, a stiff
        # constraint traps the solve in a wrong minimum (measured on an analytic chain: 19
        # degrees RMS with the hinge from the start, 0.55 with it on the last level only, 0.85
        # without; chicken walk with ranges: 84 degrees from the start, 52 on the last level)
        last = i == len(steps) - 1
        problem = _Problem(
            np.where(use[..., None], a, 0.0),
            np.where(use[..., None], m_dir, 0.0),
            use,
            k / rate_hz,
            skeleton if last else _loose(skeleton),
            ref,
            setup.priors,
            slot=setup.slot,
        )
        if setup.weigh_disturbance:
            problem.weigh_disturbance(np.nan_to_num(m))
        if carry is not None:  # a level sample is carried if any sample it stands for is
            near = maximum_filter1d(carry.astype(np.uint8), size=k, axis=0)[::k].astype(bool)
            problem.mag_weight = np.where(near, 0.0, problem.mag_weight)
        if V.shape[:2] != (t_level.size, problem.n_vel):
            V = np.zeros((t_level.size, problem.n_vel, 3))
        R, V, it, cost = _levenberg_marquardt(problem, R, V, setup.max_iter if i == 0 else setup.fine_iter)
        total += it
        t_prev = t_level
    assert R is not None and problem is not None
    return R, V, t_prev, problem, cost, total


def _solve_tree(data: _Data, setup: _Setup, segment_s: float) -> tuple[np.ndarray, int]:
    """One tree's sensors over the recording, ``(F, N, 3, 3)``, solved in overlapping segments
    (:data:`SEGMENT_S`), and the iterations."""
    f, n = data.ok.shape
    R = np.empty((f, n, 3, 3))
    seg = max(round(segment_s * setup.rate_hz), MIN_SEGMENT_FRAMES)
    over = min(round(OVERLAP_S * setup.rate_hz), seg // 4)
    iterations = 0
    start = 0
    kept = 0  # first frame not yet written
    while kept < f:
        stop = min(start + seg, f)
        Rs, it = _solve_span(data.take(slice(start, stop), axis=0), setup)
        iterations += it
        keep_to = f if stop == f else stop - over // 2
        R[kept:keep_to] = Rs[kept - start : keep_to - start]
        kept = keep_to
        start = stop - over
    return R, iterations


def skeleton_orientation(
    acc: np.ndarray,
    mag: np.ndarray,
    rate_hz: float,
    skeleton: Skeleton | None = None,
    ref: Reference | None = None,
    *,
    valid: np.ndarray | None = None,
    priors: Priors | None = None,
    levels_hz: tuple[float, ...] = LEVELS_HZ,
    max_iter: int = 25,
    fine_iter: int = 10,
    segment_s: float = SEGMENT_S,
    weigh_disturbance: bool = False,
    carry: np.ndarray | None = None,
    starts: tuple[tuple[float, ...], ...] = STARTS,
    acc_clipped: np.ndarray | None = None,
) -> Estimate:
    """Every sensor's orientation over the recording, jointly on the skeleton (module docstring).

    Args:
        acc: ``(F, N, 3)`` measured specific force (m/s^2) in each sensor's frame, frames
            first, at a constant rate.
        mag: ``(F, N, 3)`` measured magnetic field (any unit) in each sensor's frame, the same
            frames.
        rate_hz: sample rate, Hz.
        skeleton: the tree and its joints in the sensors' frames, m (``None``: every sensor on
            its own).
        ref: reference vectors; default from the data (:func:`reference_from_data`) of the
            roots' samples only: a root accelerates least, and a limb's accelerations would bias
            the gravity and the field's inclination.
        valid: optional ``(F, N)`` mask of usable samples.
        priors: the residuals' standard deviations (:class:`Priors`).
        levels_hz: the coarse-to-fine levels' rates, Hz.
        max_iter: Levenberg-Marquardt iterations per level at most.
        segment_s: longest span solved at once, s.
        weigh_disturbance: down-weight magnetometer samples whose field strength departs from
            the sensor's own (:meth:`_Problem.weigh_disturbance`). Off by default: measured, it
            made the humanoid exercise worse (3.4 -> 5.6 degrees with clean fields, consumer
            sensors 17.8 -> 19.1) for a gain near a magnet (17.4 -> 15.6), and BROAD trial 30
            no better.
        carry: optional ``(F, N)`` magnetometer samples not to use (a disturbance found in the
            data, e.g. :func:`calibration.orientation.disturbed_spans`): the heading is carried
            across them by the rest of the problem (joints, smoothness) from their ends. Not
            used by :func:`simbench.orient.estimate`: on BROAD, carrying across the spans left
            after recalibration paid nothing on the stationary-magnet trials (67.2 -> 66.9
            degrees) and lost on attached-magnet trial 33 (26.6 -> 30.8, a 12 s span in which
            the sensor turns), where the disturbed field still says more than nothing.
        starts: the solves, each the coarser levels (Hz) it takes before ``levels_hz``; their
            solutions are mixed (module docstring: several starts). ``((),)`` solves once,
            from ``levels_hz`` alone, in about a third of the time.
        acc_clipped: optional ``(F, N, 3)`` accelerometer axes at their range (saturated): the
            sample's value there is the range, a bound; the axis's specific force is what the
            skeleton's motion asks of it, where that is beyond the range (module docstring:
            clipped accelerometers). The other axes and the magnetometer are used as measured.

    Returns:
        The orientations ``R_w_s`` (``ref``'s frame) at every sample; NaN where the sample was
        not usable (NaN or near-zero input, or masked), although the solve carries every
        sensor through such spans.
    """
    acc = np.asarray(acc, dtype=float)
    mag = np.asarray(mag, dtype=float)
    if acc.ndim != 3 or acc.shape[-1] != 3 or mag.shape != acc.shape:
        raise CalibrationInputError(
            f"Expected acc and mag of one shape (frames, sensors, 3), got {acc.shape} and {mag.shape}"
        )
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise CalibrationInputError(f"rate_hz must be > 0, got {rate_hz}")
    f, n = acc.shape[:2]
    skeleton = skeleton or Skeleton.none(n)
    if np.asarray(skeleton.parent).shape != (n,):
        raise CalibrationInputError(
            f"the skeleton has {np.asarray(skeleton.parent).shape[0]} sensors, the data {n}"
        )
    priors = priors or Priors()
    if valid is not None and np.shape(valid) != (f, n):
        raise CalibrationInputError(f"Expected valid of shape {(f, n)}, got {np.shape(valid)}")
    clipped = None
    if acc_clipped is not None:
        clipped = np.asarray(acc_clipped, dtype=bool)
        if clipped.shape != (f, n, 3):
            raise CalibrationInputError(f"Expected acc_clipped of shape {(f, n, 3)}, got {clipped.shape}")
        clipped = clipped if clipped.any() else None
    if carry is not None:
        carry = np.asarray(carry, dtype=bool)
        if carry.shape != (f, n):
            raise CalibrationInputError(f"Expected carry of shape {(f, n)}, got {carry.shape}")
    if ref is None:
        roots = skeleton.roots
        v = None if valid is None else np.asarray(valid, dtype=bool)[:, roots]
        ref = reference_from_data(acc[:, roots], mag[:, roots], valid=v)
    _, _, ok = measured_directions(acc, mag, ref, valid)
    # each tree on its own, over its sensors in an order that narrows the band; BLAS on one thread
    # (:data:`BLAS_THREADS`)
    data = _Data(acc, mag, ok, clipped, carry)
    R = np.empty((f, n, 3, 3))
    iterations = 0
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        for tree in skeleton.trees():
            tree_skeleton = skeleton.permuted(tree)
            setup = _Setup(
                rate_hz,
                tree_skeleton,
                ref,
                priors,
                tuple(levels_hz),
                max_iter,
                fine_iter,
                weigh_disturbance,
                tuple(tuple(p) for p in starts) or ((),),
                _band_slots(tree_skeleton),
            )
            R[:, tree], it = _solve_tree(data.take(tree, axis=1), setup, segment_s)
            iterations += it
    return Estimate(quat_where(R, ok), ok, ref.frame, iterations=iterations)
