"""How much real marker clusters deform: the rigid-fit residual of each cluster found (issue 42).

    .venv/bin/python studies/marker_deformation.py [--real PATH ...] [--seeds 3] [--out FILE]

Not a test: the figures behind ``simbench.sim.marker_clusters.simulate_markers``' deformation
(docs/cluster-finding.md, "Fourth round"). A marker's skin motion is a motion of its cluster
over the bone (no bone in a marker file: not measurable here) plus a deformation of the cluster;
the rigid fit of a cluster (``rigid_fit`` of its ``reference_shape``) takes out the common motion
(translation and rotation), so its residual is the deformation (and the camera noise). For every
moving cluster ``find_clusters`` finds on each real file (C3D and TRC):

- ``deform_mm``: the deformation per coordinate, mm: sqrt(sum of squared residuals over all frames
  and markers / (sum over frames of 3 k - 6)) -- the per-coordinate standard deviation of an
  independent isotropic deformation, corrected for the 6 degrees of freedom the fit takes;
- ``size_mm``: the cluster's radius, the rms distance of its markers from their centroid, mm;
- ``relative``: ``deform_mm / size_mm`` (unit-free);
- ``relative_noise``: the median over its pairs of distance spread over distance
  (``cluster_evidence.relative_noise``);
- ``corr_s``: the correlation time of the residual, s (first lag where the autocorrelation of
  the residual coordinates, averaged, falls below 1/e).

The same figures are taken for the humanoid's simulated segments (``sb.simulate("humanoid",
duration_s=20, seed=s, markers=MarkerConfig(skin_sd_m=0.002))``, seeds 0 to ``--seeds`` - 1) on
the markers' true segments. Results go to ``studies/results/marker_deformation.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import simbench as sb
from calibration.clusters import find_clusters, reference_shape, rigid_fit
from simbench.io.atomic import atomic_write_text
from simbench.io.c3d import read_c3d
from simbench.io.trc import read_trc
from simbench.sim.marker_clusters import MarkerConfig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cluster_evidence import relative_noise
from cluster_sessions import compact_json

OUT = Path(__file__).resolve().parent / "results" / "marker_deformation.json"
#: Trials without motion to deform a cluster: a standing pose, a probing trial.
STILL_NAMES = r"static|probing|anat_pose"


def correlation_s(residual: np.ndarray, rate_hz: float) -> float:
    """First lag (s) where the mean autocorrelation of the residual's coordinates falls below 1/e,
    over the longest stretch of frames where every marker is seen."""
    r = residual.reshape(len(residual), -1)
    full = np.concatenate([[False], np.isfinite(r).all(axis=1), [False]])
    edges = np.flatnonzero(np.diff(full.astype(int)))
    starts, ends = edges[::2], edges[1::2]
    if starts.size == 0:
        return float("nan")
    longest = int(np.argmax(ends - starts))
    r = r[starts[longest] : ends[longest]]
    if len(r) < 8:
        return float("nan")
    r = r - r.mean(axis=0)
    n = len(r)
    spec = np.fft.rfft(r, 2 * n, axis=0)
    acf = np.fft.irfft(np.abs(spec) ** 2, axis=0)[:n].mean(axis=1)
    acf = acf / acf[0]
    below = np.flatnonzero(acf < np.exp(-1.0))
    return float(below[0] / rate_hz) if below.size else float("nan")


def deformation(x: np.ndarray, rate_hz: float) -> dict[str, float]:
    """One cluster's deformation figures (module docstring); ``x`` ``(F, k, 3)`` in metres."""
    shape = reference_shape(x)
    fit = rigid_fit(shape, x)
    fitted = np.einsum("fij,kj->fki", fit.R_w_c, shape) + fit.p_w_c[:, None]
    residual = x - fitted
    seen = np.isfinite(residual).all(axis=2)
    counts = seen.sum(axis=1)
    dof = np.where(counts >= 3, 3 * counts - 6, 0).sum()
    ss = np.nansum(np.where(seen[..., None], residual, 0.0) ** 2)
    deform = float(np.sqrt(ss / dof)) if dof > 0 else float("nan")
    size = float(np.sqrt((shape**2).sum(axis=1).mean()))
    return {
        "k": int(x.shape[1]),
        "deform_mm": round(deform * 1e3, 3),
        "size_mm": round(size * 1e3, 1),
        "relative": round(deform / size, 4),
        "relative_noise": relative_noise(x, [list(range(x.shape[1]))])[0],
        "corr_s": round(correlation_s(residual, rate_hz), 3),
    }


