"""A command that writes one file has a default name for it (issue 44): `simbench simulate --model
humanoid` runs anywhere."""

from __future__ import annotations

import argparse

from simbench.cli import main
from simbench.cli.simulate import default_output
from simbench.io.dataset import read_dataset


def test_simulate_without_o_writes_a_file_named_for_what_made_it(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--duration", "1", "--seed", "4"]) == 0
    assert "wrote linkage-exercise-ideal-seed4.h5" in capsys.readouterr().out
    ds = read_dataset(tmp_path / "linkage-exercise-ideal-seed4.h5")
    assert ds.meta["seed"] == 4 and ds.meta["model"] == "linkage"


def test_the_default_name_takes_files_by_their_stem_and_keeps_to_safe_characters():
    args = argparse.Namespace(
        model="models/My Arm.xml", motion="clips/walk 01.bvh", sensors="lab.toml", seed=7
    )
    assert default_output(args) == "My_Arm-walk_01-lab-seed7.h5"
    args = argparse.Namespace(model="dm_control:humanoid", motion="gait", sensors="mems-consumer", seed=0)
    assert default_output(args) == "dm_control_humanoid-gait-mems-consumer-seed0.h5"
