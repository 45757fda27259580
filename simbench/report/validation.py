"""The validation report: O'Brien et al.'s and Fontaine et al.'s figures beside simbench's.

:func:`write_report` turns the figures of :func:`simbench.experiments.validate.run_validation` into
``index.md``, a self-contained ``index.html`` (images embedded), ``results.json`` and the PNG
images beside them. Writes are atomic. The pictures of the linkage need an offscreen GL context
(:mod:`simbench.report.pictures`); without one they are skipped and the report says so.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from simbench.report.decisions import decisions_markdown
from simbench.report.markdown import markdown_table
from simbench.report.output import write_report_files
from simbench.report.paper_tables import paper_tables_markdown
from simbench.report.pictures import render_joint_centres
from simbench.report.plots import (
    limb_spread,
    plot_limb_errors,
    plot_limb_lengths,
    plot_orientation,
    plot_residual_histograms,
    plot_slip,
)
from simbench.report.realism import realism_markdown
from simbench.sim.models import load_capture_model
from simbench.versions import software_versions


def _side_by_side(results: dict[str, Any]) -> list[str]:
    """The paper's figures beside simbench's."""
    s = results["summary"]
    p = results["paper"]
    unit_scale = results["unit_scale"]
    f = results["walk_failures"]["summary"]
    n_walks = len(results["walk_failures"]["seeds"])
    rows = [
        ["unit scale factor (two sensors 56.5 cm apart)", p["unit_scale"], unit_scale["scale"]],
        ["scaled std of their distance (cm)", p["scaled_std_cm"], unit_scale["scaled_std_cm"]],
        ["linkage: max length error (cm)", p["linkage_max_error_cm"], s["linkage_max_error_cm"]],
        [
            "linkage: hierarchy",
            p["linkage_hierarchy"],
            f"correct in {s['linkage_hierarchy_correct']} of {s['linkage_sets']} sets",
        ],
        ["human: max limb error (cm)", p["male_max_error_cm"], s["humanoid_max_error_cm"]],
        [
            "exercise trials: hierarchy",
            p["exercise_hierarchy"],
            f"correct in {s['exercise_hierarchy_correct']} of {s['exercise_trials']}",
        ],
        [
            "walk trials: hierarchy",
            p["walk_hierarchy"],
            f"correct in {s['walk_hierarchy_correct']} of {s['walk_trials']} (the paper's minimum spanning "
            f"tree: {s['walk_hierarchy_correct_mst']} of {s['walk_trials']})",
        ],
        [
            "walks with the paper's failure: transmitter on the stand, hips about one axis",
            p["walk_hierarchy"],
            f"minimum spanning tree correct in {f['mst']['correct']} of {n_walks} (one thigh the child of "
            f"the other in {f['mst']['thigh_child_of_thigh']}); misfit tree correct in "
            f"{f['misfit']['correct']} of {n_walks}",
        ],
    ]
    return [
        "## The paper and simbench side by side",
        "",
        markdown_table(["figure", "paper", "simbench"], rows),
        "",
    ]


def _lengths_table(first: str, tables: list[dict[str, Any]], names: list[str], diff_names: list[str]) -> str:
    """True lengths and the computed ones of several sets or trials, then their differences in a
    table of their own (cm): one row per length, so that many trials keep the tables within a
    page's width.

    Args:
        first: the title of the first column (what a row is).
        tables: each ``{"rows": {label: {"true_cm", "computed_cm", "difference_cm"}}}``.
        names, diff_names: the titles of each table's computed and difference columns.
    """
    labels = list(tables[0]["rows"])
    computed = markdown_table(
        [first, "true", *names],
        [
            [label, tables[0]["rows"][label]["true_cm"], *[t["rows"][label]["computed_cm"] for t in tables]]
            for label in labels
        ],
    )
    differences = markdown_table(
        [first, *diff_names],
        [[label, *[t["rows"][label]["difference_cm"] for t in tables]] for label in labels],
    )
    return computed + "\n\n" + differences


def _linkage(linkage: dict[str, Any]) -> list[str]:
    """O'Brien's Table 1: the wooden linkage."""
    sets = linkage["sets"]
    hierarchy = ", ".join(f"set {x['set']} {'correct' if x['hierarchy_correct'] else 'WRONG'}" for x in sets)
    return [
        f"## Linkage (Table 1): {len(sets)} sets, `{linkage['preset']}`, {linkage['duration_s']:g} s each",
        "",
        "Computed joint-to-joint distances (cm, converted with the measured unit scale factor) and "
        "computed minus true differences.",
        "",
        _lengths_table(
            "distance", sets, [f"set {x['set']}" for x in sets], [f"diff {x['set']}" for x in sets]
        ),
        "",
        "Hierarchy per set: " + hierarchy,
        "",
    ]


def _tree_verdict(correct: bool, wrong_edges: Any) -> str:
    """``"correct"``, or ``"wrong: a-b, c-d"`` naming the inferred tree's edges the truth lacks."""
    if correct:
        return "correct"
    return "wrong: " + (", ".join(wrong_edges) if wrong_edges else "(edges not recorded)")


