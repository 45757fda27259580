"""Markdown of the reports: tables, and the conversion to one self-contained HTML page.

The reports are written in CommonMark with GitHub-style tables; :func:`markdown_to_html` renders
them with markdown-it-py (raw HTML in the text is escaped, not passed through) and embeds every
image as a base64 ``data:`` URI, so that the page can be mailed or archived alone.
"""

from __future__ import annotations

import base64
import html
import mimetypes
import numbers
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from markdown_it import MarkdownIt
from markdown_it.token import Token

#: CommonMark, tables on, raw HTML off (a sensor or file name is never taken for markup).
_MARKDOWN = MarkdownIt("commonmark", {"html": False}).enable("table")

_STYLE = (
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
    "table{border-collapse:collapse;font-size:13px;margin:1em 0;display:block;max-width:100%;overflow-x:auto}"
    "td,th{border:1px solid #bbb;padding:3px 7px}th{background:#eee}"
    "code{background:#f3f3f3;padding:0 2px}img{max-width:100%}"
)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _cell(value: Any) -> str:
    """A table cell: floats with two decimals, anything else as ``str``; ``|`` escaped."""
    text = f"{value:.2f}" if isinstance(value, float) else str(value)
    return text.replace("|", "\\|")


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """A Markdown table; columns of numbers right-aligned, all others left-aligned.

    Args:
        header: the column titles.
        rows: the rows, each with one value per column; floats are printed with two decimals.
    """
    numeric = [bool(rows) and all(_is_number(row[k]) for row in rows) for k in range(len(header))]
    lines = [
        "| " + " | ".join(_cell(title) for title in header) + " |",
        "|" + "".join("---:|" if right else ":---|" for right in numeric),
    ]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def _data_uri(path: Path) -> str:
    """The file as a ``data:`` URI (type from its suffix)."""
    mime = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return f"data:{mime};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def _embed_images(tokens: list[Token], image_dir: Path) -> None:
    """Replace the ``src`` of every image with a local file by its ``data:`` URI, in place."""
    for token in tokens:
        for child in token.children or ():
            if child.type != "image":
                continue
            src = str(child.attrGet("src") or "")
            if urlsplit(src).scheme:  # http:, data: ...: not a file of ours
                continue
            child.attrSet("src", _data_uri(image_dir / unquote(src)))


def _first_heading(tokens: list[Token]) -> str | None:
    """The plain text of the first heading, or ``None``."""
    for k, token in enumerate(tokens[:-1]):
        if token.type == "heading_open":
            return "".join(
                c.content for c in tokens[k + 1].children or () if c.type in ("text", "code_inline")
            )
    return None


def markdown_to_html(md: str, image_dir: Path, *, title: str | None = None) -> str:
    """A self-contained HTML page of a Markdown report.

    Args:
        md: the report (CommonMark and GitHub-style tables with alignment rows).
        image_dir: the folder that image links are relative to; every linked image is embedded.
        title: the page title (default: the text of the first heading).

    Raises:
        OSError: a linked image cannot be read.
    """
    tokens = _MARKDOWN.parse(md)
    _embed_images(tokens, image_dir)
    body = _MARKDOWN.renderer.render(tokens, _MARKDOWN.options, {})
    page_title = html.escape(title or _first_heading(tokens) or "simbench report")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{page_title}</title><style>{_STYLE}</style></head><body>\n" + body + "</body></html>\n"
    )
