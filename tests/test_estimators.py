"""The estimator registry: built-ins and users' estimators (Python, plugin, command) alike."""

from __future__ import annotations

import ast
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import simbench
from calibration import SINGLE_AXIS_RATIO
from simbench.errors import InputError
from simbench.estimators import (
    EstimatorError,
    catalog,
    joints_result,
    names,
    resolve,
    run_joints,
    run_orientation,
)
from simbench.experiments.metrics import joint_method_metrics
from simbench.sim.session import SessionConfig, load_session_model, run_session

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples" / "estimators"


@pytest.fixture(scope="module")
def linkage():
    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=6.0, seed=3, sensors="polhemus-liberty"
    )
    return run_session(config, load_session_model(config))


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


SHIFTED = """
import simbench.estimators as se

def estimate(poses, *, hierarchy=None, shift_m=0.01):
    got = se.run_joints(se.resolve("obrien"), poses, hierarchy=hierarchy)
    j = got.joints
    return {"units": poses.unit, "joints": [
        {"parent": p, "child": c, "joint_in_parent": (j.joint_in_parent[k] + [shift_m, 0, 0]).tolist(),
         "joint_in_child": j.joint_in_child[k].tolist()}
        for k, (p, c) in enumerate(zip(j.parent, j.child, strict=True))]}
"""


def test_every_builtin_is_registered_with_its_kind_and_defaults():
    joints, orientation = names("joints", plugins=False), names("orientation", plugins=False)
    assert {"obrien", "obrien-eiv", "obrien-robust", "score", "sara", "inertial"} <= set(joints)
    assert {"sphere-gamage-lasenby", "sphere-geometric"} <= set(joints)
    assert set(orientation) == {"skeleton", "fontaine", "triad", "wahba", "mahony", "vqf"}
    assert resolve("obrien").defaults["single_axis_ratio"] == SINGLE_AXIS_RATIO
    assert "hierarchy" in resolve("score").needs and "gyro" in resolve("vqf").needs
    assert resolve("skeleton").takes_skeleton and not resolve("triad").takes_skeleton


def test_no_second_list_of_method_names():
    """The registry is the one list: no tuple, list, set or dict literal elsewhere in the package
    names two or more registered estimators but the catalog the registry is filled from
    (``simbench.estimators.catalog``) and the core's own names of its pose methods
    (``calibration.defaults``, which ``calibration.methods`` maps to its functions)."""
    registered = set(names(plugins=False))
    allowed = {
        ROOT / "simbench" / "estimators" / "catalog.py",
        ROOT / "calibration" / "defaults.py",
    }
    offenders = []
    for path in [*(ROOT / "simbench").rglob("*.py"), *(ROOT / "calibration").rglob("*.py")]:
        if path in allowed:
            continue
        tree = ast.parse(path.read_text())
        exported = {
            id(n.value)
            for n in ast.walk(tree)
            if isinstance(n, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets)
        }
        for node in ast.walk(tree):
            if id(node) in exported:
                continue
            items = node.keys if isinstance(node, ast.Dict) else getattr(node, "elts", None)
            if not isinstance(node, ast.Tuple | ast.List | ast.Set | ast.Dict) or items is None:
                continue
            found = {e.value for e in items if isinstance(e, ast.Constant) and e.value in registered}
            if len(found) >= 2:
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} {sorted(found)}")
    assert not offenders, offenders


def test_unknown_spec_names_the_builtins():
    with pytest.raises(InputError, match=r"unknown estimator 'magic': expected one of obrien, obrien-eiv"):
        resolve("magic", "joints")
    with pytest.raises(InputError, match="'vqf' estimates orientation, not joints"):
        resolve("vqf", "joints")


def test_python_file_estimator_is_scored_like_a_builtin(tmp_path, linkage):
    spec = f"{_write(tmp_path / 'shifted.py', SHIFTED)}:estimate"
    est = resolve(spec, "joints")
    assert est.kind == "joints" and est.origin == "python" and est.defaults == {"shift_m": 0.01}
    shifted = joint_method_metrics(linkage, spec)["joint_centre_error_m"]
    obrien = joint_method_metrics(linkage, "obrien")["joint_centre_error_m"]
    # every centre moved 1 cm in the parent frame: the error is about 1 cm, far above O'Brien's
    assert shifted > obrien + 0.005 and shifted == pytest.approx(0.01, abs=obrien + 1e-3)
    # a parameter reaches the function, a wrong one is refused by name
    got = run_joints(est, linkage.poses(), hierarchy=linkage.truth.parent_of, params={"shift_m": 0.0})
    ref = run_joints(resolve("obrien"), linkage.poses(), hierarchy=linkage.truth.parent_of)
    np.testing.assert_allclose(
        got.joints.joint_in_parent, ref.joints.joint_in_parent, atol=1e-12
    )  # exact copy
    with pytest.raises(InputError, match="no parameter 'shift'"):
        run_joints(est, linkage.poses(), params={"shift": 1.0})


