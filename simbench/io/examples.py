"""The example files that ship inside the package, written out for a new user
(``simbench examples DIR``, ``sb.write_examples``).

A checkout has them at their places (``examples/``, ``studies/``, ``reports/baseline.json``); an
installed wheel has them in ``simbench/data/examples`` only. :func:`write_examples` lays them out
in a folder as in the checkout, so that every step of the README runs there.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from simbench.errors import InputError
from simbench.io.atomic import atomic_path

#: Where the packaged examples are.
PACKAGED = Path(__file__).resolve().parents[1] / "data" / "examples"

#: ``{packaged file: its place in the folder}``; the place is that of the repository.
EXAMPLE_FILES: dict[str, str] = {
    "linkage_exercise.csv": "examples/linkage_exercise.csv",
    "linkage_exercise_truth.json": "examples/linkage_exercise_truth.json",
    "sphere_fit.py.txt": "examples/estimators/sphere_fit.py",
    "pair_fit_cmd.py.txt": "examples/estimators/pair_fit_cmd.py",
    "quickstart.toml": "studies/quickstart.toml",
    "noise.toml": "studies/noise.toml",
    "slip.toml": "studies/slip.toml",
    "placement.toml": "studies/placement.toml",
    "hip_c3d.toml": "studies/hip_c3d.toml",
    "baseline.json": "reports/baseline.json",
}


def packaged_baseline() -> Path:
    """The accepted accuracy figures that ship with the package (``simbench baseline``'s default
    outside a checkout)."""
    return PACKAGED / "baseline.json"


def write_examples(folder: str | os.PathLike[str], *, force: bool = False) -> list[Path]:
    """Write the example recordings, studies, cluster spec, estimators and baseline into ``folder``
    (made if missing), laid out as in the repository (:data:`EXAMPLE_FILES`); returns the paths.

    Raises:
        InputError: ``folder`` is a file, or (without ``force``) one of the files is there already
            (nothing is written then).
    """
    root = Path(folder)
    if root.exists() and not root.is_dir():
        raise InputError(f"{root}: exists and is not a folder")
    targets = {PACKAGED / name: root / place for name, place in EXAMPLE_FILES.items()}
    missing = [str(src) for src in targets if not src.is_file()]
    if missing:
        raise InputError(f"the package's examples are incomplete: {missing} missing (a broken install?)")
    there = [str(dst) for dst in targets.values() if dst.exists()]
    if there and not force:
        raise InputError(
            f"{there[0]} exists ({len(there)} of the examples' files do); use --force to replace them"
        )
    written = []
    for src, dst in targets.items():
        dst.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)
        written.append(dst)
    return written


__all__ = ["EXAMPLE_FILES", "PACKAGED", "packaged_baseline", "write_examples"]