def _humanoid(humanoid: dict[str, Any]) -> list[str]:
    """O'Brien's Tables 2-4: the human subject's limb lengths and hierarchies."""
    trials = humanoid["trials"]
    hierarchies = [
        [
            t["trial"],
            _tree_verdict(t["hierarchy_correct"], t.get("wrong_joints", ())),
            _tree_verdict(t["hierarchy_correct_mst"], t.get("wrong_joints_mst", ())),
            t["thigh_parents"]["thigh_l"],
            t["thigh_parents"]["thigh_r"],
            t["max_abs_error_cm"],
        ]
        for t in trials
    ]
    return [
        f"## Human subject (Tables 2-4): `{humanoid['preset']}`, {humanoid['duration_s']:g} s trials",
        "",
        "Limb lengths (cm) computed with the true hierarchy, as the paper reports them; computed minus "
        "true in the difference columns.",
        "",
        _lengths_table("limb", trials, [t["trial"] for t in trials], [f"diff {t['trial']}" for t in trials]),
        "",
        markdown_table(
            [
                "trial",
                "hierarchy (misfit)",
                "hierarchy (paper's tree)",
                "thigh_l parent",
                "thigh_r parent",
                "max error (cm)",
            ],
            hierarchies,
        ),
        "",
        *_limb_spread(humanoid),
    ]


def _limb_spread(humanoid: dict[str, Any]) -> list[str]:
    """Each subject's limb lengths over its trials (seeds): the truth, the mean estimate and its
    spread (the scatter of the figures shows every trial)."""
    rows = [
        [s.subject, s.limb, s.true_mm, s.mean_mm, s.sd_mm, len(s.estimated_mm)] for s in limb_spread(humanoid)
    ]
    return [
        "Limb lengths over each subject's trials (one seed each): the mean estimate and the sample "
        "standard deviation over the trials, mm (figure: estimate against truth).",
        "",
        markdown_table(["subject", "limb", "true (mm)", "mean estimate (mm)", "s.d. (mm)", "trials"], rows),
        "",
    ]


def _walk_failures(walks: dict[str, Any]) -> list[str]:
    """The paper's walk failure reproduced, with both hierarchy methods."""
    rows = []
    for t in walks["trials"]:
        for method in ("mst", "misfit"):
            m = t["methods"][method]
            rows.append(
                [
                    f"walk {t['seed']}",
                    {"mst": "paper's minimum spanning tree", "misfit": "misfit (default)"}[method],
                    "correct" if m["correct"] else "WRONG",
                    ", ".join(m["wrong_edges"]) or "-",
                    "yes" if m["thigh_child_of_thigh"] else "no",
                ]
            )
    return [
        "## Walk hierarchies: the paper's failure and the fix",
        "",
        "The paper's walks made one thigh the child of the other in 3 of 5 trials. Here: walks whose "
        "hips turn nearly about one lateral axis (as a person's do), the transmitter on the stand in "
        "front (the far end of the walk 2 m away, its noise growing as r^4), the pelvis sensor on "
        "the pushed pack; each tree by the paper's method and by the default, which weighs each pair "
        "by its residual less the residual's own noise (`calibration.hierarchy`). "
        "`studies/walk_hierarchy.py` runs 20 seeds of each condition.",
        "",
        markdown_table(["trial", "method", "tree", "wrong edges", "one thigh the other's child"], rows),
        "",
    ]