def test_example_estimators_run_from_their_files(linkage):
    sphere = joint_method_metrics(linkage, f"{EXAMPLES / 'sphere_fit.py'}:estimate")
    builtin = joint_method_metrics(linkage, "sphere-gamage-lasenby")
    # the example is the algebraic sphere fit: the built-in closed form gives the same centres
    assert sphere["joint_centre_error_m"] == pytest.approx(builtin["joint_centre_error_m"], rel=1e-6)
    cmd = f"cmd:{sys.executable} {EXAMPLES / 'pair_fit_cmd.py'} {{poses}} {{hierarchy}} {{out}}"
    via_cmd = joint_method_metrics(linkage, cmd)
    obrien = joint_method_metrics(linkage, "score")  # the same least squares per pair
    assert via_cmd["joint_centre_error_m"] == pytest.approx(obrien["joint_centre_error_m"], rel=1e-6)


def test_module_function_and_plugin_specs(tmp_path, monkeypatch, linkage):
    pkg = tmp_path / "mylab"
    pkg.mkdir()
    _write(pkg / "__init__.py", "")
    _write(pkg / "fit.py", SHIFTED)
    monkeypatch.syspath_prepend(str(tmp_path))
    est = resolve("mylab.fit:estimate")
    assert est.kind == "joints" and est.origin == "python"

    class EntryPoint:
        name, value = "mylab-shifted", "mylab.fit:estimate"

        def load(self):
            import mylab.fit

            return mylab.fit.estimate

    monkeypatch.setattr(catalog, "plugin_entry_points", lambda: {"mylab-shifted": EntryPoint()})
    plugin = resolve("mylab-shifted", "joints")
    assert plugin.origin == "plugin" and "mylab-shifted" in names("joints")
    assert joint_method_metrics(linkage, "mylab-shifted")["joint_centre_error_m"] > 0.005
    with pytest.raises(InputError, match="no module 'nolab'"):
        resolve("nolab.fit:estimate")
    with pytest.raises(InputError, match="has no 'nothing'"):
        resolve("mylab.fit:nothing")


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("raise RuntimeError('boom')", "raised RuntimeError: boom"),
        (
            "return {'units': 'm', 'joints': [{'parent': 'chest', 'child': 'ghost', "
            "'joint_in_parent': [0,0,0], 'joint_in_child': [0,0,0]}]}",
            r"sensors the data lacks: \['ghost'\]",
        ),
        (
            "return {'units': 'm', 'joints': [{'parent': 'chest', 'child': 'head', "
            "'joint_in_parent': [float('nan'),0,0], 'joint_in_child': [0,0,0]}]}",
            "expected 'joint_in_parent' to be 3 finite numbers",
        ),
        ("return 42", "returned a int"),
    ],
)
def test_a_users_failure_is_named(tmp_path, linkage, body, message):
    path = _write(tmp_path / "bad.py", f"def estimate(poses, *, hierarchy=None):\n    {body}\n")
    with pytest.raises(EstimatorError, match=message):
        run_joints(resolve(f"{path}:estimate"), linkage.poses(), hierarchy=linkage.truth.parent_of)


@pytest.mark.parametrize(
    ("script", "message"),
    [
        ("import sys; sys.stderr.write('no licence'); sys.exit(3)", "exited 3; its stderr ends: no licence"),
        ("pass", "exited 0 but wrote nothing"),
        ("import sys; open(sys.argv[1], 'w').write('{not json')", "not valid JSON"),
        ("import time; time.sleep(30)", "time limit of 1 s"),
    ],
)
def test_a_failing_command_is_named_and_leaves_nothing(tmp_path, linkage, script, message, monkeypatch):
    path = _write(tmp_path / "bad_cmd.py", script)
    est = resolve(f"cmd:{sys.executable} {path} {{out}} {{poses}}")
    own_tmp = tmp_path / "tmp"  # this test's temporary folder: other runs' folders do not count
    own_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(own_tmp))
    t0 = time.perf_counter()
    with pytest.raises(EstimatorError, match=message):
        run_joints(est, linkage.poses(), params={"time_limit_s": 1.0})
    assert time.perf_counter() - t0 < 20
    assert list(own_tmp.iterdir()) == []  # the working folder is removed


