"""The examples at the foot of each command's ``--help`` (one command line per line, ``#`` notes).

``tests/test_cli_help.py`` parses every line with the real parser, so an example cannot drift from
the options it shows.
"""

from __future__ import annotations

#: ``{command: lines}``; each line is a full ``simbench ...`` command, optionally followed by
#: ``  # a note``.
EXAMPLES: dict[str, tuple[str, ...]] = {
    "calibrate": (
        "simbench calibrate session.h5 --json calibration.json",
        "simbench calibrate poses.csv --units mm --hierarchy tree.json",
        "simbench calibrate markers.c3d --clusters clusters.toml  # or let the clusters be found",
        "simbench calibrate export.csv --wide liberty.toml --intervals",
        "simbench calibrate poses.csv --follow --timeout 600  # live, as a logger appends",
        "simbench calibrate poses.csv --method sphere-geometric",
    ),
    "replay": (
        "simbench replay session.h5 --rate 10x",
        "simbench replay poses.csv --rate max --refresh 5",
    ),
    "scale": ("simbench scale poses.csv --sensors A B --distance 0.30",),
    "simulate": (
        "simbench simulate -o session.h5",
        "simbench simulate --model humanoid --sensors polhemus-liberty --duration 30 -o human.h5",
        "simbench simulate --model humanoid --motion gait --sensors mems-consumer -o walk.h5",
        "simbench simulate --markers --marker-skin 2 -o markers.h5 --csv poses.csv --truth-json truth.json",
        "simbench simulate --motion clip.bvh --sensors imu-lab -o clip.h5  # a recorded motion",
    ),
    "export": (
        "simbench export session.h5 --trc markers.trc --c3d markers.c3d",
        "simbench export session.h5 --sto orientations.sto --imu-csv imu.csv",
        "simbench export session.h5 --osim model.osim --calibration calibration.json",
        "simbench export session.h5 --mjcf truth.xml  # the skeleton of the truth",
    ),
    "orient": (
        "simbench orient session.h5 --csv orientations.csv",
        "simbench orient trial.hdf5 --method triad",
        "simbench orient session.h5 --skeleton calibration.json",
    ),
    "twin": (
        "simbench twin trial.hdf5 --json twin.json --out twin/",
        "simbench twin trial.hdf5 --without time_offset --without gradient",
    ),
    "validate": (
        "simbench validate  # the main job: the paper's experiments, scored; reports/",
        "simbench validate --quick --out /tmp/report",
    ),
    "report": (
        "simbench report session.h5 --out report/",
        "simbench report poses.csv --calibration calibration.json",
    ),
    "baseline": (
        "simbench baseline  # exit 1 if an accuracy figure got worse",
        "simbench baseline --update",
        "simbench baseline --scenarios mine.toml",
    ),
    "sweep": (
        "simbench sweep studies/noise.toml --workers 2",
        "simbench sweep studies/noise.toml --scheduler tcp://127.0.0.1:8786",
    ),
    "examples": (
        "simbench examples first-steps  # then there: simbench calibrate examples/linkage_exercise.csv",
        "simbench examples . --force",
    ),
    "bench": (
        "simbench bench --quick",
        "simbench bench --estimator mypkg.joints:estimate --kind joints",
    ),
}


def epilog(command: str) -> str | None:
    """The ``examples:`` block of a command's help, or ``None``."""
    lines = EXAMPLES.get(command)
    return None if not lines else "examples:\n" + "\n".join(f"  {line}" for line in lines)
