"""Every Python example of the README and of ``docs/`` runs, as a user would paste it, in a folder
laid out by ``simbench examples`` (the newcomer's path: the example files, not the checkout).

A block that is not meant to run here says so on the line before its fence:

- ``<!-- no-run: REASON -->``: not run by this test (the reason names where it runs, or why not);
- ``<!-- needs: FILE -->``: a real recording of ``../shared/data``, linked into the folder; the
  block runs when the file is there and is skipped otherwise.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import pytest
from markdown_it import MarkdownIt

import simbench as sb

ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = ROOT.parent / "shared" / "data"

#: The new-user flow: its blocks run in order, with its files, in ``tests/test_readme_flow.py``.
FLOW_PAGE = ROOT / "docs" / "getting-started.md"
FLOW_SECTION = "First steps"

#: ``<!-- no-run: reason -->`` or ``<!-- needs: file -->`` on the line before a fence.
MARKER = re.compile(r"^<!--\s*(no-run|needs):\s*(\S.*?)\s*-->\s*$")


class Fence(NamedTuple):
    """A fenced block: its file, the title of the ``##`` heading above it, its language and code,
    and the marker before it (``("no-run", reason)``, ``("needs", file)`` or ``None``)."""

    path: Path
    section: str
    lang: str
    code: str
    marker: tuple[str, str] | None
    line: int


def markdown_files() -> list[Path]:
    """The README and every page of ``docs/``."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def fences(path: Path) -> list[Fence]:
    """Every fenced block of a Markdown file, in order."""
    tokens = MarkdownIt("commonmark").parse(path.read_text(encoding="utf-8"))
    out, section = [], ""
    for k, t in enumerate(tokens):
        if t.type == "heading_open" and t.tag == "h2":
            section = tokens[k + 1].content
        elif t.type == "fence":
            marker = None
            if k and tokens[k - 1].type == "html_block":  # the marker is the block right above
                lines = tokens[k - 1].content.strip().splitlines()
                match = MARKER.match(lines[-1]) if lines else None
                marker = (match[1], match[2]) if match else None
            out.append(Fence(path, section, t.info.strip().split(" ")[0], t.content, marker, t.map[0] + 1))
    return out


def readme_fences() -> list[tuple[str, str, str]]:
    """``(section, language, code)`` of every fenced block of the README."""
    return [(f.section, f.lang, f.code) for f in fences(ROOT / "README.md")]


def flow_fences() -> list[Fence]:
    """The new-user flow's blocks, in order."""
    return [f for f in fences(FLOW_PAGE) if f.section == FLOW_SECTION]


def python_examples() -> list[Fence]:
    """The stand-alone Python examples of the README and the docs (the flow's run in its own test)."""
    out = []
    for path in markdown_files():
        for fence in fences(path):
            if fence.lang != "python" or (path == FLOW_PAGE and fence.section == FLOW_SECTION):
                continue
            out.append(fence)
    return out


def _id(fence: Fence) -> str:
    return f"{fence.path.relative_to(ROOT)}:{fence.line}"


EXAMPLES = python_examples()


def test_readme_has_the_quickstart():
    examples = [f.code for f in EXAMPLES if f.path.name == "README.md"]
    assert len(examples) >= 1
    assert "sb.simulate(" in examples[0] and "sb.score(" in examples[0] and "sb.orient(" in examples[0]


def test_docs_have_examples_and_few_exceptions():
    """The docs' examples are found, and the blocks that do not run here are few and say why."""
    assert len(EXAMPLES) >= 8
    skipped = [f for f in EXAMPLES if f.marker is not None]
    assert len(skipped) <= 4, [_id(f) for f in skipped]
    for fence in skipped:
        kind, what = fence.marker
        assert len(what) > 10 or kind == "needs", (_id(fence), "a no-run marker needs its reason")
    # a marker names a known kind only (a typo would silently run or skip a block)
    for path in markdown_files():
        for line in path.read_text(encoding="utf-8").splitlines():
            if line.startswith("<!--") and ("no-run" in line or "needs" in line):
                assert MARKER.match(line), (path.name, line)


@pytest.mark.parametrize("fence", EXAMPLES, ids=_id)
def test_example_runs(fence, tmp_path, capsys, monkeypatch):
    if fence.marker is not None and fence.marker[0] == "no-run":
        pytest.skip(f"no-run: {fence.marker[1]}")
    sb.write_examples(tmp_path)  # the files of `simbench examples DIR`, laid out as the docs expect
    if fence.marker is not None and fence.marker[0] == "needs":
        source = SHARED_DATA / fence.marker[1]
        if not source.is_file():
            pytest.skip(f"{source} not beside the repository")
        (tmp_path / source.name).symlink_to(source)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "docs_example"}
    exec(compile(fence.code, _id(fence), "exec"), namespace)
    out = capsys.readouterr().out
    if "sphere_fit.py" in fence.code and "sphere fit:" in fence.code:
        assert "sphere fit:" in out and "cm from the true centres" in out
    if "result" in namespace and fence.path.name == "README.md":
        # the quickstart's claims: the linkage's tree is right and its limbs within the paper's 1.1 cm
        result = namespace["result"]
        assert result.tree.correct and result.tree.wrong_edges == ()
        assert result.max_length_error_m < 0.011
        assert namespace["ori"].score.total_rmse_deg < 2.0
        assert "True ()" in out
