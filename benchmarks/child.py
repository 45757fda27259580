"""What the benchmarks share: code that reads a child process's own peak resident memory, and the
large synthetic capture they write to disk in chunks. Peak RSS is read from ``/proc/self/status``
(VmHWM), which belongs to this process image alone; ``getrusage``'s ``ru_maxrss`` would also count
the parent's memory at fork time."""

from collections.abc import Iterator

import numpy as np

from simbench.sim.synthetic import Skeleton, SyntheticCapture, random_tree, simulate_motion


def capture_chunks(
    n_frames: int, n_sensors: int, chunk: int
) -> tuple[Skeleton, Iterator[tuple[int, int, SyntheticCapture]]]:
    """A random tree of ``n_sensors`` (seed 2) and its motion at 120 Hz with 4 mm of position
    noise, ``(start, stop, capture)`` for each ``chunk`` of frames (seeds ``(3, k)``), so that a
    million frames never sit in memory at once."""
    skeleton = random_tree(n_sensors, np.random.default_rng(2))

    def chunks() -> Iterator[tuple[int, int, SyntheticCapture]]:
        for k, start in enumerate(range(0, n_frames, chunk)):
            stop = min(start + chunk, n_frames)
            cap = simulate_motion(
                skeleton,
                n_frames=stop - start,
                rate_hz=120.0,
                rng=np.random.default_rng((3, k)),
                position_noise_m=0.004,
            )
            yield start, stop, cap

    return skeleton, chunks()


PEAK_RSS = """
def peak_rss_mib():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
"""
