"""
docs/cli.md holds the ``sb3-affect`` command's help texts as plain text blocks, readable on the repository's web page
as on the docs site; they must be what the parser prints (at 92 columns, the width of the site's code blocks). After
a change to the command's options, write them again: ``python tests/test_docs_cli_page.py``.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

PAGE = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
#: A help block: the comment naming the command, then the text block.
BLOCK = re.compile(r"<!-- help: (?P<command>[a-z ]*?) -->\n```text\n(?P<text>.*?)```\n", re.S)


def help_text(command: str) -> str:
    """``sb3-affect [COMMAND] --help`` as the parser prints it at 92 columns."""
    from sb3_affect.study.cli import build_parser

    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "92"
    try:
        parser = build_parser()
        if command:
            subparsers = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
            parser = subparsers.choices[command]  # type: ignore[attr-defined]
        return parser.format_help()
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous


def written(text: str) -> str:
    """The page with every help block as the parser prints it now."""
    return BLOCK.sub(lambda m: f"<!-- help: {m['command']} -->\n```text\n{help_text(m['command'])}```\n", text)


def test_the_cli_page_shows_every_command_and_its_help_as_the_parser_prints_it() -> None:
    text = PAGE.read_text()
    commands = [m["command"] for m in BLOCK.finditer(text)]
    assert commands == ["", "run", "status", "report", "replicate", "forensics"]
    assert "{cli-help}" not in text and "{doc}" not in text
    assert text == written(text), "docs/cli.md is out of date: python tests/test_docs_cli_page.py"


if __name__ == "__main__":
    PAGE.write_text(written(PAGE.read_text()))
    sys.exit(0)
