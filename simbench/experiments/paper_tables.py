"""Tables 1-4 of O'Brien et al. 2000, transcribed: measured and computed lengths, cm.

The seed text (``../shared/seeds/obrien2000_joint_parameter_estimation.txt``) is not shipped with
simbench, so the tables live here as data. Each row holds the length measured by hand, the length
the paper computed in each trial and the difference it printed (measured minus computed: a
negative difference is a computed length longer than the measured one). The differences are kept
as printed rather than recomputed, so that a transcription error shows as a disagreement
(``tests/test_paper_tables.py``); where the seed text is at hand the test also compares every
number with it.

- Table 1: the wooden linkage, six sets (Set 6 after the sensors were moved).
- Table 2: the male subject, four exercise trials.
- Table 3: the male subject, three walk trials.
- Table 4: the female subject, one exercise and two walk trials.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class PaperTable:
    """One of the paper's tables.

    Attributes:
        title: what the table holds.
        trials: ``(T,)`` the trials' names, in the table's order.
        measured_cm: row name -> the length measured by hand, cm.
        computed_cm: row name -> ``(T,)`` the paper's computed lengths, cm.
        printed_difference_cm: row name -> ``(T,)`` the printed measured minus computed, cm
            (kept as printed; :func:`side_by_side` shows them negated, computed minus measured).
    """

    title: str
    trials: tuple[str, ...]
    measured_cm: dict[str, float]
    computed_cm: dict[str, tuple[float, ...]]
    printed_difference_cm: dict[str, tuple[float, ...]]

    @property
    def rows(self) -> tuple[str, ...]:
        """The rows' names, in the table's order."""
        return tuple(self.measured_cm)

    def difference_cm(self) -> np.ndarray:
        """``(rows, T)`` the printed differences (measured minus computed), cm."""
        return np.array([self.printed_difference_cm[r] for r in self.rows], dtype=float)


def _table(title: str, trials: tuple[str, ...], text: dict[str, str]) -> PaperTable:
    """A table from its rows as printed: measured, the computed lengths, the differences."""
    n = len(trials)
    rows = {name: tuple(float(x) for x in line.split()) for name, line in text.items()}
    for name, values in rows.items():
        if len(values) != 1 + 2 * n:
            raise ValueError(f"{title}, row {name!r}: expected {1 + 2 * n} numbers, got {len(values)}")
    return PaperTable(
        title=title,
        trials=trials,
        measured_cm={r: v[0] for r, v in rows.items()},
        computed_cm={r: tuple(v[1 : 1 + n]) for r, v in rows.items()},
        printed_difference_cm={r: tuple(v[1 + n :]) for r, v in rows.items()},
    )


#: Each row as printed: measured, the computed lengths, the differences (cm).
TABLE_1 = _table(
    "Table 1: the wooden linkage",
    ("Set 1", "Set 2", "Set 3", "Set 4", "Set 5", "Set 6"),
    {
        "Neck - Left Shoulder": "39.0 39.4 38.8 39.8 39.1 39.1 40.1 -0.4 0.2 -0.8 -0.1 -0.1 -1.1",
        "Neck - Right Shoulder": "39.7 39.8 39.8 40.3 40.0 39.9 40.3 -0.1 -0.1 -0.6 -0.3 -0.2 -0.6",
        "Between Shoulders": "34.3 34.3 33.7 34.5 34.3 34.3 34.8 0.0 0.6 -0.2 0.0 0.0 -0.5",
        "Right Upper Arm": "28.6 29.2 29.0 28.8 28.9 29.0 29.1 -0.6 -0.4 -0.2 -0.3 -0.4 -0.5",
        "Left Upper Arm": "31.4 31.5 31.7 31.9 31.5 31.1 31.2 -0.1 -0.3 -0.5 -0.1 0.3 0.2",
    },
)
TABLE_2 = _table(
    "Table 2: the male subject, exercise",
    ("Exer. 1", "Exer. 2", "Exer. 3", "Exer. 4"),
    {
        "Right Lower Leg": "40.0 40.8 40.9 42.2 42.5 -0.8 -0.9 -2.2 -2.5",
        "Left Lower Leg": "40.3 37.3 38.4 41.2 41.5 3.0 1.9 -0.9 -1.2",
        "Right Upper Leg": "41.6 41.5 42.1 42.9 42.2 0.1 -0.5 -1.3 -0.6",
        "Left Upper Leg": "43.2 41.4 41.8 43.2 43.0 1.8 1.4 0.0 0.2",
        "Right Lower Arm": "27.0 26.3 26.7 27.7 27.0 0.7 0.3 -0.7 0.0",
        "Left Lower Arm": "26.7 26.5 27.0 26.7 27.1 0.1 -0.3 -0.1 -0.4",
        "Right Upper Arm": "29.5 32.1 31.3 29.3 28.8 -2.6 -1.8 0.2 0.7",
        "Left Upper Arm": "29.5 33.7 32.9 30.1 29.9 -4.1 -3.4 -0.6 -0.4",
    },
)
TABLE_3 = _table(
    "Table 3: the male subject, walk",
    ("Walk 1", "Walk 2", "Walk 3"),
    {
        "Right Lower Leg": "40.0 40.7 40.3 38.9 -0.6 -0.3 1.1",
        "Left Lower Leg": "40.3 40.8 38.9 39.8 -0.4 1.4 0.5",
        "Right Upper Leg": "41.6 40.7 40.6 42.6 0.9 1.0 -1.0",
        "Left Upper Leg": "43.2 45.1 42.7 43.1 -1.9 0.5 0.1",
        "Right Lower Arm": "27.0 27.3 27.5 25.8 -0.3 -0.5 1.2",
        "Left Lower Arm": "26.7 26.2 24.9 25.6 0.5 1.7 1.0",
        "Right Upper Arm": "29.5 31.0 31.1 32.7 -1.4 -1.6 -3.2",
        "Left Upper Arm": "29.5 32.3 32.3 30.8 -2.7 -2.7 -1.3",
    },
)
TABLE_4 = _table(
    "Table 4: the female subject",
    ("Exer. 1", "Walk 1", "Walk 2"),
    {
        "Right Lower Leg": "36.8 39.1 38.0 38.1 -2.3 -1.2 -1.3",
        "Left Lower Leg": "36.5 37.6 37.0 37.4 -1.1 -0.5 -0.9",
        "Right Upper Leg": "42.2 42.9 43.3 42.2 -0.7 -1.1 0.0",
        "Left Upper Leg": "41.9 42.4 44.1 42.9 -0.5 -2.2 -1.0",
        "Right Lower Arm": "24.8 25.5 25.3 22.4 -0.7 -0.5 2.3",
        "Left Lower Arm": "24.8 25.1 24.8 23.0 -0.3 0.0 1.8",
        "Right Upper Arm": "27.6 27.5 27.5 28.7 0.2 0.1 -1.0",
        "Left Upper Arm": "27.6 28.5 30.0 29.0 -0.9 -2.4 -1.3",
    },
)
TABLES = (TABLE_1, TABLE_2, TABLE_3, TABLE_4)


def difference_summary(differences_cm: dict[str, list[float]]) -> dict[str, Any]:
    """The figures a table's differences are compared by (computed minus measured or true, cm).

    Args:
        differences_cm: row name -> the differences of its trials, cm (NaN where a trial has no
            value).

    Returns:
        ``max_abs_cm`` and the row it is in (``max_row``), ``mean_cm`` over all differences,
        ``longer`` (computed longer: positive) of ``n``, ``row_mean_cm`` (each row's mean difference) and
        ``largest_rows``: the rows by mean absolute difference, largest first.
    """
    rows = list(differences_cm)
    d = [np.asarray(differences_cm[r], dtype=float) for r in rows]
    flat = np.concatenate(d)
    ok = np.isfinite(flat)
    row_max = [float(np.nanmax(np.abs(x))) if np.isfinite(x).any() else -1.0 for x in d]
    row_mean = [float(np.nanmean(np.abs(x))) if np.isfinite(x).any() else -1.0 for x in d]
    return {
        "max_abs_cm": float(np.max(np.abs(flat[ok]))) if ok.any() else float("nan"),
        "max_row": rows[int(np.argmax(row_max))],
        "mean_cm": float(np.mean(flat[ok])) if ok.any() else float("nan"),
        "longer": int(np.sum(flat[ok] > 0)),
        "n": int(ok.sum()),
        "row_mean_cm": {
            r: float(np.nanmean(x)) if np.isfinite(x).any() else float("nan")
            for r, x in zip(rows, d, strict=True)
        },
        "largest_rows": [rows[k] for k in np.argsort(row_mean, kind="stable")[::-1]],
    }


def _spread(values: list[float]) -> dict[str, float]:
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"mean": float("nan"), "sd": float("nan"), "n": 0}
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)) if x.size > 1 else 0.0, "n": int(x.size)}


def side_by_side(table: PaperTable, runs: list[dict[str, dict[str, float]]]) -> dict[str, Any]:
    """One of the paper's tables beside simbench's trials of the same kind.

    Args:
        table: the paper's table.
        runs: simbench's trials (each its own seed), each ``{row: {"true_cm", "computed_cm",
            "difference_cm"}}`` with every row of ``table`` (cm; difference = computed - true).

    Returns:
        JSON-ready: ``title``, ``trials`` (the paper's), per row the measured length, the paper's
        computed lengths and differences (computed minus measured: the paper printed the opposite,
        measured minus computed; one sign, estimate minus truth, in every simbench table),
        simbench's true length and its computed lengths and
        differences as mean, sample standard deviation and count over the trials; and the
        :func:`difference_summary` of the paper's and of simbench's differences.
    """
    missing = [r for r in table.rows if any(r not in run for run in runs)]
    if missing or not runs:
        raise ValueError(f"{table.title}: simbench's trials lack rows {missing or list(table.rows)}")
    rows = {}
    for r in table.rows:
        rows[r] = {
            "measured_cm": table.measured_cm[r],
            "paper_computed_cm": list(table.computed_cm[r]),
            "paper_difference_cm": [-x for x in table.printed_difference_cm[r]],  # computed - measured
            "true_cm": runs[0][r]["true_cm"],
            "simbench_computed_cm": _spread([run[r]["computed_cm"] for run in runs]),
            "simbench_difference_cm": _spread([run[r]["difference_cm"] for run in runs]),
        }
    return {
        "title": table.title,
        "trials": list(table.trials),
        "rows": rows,
        "paper": difference_summary({r: [-x for x in table.printed_difference_cm[r]] for r in table.rows}),
        "simbench": difference_summary({r: [run[r]["difference_cm"] for run in runs] for r in table.rows}),
    }
