"""``simbench examples DIR``: the packaged examples, as the repository has them; the packaged baseline
is the checkout's and is not rewritten in place (issue 44)."""

from __future__ import annotations

import json

from simbench.cli import baseline as cli_baseline
from simbench.cli import main
from simbench.experiments.baseline import BASELINE_FILE, CHECKOUT_BASELINE, load_baseline
from simbench.io.examples import EXAMPLE_FILES, packaged_baseline
from tests.test_packaging import ROOT


def test_the_examples_are_written_as_the_repository_lays_them_out(tmp_path, capsys):
    folder = tmp_path / "first"
    assert main(["examples", str(folder)]) == 0
    assert f"simbench examples: {len(EXAMPLE_FILES)} files in {folder}" in capsys.readouterr().out
    for place in EXAMPLE_FILES.values():
        assert (folder / place).read_bytes() == (ROOT / place).read_bytes(), place
    assert main(["examples", str(folder)]) == 2  # nothing replaced without --force
    assert "exists (10 of the examples' files do); use --force" in capsys.readouterr().err
    (folder / "studies" / "noise.toml").write_text("changed")
    assert main(["examples", str(folder), "--force"]) == 0
    assert (folder / "studies" / "noise.toml").read_bytes() == (ROOT / "studies" / "noise.toml").read_bytes()
    assert main(["examples", str(folder / "studies" / "noise.toml")]) == 2  # a file, not a folder


def test_the_packaged_baseline_is_the_checkout_s_and_not_updated_in_place(monkeypatch, capsys):
    assert BASELINE_FILE == CHECKOUT_BASELINE  # in a checkout: the file --update rewrites
    assert json.loads(packaged_baseline().read_text()) == json.loads(CHECKOUT_BASELINE.read_text())
    assert load_baseline(packaged_baseline()) == load_baseline(CHECKOUT_BASELINE)
    monkeypatch.setattr(cli_baseline, "BASELINE_FILE", packaged_baseline())  # as an installed copy has it
    assert main(["baseline", "--update"]) == 2
    assert (
        "is the installed package's baseline, not yours to rewrite; give --file PATH"
        in capsys.readouterr().err
    )