def _slip_and_orientation(slip: dict[str, Any], orientation: dict[str, Any]) -> list[str]:
    """Slip detection, and the sourceless orientation estimators' errors."""
    events = ", ".join(f"{t:.2f} s" for t in slip["events_s"]) or "nothing"
    jumps = ", ".join(f"{j:.1f} mm" for j in slip["jumps_mm"])
    errors = [
        [k, v["total_rmse_deg"], v["heading_rmse_deg"], v["inclination_rmse_deg"]]
        for k, v in orientation["methods"].items()
    ]
    return [
        "## Slip detection",
        "",
        f"A 3 cm slip of the left forearm's sensor at {slip['true_slip_s']:.1f} s: detected at "
        f"{events} (jump {jumps}) on joint `{slip['joint']}`.",
        "",
        f"## Sourceless orientation (humanoid exercise, `{orientation['preset']}`)",
        "",
        "`skeleton`, the default, estimates every sensor over the whole session at once on the skeleton "
        "that `simbench calibrate` finds from the same session's tracker poses, each joint kept within "
        "the range of motion those poses show: a joint's acceleration is the same seen from both its "
        "sensors, so the limbs' linear acceleration is predicted from the chain's motion instead of "
        "being taken for gravity. On BROAD (one IMU, no skeleton) the sensor moves on its own: its "
        "velocity, the integral of its linear acceleration, has a prior, and its angular acceleration "
        "another. The others are per sample: Fontaine et al.'s weighted quadratic error minimised by "
        "Gauss-Newton (`fontaine`), the same minimum in closed form (`wahba`: the two rows agree, a "
        "check of the iteration), and TRIAD; VQF uses the gyroscope.",
        "",
        markdown_table(["estimator", "total RMSE (deg)", "heading", "inclination"], errors),
        "",
        *_simulation_target(orientation),
        *_broad_orientation(orientation.get("broad", {})),
    ]


def _simulation_target(orientation: dict[str, Any]) -> list[str]:
    """The default estimator's simulation target, met or not."""
    if "target_deg" not in orientation:
        return []
    d = orientation["default"]
    verdict = "met" if orientation["target_met"] else "**not met**"
    return [
        f"Target for the default gyro-free estimator ({d}): total RMSE at most "
        f"{orientation['target_deg']:g} degrees: {verdict} "
        f"({orientation['methods'][d]['total_rmse_deg']:.2f} degrees).",
        "",
    ]


def _broad_orientation(broad: dict[str, Any]) -> list[str]:
    """Each estimator on the BROAD trials at hand, against TRIAD and the default's target."""
    out = []
    for trial, r in broad.items():
        rows = [
            [k, v["total_deg"], v["heading_deg"], v["inclination_deg"], v["ratio_to_triad"]]
            for k, v in r["methods"].items()
        ]
        verdict = "met" if r["target_met"] else "**not met**"
        out += [
            f"### BROAD trial {trial} (real IMU, optical reference)",
            "",
            markdown_table(["estimator", "total RMSE (deg)", "heading", "inclination", "x TRIAD"], rows),
            "",
            f"Target for the default gyro-free estimator ({r['default']}): at most {r['target_ratio']:g} x "
            f"TRIAD's total RMSE: {verdict} ({r['methods'][r['default']]['ratio_to_triad']:.2f} x).",
            "",
        ]
    return out


