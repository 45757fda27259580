"""Every Python example of the README runs, from the repository root, as a user would paste it."""

from __future__ import annotations

from pathlib import Path

import pytest
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parent.parent


def python_examples() -> list[str]:
    tokens = MarkdownIt("commonmark").parse((ROOT / "README.md").read_text(encoding="utf-8"))
    return [t.content for t in tokens if t.type == "fence" and t.info.strip() == "python"]


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
    if "sb.score(" in code:
        # the quickstart's claims: the linkage's tree is right and its limbs within the paper's 1.1 cm
        result = namespace["result"]
        assert result.tree.correct and result.tree.wrong_edges == ()
        assert result.max_length_error_m < 0.011
        assert namespace["ori"].score.total_rmse_deg < 2.0
        assert "True ()" in out