def real(paths: list[Path]) -> list[dict[str, Any]]:
    """Each real file's moving clusters and their deformation; ``same_as`` names an earlier file
    with the same contents (or the same clusters' figures), ``still`` marks a static or probing
    trial (by its name). The summary takes neither."""
    files = sorted({f for p in paths for f in ([p] if p.is_file() else [*p.glob("*.c3d"), *p.glob("*.trc")])})
    rows: list[dict[str, Any]] = []
    seen: dict[str, str] = {}
    for f in files:
        digest = hashlib.sha256(f.read_bytes()).hexdigest()
        if digest in seen:
            rows.append({"file": f.name, "same_as": seen[digest]})
            continue
        seen[digest] = f.name
        try:
            if f.suffix == ".c3d":
                read = read_c3d(f)
                x, rate, labels = read.xyz_m, read.rate_hz, read.labels
            else:
                read = read_trc(f)
                x, rate, labels = read.xyz, read.rate_hz, read.labels
        except Exception as error:  # a study: a file not read is recorded
            rows.append({"file": f.name, "not read": str(error)[:120]})
            continue
        found = find_clusters(x)
        clusters = []
        for c in found.clusters:
            clusters.append({"labels": [labels[i] for i in c], **deformation(x[:, c], rate)})
        figures = json.dumps([[c["deform_mm"], c["size_mm"]] for c in clusters])
        if clusters and figures in seen:
            rows.append({"file": f.name, "same_as": seen[figures]})
            continue
        seen[figures] = f.name
        still = bool(re.search(STILL_NAMES, f.name, re.IGNORECASE))
        rows.append({"file": f.name, "rate_hz": rate, "still": still, "clusters": clusters})
    return rows


def simulated(seeds: int, skin_m: float) -> list[dict[str, Any]]:
    """The humanoid's segments' deformation at ``skin_m``, seeds ``0 .. seeds - 1``."""
    rows = []
    for seed in range(seeds):
        ds = sb.simulate("humanoid", duration_s=20.0, seed=seed, markers=MarkerConfig(skin_sd_m=skin_m))
        segment = np.array(ds.markers.segment)
        rate = (ds.time_s.size - 1) / float(ds.time_s[-1] - ds.time_s[0])
        for s in ds.sensors:
            c = np.flatnonzero(segment == s)
            rows.append({"seed": seed, "segment": s, **deformation(ds.markers.xyz[:, c], rate)})
    return rows


def quantiles(values: list[float]) -> dict[str, float]:
    """Minimum, quartiles, maximum."""
    v = np.asarray([x for x in values if np.isfinite(x)])
    q = np.percentile(v, [0, 25, 50, 75, 100]) if v.size else [float("nan")] * 5
    return dict(zip(("min", "q25", "median", "q75", "max"), (round(float(a), 4) for a in q), strict=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, nargs="*", default=[])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--skin-mm", type=float, default=2.0)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    start = time.perf_counter()
    files = real(args.real)
    clusters = [c for f in files if not f.get("still", True) for c in f["clusters"]]
    sim = simulated(args.seeds, args.skin_mm / 1e3)
    summary = {
        "real": {
            "files": sum(bool(f.get("clusters")) and not f["still"] for f in files),
            "clusters": len(clusters),
            **{key: quantiles([c[key] for c in clusters]) for key in ("deform_mm", "size_mm", "relative")},
            "relative_noise": quantiles([c["relative_noise"] for c in clusters]),
            "corr_s": quantiles([c["corr_s"] for c in clusters]),
        },
        f"humanoid {args.skin_mm:g} mm": {
            "segments": len(sim),
            **{
                key: quantiles([c[key] for c in sim])
                for key in ("deform_mm", "size_mm", "relative", "relative_noise", "corr_s")
            },
        },
    }
    result = {
        "summary": summary,
        "real": files,
        "simulated": sim,
        "seconds": round(time.perf_counter() - start, 1),
    }
    atomic_write_text(args.out, compact_json(result, ("real", "simulated")))
    print(json.dumps(summary, indent=1))
    print(f"wrote {args.out} in {result['seconds']} s")


if __name__ == "__main__":
    main()
