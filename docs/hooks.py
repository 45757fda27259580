"""MkDocs hooks (``hooks:`` in mkdocs.yml): pages generated at build time, so they cannot go stale.

- ``<!-- cli-reference -->`` becomes the reference of every ``simbench`` command, rendered from
  the real parser (:func:`simbench.cli.build_parser`): usage, description, arguments with their
  defaults and choices, and the ``examples:`` epilog of :mod:`simbench.cli.help_examples`.
- ``<!-- benchmark-results -->`` becomes every figure of every file in ``benchmarks/results/``,
  read from the files themselves.
- ``<!-- include: FILE -->`` becomes the repository's ``FILE`` (ARCHITECTURE.md: one source).
- The pictures the pages show from ``reports/`` (the committed reference report) are added to
  the site from there (:data:`REPORT_PICTURES`), not copied into ``docs/``.

Both are plain functions of the repository, tested in ``tests/test_docs_site.py``.
"""

from __future__ import annotations

import argparse
import html
import json
import re
import sys
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parent.parent
CLI_MARKER = "<!-- cli-reference -->"
RESULTS_MARKER = "<!-- benchmark-results -->"
INCLUDE = re.compile(r"^<!-- include: ([\w./-]+) -->$", flags=re.MULTILINE)
#: ``{path in the site: file in the repository}``: pictures of the reference report the pages show.
REPORT_PICTURES = {"assets/pictures_linkage.png": ROOT / "reports" / "pictures_linkage.png"}


def _text(text: str) -> str:
    """Help text as Markdown: HTML's specials escaped, emphasis characters kept literal."""
    return html.escape(" ".join(text.split()), quote=False).replace("*", r"\*").replace("_", r"\_")


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """``{name: parser}`` of the parser's subcommands, in the order ``--help`` lists them."""
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def _summaries(parser: argparse.ArgumentParser) -> dict[str, str]:
    """``{name: one-line help}`` of the subcommands, as ``simbench --help`` lists them."""
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return {a.dest: a.help or "" for a in action._choices_actions}


def _usage(parser: argparse.ArgumentParser) -> str:
    """The usage line(s) without argparse's ``usage: `` prefix, continuation lines moved left with it."""
    prefix = "usage: "
    lines = parser.format_usage().strip().splitlines()
    lines = [lines[0].removeprefix(prefix)] + [line.removeprefix(" " * len(prefix)) for line in lines[1:]]
    return "\n".join(lines)


def _argument(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """One argument as a Markdown list item: its flags and metavar, help, default and choices."""
    formatter = parser._get_formatter()
    if action.option_strings:
        if action.nargs == 0:
            name = ", ".join(action.option_strings)
        else:
            metavar = formatter._format_args(action, action.dest.upper())
            name = ", ".join(f"{flag} {metavar}" for flag in action.option_strings)
    else:
        name = formatter._format_args(action, action.dest)
    text = _text(formatter._expand_help(action)) if action.help else ""
    extras = []
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        extras.append("choices: " + ", ".join(f"`{c}`" for c in action.choices))
    if (
        action.option_strings
        and action.nargs != 0
        and action.default not in (None, argparse.SUPPRESS, [])
        and "default" not in (action.help or "")
    ):
        extras.append(f"default: `{action.default}`")
    if action.required and action.option_strings:
        extras.append("required")
    tail = f" ({'; '.join(extras)})" if extras else ""
    return f"- `{name}`: {text}{tail}".rstrip()


def command_markdown(name: str, parser: argparse.ArgumentParser, summary: str) -> str:
    """The reference of one subcommand: heading, summary, description, usage, arguments, examples."""
    lines = [f"## simbench {name}", ""]
    if summary:
        lines += [f"*{_text(summary)}*", ""]
    if parser.description:
        lines += [_text(parser.description), ""]
    lines += ["```text", _usage(parser), "```", ""]
    positionals = [a for a in parser._actions if not a.option_strings]
    options = [a for a in parser._actions if a.option_strings and a.help != argparse.SUPPRESS]
    if positionals:
        lines += ["**Arguments**", ""] + [_argument(parser, a) for a in positionals] + [""]
    if options:
        lines += ["**Options**", ""] + [_argument(parser, a) for a in options] + [""]
    if parser.epilog and parser.epilog.startswith("examples:\n"):
        examples = [line.strip() for line in parser.epilog.splitlines()[1:] if line.strip()]
        lines += ["**Examples**", "", "```bash", *examples, "```", ""]
    return "\n".join(lines)


def cli_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The whole command-line reference as Markdown: a table of the commands, then each one."""
    if parser is None:
        if str(ROOT) not in sys.path:  # this checkout's parser, whatever simbench is installed
            sys.path.insert(0, str(ROOT))
        from simbench.cli import build_parser  # the real parser, imported when a page asks for it

        parser = build_parser()
    commands = _subcommands(parser)
    summaries = _summaries(parser)
    lines = [
        "```text",
        _usage(parser),
        "```",
        "",
        _text(parser.description or ""),
        "",
        "| command | what it does |",
        "| --- | --- |",
    ]
    for name in commands:
        lines.append(f"| [`simbench {name}`](#simbench-{name}) | {_text(summaries.get(name, ''))} |")
    lines.append("")
    for name, sub in commands.items():
        lines.append(command_markdown(name, sub, summaries.get(name, "")))
    return "\n".join(lines)


def _number(value: Any) -> str:
    """A figure as the tables print it: 3 significant digits, thousands separated."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return html.escape(str(value), quote=False).replace("|", r"\|")
    if isinstance(value, int) or (float(value).is_integer() and abs(value) >= 1000):
        return f"{int(value):,}"
    return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"


def _flatten(doc: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """``(dotted key, value)`` of every number, string and flag in a results file, lists of
    numbers (the repeats of a timing) left out: their median is in the file beside them."""
    if isinstance(doc, dict):
        out = []
        for key, value in doc.items():
            out += _flatten(value, f"{prefix}.{key}" if prefix else str(key))
        return out
    if isinstance(doc, list):
        if all(isinstance(v, int | float) for v in doc):
            return []
        out = []
        for k, value in enumerate(doc):
            label = value.get("label") if isinstance(value, dict) else None
            out += _flatten(value, f"{prefix}[{label or k}]")
        return out
    return [(prefix, doc)]


def results_markdown(folder: Path | None = None) -> str:
    """Every ``benchmarks/results/*.json`` as a section: the file's figures, each by its key."""
    folder = ROOT / "benchmarks" / "results" if folder is None else folder
    lines: list[str] = []
    for path in sorted(folder.glob("*.json")):
        doc = json.loads(path.read_text(encoding="utf-8"))
        rows = _flatten(doc)
        lines += [
            f"### {path.stem}",
            "",
            f"`benchmarks/results/{path.name}` ({len(rows)} figures)",
            "",
            '??? note "every figure of the file"',
            "",
            "    | key | value |",
            "    | --- | --- |",
        ]
        lines += [f"    | `{key}` | {_number(value)} |" for key, value in rows]
        lines.append("")
    return "\n".join(lines)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """MkDocs event: fill the generated sections of a page."""
    if CLI_MARKER in markdown:
        markdown = markdown.replace(CLI_MARKER, cli_reference())
    if RESULTS_MARKER in markdown:
        markdown = markdown.replace(RESULTS_MARKER, results_markdown())
    return INCLUDE.sub(lambda m: (ROOT / m[1]).read_text(encoding="utf-8"), markdown)


def on_files(files: Any, config: Any) -> Any:
    """MkDocs event: add the reference report's pictures to the site."""
    for uri, path in REPORT_PICTURES.items():
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files
