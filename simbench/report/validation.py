"""Reports: tables, plots (matplotlib) and pictures (MuJoCo's offscreen renderer) of a run.

:func:`write_report` turns the figures of :func:`simbench.experiments.validate.run_validation` into
``index.md``, a self-contained ``index.html`` (images embedded), ``results.json`` and the PNG
images beside them. Writes are atomic. Rendering uses MuJoCo's offscreen context (``simbench``
sets ``MUJOCO_GL=egl`` when there is no display and the caller chose no backend); if no GL
context can be made the pictures are skipped and the report says so.
"""

from __future__ import annotations

import base64
import html
import io
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simbench.io.atomic import atomic_open, atomic_write_text
from simbench.versions import software_versions


def _savefig(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())


def plot_residual_histograms(cal, path: Path, scale: float) -> None:
    """Residual-norm histogram of every joint (O'Brien Figures 6-7), mm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    joints = list(cal.joints)
    fig, axes = plt.subplots(1, len(joints), figsize=(3.2 * len(joints), 2.8), squeeze=False)
    for ax, j in zip(axes[0], joints, strict=True):
        r = np.asarray(j.fit.frame_residual) * scale * 1e3
        ax.hist(r[np.isfinite(r)], bins=40, color="#4477aa")
        ax.set_title(j.name, fontsize=9)
        ax.set_xlabel("residual norm (mm)")
    axes[0][0].set_ylabel("frames")
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def plot_limb_errors(humanoid: dict[str, Any], path: Path) -> None:
    """Limb-length error (true - computed, cm) per segment and trial."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trials = humanoid["trials"]
    labels = list(trials[0]["rows"])
    x = np.arange(len(labels))
    width = 0.8 / len(trials)
    fig, ax = plt.subplots(figsize=(10, 3.6))
    for k, t in enumerate(trials):
        ax.bar(x + k * width, [t["rows"][lab]["difference_cm"] for lab in labels], width, label=t["trial"])
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(x + 0.4 - width / 2, labels, rotation=20, fontsize=8)
    ax.set_ylabel("true - computed (cm)")
    ax.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def plot_slip(slip: dict[str, Any], path: Path) -> None:
    """A joint's residual over time with the detected slip intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(slip["time_s"])
    fig, ax = plt.subplots(figsize=(10, 3))
    ax.plot(t, slip["residual_mm"], lw=0.6, label=f"residual of {slip['joint']}")
    ax.plot(t, slip["jump_statistic_mm"], lw=0.8, label="window jump statistic")
    for a, b in slip["intervals_s"]:
        ax.axvspan(a, b, color="orange", alpha=0.2, label="detected slipped interval")
    ax.axvline(slip["true_slip_s"], color="k", ls="--", lw=0.8, label="true slip")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mm")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def plot_orientation(orientation: dict[str, Any], path: Path) -> None:
    """Orientation error (RMS over sensors) over time for each estimator."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(orientation["time_s"])
    fig, ax = plt.subplots(figsize=(10, 3))
    for label, m in orientation["methods"].items():
        ax.plot(t, m["per_frame_deg"], lw=0.7, label=f"{label} ({m['total_rmse_deg']:.1f} deg RMS)")
    ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("error (deg, RMS over sensors)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def _qpos_from_truth(cm, ds, frame: int) -> np.ndarray:
    """The model's joint positions reproducing the dataset's true segment poses at a frame."""
    import mujoco

    from calibration.rotations import matrix_to_quat, quat_to_matrix

    m = cm.model
    qpos = m.qpos0.copy()
    R_b = quat_to_matrix(np.asarray(ds.truth.q_w_b[frame]))
    index = {n: k for k, n in enumerate(ds.sensors)}
    root = cm.body_ids[0]
    for j in range(m.njnt):
        if m.jnt_bodyid[j] == root and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            adr = m.jnt_qposadr[j]
            qpos[adr : adr + 3] = ds.truth.p_w_b[frame, 0]
            qpos[adr + 3 : adr + 7] = ds.truth.q_w_b[frame, 0]
    for art in cm.articulations:
        if art.kinds != ("ball",):
            continue
        c = index[art.sensor]
        p = index[cm.parent_of[art.sensor]]
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, art.joints[0])
        adr = m.jnt_qposadr[j]
        qpos[adr : adr + 4] = matrix_to_quat(R_b[p].T @ R_b[c])
    return qpos


