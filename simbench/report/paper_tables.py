"""O'Brien et al.'s Tables 1-4 beside simbench's, with the causes measured (validation report).

Turns :func:`simbench.experiments.obrien.paper_tables`'s figures into Markdown: per table the
measured (paper) and true (simbench) length of each row, the paper's computed lengths and mean
difference, simbench's computed length and difference as mean +- standard deviation over its
seeded trials; the sentence that explains the difference; and the table of the same figures with
each effect switched off.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simbench.report.markdown import markdown_table


def _pm(spread: dict[str, float]) -> str:
    if spread["n"] == 0:
        return "-"
    return f"{spread['mean']:.2f} ± {spread['sd']:.2f}"


def _rows(table: dict[str, Any]) -> list[list[Any]]:
    rows = []
    for name, r in table["rows"].items():
        paper_diff = np.asarray(r["paper_difference_cm"], dtype=float)
        rows.append(
            [
                name,
                r["measured_cm"],
                r["true_cm"],
                " ".join(f"{x:.1f}" for x in r["paper_computed_cm"]),
                f"{paper_diff.mean():+.2f} ({paper_diff.min():+.1f} to {paper_diff.max():+.1f})",
                _pm(r["simbench_computed_cm"]),
                _pm(r["simbench_difference_cm"]),
            ]
        )
    return rows


def _cause_rows(table: dict[str, Any]) -> list[list[Any]]:
    """Largest error, mean difference, negatives and the paper's largest row's mean, per variant."""
    row = table["paper"]["largest_rows"][0]
    named = {"none": "nothing", "all": "all of them"}
    summaries = [("the paper", table["paper"])]
    if "none" not in table["causes"]:
        summaries.append(("nothing (as in the table)", table["simbench"]))
    summaries += [(named.get(c, c), s) for c, s in table["causes"].items()]
    return [
        [
            label,
            s["max_abs_cm"],
            s["max_row"],
            f"{s['mean_cm']:+.2f}",
            f"{s['longer']} of {s['n']}",
            s["row_mean_cm"][row],
        ]
        for label, s in summaries
    ]


def paper_tables_markdown(tables: list[dict[str, Any]], presets: dict[str, str]) -> list[str]:
    """The section's Markdown lines.

    Args:
        tables: :func:`simbench.experiments.obrien.paper_tables`'s result.
        presets: ``{table key: preset name}`` for the headings.
    """
    out = [
        "## The paper's tables side by side",
        "",
        "Differences are computed minus measured (paper) or true (simbench), in cm, the estimate "
        "minus the truth as everywhere in simbench (the paper printed measured minus computed); "
        "positive: computed longer. simbench's columns are mean ± standard deviation over its seeded trials "
        "(the paper's are its trials' values). Under each table, the same figures with each "
        "effect of the preset switched off in turn (the unit scale factor measured again each "
        "time); for the human tables over the table's first trial.",
        "",
    ]
    for table in tables:
        sim_n = next(iter(table["rows"].values()))["simbench_difference_cm"]["n"]
        out += [
            f"### {table['title']}: the paper's {len(table['trials'])} trials, simbench's {sim_n} "
            f"(preset {presets.get(table['key'], '?')})",
            "",
            markdown_table(
                [
                    "row",
                    "measured (paper)",
                    "true (simbench)",
                    "paper computed",
                    "paper difference, mean (range)",
                    "simbench computed",
                    "simbench difference",
                ],
                _rows(table),
            ),
            "",
        ]
        if table["causes"]:
            row = table["paper"]["largest_rows"][0]
            out += [
                table["explanation"],
                "",
                markdown_table(
                    [
                        "switched off",
                        "largest error",
                        "in row",
                        "mean difference",
                        "computed longer",
                        f"{row}, mean",
                    ],
                    _cause_rows(table),
                ),
                "",
            ]
    return out
