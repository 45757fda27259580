"""The spread test's null quantiles (``calibration.clusters.SPREAD_NULL``), by Monte Carlo.

    .venv/bin/python scripts/cluster_spread_null.py [--workers 2]

One rigid body of ``n`` markers whose pairs' log distance spreads are independent standard normal
draws: the complete-linkage tree is built on them (as ``calibration.clusters`` builds it on the
spreads: the order, hence the tree, is the same for the logs), and at its top union the median log
spread of the pairs between the two branches less that of the pairs within them is recorded, by the
branches' sizes ``(smaller, larger)`` (two single markers, no within pair: not recorded). 400,000
sets for each ``n`` from 3 to 10 markers, 60,000 from 11 to 16, each ``n`` seeded on its own
(``SeedSequence(20240601, spawn_key=(n,))``). Prints the table of the 0.99 and 0.999 quantiles of
the sizes drawn at least 5,000 times, as the module holds it. About 15 minutes on two cores.
"""

from __future__ import annotations

import argparse
import itertools
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy.cluster.hierarchy import linkage

SEED = 20240601
SETS = {n: 400_000 if n <= 10 else 60_000 for n in range(3, 17)}
LEAST = 5_000


def draws(n: int) -> dict[tuple[int, int], list[float]]:
    """The statistic at the top union of ``SETS[n]`` sets of ``n`` markers, by branch sizes."""
    rng = np.random.default_rng(np.random.SeedSequence(SEED, spawn_key=(n,)))
    iu = np.triu_indices(n, 1)
    out: dict[tuple[int, int], list[float]] = {}
    for _ in range(SETS[n]):
        logs = rng.standard_normal(n * (n - 1) // 2)
        Z = linkage(logs - logs.min() + 1.0, method="complete")  # positive, same order
        nodes = [[i] for i in range(n)]
        for a, b, _, _ in Z:
            nodes.append(nodes[int(a)] + nodes[int(b)])
        A, B = nodes[int(Z[-1, 0])], nodes[int(Z[-1, 1])]
        if len(A) == 1 and len(B) == 1:
            continue
        D = np.zeros((n, n))
        D[iu] = logs
        D = D + D.T
        within = [D[i, j] for part in (A, B) for i, j in itertools.combinations(part, 2)]
        between = D[np.ix_(A, B)].ravel()
        key = (min(len(A), len(B)), max(len(A), len(B)))
        out.setdefault(key, []).append(float(np.median(between) - np.median(within)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    merged: dict[tuple[int, int], list[float]] = {}
    with ProcessPoolExecutor(args.workers) as pool:
        for part in pool.map(draws, sorted(SETS, key=lambda n: -n * SETS[n])):
            for key, values in part.items():
                merged.setdefault(key, []).extend(values)
    print("SPREAD_NULL: dict[tuple[int, int], tuple[float, float]] = {")
    for key in sorted(merged):
        values = np.array(merged[key])
        if len(values) >= LEAST:
            q99, q999 = np.quantile(values, [0.99, 0.999])
            print(f"    {key}: ({q99:.2f}, {q999:.2f}),  # {len(values)} draws")
    print("}")
    print(f"# {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
