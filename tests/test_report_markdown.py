"""Markdown tables and the Markdown -> self-contained HTML conversion of the reports."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

from simbench.report.markdown import markdown_table, markdown_to_html

# The smallest valid PNG (1x1 transparent pixel): its bytes must come back out of the page.
PNG_1X1 = base64.b64decode(
    "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNkYPhfDwAChwGA60e6kgAAAABJRU5ErkJggg=="
)


def test_table_aligns_text_left_and_numbers_right():
    table = markdown_table(
        ["limb", "true", "frames", "note"],
        [["upper_arm_l", 29.5, 12, "a | b"], ["thigh_r", np.float64(41.625), np.int64(3), True]],
    )
    lines = table.splitlines()
    assert lines[0] == "| limb | true | frames | note |"
    assert lines[1] == "|:---|---:|---:|:---|"  # numpy numbers count as numbers, bools as text
    assert lines[2] == "| upper_arm_l | 29.50 | 12 | a \\| b |"  # floats 2 decimals, | escaped
    assert lines[3] == "| thigh_r | 41.62 | 3 | True |"


def test_table_without_rows_is_left_aligned():
    assert markdown_table(["a", "b"], []).splitlines()[1] == "|:---|:---|"


def test_html_renders_tables_code_and_embeds_images(tmp_path):
    (tmp_path / "plot.png").write_bytes(PNG_1X1)
    md = "\n".join(
        [
            "# Report of `run.h5`",
            "",
            "Joint `chest-head` of <b>run</b>.",
            "",
            markdown_table(["joint", "rms residual (mm)"], [["chest -> head", 1.234]]),
            "",
            '- plan: `{"quick": true}`',
            "",
            "![residual norms](plot.png)",
            "",
        ]
    )
    page = markdown_to_html(md, tmp_path)
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert "<title>Report of run.h5</title>" in page
    assert "<code>chest-head</code>" in page and "<code>run.h5</code>" in page
    assert "<code>{&quot;quick&quot;: true}</code>" in page
    assert "`" not in page  # every inline code span was rendered
    assert "&lt;b&gt;run&lt;/b&gt;" in page  # raw HTML in the text is shown, not interpreted
    assert re.search(r'<th style="text-align:left">joint</th>\s*<th style="text-align:right">rms', page)
    cells = r'<td style="text-align:left">chest -&gt; head</td>\s*<td style="text-align:right">1.23</td>'
    assert re.search(cells, page)
    data = re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)" alt="residual norms"', page)
    assert [base64.b64decode(x) for x in data] == [PNG_1X1]
    assert "plot.png" not in page  # self-contained: no link to the file is left


def test_html_title_can_be_given_and_remote_images_stay_links(tmp_path):
    page = markdown_to_html("text\n\n![logo](https://example.org/logo.png)\n", tmp_path, title="A & B")
    assert "<title>A &amp; B</title>" in page and 'src="https://example.org/logo.png"' in page


def test_html_fails_on_a_missing_image(tmp_path):
    with pytest.raises(FileNotFoundError):
        markdown_to_html("![gone](gone.png)\n", tmp_path)