def render_joint_centres(cm, ds, cal, scale: float, frames: list[int], path: Path) -> bool:
    """Pictures of the model in a few poses, true joint centres green, estimated red.

    Returns False (and writes nothing) when no offscreen GL context can be made.
    """
    try:
        import mujoco
    except ImportError:
        return False
    from calibration.rotations import quat_to_matrix

    m = cm.model
    m.geom_rgba[:, 3] = np.minimum(m.geom_rgba[:, 3], 0.35)  # see-through, so the marks show
    try:
        renderer = mujoco.Renderer(m, 360, 480)
    except Exception:  # no GL context on this machine
        return False
    d = mujoco.MjData(m)
    index = {n: k for k, n in enumerate(ds.sensors)}
    R_meas = quat_to_matrix(np.where(ds.measured.valid[..., None], ds.measured.q_w_s, [1.0, 0, 0, 0]))
    images = []
    for f in frames:
        d.qpos[:] = _qpos_from_truth(cm, ds, f)
        mujoco.mj_kinematics(m, d)
        cam = mujoco.MjvCamera()
        cam.lookat[:] = ds.truth.p_w_b[f, 0]
        cam.distance = 2.0 if len(ds.sensors) < 10 else 2.8
        cam.azimuth, cam.elevation = 120.0, -15.0
        renderer.update_scene(d, cam)
        scene = renderer.scene
        marks = []
        for k in range(len(ds.truth.child)):
            marks.append((ds.truth.joint_w[f, k], (0.1, 0.8, 0.1, 1.0)))
        for j in cal.joints:
            p = index[j.parent]
            est = scale * (R_meas[f, p] @ j.fit.joint_in_parent + ds.measured.p_w_s[f, p])
            if np.all(np.isfinite(est)):
                marks.append((est, (0.9, 0.1, 0.1, 1.0)))
        for pos, rgba in marks:
            if scene.ngeom >= scene.maxgeom:
                break
            mujoco.mjv_initGeom(
                scene.geoms[scene.ngeom],
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=np.array([0.022, 0.0, 0.0]),
                pos=np.asarray(pos, dtype=float),
                mat=np.eye(3).ravel(),
                rgba=np.asarray(rgba, dtype=np.float32),
            )
            scene.ngeom += 1
        images.append(renderer.render().copy())
    renderer.close()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(images), figsize=(4.8 * len(images), 3.8))
    for ax, img, f in zip(np.atleast_1d(axes), images, frames, strict=True):
        ax.imshow(img)
        ax.set_title(f"t = {ds.time_s[f]:.1f} s (green: true, red: estimated)", fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)
    return True


