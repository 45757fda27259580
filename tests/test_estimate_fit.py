"""Any estimator's joints are checked against the poses as O'Brien's are: residuals, the least
residual any centre leaves, and warnings that tell an estimate that misfits from data at fault."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import simbench
from calibration.diagnostics import joint_residuals
from calibration.errors import CalibrationInputError
from simbench.cli import main
from simbench.estimators import resolve, run_joints
from simbench.io.poses import write_pose_csv
from simbench.sim.session import SessionConfig, load_session_model, run_session


@pytest.fixture(scope="module")
def linkage():
    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=6.0, seed=3, sensors="polhemus-liberty"
    )
    return run_session(config, load_session_model(config))


def _obriens_joints(poses, *, hierarchy=None, shift_m=0.0, joint=0):
    """O'Brien's joints as a bare document, one joint's parent centre moved by ``shift_m``."""
    got = run_joints(resolve("obrien"), poses, hierarchy=hierarchy)
    j = got.joints
    rows = []
    for k, (p, c) in enumerate(zip(j.parent, j.child, strict=True)):
        lp = j.joint_in_parent[k] + ([shift_m, 0.0, 0.0] if k == joint else 0.0)
        rows.append(
            {
                "parent": p,
                "child": c,
                "joint_in_parent": lp.tolist(),
                "joint_in_child": j.joint_in_child[k].tolist(),
            }
        )
    return {"units": poses.unit, "joints": rows}


def _at_origins(poses, *, hierarchy=None):
    """Every joint at both sensors' origins: the sensors' own distance is the residual."""
    rows = [
        {"parent": p, "child": c, "joint_in_parent": [0, 0, 0], "joint_in_child": [0, 0, 0]}
        for c, p in hierarchy.items()
    ]
    return {"units": poses.unit, "joints": rows}


def test_obriens_joints_through_another_door_get_obriens_residuals(linkage):
    tree = linkage.truth.parent_of
    cal = simbench.calibrate(linkage, hierarchy=tree)
    got = simbench.calibrate(linkage, method=_obriens_joints, hierarchy=tree)
    assert got.calibration is None and got.residuals is not None
    own = {(j.parent, j.child): j.fit.rms_residual for j in cal.joints}
    for k, pair in enumerate(zip(got.joints.parent, got.joints.child, strict=True)):
        assert got.residuals.rms[k] == pytest.approx(own[pair], rel=1e-9)
        assert got.residuals.best[k] == pytest.approx(own[pair], rel=1e-9)  # it is the least-squares fit
        assert got.residuals.max[k] > got.residuals.rms[k]
    rec = linkage.poses()
    ok = rec.valid & np.isfinite(rec.p_w_s).all(axis=2)
    j = got.joints
    both = [int((ok[:, p] & ok[:, c]).sum()) for p, c in zip(j.parent_index, j.child_index, strict=True)]
    assert got.residuals.frames.tolist() == both
    assert got.warnings == ()


def test_an_estimate_off_by_centimetres_is_named_as_the_estimates_fault(linkage):
    tree = linkage.truth.parent_of
    got = simbench.calibrate(linkage, method=_obriens_joints, params={"shift_m": 0.25}, hierarchy=tree)
    k = 0
    name = f"{got.joints.parent[k]}-{got.joints.child[k]}"
    assert got.residuals.rms[k] > 20 * got.residuals.best[k]
    assert len(got.warnings) == 1
    assert (
        got.warnings[0].startswith(f"joint {name}:")
        and "the estimate does not fit these poses" in got.warnings[0]
    )