def _joint_methods(methods: dict[str, Any] | None) -> list[str]:
    """Every joint-centre method on the same sessions, and O'Brien's regions' coverage."""
    if not methods:
        return []
    out = [
        "## Joint-centre methods side by side",
        "",
        "Each built-in joints estimator that takes poses (`simbench.estimators`) on the joints of "
        f"the true hierarchy of the same seeded exercise sessions ({methods['seeds']} seed(s) x "
        f"{methods['duration_s']:g} s per condition): mean joint-centre error (parent frame) and "
        "limb-length error, mm. SARA's centre on a ball joint is an arbitrary point of an "
        "arbitrary axis: no accuracy figure. "
        "`studies/methods.py` runs more seeds and conditions.",
        "",
    ]
    conditions = methods["conditions"]
    names = list(next(iter(conditions.values()))["methods"])
    rows = [
        [name, *[f"{c['methods'][name]['centre_error_mm']:.2f}" for c in conditions.values()]]
        for name in names
    ]
    out += [markdown_table(["method (centre error, mm)", *conditions], rows), ""]
    rows = [
        [name, *[f"{c['methods'][name]['length_error_mm']:.2f}" for c in conditions.values()]]
        for name in names
    ]
    out += [markdown_table(["method (length error, mm)", *conditions], rows), ""]
    rows = []
    for label, c in conditions.items():
        cov = c["coverage"]
        rows.append([label, *[_share(cov[k]) for k in ("batch-means", "iid", "eiv") if k in cov]])
    out += [
        "O'Brien's 95 % regions (both sensor frames of every joint) that hold the true centre: "
        "batch means over blocks long against the residual's correlation (`calibration.uncertainty`, "
        "the default of `simbench calibrate --intervals`) against i.i.d. residuals; and the fit "
        "corrected for the rotations' noise (`obrien-eiv`, `calibration.eiv`), batch means. A "
        "batch-means region is bounded by the 95 % quantile of its own statistic simulated under the "
        "working model (`calibration.uncertainty.working_model_null`), or by Hotelling's T² where "
        "the recording is too short for the blocks the residual's correlation asks for. "
        "Target 93-97 %.",
        "",
        markdown_table(
            ["session", "O'Brien, batch means", "O'Brien, i.i.d.", "corrected, batch means"], rows
        ),
        "",
    ]
    study = methods.get("study")
    if study:
        out += [
            f"Over {study['seeds']} seeds per condition ({study['duration_s']:g} s sessions; "
            f"`{study['command']}`, `{study['file']}`), the share of 95 % regions that hold the "
            "true centre, and the share of the corrected fit's batch-means regions that are bounded "
            "at all: with fewer independent blocks than dimensions (a residual correlated over "
            "seconds in a short session) the region is all of space and holds the truth trivially. "
            "The slip condition's sensors slip by 1.5-2 cm half-way through a Polhemus session.",
            "",
            markdown_table(
                [
                    "condition",
                    "O'Brien, batch means",
                    "O'Brien, i.i.d.",
                    "corrected, batch means",
                    "corrected, i.i.d.",
                    "bounded",
                    "corrected, batch means, of the bounded",
                    "regions",
                ],
                [
                    [
                        name,
                        *[f"{100 * v:.1f} %" for v in row["shares"]],
                        "-" if row.get("bounded") is None else f"{100 * row['bounded']:.1f} %",
                        _bounded_share(row),
                        str(row["regions"]),
                    ]
                    for name, row in study["conditions"].items()
                ],
            ),
            "",
        ]
    return out


def _bounded_share(row: dict[str, Any]) -> str:
    """The corrected fit's batch-means coverage among its bounded regions: an unbounded region
    always holds the truth, so ``(share - (1 - bounded)) / bounded``."""
    bounded = row.get("bounded")
    if not bounded:
        return "-"
    return f"{100 * (row['shares'][2] - (1.0 - bounded)) / bounded:.1f} %"


def _share(hits: dict[str, int]) -> str:
    """``covered / regions`` as a percentage with the count."""
    return f"{100 * hits['covered'] / max(hits['regions'], 1):.0f} % of {hits['regions']}"