def _md_table(header: list[str], rows: list[list[Any]]) -> str:
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.2f}"
        return str(v)

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def validation_markdown(results: dict[str, Any], images: dict[str, str]) -> str:
    """The validation report in Markdown (tables, image links)."""
    s = results["summary"]
    p = results["paper"]
    lk = results["linkage"]
    hm = results["humanoid"]
    out = [
        "# simbench validation report",
        "",
        "O'Brien et al. (2000)'s experiments reproduced in simulation (MuJoCo physics, modelled "
        "sensors) and scored against the exact truth; Fontaine et al.'s sourceless orientation "
        f"scored the same way. {'Quick variant (CI): fewer, shorter sessions.' if results['quick'] else ''}",
        "",
        "## The paper and simbench side by side",
        "",
        _md_table(
            ["figure", "paper", "simbench"],
            [
                [
                    "unit scale factor (two sensors 56.5 cm apart)",
                    p["unit_scale"],
                    results["unit_scale"]["scale"],
                ],
                [
                    "scaled std of their distance (cm)",
                    p["scaled_std_cm"],
                    results["unit_scale"]["scaled_std_cm"],
                ],
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
                    f"correct in {s['walk_hierarchy_correct']} of {s['walk_trials']}",
                ],
            ],
        ),
        "",
        f"## Linkage (Table 1): {len(lk['sets'])} sets, `{lk['preset']}`, {lk['duration_s']:g} s each",
        "",
        "Computed joint-to-joint distances (cm, converted with the measured unit scale factor) and "
        "true minus computed differences.",
        "",
    ]
    labels = list(lk["sets"][0]["rows"])
    header = [
        "distance",
        "true",
        *[f"set {x['set']}" for x in lk["sets"]],
        *[f"diff {x['set']}" for x in lk["sets"]],
    ]
    rows = [
        [
            lab,
            lk["sets"][0]["rows"][lab]["true_cm"],
            *[x["rows"][lab]["computed_cm"] for x in lk["sets"]],
            *[x["rows"][lab]["difference_cm"] for x in lk["sets"]],
        ]
        for lab in labels
    ]
    out += [_md_table(header, rows), ""]
    out += [
        "Hierarchy per set: "
        + ", ".join(f"set {x['set']} {'correct' if x['hierarchy_correct'] else 'WRONG'}" for x in lk["sets"]),
        "",
        f"## Human subject (Tables 2-4): `{hm['preset']}`, {hm['duration_s']:g} s trials",
        "",
        "Limb lengths (cm) computed with the true hierarchy, as the paper reports them; true minus "
        "computed in the difference columns.",
        "",
    ]
    labels = list(hm["trials"][0]["rows"])
    header = [
        "limb",
        "true",
        *[t["trial"] for t in hm["trials"]],
        *[f"diff {t['trial']}" for t in hm["trials"]],
    ]
    rows = [
        [
            lab,
            hm["trials"][0]["rows"][lab]["true_cm"],
            *[t["rows"][lab]["computed_cm"] for t in hm["trials"]],
            *[t["rows"][lab]["difference_cm"] for t in hm["trials"]],
        ]
        for lab in labels
    ]
    out += [_md_table(header, rows), ""]
    out += [
        _md_table(
            ["trial", "hierarchy (inferred)", "thigh_l parent", "thigh_r parent", "max error (cm)"],
            [
                [
                    t["trial"],
                    "correct" if t["hierarchy_correct"] else "WRONG",
                    t["thigh_parents"]["thigh_l"],
                    t["thigh_parents"]["thigh_r"],
                    t["max_abs_error_cm"],
                ]
                for t in hm["trials"]
            ],
        ),
        "",
    ]
    sl = results["slip"]
    out += [
        "## Slip detection",
        "",
        f"A 3 cm slip of the left forearm's sensor at {sl['true_slip_s']:.1f} s: detected at "
        f"{', '.join(f'{t:.2f} s' for t in sl['events_s']) or 'nothing'} (jump "
        f"{', '.join(f'{j:.1f} mm' for j in sl['jumps_mm'])}) on joint `{sl['joint']}`.",
        "",
    ]
    ori = results["orientation"]
    out += [
        f"## Sourceless orientation (humanoid exercise, `{ori['preset']}`)",
        "",
        _md_table(
            ["estimator", "total RMSE (deg)", "heading", "inclination"],
            [
                [k, v["total_rmse_deg"], v["heading_rmse_deg"], v["inclination_rmse_deg"]]
                for k, v in ori["methods"].items()
            ],
        ),
        "",
        "## Figures",
        "",
    ]
    for title, name in images.items():
        out += [f"### {title}", "", f"![{title}]({name})", ""]
    if not any("pictures" in t for t in images):
        out += ["(No pictures: no offscreen GL context on this machine.)", ""]
    out += [
        "## Provenance",
        "",
        f"- run time: {results['run_time_s']:.1f} s",
        f"- plan: `{json.dumps(results['plan'])}`",
        f"- versions: `{json.dumps(results['versions'])}`",
        "- seeds: linkage sets 1..N, humanoid trials 101.. (exercise and walk), slip 21, "
        "orientation 31, unit scale 7",
        "- every figure is in `results.json`",
        "",
    ]
    return "\n".join(out)


def markdown_to_html(md: str, image_dir: Path) -> str:
    """A small Markdown-to-HTML conversion for our own reports, images embedded (self-contained)."""
    body: list[str] = []
    lines = md.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("|"):
            table = []
            while i < len(lines) and lines[i].startswith("|"):
                table.append(lines[i])
                i += 1
            cells = [
                [c.strip() for c in row.strip("|").split("|")] for row in table if not set(row) <= set("|-: ")
            ]
            body.append("<table>")
            for r, row in enumerate(cells):
                tag = "th" if r == 0 else "td"
                body.append("<tr>" + "".join(f"<{tag}>{html.escape(c)}</{tag}>" for c in row) + "</tr>")
            body.append("</table>")
            continue
        if line.startswith("!["):
            alt, src = line[2:].split("](", 1)
            data = base64.b64encode((image_dir / src.rstrip(")")).read_bytes()).decode()
            img = f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}" style="max-width:100%">'
            body.append(f"<p>{img}</p>")
        elif line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            body.append(f"<h{level}>{html.escape(line[level:].strip())}</h{level}>")
        elif line.startswith("- "):
            body.append(f"<ul><li>{html.escape(line[2:])}</li></ul>")
        elif line.strip():
            body.append(f"<p>{html.escape(line)}</p>")
        i += 1
    style = (
        "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
        "table{border-collapse:collapse;font-size:13px;margin:1em 0}"
        "td,th{border:1px solid #bbb;padding:3px 7px;text-align:right}th{background:#eee}"
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>simbench validation report</title><style>{style}</style></head><body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )


