"""Walk hierarchies (issue 13): the pushed pack of the pelvis sensor, the pairs' noise, the misfit
tree against O'Brien's minimum spanning tree."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from calibration import (
    CalibrationInputError,
    calibrate,
    misfit_weights,
    pair_noise_variance,
    pair_statistics,
    solve_pairs,
)
from calibration.rotations import rotvec_to_matrix
from simbench.cli import main
from simbench.errors import InputError
from simbench.experiments.walk_hierarchy import walk_sensors, walk_trial
from simbench.io.poses import PoseRecording, write_pose_csv
from simbench.sim.sensor_config import load_sensor_config, parse_sensor_config
from simbench.sim.session import SessionConfig, load_session_model, run_session
from simbench.sim.skin import SkinPack, pack_offsets
from simbench.sim.synthetic import linkage, simulate_motion

PACK = {
    "sensor": "pelvis",
    "pushed_by": "thigh_r",
    "flexion_axis": [0.0, -1.0, 0.0],
    "threshold_rad": 0.5,
    "gain_m_per_rad": 0.05,
    "direction": [0.0, 0.0, 1.0],
}


def skin_with(pack: dict) -> dict:
    return {"name": "t", "skin": {"pack": pack}}


# --- the pack: parsing, bad input, the offset it gives --------------------------------------------


def test_pack_parses_and_the_preset_carries_it():
    skin = parse_sensor_config(skin_with(PACK), "t.toml").skin
    assert skin.pack == SkinPack("pelvis", "thigh_r", (0.0, -1.0, 0.0), 0.5, 0.05, (0.0, 0.0, 1.0))
    preset = load_sensor_config("skin-paper-human").skin.pack
    assert preset is not None and preset.sensor == "pelvis" and preset.pushed_by in ("thigh_l", "thigh_r")
    assert parse_sensor_config({"skin": {}}, "t.toml").skin.pack is None
    assert json.dumps(load_sensor_config("skin-paper-human").as_dict())  # JSON-ready in the metadata


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"gain_m_per_rad": -0.01},
            r"t\.toml: skin\.pack: pack\.gain_m_per_rad must be a finite number >= 0",
        ),
        ({"gain_m_per_rad": "5 cm"}, r"skin\.pack\.gain_m_per_rad: expected a number"),
        ({"threshold_rad": 4.0}, r"pack\.threshold_rad must be in \[-pi, pi\]"),
        ({"flexion_axis": [0.0, 0.0, 0.0]}, r"pack\.flexion_axis must be 3 finite numbers, not all zero"),
        ({"direction": [0.0, 1.0]}, r"pack\.direction must be 3 finite numbers"),
        ({"pushed_by": "pelvis"}, r"pack\.pushed_by must differ from pack\.sensor"),
        ({"sensor": 3}, r"pack\.sensor must be a sensor name, got 3"),
        ({"push": 1.0}, r"skin\.pack: unknown keys \['push'\]"),
    ],
)
def test_bad_pack_values_are_named(change, message):
    with pytest.raises(InputError, match=message):
        parse_sensor_config(skin_with({**PACK, **change}), "t.toml")


def test_pack_missing_key_and_not_a_table():
    pack = {k: v for k, v in PACK.items() if k != "direction"}
    with pytest.raises(InputError, match=r"skin\.pack: .*direction"):
        parse_sensor_config(skin_with(pack), "t.toml")
    with pytest.raises(InputError, match=r"skin\.pack: expected a table"):
        parse_sensor_config(skin_with([PACK]), "t.toml")  # type: ignore[arg-type]


def test_pack_offset_is_the_ramp_along_its_direction():
    # pelvis level; the right thigh flexed about the pelvis's -y by 0.2, 0.5, 0.8 and 1.1 rad
    flexion = np.array([0.2, 0.5, 0.8, 1.1])
    R_w_b = np.tile(np.eye(3), (4, 3, 1, 1))
    R_w_b[:, 2] = rotvec_to_matrix(flexion[:, None] * np.array([0.0, -1.0, 0.0]))
    pack = SkinPack("pelvis", "thigh_r", (0.0, -2.0, 0.0), 0.5, 0.05, (0.0, 0.0, 3.0))  # normalised
    out = pack_offsets(R_w_b, ["pelvis", "thigh_l", "thigh_r"], pack)
    expected = 0.05 * np.maximum(flexion - 0.5, 0.0)  # m
    np.testing.assert_allclose(out[:, 0, 2], expected, rtol=0, atol=1e-15)  # rounding only
    assert not np.any(out[:, 0, :2]) and not np.any(out[:, 1:])
    assert not np.any(pack_offsets(R_w_b, ["pelvis", "thigh_l", "thigh_r"], None))
    with pytest.raises(InputError, match=r"skin\.pack names 'thigh_r', which carries no sensor"):
        pack_offsets(R_w_b, ["pelvis", "thigh_l", "knee"], pack)


@pytest.fixture(scope="module")
def humanoid_cm():
    return load_session_model(SessionConfig(model="humanoid", sensors=walk_sensors(pack=False)))


def test_walk_sensors_rejects_unknown_tracker():
    with pytest.raises(InputError, match=r"tracker must be one of \['preset', 'stand', 'quiet'\]"):
        walk_sensors(tracker="far")


def test_pack_off_leaves_sensor_positions_unchanged(humanoid_cm):
    def worn(sensors):
        config = SessionConfig(model="humanoid", motion="walk", duration_s=3.0, seed=5, sensors=sensors)
        return run_session(config, humanoid_cm)

    without = worn(walk_sensors(pack=False))
    preset = walk_sensors(pack=True)
    no_gain = SkinPack(**{**PACK, "gain_m_per_rad": 0.0})  # type: ignore[arg-type]
    off = worn(dataclasses.replace(preset, skin=dataclasses.replace(preset.skin, pack=no_gain)))
    with_pack = worn(walk_sensors(pack=True))
    np.testing.assert_array_equal(off.truth.actual.p_w_s, without.truth.actual.p_w_s)
    np.testing.assert_array_equal(off.measured.p_w_s, without.measured.p_w_s)
    # with the pack on, only the pelvis sensor moves, and only upwards in the pelvis frame
    moved = np.any(with_pack.truth.actual.p_w_s != without.truth.actual.p_w_s, axis=(0, 2))
    assert moved.tolist() == [name == "pelvis" for name in without.sensors]
    np.testing.assert_array_equal(with_pack.truth.actual.q_w_s, without.truth.actual.q_w_s)


# --- the noise of a pair's residual --------------------------------------------------------------


@pytest.fixture(scope="module")
def exact_linkage():
    return simulate_motion(linkage(), n_frames=3000, rate_hz=120.0, rng=np.random.default_rng(7))


def test_pair_noise_recovers_white_noise(exact_linkage):
    cap = exact_linkage
    sigma = np.linspace(0.002, 0.012, len(cap.names))  # m per axis, a different level per sensor
    rng = np.random.default_rng(8)
    p = cap.p_w_s + rng.normal(size=cap.p_w_s.shape) * sigma[None, :, None]
    index = {name: k for k, name in enumerate(cap.names)}
    par = np.array([index[p_] for c, p_ in cap.skeleton.parent_of.items()])
    chi = np.array([index[c] for c in cap.skeleton.parent_of])
    sol = solve_pairs(pair_statistics(cap.R_w_s, p), par, chi)
    nu = pair_noise_variance(cap.R_w_s, p, par, chi, sol.joint_in_parent, sol.joint_in_child)
    expected = 3 * (sigma[par] ** 2 + sigma[chi] ** 2)  # both sensors, three axes
    # 3000 frames, three axes, third differences correlated over three lags (rho -0.75, 0.3,
    # -0.05): the estimate's relative standard error is about 2.3 %, so 10 % is over four of them
    np.testing.assert_allclose(nu, expected, rtol=0.10)
    # the misfit left is the residual's, less the noise: near zero on exact joints
    np.testing.assert_allclose(sol.rms_residual**2 - nu, 0.0, atol=0.1 * expected.max())


def test_pair_noise_same_over_chunks_pair_groups_and_missing_frames(exact_linkage, monkeypatch):
    cap = exact_linkage
    p = cap.p_w_s + np.random.default_rng(9).normal(scale=0.004, size=cap.p_w_s.shape)
    valid = np.ones(p.shape[:2], dtype=bool)
    valid[100:104, 2] = False
    valid[1500, 0] = False
    par, chi = np.array([0, 0, 2]), np.array([1, 2, 4])
    sol = solve_pairs(pair_statistics(cap.R_w_s, p, valid=valid), par, chi)
    args = (cap.R_w_s, p, par, chi, sol.joint_in_parent, sol.joint_in_child)
    whole = pair_noise_variance(*args, valid=valid, chunk_frames=10_000)
    np.testing.assert_allclose(pair_noise_variance(*args, valid=valid, chunk_frames=7), whole, rtol=1e-12)
    np.testing.assert_allclose(pair_noise_variance(*args, valid=valid, chunk_frames=2), whole, rtol=1e-12)
    monkeypatch.setattr("calibration.pair_noise.WORK_BYTES", 1)  # one pair at a time
    np.testing.assert_allclose(pair_noise_variance(*args, valid=valid, chunk_frames=1000), whole, rtol=1e-12)
    # a loop over the frames as reference: third differences where all four frames are valid
    for k in range(len(par)):
        a, b = par[k], chi[k]
        e = (
            np.einsum("fij,j->fi", cap.R_w_s[:, a], sol.joint_in_parent[k])
            + p[:, a]
            - np.einsum("fij,j->fi", cap.R_w_s[:, b], sol.joint_in_child[k])
            - p[:, b]
        )
        ok = valid[:, a] & valid[:, b]
        d3 = np.diff(e, n=3, axis=0)
        use = ok[:-3] & ok[1:-2] & ok[2:-1] & ok[3:]
        np.testing.assert_allclose(whole[k], np.mean(np.sum(d3[use] ** 2, axis=1)) / 20.0, rtol=1e-10)


def test_misfit_weights_keep_unfittable_pairs_out():
    res = np.array([[np.inf, 0.1], [0.1, np.inf]])
    w = misfit_weights(res, np.array([[0.0, 0.004], [0.004, 0.0]]))
    np.testing.assert_allclose(w, [[np.inf, 0.006], [0.006, np.inf]], rtol=1e-12)
    with pytest.raises(CalibrationInputError, match=r"Expected noise_variance of shape \(2, 2\)"):
        misfit_weights(res, np.zeros(2))


def test_unknown_hierarchy_method_is_an_input_error(exact_linkage):
    cap = exact_linkage
    with pytest.raises(CalibrationInputError, match=r"hierarchy_method must be one of \['misfit', 'mst'\]"):
        calibrate(cap.R_w_s, cap.p_w_s, cap.names, hierarchy_method="kruskal")


# --- a walk the paper's tree gets wrong ----------------------------------------------------------


@pytest.fixture(scope="module")
def sagittal_walk():
    """Seed 101, 30 s, the pack on, the hips turning nearly about one lateral axis, the
    transmitter on the stand (the walk's far end 2 m away, several centimetres of noise, more on
    the right thigh and the pelvis than on the left thigh): the MST makes one thigh the child of
    the other (as in O'Brien's walks), the misfit tree is right."""
    return walk_trial(101, 30.0, pack=True, hips="sagittal", tracker="stand")


def test_walk_mst_wrong_misfit_right(sagittal_walk):
    mst, misfit = sagittal_walk["methods"]["mst"], sagittal_walk["methods"]["misfit"]
    assert mst["thigh_child_of_thigh"] and not mst["correct"]
    assert "thigh_l-thigh_r" in mst["wrong_edges"]
    assert misfit["correct"] and misfit["wrong_edges"] == []
    pairs = sagittal_walk["hip_pairs"]
    # the mechanism: the thigh-thigh pair has the larger misfit; its residual beats the pelvis-right
    # thigh one because that pair's sensors are the noisier
    assert pairs["pelvis-thigh_r"]["rms_residual_cm"] > pairs["thigh_l-thigh_r"]["rms_residual_cm"]
    assert pairs["pelvis-thigh_r"]["noise_cm"] > pairs["thigh_l-thigh_r"]["noise_cm"]
    assert pairs["thigh_l-thigh_r"]["misfit_cm"] > max(
        pairs["pelvis-thigh_l"]["misfit_cm"], pairs["pelvis-thigh_r"]["misfit_cm"]
    )


def test_misfit_tree_does_not_depend_on_the_length_unit():
    sensors = walk_sensors(pack=True, tracker="stand")  # noisy: the noise estimate matters
    config = SessionConfig(model="humanoid", motion="walk", duration_s=20.0, seed=102, sensors=sensors)
    rec = run_session(config).poses()
    trees = [
        calibrate(rec.R_w_s, rec.p_w_s * scale, rec.names, valid=rec.valid, root="pelvis").parent_of
        for scale in (1.0, 1000.0)  # metres, millimetres
    ]
    assert trees[0] == trees[1]


def test_cli_hierarchy_method(tmp_path, capsys):
    cap = simulate_motion(
        linkage(), n_frames=600, rate_hz=120.0, rng=np.random.default_rng(3), position_noise_m=0.002
    )
    path = tmp_path / "linkage.csv"
    write_pose_csv(
        path, PoseRecording(cap.names, cap.time_s, cap.R_w_s, cap.p_w_s, np.ones(cap.p_w_s.shape[:2], bool))
    )
    docs = {}
    for method in ("mst", "misfit"):
        out_json = tmp_path / f"{method}.json"
        assert (
            main(["calibrate", str(path), "--hierarchy-method", method, "--no-slip", "--json", str(out_json)])
            == 0
        )
        docs[method] = json.loads(out_json.read_text())
    capsys.readouterr()
    for method, doc in docs.items():
        assert doc["options"]["hierarchy_method"] == method
        assert {j["child"]: j["parent"] for j in doc["joints"]} == cap.skeleton.parent_of
    with pytest.raises(SystemExit):
        main(["calibrate", str(path), "--hierarchy-method", "kruskal"])
    assert "invalid choice: 'kruskal'" in capsys.readouterr().err