def _figures_and_provenance(results: dict[str, Any], images: dict[str, str]) -> list[str]:
    """The images, and what made the report (run time, plan, versions, seeds)."""
    out = ["## Figures", ""]
    for title, name in images.items():
        out += [f"### {title}", "", f"![{title}]({name})", ""]
    if not any("pictures" in t for t in images):
        out += ["(No pictures: no offscreen GL context on this machine.)", ""]
    return [
        *out,
        "## Provenance",
        "",
        f"- run time: {results['run_time_s']:.1f} s",
        f"- plan: `{json.dumps(results['plan'])}`",
        f"- versions: `{json.dumps(results['versions'])}`",
        "- seeds: linkage sets 1..N (set 6 with the sensors moved), male subject 101.., female 201.. "
        "(walks 211..), slip 21, "
        "orientation 31, unit scale 7, decisions: slips 1000.., hinges and clusters 0.., joint-centre "
        "methods 41..",
        "- every figure is in `results.json`",
        "",
    ]


def validation_markdown(results: dict[str, Any], images: dict[str, str]) -> str:
    """The validation report in Markdown (tables, image links).

    Args:
        results: the figures of :func:`simbench.experiments.validate.run_validation`, with
            ``versions`` added.
        images: ``{title: file name}`` of the images beside the report.
    """
    quick = "Quick variant (CI): fewer, shorter sessions." if results["quick"] else ""
    out = [
        "# simbench validation report",
        "",
        "O'Brien et al. (2000)'s experiments reproduced in simulation (MuJoCo physics, modelled "
        "sensors) and scored against the exact truth; Fontaine et al.'s sourceless orientation "
        f"scored the same way. {quick}",
        "",
        *_side_by_side(results),
        *paper_tables_markdown(
            results["paper_tables"],
            {
                "table_1": results["linkage"]["preset"],
                **dict.fromkeys(("table_2", "table_3", "table_4"), results["humanoid"]["preset"]),
            },
        ),
        *_linkage(results["linkage"]),
        *_humanoid(results["humanoid"]),
        *_walk_failures(results["walk_failures"]),
        *_slip_and_orientation(results["slip"], results["orientation"]),
        *decisions_markdown(results["decisions"]),
        *realism_markdown(results["realism"]),
        *_joint_methods(results.get("joint_methods")),
        *_figures_and_provenance(results, images),
    ]
    return "\n".join(out)


def write_report(results: dict[str, Any], keep: dict[str, Any], out: Path) -> dict[str, Path]:
    """Write the validation report into ``out``; returns the paths written.

    Args:
        results: the figures of :func:`simbench.experiments.validate.run_validation`.
        keep: what the run kept for the pictures: ``linkage_ds`` (the first linkage set's
            dataset) and ``linkage_cal`` (its calibration).
        out: the report folder (made if missing).

    Returns:
        ``{"md": ..., "html": ..., "json": ...}``: the paths written (the PNGs lie beside them).
    """
    out.mkdir(parents=True, exist_ok=True)
    results = dict(results, versions=software_versions())
    scale = results["unit_scale"]["scale"]
    linkage_cal = keep["linkage_cal"]
    images: dict[str, str] = {}
    plot_residual_histograms(linkage_cal.joints, out / "residual_histograms.png", scale)
    images["Residual norms per joint, linkage set 1 (O'Brien Figures 6-7)"] = "residual_histograms.png"
    plot_limb_errors(results["humanoid"], out / "limb_errors.png")
    images["Limb-length error per segment and trial"] = "limb_errors.png"
    plot_limb_lengths(results["humanoid"], out / "limb_lengths.png")
    images["Limb lengths: estimate against truth over each subject's trials (seeds)"] = "limb_lengths.png"
    plot_slip(results["slip"], out / "slip.png")
    images["Residual over time and detected slip"] = "slip.png"
    plot_orientation(results["orientation"], out / "orientation.png")
    images["Orientation error: each estimator over the frames, the default over time"] = "orientation.png"
    ds = keep["linkage_ds"]
    n = ds.time_s.size
    frames = [n // 5, n // 2, 4 * n // 5]
    cm = load_capture_model("linkage")
    if render_joint_centres(cm, ds, linkage_cal.joints, scale, frames, out / "pictures_linkage.png"):
        images["Linkage pictures: true (blue spheres) and estimated (vermillion cubes) joint centres"] = (
            "pictures_linkage.png"
        )
    return write_report_files(out, validation_markdown(results, images), results)