def test_command_specs_are_checked_before_running():
    with pytest.raises(InputError, match=r"unknown placeholder\(s\) \['\{pose\}'\]"):
        resolve("cmd:fit {pose} {out}")
    with pytest.raises(InputError, match=r"needs \{poses\} and \{out\}"):
        resolve("cmd:fit {poses}")
    with pytest.raises(InputError, match="estimator of joints, not orientation"):
        resolve("cmd:fit {poses} {out}", "orientation")
    with pytest.raises(InputError, match="cannot run 'no-such-program'"):
        est = resolve("cmd:no-such-program {imu} {out}")
        rec = _tiny_imu()
        run_orientation(est, rec)


def _tiny_imu():
    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=2.0, seed=1, sensors="mems-industrial", rate_hz=50.0
    )
    return run_session(config, load_session_model(config)).imu()


ORIENT_CMD = """
import csv, sys
rows = list(csv.reader(open(sys.argv[1])))
header = [r for r in rows if r and not r[0].startswith('#')][0]
names = [h[:-6] for h in header if h.endswith('_acc_x')]
with open(sys.argv[2], 'w') as fh:
    fh.write('time,sensor,qw,qx,qy,qz\\n')
    for r in rows[rows.index(header) + 1:]:
        for n in names:
            fh.write(f'{r[0]},{n},1,0,0,0\\n')
"""


def test_orientation_command_and_callable(tmp_path):
    rec = _tiny_imu()
    path = _write(tmp_path / "still.py", ORIENT_CMD)
    got = run_orientation(resolve(f"cmd:{sys.executable} {path} {{imu}} {{out}}"), rec)
    assert got.q_enu.shape == (rec.time_s.size, len(rec.names), 4) and got.ok.all()
    np.testing.assert_array_equal(got.q_enu[..., 0], 1.0)

    def identity(imu):
        return np.tile([1.0, 0, 0, 0], (imu.time_s.size, len(imu.names), 1))

    direct = simbench.orient(rec, identity, calibrate_mag=False)
    np.testing.assert_array_equal(direct.q_w_s, got.q_enu)
    with pytest.raises(EstimatorError, match="unit quaternions"):
        simbench.orient(rec, lambda imu: 2 * identity(imu), calibrate_mag=False)


def test_builtin_orientation_through_the_registry_equals_the_direct_call():
    rec = _tiny_imu()
    from simbench.orient import estimate

    for name in ("triad", "fontaine"):
        np.testing.assert_array_equal(run_orientation(resolve(name), rec).q_enu, estimate(rec, name).q_enu)


def test_api_calibrate_and_score_take_any_estimator(linkage, tmp_path):
    got = simbench.calibrate(linkage, method="score", hierarchy=linkage.truth.parent_of)
    scored = simbench.score(got, linkage)
    assert scored.tree.correct and scored.mean_centre_error_m < 0.01
    doc = tmp_path / "cal.json"
    j = got.joints
    doc.write_text(
        json.dumps(
            {
                "units": "mm",
                "joints": [
                    {
                        "parent": p,
                        "child": c,
                        "joint_in_parent": (1000 * j.joint_in_parent[k]).tolist(),
                        "joint_in_child": (1000 * j.joint_in_child[k]).tolist(),
                    }
                    for k, (p, c) in enumerate(zip(j.parent, j.child, strict=True))
                ],
            }
        )
    )
    from_file = simbench.score(str(doc), linkage)  # an estimate made anywhere, in millimetres
    assert from_file.mean_centre_error_m == pytest.approx(scored.mean_centre_error_m, rel=1e-9)
    with pytest.raises(InputError, match="give one"):
        simbench.calibrate(linkage, method="score")
    with pytest.raises(InputError, match="options of O'Brien's calibration"):
        simbench.calibrate(linkage, method="score", robust="tukey", hierarchy=linkage.truth.parent_of)


def test_a_python_estimator_past_its_time_limit_is_stopped(tmp_path, linkage):
    path = _write(
        tmp_path / "slow.py", "import time\n\ndef estimate(poses, *, hierarchy=None):\n    time.sleep(60)\n"
    )
    t0 = time.perf_counter()
    with pytest.raises(EstimatorError, match=r"did not return within its time limit of 0\.5 s"):
        run_joints(resolve(f"{path}:estimate"), linkage.poses(), time_limit_s=0.5)
    assert time.perf_counter() - t0 < 10
    # the timer is gone afterwards: a built-in runs on unhindered
    assert run_joints(resolve("obrien"), linkage.poses()).joints.child


