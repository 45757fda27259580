"""The documentation site (mkdocs.yml, docs/): it builds with ``mkdocs build --strict`` and no network,
its generated pages cover every command and every saved result, and the README stays short and
points into it."""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from markdown_it import MarkdownIt

from simbench.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent

pytest.importorskip("mkdocs")
pytest.importorskip("material")
pytest.importorskip("mkdocstrings_handlers.python")


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


HOOKS = _hooks()


def _commands() -> dict[str, argparse.ArgumentParser]:
    (action,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """``mkdocs build --strict`` into a fresh folder: every warning (a broken link, a page left out
    of the nav, a docstring mkdocstrings cannot read) fails it."""
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)}
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr[-4000:]
    assert "WARNING" not in run.stderr, run.stderr[-4000:]
    return out


def test_site_builds_strict_with_every_page(site):
    pages = ("index.html", "getting-started/index.html", "reference/cli/index.html", "figures/index.html")
    for page in pages:
        assert (site / page).is_file(), page
    # every Markdown page of docs/ is in the site (mkdocs.yml's nav warns about any left out)
    for path in (ROOT / "docs").rglob("*.md"):
        rel = path.relative_to(ROOT / "docs").with_suffix("")
        built = site / ("index.html" if rel.name == "index" else rel / "index.html")
        assert built.is_file(), rel
    # the picture the home page shows comes from the reference report
    assert (site / "assets" / "pictures_linkage.png").read_bytes() == (
        ROOT / "reports" / "pictures_linkage.png"
    ).read_bytes()


def test_api_reference_is_generated_from_the_docstrings(site):
    api = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    for name in ("simulate", "calibrate", "score", "orient", "export", "follow", "replay"):
        assert f'id="simbench.api.{name}"' in api, name
    core = (site / "reference" / "calibration" / "index.html").read_text(encoding="utf-8")
    assert 'id="calibration.pipeline.calibrate"' in core and 'id="calibration.joint.fit_joint"' in core
    streaming = (site / "reference" / "calibration-streaming" / "index.html").read_text(encoding="utf-8")
    assert 'id="calibration.streaming.StreamingCalibrator"' in streaming


def test_site_needs_no_network():
    """Nothing is fetched at build time or by the pages: no web fonts, no plugin that downloads."""
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert re.search(r"^\s+font: false$", text, flags=re.MULTILINE)
    for plugin in ("social", "privacy", "optimize"):
        assert not re.search(rf"^\s+- {plugin}\b", text, flags=re.MULTILINE), plugin


def test_built_pages_load_nothing_from_elsewhere(site):
    for page in (site / "index.html", site / "reference" / "cli" / "index.html"):
        html = page.read_text(encoding="utf-8")
        assert "fonts.googleapis" not in html and "fonts.gstatic" not in html
        assert not re.search(r'<(?:link|script)[^>]+(?:href|src)="https?://', html), page


def test_cli_reference_has_every_command_and_option(site):
    text = HOOKS.cli_reference()
    html = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    for name, parser in _commands().items():
        assert f"## simbench {name}\n" in text and f'id="simbench-{name}"' in html, name
        section = text.split(f"## simbench {name}\n", 1)[1].split("\n## simbench ", 1)[0]
        for action in parser._actions:
            for flag in action.option_strings:
                assert f"`{flag}" in section or f", {flag}" in section, (name, flag)
        if parser.epilog:  # the help's examples, line for line
            for line in parser.epilog.splitlines()[1:]:
                assert line.strip() in section, (name, line)


def test_cli_reference_renders_an_analytic_parser():
    """A parser made here: usage, summary, positional, flag, choices, default and examples."""
    parser = argparse.ArgumentParser(prog="simbench")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    cmd = sub.add_parser("demo", help="a demo command", description="Demo *with* <tags>.")
    cmd.add_argument("input", help="the input file")
    cmd.add_argument("--units", choices=["m", "mm"], default="m", help="length unit")
    cmd.add_argument("--quiet", action="store_true", help="say less")
    cmd.epilog = "examples:\n  simbench demo a.csv --units mm"
    text = HOOKS.cli_reference(parser)
    assert "| [`simbench demo`](#simbench-demo) | a demo command |" in text
    assert r"Demo \*with\* &lt;tags&gt;." in text
    assert "usage: " not in text and "simbench demo [-h] [--units {m,mm}] [--quiet] input" in text
    assert "- `input`: the input file" in text
    assert "- `--units {m,mm}`: length unit (choices: `m`, `mm`; default: `m`)" in text
    assert "- `--quiet`: say less" in text
    assert "```bash\nsimbench demo a.csv --units mm\n```" in text


def test_figures_page_lists_every_saved_result(site, tmp_path):
    results = sorted((ROOT / "benchmarks" / "results").glob("*.json"))
    assert results
    html = (site / "figures" / "index.html").read_text(encoding="utf-8")
    for path in results:
        assert f"benchmarks/results/{path.name}" in html, path.name
    # the tables are the files' figures: an analytic file renders key by key
    (tmp_path / "demo.json").write_text(
        json.dumps({"rows": {"a": {"median_s": 0.012345, "times_s": [1, 2]}}, "frames": 200000, "ok": True})
    )
    text = HOOKS.results_markdown(tmp_path)
    assert "| `rows.a.median_s` | 0.0123 |" in text
    assert "| `frames` | 200,000 |" in text and "| `ok` | True |" in text
    assert "times_s" not in text  # the repeats: their median is beside them


def test_readme_is_short_and_points_into_the_docs():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    # one picture, from the committed report, by a relative path (GitHub and the wheel's metadata)
    pictures = re.findall(r"!\[[^\]]+\]\(([^)]+)\)", text)
    assert pictures == ["reports/pictures_linkage.png"] and (ROOT / pictures[0]).is_file()
    # the two commands, unchanged (.ci/run calls the second)
    assert "bash scripts/run.sh     # set up, then run the main job on built-in defaults" in text
    assert "bash scripts/test.sh    # set up, then run ruff (lint + format check) and the test suite" in text
    assert "bash scripts/test.sh" in (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    # every relative link names a file of the repository
    tokens = MarkdownIt("commonmark").parse(text)
    links = [
        child.attrs["href"]
        for t in tokens
        if t.type == "inline"
        for child in t.children or ()
        if child.type == "link_open"
    ]
    relative = [link for link in links if not re.match(r"[a-z]+:", link)]
    assert len(relative) >= 20
    for link in relative:
        assert (ROOT / link.split("#", 1)[0]).is_file(), link
    # the commands table names every command the parser has
    table = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    for name in _commands():
        assert f"| `simbench {name}` |" in table, name
