"""The new-user flow ("First steps" of docs/getting-started.md), every step in order as a user would
run it: write the example files into a folder and work there, simulate a marker dataset, export it,
load the TRC file into pandas, run a study, open the HTML report."""

from __future__ import annotations

import base64
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from simbench.cli import main
from simbench.io.dataset import read_dataset
from tests.test_readme import FLOW_PAGE, flow_fences

pytest.importorskip("pandas")
pytest.importorskip("distributed")  # simbench sweep (the studies extra)

#: Lines of the shell blocks that install simbench, which the test suite already has.
SETUP = ("pip install", "bash scripts/setup.sh", "source .venv/bin/activate")


def flow_steps() -> list[tuple[str, str]]:
    """``(language, code)`` of the flow's blocks, in order."""
    return [(f.lang, f.code) for f in flow_fences()]


def test_the_flow_has_every_step():
    text = "\n".join(code for _, code in flow_steps())
    assert "pip install" in text and "simbench examples" in text  # from a wheel, in a folder of one's own
    for step in ("simbench simulate", "--markers", "simbench export", "--trc", "pd.DataFrame", "read_trc"):
        assert step in text
    for step in ("simbench sweep studies/", "simbench report", "index.html"):
        assert step in text


def test_readme_flow_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    opened = []
    for lang, code in flow_steps():
        if lang == "python":
            namespace: dict = {"__name__": "readme_flow"}
            exec(compile(code, f"{FLOW_PAGE.name} First steps", "exec"), namespace)
            markers = namespace["markers"]
            continue
        assert lang == "bash", lang
        for line in code.splitlines():
            line = line.split("  #", 1)[0].strip()
            if not line or line.startswith(SETUP):
                continue
            for command in line.split(" && "):
                argv = shlex.split(command)
                if argv[0] == "cd":  # into the folder `simbench examples` wrote
                    monkeypatch.chdir(argv[1])
                    continue
                if argv[0] == "xdg-open":  # the user opens the report: it must be there, whole
                    opened.append(Path.cwd() / argv[1])
                    continue
                assert argv[0] == "simbench", line
                assert main(argv[1:]) == 0, (line, capsys.readouterr().err)
    work = Path.cwd()
    assert work != tmp_path and work.parent == tmp_path  # the steps ran in the examples' folder
    out = capsys.readouterr().out
    # the README's claims: 600 samples of 24 markers, every export written, the study summarised
    ds = read_dataset(work / "first.h5")
    assert markers.shape == (600, 72) and "(600, 72)" in out
    assert np.allclose(markers.to_numpy().reshape(600, 24, 3), ds.markers.xyz, rtol=0, atol=5.1e-10)
    for name in ("first.trc", "first.c3d", "first.sto", "first_imu.csv", "first.xml"):
        assert (work / name).stat().st_size > 0, name
    assert (work / "quickstart" / "summary.md").read_text().startswith("# Study quickstart")
    assert list((work / "quickstart").glob("*.png"))
    assert opened == [work / "first_report" / "index.html"]
    html = opened[0].read_text(encoding="utf-8")
    images = re.findall(r'<img [^>]*src="([^"]+)"', html)
    assert images and all(src.startswith("data:image/png;base64,") for src in images)
    assert base64.b64decode(images[0].split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"  # images load