def test_a_command_names_its_script_from_the_callers_folder(tmp_path, monkeypatch, linkage):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fit.py").write_text((EXAMPLES / "pair_fit_cmd.py").read_text())
    est = resolve(f"cmd:{sys.executable} fit.py {{poses}} {{hierarchy}} {{out}}")
    got = run_joints(est, linkage.poses(), hierarchy=linkage.truth.parent_of)
    assert set(got.joints.child) == set(linkage.truth.parent_of)


def test_the_pose_container_estimators_receive(linkage):
    poses = linkage.poses()
    assert len(poses) == poses.n_frames and poses.unit == "m"
    first = poses[:100]
    assert len(first) == 100 and first.names == poses.names
    np.testing.assert_array_equal(first.R_w_s, poses.R_w_s[:100])
    moving = poses[poses.time_s > 1.0]
    assert moving.time_s[0] > 1.0 and len(moving) < len(poses)
    two = poses.sensors(["head", "chest"])
    assert two.names == ("head", "chest")
    np.testing.assert_array_equal(two.p_w_s[:, 0], poses.p_w_s[:, poses.names.index("head")])
    mm = poses.in_unit("mm")
    np.testing.assert_allclose(mm.p_w_s, 1000 * poses.p_w_s, rtol=1e-15)
    # an estimate from poses in millimetres is in millimetres: the same joints, scaled
    a = run_joints(resolve("score"), poses, hierarchy=linkage.truth.parent_of).joints.joint_in_parent
    b = run_joints(resolve("score"), mm, hierarchy=linkage.truth.parent_of).joints.joint_in_parent
    np.testing.assert_allclose(b, 1000 * a, rtol=1e-6, atol=1e-9)
    made = simbench.PoseRecording.from_arrays(poses.names, poses.time_s, poses.R_w_s, poses.p_w_s)
    np.testing.assert_array_equal(made.valid, poses.valid)
    with pytest.raises(
        InputError, match=r"p_w_s to have shape \(720, 6, 3\) to match R_w_s, got \(720, 6, 2\)"
    ):
        simbench.PoseRecording.from_arrays(poses.names, poses.time_s, poses.R_w_s, poses.p_w_s[..., :2])
    with pytest.raises(InputError, match=r"for 3 times and 6 names"):
        simbench.PoseRecording.from_arrays(poses.names, poses.time_s[:3], poses.R_w_s, poses.p_w_s)
    with pytest.raises(InputError, match="sensor\\(s\\) \\['tail'\\] are not in the recording"):
        poses.sensors(["tail"])
    with pytest.raises(InputError, match="Expected unit to be one of"):
        simbench.PoseRecording.from_arrays(
            poses.names, poses.time_s, poses.R_w_s, poses.p_w_s, unit="furlong"
        )


_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(),
    st.floats(allow_nan=True),
    st.text(max_size=5),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=4),
)
_JOINT = st.dictionaries(
    st.sampled_from(["parent", "child", "joint_in_parent", "joint_in_child", "units", "single_axis"]),
    st.one_of(_VALUES, st.sampled_from(["chest", "head", "ghost"])),
)


@settings(max_examples=150, deadline=None, database=None, derandomize=True)
@given(
    doc=st.one_of(
        _VALUES,
        st.dictionaries(
            st.sampled_from(["joints", "units"]),
            st.one_of(
                _VALUES,
                st.lists(st.one_of(_JOINT, _VALUES), max_size=3),
                st.sampled_from(["m", "mm", "parsec"]),
            ),
        ),
    )
)
def test_whatever_an_estimator_returns_is_a_result_or_a_named_failure(doc):
    """A user's estimator may return anything: a checked result, or an EstimatorError naming it."""
    names = ("chest", "head", "upper_arm_l")
    try:
        got = joints_result(doc, "mine", names)
    except EstimatorError as exc:
        assert str(exc).startswith("estimator 'mine'")
        return
    assert np.isfinite(got.joints.joint_in_parent).all() and set(got.joints.child) <= set(names)


@settings(max_examples=150, deadline=None, database=None, derandomize=True)
@given(text=st.text(alphabet="time,sensorqwxyz0123456789.-e\nnaNhead", max_size=300))
def test_an_orientation_file_reads_or_is_refused_by_line(tmp_path_factory, text):
    from simbench.io.orientation_csv import read_orientation_csv

    path = tmp_path_factory.mktemp("o") / "out.csv"
    path.write_text(text)
    try:
        q = read_orientation_csv(path, ("head", "chest"), np.array([0.0, 0.5, 1.0]))
    except InputError as exc:
        assert str(exc).startswith(str(path))
        return
    assert q.shape == (3, 2, 4)
    finite = np.isfinite(q).all(axis=-1)
    np.testing.assert_allclose(np.linalg.norm(q[finite], axis=-1), 1.0, atol=1e-3)


