"""
The Markdown pages (docs/*.md and the README) are read on the repository's web page as well as on the docs site, so
they hold plain Markdown only: no MyST role (``{doc}`...```), no directive fence (an ``{eval-rst}`` or
``{literalinclude}`` block), no reStructuredText directive; each shows raw outside Sphinx. What a directive used to
generate is written into the page between ``<!-- KIND: ARGUMENT -->`` and ``<!-- end -->`` and must be what the code
gives now:

* ``file: PATH``: the file at ``PATH`` (from the repository's root) as a code block;
* ``docstring: MODULE``: the module's docstring (a paragraph ending in ``::`` and its indented block become a
  paragraph ending in ``:`` and a text block);
* ``sweep-schema`` and ``sweep-schema: forensics``: the experiment-file reference, one table per section, from the
  validating models of ``sb3_affect.study.launcher.schema``;
* ``controls``: the table of the package's deep controls, a row per registry entry with a ``docs_row``
  (``sb3_affect.core.registry.AGENT_ENTRIES``: the control, what it is, its class with its MiniGrid keywords).

After a change to any of them, write the pages again: ``python tests/test_docs_plain_markdown.py``.
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "README.md"]
#: A generated block: its marker, what the code gives, the end marker.
BLOCK = re.compile(
    r"<!-- (?P<kind>file|docstring|sweep-schema|controls)(?:: (?P<argument>[^ ]+))? -->\n(?P<body>.*?)<!-- end -->\n", re.S
)
#: What renders raw outside Sphinx: a MyST role, a directive fence (``` or :::), a reStructuredText directive.
RAW = re.compile(r"\{[a-z][a-z0-9:_-]*\}`|^(```+|:::+) *\{[a-z][a-z0-9:_-]*\}|^\.\. [a-z][a-z0-9:_-]*::", re.M)
#: Languages of the files a page shows, by suffix.
LANGUAGES = {".yaml": "yaml", ".yml": "yaml", ".toml": "toml", ".py": "python"}


def file_block(path: str) -> str:
    text = (ROOT / path).read_text()
    return f"```{LANGUAGES.get(Path(path).suffix, 'ini')}\n{text.rstrip()}\n```\n"


def docstring_block(module: str) -> str:
    """The docstring as Markdown: ``::`` and its indented block become ``:`` and a text block."""
    lines = inspect.cleandoc(importlib.import_module(module).__doc__ or "").splitlines()
    out: list[str] = []
    index = 0
    while index < len(lines):
        line = lines[index]
        index += 1
        if not line.endswith("::"):
            out.append(line)
            continue
        out.append(line[:-1])
        while index < len(lines) and not lines[index].strip():
            index += 1
        block: list[str] = []
        while index < len(lines) and (not lines[index].strip() or lines[index].startswith(" ")):
            block.append(lines[index])
            index += 1
        while block and not block[-1].strip():
            block.pop()
        indent = min(len(b) - len(b.lstrip()) for b in block if b.strip())
        out += ["", "```text", *(b[indent:] for b in block), "```", ""]
    return "\n".join(out).rstrip() + "\n"


def _type_name(annotation: Any) -> str:
    text = getattr(annotation, "__name__", None) if not getattr(annotation, "__args__", None) else None
    text = text or str(annotation).replace("typing.", "")
    text = text.replace("sb3_affect.study.launcher.schema.", "").replace("sb3_affect.study.launcher.deep_schema.", "")
    return text.replace("NoneType", "None")


#: How a field's JSON-schema constraints are written.
CONSTRAINTS = {
    "exclusiveMinimum": "> {}",
    "minimum": ">= {}",
    "minLength": "at least {} character(s)",
    "minItems": "at least {} item(s)",
    "pattern": "matches `{}`",
}


def _constraints(schema: dict[str, Any]) -> list[str]:
    return [template.format(option[key]) for option in [schema, *schema.get("anyOf", [])]
            for key, template in CONSTRAINTS.items() if key in option]


def _cell(text: str) -> str:
    """A table cell: ``|`` escaped, and ``<`` outside code spans (``DIR/logs/<run>/`` is no HTML tag)."""
    parts = text.replace("|", "\\|").split("`")
    return "`".join(part if index % 2 else part.replace("<", "\\<") for index, part in enumerate(parts))


def schema_block(which: str | None) -> str:
    """One table per section of an experiment file: top-level keys, ``env``, an item of ``agents`` (or a study's)."""
    from pydantic_core import PydanticUndefined

    from sb3_affect.study.launcher.deep_schema import EvaluationSpec, TrainerSpec, TunedSpec
    from sb3_affect.study.launcher.schema import AgentSpec, EnvSpec, ForensicsSpec, MemberSpec, ProtocolSpec, Sweep

    sections: tuple[tuple[str, Any], ...] = (
        ("Top-level keys", Sweep), ("`env`", EnvSpec), ("Each item of `agents`", AgentSpec),
        ("Each item of an agent's `team`", MemberSpec),
    )
    if which == "forensics":
        sections = (("`forensics`", ForensicsSpec), ("`forensics.protocol`", ProtocolSpec))
    if which == "deep":
        sections = (("`trainer`", TrainerSpec), ("`evaluation`", EvaluationSpec), ("A task's `tuned`", TunedSpec))
    lines: list[str] = []
    for title, model in sections:
        properties = model.model_json_schema()["properties"]
        lines += [f"**{title}**: {(model.__doc__ or '').strip().splitlines()[0]}", "",
                  "| key | type | default | meaning |", "|---|---|---|---|"]
        for name, field in model.model_fields.items():
            if field.is_required() or (field.default_factory is None and field.default is PydanticUndefined):
                default = "required"
            elif field.default_factory is not None:
                made = repr(field.default_factory())
                default = f"`{made}`"
                if "EnvSpec(" in made or "ProtocolSpec(" in made:
                    default = "see `env`" if "EnvSpec(" in made else "the paper's (below)"
            else:
                default = f"`{field.default!r}`"
            extra = _constraints(properties.get(name, {}))
            meaning = (field.description or "").replace("``", "`") + (f" ({'; '.join(extra)})" if extra else "")
            lines.append(f"| `{name}` | `{_cell(_type_name(field.annotation))}` | {_cell(default)} | {_cell(meaning)} |")
        lines.append("")
    return "\n".join(lines)


def controls_block() -> str:
    """The deep controls' table: a row per registry entry with a docs row, run with its zoo recipe's MiniGrid keywords."""
    from sb3_affect.core.registry import AGENT_ENTRIES

    lines = ["| control | what it is | how to run it |", "|---|---|---|"]
    for entry in AGENT_ENTRIES:
        if entry.docs_row is not None:
            keywords = ", ".join(f"{key}={value!r}" for key, value in ((entry.zoo and entry.zoo.minigrid) or {}).items())
            run = f"`{entry.name}(..., {keywords})`" if keywords else f"`{entry.name}(...)`"
            lines.append(f"| {_cell(entry.docs_row[0])} | {_cell(entry.docs_row[1])} | {run} |")
    return "\n".join(lines) + "\n"


def generated(kind: str, argument: str | None) -> str:
    if kind == "file":
        assert argument is not None
        return file_block(argument)
    if kind == "docstring":
        assert argument is not None
        return docstring_block(argument)
    if kind == "controls":
        return controls_block()
    return schema_block(argument)


def written(text: str) -> str:
    """The page with every generated block as the code gives it now."""
    def block(match: re.Match[str]) -> str:
        marker = f"<!-- {match['kind']}" + (f": {match['argument']}" if match["argument"] else "") + " -->"
        return f"{marker}\n{generated(match['kind'], match['argument'])}<!-- end -->\n"

    return BLOCK.sub(block, text)


@pytest.mark.parametrize("page", PAGES, ids=lambda page: page.name)
def test_a_page_has_nothing_that_shows_raw_outside_sphinx(page: Path) -> None:
    text = re.sub(r"^(````*)[a-z]*\n.*?^\1\n", "", page.read_text(), flags=re.S | re.M)  # code blocks show as written
    found = [match.group(0) for match in RAW.finditer(text)]
    assert not found, f"{page.name}: {found} render raw on the repository's web page; write plain Markdown"


def test_the_check_finds_roles_and_directives() -> None:
    for raw in ("see {doc}`concepts`", "```{eval-rst}\n.. plot:: x.py\n```", ":::{note}\nx\n:::", ".. automodule:: x"):
        assert RAW.search(raw), raw
    assert not RAW.search('`{"a": {}}` and ```python\nx = {}\n```')


def test_the_generated_blocks_are_what_the_code_gives_now() -> None:
    pages = {page.name: page.read_text() for page in PAGES}
    blocks = [(name, m["kind"], m["argument"]) for name, text in pages.items() for m in BLOCK.finditer(text)]
    assert ("deep_agents.md", "controls", None) in blocks
    assert ("experiment_files.md", "sweep-schema", None) in blocks and ("launcher.md", "docstring",
                                                                          "sb3_affect.study.launcher.store") in blocks
    stale = [name for name, text in pages.items() if written(text) != text]
    assert not stale, f"{stale} are out of date: python tests/test_docs_plain_markdown.py"


if __name__ == "__main__":
    for page in PAGES:
        page.write_text(written(page.read_text()))
    sys.exit(0)
