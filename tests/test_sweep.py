"""Studies (issue 7): identical rows for any executor, resumption after a kill, bad files, effects."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from simbench.errors import InputError
from simbench.experiments import sweep as sw

STUDY = """
name = "small"
seed = 3
seeds_per_cell = 2
estimators = ["calibration"]
metrics = ["joint_centre_error_m", "limb_length_error_m", "hierarchy_correct"]
[base]
model = "linkage"
motion = "exercise"
sensors = "ascension-flock"
duration_s = {duration}
[sampling]
kind = "grid"
[[parameter]]
name = "sensors.tracker.position_noise_m"
unit = "mm"
values = {values}
"""


def study_file(tmp_path: Path, duration: float = 3.0, values: str = "[0.0, 8.0]") -> Path:
    path = tmp_path / "study.toml"
    path.write_text(STUDY.format(duration=duration, values=values))
    return path


def rows(table) -> list[dict]:
    out = table.to_pylist()
    for r in out:
        r.pop("run_time_s")
    return sorted(out, key=lambda r: r["trial"])


def test_one_or_two_workers_give_identical_rows(tmp_path):
    study = sw.load_study(study_file(tmp_path))
    one = sw.run_study(study, tmp_path / "one", workers=1)
    two = sw.run_study(study, tmp_path / "two", workers=2)
    assert len(rows(one)) == 4 and rows(one) == rows(two)
    assert (tmp_path / "one" / "results.parquet").is_file()


def test_dask_local_cluster_gives_identical_rows(tmp_path):
    distributed = pytest.importorskip("distributed")
    study = sw.load_study(study_file(tmp_path))
    local = sw.run_study(study, tmp_path / "local", workers=1)
    with (
        distributed.LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            protocol="tcp",
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1")
        dask = sw.run_study(study, tmp_path / "dask", executor=client.get_executor())
    assert rows(dask) == rows(local)


def test_killed_study_resumes_with_each_trial_once(tmp_path):
    path = study_file(tmp_path, duration=2.0, values="[0.0, 2.0, 4.0, 8.0]")  # 8 trials
    out = tmp_path / "out"
    cmd = [
        sys.executable,
        "-m",
        "simbench",
        "sweep",
        str(path),
        "--out",
        str(out),
        "--workers",
        "1",
        "--no-progress",
    ]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(sw.finished(out)) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)  # the study and its worker, mid-way
    proc.wait()
    partial = sw.finished(out)
    assert 2 <= len(partial) < 8
    assert not list((out / "trials").glob(".*.tmp"))  # no half-written trial survives
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    table = sw.gather(out)
    ids = table.column("trial").to_pylist()
    assert len(ids) == 8 and len(set(ids)) == 8
    fresh = sw.run_study(sw.load_study(path), tmp_path / "fresh", workers=2)
    assert rows(table) == rows(fresh)


def test_error_grows_with_noise(tmp_path):
    study = sw.load_study(study_file(tmp_path, duration=6.0, values="[0.0, 12.0]"))
    table = sw.run_study(study, tmp_path / "noise", executor=ProcessPoolExecutor(2))
    data = table.to_pydict()
    noise = np.array(data["sensors.tracker.position_noise_m"])
    err = np.array(data["joint_centre_error_m"])
    # 12 mm of noise vs the preset's orientation noise alone: clearly larger error (a real effect)
    assert err[noise > 0].mean() > 2.0 * err[noise == 0].mean()


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        (
            ("sensors.tracker.position_noise_m", "sensors.tracker.noise"),
            "tracker has no numeric field 'noise'",
        ),
        (('unit = "mm"', 'unit = "deg"'), "unit 'deg' does not fit"),
        (("values = [0.0, 8.0]", "values = []"), "needs a non-empty list"),
        (("seeds_per_cell = 2", "seeds_per_cell = 0"), "seeds_per_cell must be an integer >= 1"),
        (("[sampling]", "colour = 1\n[sampling]"), r"unknown keys \['colour'\]"),
        (('estimators = ["calibration"]', 'estimators = ["magic"]'), "unknown 'magic'"),
        (('kind = "grid"', 'kind = "random"\nsamples = 4'), "random sampling needs low < high"),
    ],
)
def test_bad_study_files_are_rejected_before_any_work(tmp_path, patch, message):
    path = study_file(tmp_path)
    path.write_text(path.read_text().replace(*patch))
    with pytest.raises(InputError, match=message):
        sw.load_study(path)


def test_cli_rejects_bad_study_without_output(tmp_path, capsys):
    from simbench.cli import main

    path = study_file(tmp_path)
    path.write_text(path.read_text().replace("ascension-flock", "no-such-preset"))
    assert main(["sweep", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "unknown sensor preset" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_random_sampling_is_seeded_and_in_range(tmp_path):
    path = tmp_path / "r.toml"
    path.write_text(
        STUDY.format(duration=2.0, values="[0]")
        .replace('kind = "grid"', 'kind = "random"\nsamples = 50')
        .replace("values = [0]", "low = 1.0\nhigh = 10.0\nlog = true")
    )
    study = sw.load_study(path)
    a, b = sw.trials(study), sw.trials(study)
    assert a == b and len(a) == 100
    v = np.array([t.params[0][1] for t in a])
    assert v.min() >= 0.001 and v.max() <= 0.010  # mm converted to metres


def test_placement_parameter_moves_the_sensor(tmp_path):
    from simbench.sim.session import SessionConfig, load_session_model, run_session

    base = run_session(SessionConfig(duration_s=1.0))
    shifted_cfg = SessionConfig(duration_s=1.0, placement=(("forearm_l", (0.05, -0.02, 0.0)),))
    shifted = run_session(shifted_cfg, load_session_model(shifted_cfg))
    k = base.sensors.index("forearm_l")
    assert np.allclose(shifted.truth.p_b_s[k] - base.truth.p_b_s[k], [0.05, -0.02, 0.0], atol=1e-12)
    others = [i for i in range(len(base.sensors)) if i != k]
    assert np.array_equal(shifted.truth.p_b_s[others], base.truth.p_b_s[others])
    path = tmp_path / "p.toml"
    path.write_text(
        STUDY.format(duration=2.0, values="[0.0]")
        .replace("sensors.tracker.position_noise_m", "placement.forearm_l.x_m")
        .replace('unit = "mm"', 'unit = "cm"')
        .replace("values = [0.0]", "values = [-5.0, 5.0]")
    )
    study = sw.load_study(path)
    assert [t.params for t in sw.trials(study)][::2] == [
        (("placement.forearm_l.x_m", -0.05),),
        (("placement.forearm_l.x_m", 0.05),),
    ]
    path.write_text(path.read_text().replace("placement.forearm_l.x_m", "placement.forearm_l.w"))
    with pytest.raises(InputError, match=r"expected placement\.<sensor>\.x_m"):
        sw.load_study(path)