def test_orientations_made_anywhere_are_scored(tmp_path):
    """sb.score takes orientations from anywhere: an array, an orientation CSV, sb.orient's result;
    against a simulated session's truth or a real recording's reference (the package's BROAD
    excerpt), with the same figures as sb.orient's own score."""
    from simbench.experiments.suite import DATA_DIR
    from simbench.io.orientation_csv import write_orientation_csv

    broad = simbench.read(DATA_DIR / "broad_02_undisturbed_slow_rotation_B_60s.hdf5")
    ori = simbench.orient(broad, "triad", calibrate_mag=False)
    from_array = simbench.score(ori.q_w_s, broad)
    assert from_array.total_rmse_deg == ori.score.total_rmse_deg
    assert simbench.score(ori, broad).total_rmse_deg == ori.score.total_rmse_deg
    write_orientation_csv(tmp_path / "mine.csv", broad, ori.q_w_s)
    assert simbench.score(tmp_path / "mine.csv", broad).total_rmse_deg == pytest.approx(
        ori.score.total_rmse_deg, rel=1e-12
    )
    rec = _tiny_imu()
    sim = simbench.orient(rec, "fontaine", calibrate_mag=False)
    assert simbench.score(sim.q_w_s, rec).total_rmse_deg == sim.score.total_rmse_deg
    with pytest.raises(InputError, match=r"expected quaternions of shape \(\d+, 1, 4\)"):
        simbench.score(np.ones((3, 1, 4)), broad)
    with pytest.raises(InputError, match="unit quaternions"):
        simbench.score(2 * ori.q_w_s, broad)


def test_a_users_estimator_cannot_change_the_data(tmp_path, linkage):
    """The next estimator gets the data as recorded: a user's that writes into its input fails,
    named, and the poses are unchanged."""
    path = _write(
        tmp_path / "vandal.py",
        "def estimate(poses, *, hierarchy=None):\n    poses.p_w_s[:] = 0.0\n    return {'joints': []}\n",
    )
    poses = linkage.poses()
    before = poses.p_w_s.copy()
    with pytest.raises(EstimatorError, match="raised ValueError: assignment destination is read-only"):
        run_joints(resolve(f"{path}:estimate"), poses)
    np.testing.assert_array_equal(poses.p_w_s, before)
    assert poses.p_w_s.flags.writeable  # the caller's own arrays stay writable


def test_joints_returned_as_arrays_get_the_documents_checks():
    from simbench.io.calibration_json import CalibrationJoints

    names = ("chest", "head")

    def joints(parent, child, jp):
        return CalibrationJoints(
            (parent,),
            (child,),
            np.array([0]),
            np.array([1]),
            np.array([jp]),
            np.zeros((1, 3)),
            np.array([False]),
        )

    assert joints_result(joints("chest", "head", [0.0, 0.0, 0.1]), "mine", names).joints.child == ("head",)
    with pytest.raises(EstimatorError, match=r"joints of a sensor with itself: \['head'\]"):
        joints_result(joints("head", "head", [0.0, 0.0, 0.1]), "mine", names)
    with pytest.raises(EstimatorError, match="3 finite numbers within 1e\\+06"):
        joints_result(joints("chest", "head", [0.0, 0.0, 1e300]), "mine", names)
    with pytest.raises(EstimatorError, match=r"of shape \(1, 3\), got \(1, 2\)"):
        joints_result(
            CalibrationJoints(
                ("chest",),
                ("head",),
                np.array([0]),
                np.array([1]),
                np.zeros((1, 2)),
                np.zeros((1, 3)),
                np.array([False]),
            ),
            "mine",
            names,
        )


def test_the_true_skeleton_goes_to_estimators_that_take_one():
    from simbench.experiments.metrics import orientation_metrics, true_skeleton

    config = SessionConfig(
        model="linkage", motion="exercise", duration_s=2.0, seed=1, sensors="mems-industrial", rate_hz=50.0
    )
    ds = run_session(config, load_session_model(config))
    skeleton = true_skeleton(ds)
    names = list(ds.sensors)
    got = {names[c]: names[skeleton.parent[c]] for c in skeleton.children}
    assert got == ds.truth.parent_of
    # a method that takes none is scored as before, the skeleton not passed to it
    assert orientation_metrics(ds, "triad", skeleton=skeleton) == orientation_metrics(ds, "triad")