def test_joints_at_the_sensors_explain_nothing_and_the_verdicts_are_unit_free(linkage):
    tree = linkage.truth.parent_of
    rec = linkage.poses()
    got = simbench.calibrate(rec, method=_at_origins, hierarchy=tree)
    np.testing.assert_allclose(got.residuals.rms, got.residuals.separation, rtol=1e-12)
    assert np.all(got.residuals.best < 0.05 * got.residuals.rms)
    assert len(got.warnings) == len(tree)
    assert all("does not fit these poses" in w for w in got.warnings)
    in_mm = simbench.calibrate(rec.in_unit("mm"), method=_at_origins, hierarchy=tree)
    np.testing.assert_allclose(in_mm.residuals.rms, 1000 * got.residuals.rms, rtol=1e-9)
    np.testing.assert_allclose(in_mm.residuals.best, 1000 * got.residuals.best, rtol=1e-6, atol=1e-9)
    assert in_mm.warnings == got.warnings
    doc, doc_mm = simbench.calibration_document(got), simbench.calibration_document(in_mm)
    assert (doc["units"], doc_mm["units"]) == ("m", "mm")
    assert doc_mm["joints"][0]["rms_residual"] == pytest.approx(1000 * doc["joints"][0]["rms_residual"])
    scored = simbench.score(doc, linkage).mean_centre_error_m
    assert simbench.score(doc_mm, linkage).mean_centre_error_m == pytest.approx(scored, rel=1e-12)


def test_poses_not_of_one_body_are_the_datas_fault(linkage):
    """A sensor whose frames are shuffled is no neighbour of anything: no centre fits it, and the
    warning is the data's (as O'Brien's calibration gives it), not the estimate's."""
    tree = linkage.truth.parent_of
    rec = linkage.poses()
    child = next(iter(tree))
    s = rec.names.index(child)
    order = np.random.default_rng(0).permutation(len(rec))
    R, p = rec.R_w_s.copy(), rec.p_w_s.copy()
    R[:, s], p[:, s] = R[order, s], p[order, s]
    mixed = dataclasses.replace(rec, R_w_s=R, p_w_s=p)
    got = simbench.calibrate(mixed, method=_obriens_joints, hierarchy=tree)
    flagged = [w for w in got.warnings if child in w.split(":")[0]]
    assert flagged and not any("does not fit these poses" in w for w in got.warnings)
    assert any("probably not neighbours" in w or "explains almost nothing" in w for w in flagged)


def test_missing_frames_are_left_out_and_bad_shapes_refused(linkage):
    rec = linkage.poses()
    valid = np.ones((len(rec), len(rec.names)), dtype=bool)
    valid[:100, 1] = False
    lp = np.zeros((1, 3))
    got = joint_residuals(rec.R_w_s, rec.p_w_s, [0], [1], lp, lp, valid=valid)
    assert got.frames.tolist() == [len(rec) - 100]
    d = np.linalg.norm(rec.p_w_s[100:, 0] - rec.p_w_s[100:, 1], axis=1)
    assert got.rms[0] == pytest.approx(np.sqrt(np.mean(d**2)), rel=1e-12)
    assert got.max[0] == pytest.approx(d.max(), rel=1e-12)
    with pytest.raises(CalibrationInputError, match="one parent, child and two centres per joint"):
        joint_residuals(rec.R_w_s, rec.p_w_s, [0, 1], [1], lp, lp)


def test_the_command_line_prints_the_fit_and_the_warnings(linkage, tmp_path, capsys):
    poses = tmp_path / "poses.csv"
    write_pose_csv(poses, linkage.poses())
    tree = tmp_path / "tree.json"
    tree.write_text(json.dumps(linkage.truth.parent_of))
    script = tmp_path / "mine.py"
    script.write_text(
        "def estimate(poses, *, hierarchy=None):\n"
        "    rows = [{'parent': p, 'child': c, 'joint_in_parent': [0, 0, 0], 'joint_in_child': [0, 0, 0]}\n"
        "            for c, p in hierarchy.items()]\n"
        "    return {'units': poses.unit, 'joints': rows}\n"
    )
    assert main(["calibrate", str(poses), "--hierarchy", str(tree), "--method", f"{script}:estimate"]) == 0
    out = capsys.readouterr().out
    assert "least-squares rms mm" in out
    assert out.count("warning: joint ") == len(linkage.truth.parent_of)