def _finite(x: Any) -> Any:
    """JSON cannot hold NaN or inf: they become ``null``."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_finite(v) for v in x]
    if isinstance(x, float | np.floating):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer | np.bool_):
        return x.item()
    return x


def write_report(results: dict[str, Any], keep: dict[str, Any], out: Path) -> dict[str, Path]:
    """Write the validation report into ``out``; returns the paths written."""
    out.mkdir(parents=True, exist_ok=True)
    results = dict(results, versions=software_versions())
    scale = results["unit_scale"]["scale"]
    images: dict[str, str] = {}
    plot_residual_histograms(keep["linkage_cal"], out / "residual_histograms.png", scale)
    images["Residual norms per joint, linkage set 1 (O'Brien Figures 6-7)"] = "residual_histograms.png"
    plot_limb_errors(results["humanoid"], out / "limb_errors.png")
    images["Limb-length error per segment and trial"] = "limb_errors.png"
    plot_slip(results["slip"], out / "slip.png")
    images["Residual over time and detected slip"] = "slip.png"
    plot_orientation(results["orientation"], out / "orientation.png")
    images["Orientation error over time"] = "orientation.png"
    from simbench.sim.models import load_capture_model

    ds = keep["linkage_ds"]
    cm = load_capture_model("linkage")
    n = ds.time_s.size
    if render_joint_centres(
        cm, ds, keep["linkage_cal"], scale, [n // 5, n // 2, 4 * n // 5], out / "pictures_linkage.png"
    ):
        images["Linkage pictures: true (green) and estimated (red) joint centres"] = "pictures_linkage.png"
    md = validation_markdown(results, images)
    atomic_write_text(out / "index.md", md)
    atomic_write_text(out / "index.html", markdown_to_html(md, out))
    atomic_write_text(out / "results.json", json.dumps(_finite(results), indent=1, allow_nan=False) + "\n")
    return {"md": out / "index.md", "html": out / "index.html", "json": out / "results.json"}


@dataclass(frozen=True)
class _Fitted:
    """Joints and lengths read from a calibration JSON (what the plots need of a Calibration)."""

    joints: tuple
    lengths: tuple


def dataset_report(
    dataset: Path,
    out: Path,
    calibration_file: Path | None = None,
    *,
    units: str = "m",
    clusters: str | None = None,
    wide: str | None = None,
) -> dict[str, Path]:
    """The report of one recording: residuals, hierarchy and lengths; scored when it has truth.

    Args:
        dataset: a simbench dataset (HDF5), or any pose input ``simbench calibrate`` reads (pose
            CSV, wide tracker export with ``wide``, C3D markers with ``clusters``).
        out: report folder.
        calibration_file: a calibration JSON (``simbench calibrate --json``) to report instead of
            calibrating the recording here.
        units, clusters, wide: as for ``simbench calibrate``.
    """
    from calibration import calibrate, frame_residuals
    from calibration.hierarchy import hierarchy_from_parents
    from calibration.joint import JointFit
    from calibration.pipeline import Joint
    from calibration.skeleton import segment_lengths
    from simbench.errors import InputError
    from simbench.io.dataset import read_dataset
    from simbench.score import compare_trees, estimated_lengths, length_of, truth_lengths

    if Path(dataset).suffix.lower() in (".h5", ".hdf5"):
        ds = read_dataset(dataset)
        rec = ds.poses()
        scale = ds.position_unit_scale
    else:
        from simbench.io.read import read_poses

        ds, rec, scale = None, read_poses(str(dataset), units, clusters, wide), 1.0
    if calibration_file is None:
        cal = calibrate(rec.R_w_s, rec.p_w_s, rec.names, valid=rec.valid)
        joints = list(cal.joints)
        parent_of = cal.parent_of
        source = "calibrated here (hierarchy inferred)"
    else:
        try:
            doc = json.loads(Path(calibration_file).read_text(encoding="utf-8"))
            entries = doc["joints"]
            parent_of = {j["child"]: j["parent"] for j in entries}
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise InputError(f"{calibration_file}: not a calibration JSON ({exc})") from None
        hierarchy_from_parents(parent_of, rec.names)  # checks the names and the tree
        idx = {n: k for k, n in enumerate(rec.names)}
        pairs = [(idx[j["parent"]], idx[j["child"]]) for j in entries]
        lp = np.array([j["joint_in_parent"] for j in entries], dtype=float)
        lc = np.array([j["joint_in_child"] for j in entries], dtype=float)
        par, chi = [p for p, _ in pairs], [c for _, c in pairs]
        rms, per = frame_residuals(rec.R_w_s, rec.p_w_s, par, chi, lp, lc, valid=rec.valid)
        joints = [
            Joint(
                j["parent"],
                j["child"],
                JointFit(
                    lp[k],
                    lc[k],
                    float(rms[k]),
                    per[:, k],
                    np.full(6, np.nan),
                    6,
                    bool(j.get("single_axis")),
                    None,
                    None,
                    rec.n_frames,
                    0,
                ),
            )
            for k, j in enumerate(entries)
        ]
        cal = _Fitted(tuple(joints), tuple(segment_lengths(rec.names, pairs, lp, lc)))
        source = f"from {calibration_file}"
    out.mkdir(parents=True, exist_ok=True)
    plot_residual_histograms(cal, out / "residual_histograms.png", scale)
    results: dict[str, Any] = {
        "dataset": str(dataset),
        "calibration": source,
        "sensors": list(rec.names),
        "frames": rec.n_frames,
        "position_unit_scale": scale,
        "joints": [
            {"parent": j.parent, "child": j.child, "rms_residual_mm": j.fit.rms_residual * scale * 1e3}
            for j in joints
        ],
        "versions": software_versions(),
        "meta": {}
        if ds is None
        else {k: ds.meta.get(k) for k in ("model", "program", "seed", "rate_hz", "sensor_model")},
        "read": list(rec.notes),
    }
    lines = [
        f"# simbench report: {dataset}",
        "",
        f"Calibration: {source}. Lengths in cm (x {scale:g} to metres).",
        "",
    ]
    lines += [
        _md_table(
            ["joint", "rms residual (mm)"],
            [[f"{j.parent} -> {j.child}", j.fit.rms_residual * scale * 1e3] for j in joints],
        ),
        "",
    ]
    got = estimated_lengths(cal)
    if rec.notes:
        lines += ["What was read:", "", *[f"- {note}" for note in rec.notes], ""]
    if ds is not None and ds.truth is not None:
        truth = truth_lengths(ds)
        rows = []
        for key, value in truth.items():
            computed = length_of(got, key) * scale
            rows.append(
                [f"{key[0]}: {key[1]} / {key[2]}", value * 100, computed * 100, (value - computed) * 100]
            )
        results["hierarchy_correct"] = compare_trees(parent_of, ds.truth.parent_of).correct
        results["lengths_cm"] = [
            {"length": r[0], "true": r[1], "computed": r[2], "difference": r[3]} for r in rows
        ]
        lines += [
            f"Hierarchy: {'correct' if results['hierarchy_correct'] else 'WRONG'} (against the truth).",
            "",
        ]
        lines += [_md_table(["length", "true", "computed", "true - computed"], rows), ""]
    else:
        rows = [[f"{x.segment}: {x.joint_a} / {x.joint_b}", x.length * scale * 100] for x in cal.lengths]
        results["lengths_cm"] = [{"length": r[0], "computed": r[1]} for r in rows]
        lines += [_md_table(["length", "computed"], rows), ""]
    lines += ["## Residual norms per joint", "", "![residual norms](residual_histograms.png)", ""]
    md = "\n".join(lines)
    atomic_write_text(out / "index.md", md)
    atomic_write_text(out / "index.html", markdown_to_html(md, out))
    atomic_write_text(out / "results.json", json.dumps(_finite(results), indent=1, allow_nan=False) + "\n")
    return {"md": out / "index.md", "html": out / "index.html", "json": out / "results.json"}
