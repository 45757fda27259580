"""Every Python example of the README runs, from the repository root, as a user would paste it."""

from __future__ import annotations

from pathlib import Path

import pytest
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parent.parent


#: The README's new-user flow: its blocks run in order, with its files, in ``tests/test_readme_flow.py``.
FLOW_SECTION = "First steps"


def readme_fences() -> list[tuple[str, str, str]]:
    """``(section, language, code)`` of every fenced block of the README, ``section`` the title of
    the ``##`` heading above it."""
    tokens = MarkdownIt("commonmark").parse((ROOT / "README.md").read_text(encoding="utf-8"))
    out, section = [], ""
    for k, t in enumerate(tokens):
        if t.type == "heading_open" and t.tag == "h2":
            section = tokens[k + 1].content
        elif t.type == "fence":
            out.append((section, t.info.strip(), t.content))
    return out


def python_examples() -> list[str]:
    """The README's stand-alone Python examples (the new-user flow's are run by its own test)."""
    return [code for section, lang, code in readme_fences() if lang == "python" and section != FLOW_SECTION]


def test_readme_has_the_quickstart():
    examples = python_examples()
    assert len(examples) >= 3
    assert "sb.simulate(" in examples[0] and "sb.score(" in examples[0] and "sb.orient(" in examples[0]


@pytest.mark.parametrize("index", range(len(python_examples())))
def test_readme_example_runs(index, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    code = python_examples()[index]
    namespace: dict = {"__name__": f"readme_example_{index}"}
    exec(compile(code, f"README.md python example {index + 1}", "exec"), namespace)
    out = capsys.readouterr().out
    if "sphere_fit.py" in code:  # a user's estimator from its file, scored like a built-in
        assert "sphere fit:" in out and "cm from the true centres" in out
    if "result" in namespace:
        # the quickstart's claims: the linkage's tree is right and its limbs within the paper's 1.1 cm
        result = namespace["result"]
        assert result.tree.correct and result.tree.wrong_edges == ()
        assert result.max_length_error_m < 0.011
        assert namespace["ori"].score.total_rmse_deg < 2.0
        assert "True ()" in out
