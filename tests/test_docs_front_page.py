"""
The README is the front page: its documentation list names every page of the site, its install section and the install
section of docs/use_it_in_your_project.md give the command that compiles the kernels, and the docs point to the
runnable examples as files of the repository (``examples/``, shipped in the sdist: ``test_wheel.py``).
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
LINK = re.compile(r"\]\((?P<target>[^)#\s]+)(?:#[^)]*)?\)")
PRECOMPILE = "python -m sb3_affect.kernel"


def section(text: str, heading: str) -> str:
    """The text under ``heading`` (a ``## `` line) up to the next heading of that level."""
    start = text.index(f"\n{heading}\n")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def test_the_readme_lists_every_page_of_the_site() -> None:
    pages = {p.name for p in (ROOT / "docs").iterdir() if p.suffix in {".md", ".rst"} and p.name != "index.rst"}
    listed = {Path(m["target"]).name for m in LINK.finditer(section(README, "## Documentation"))
              if m["target"].startswith("docs/")}
    assert pages - listed == set(), f"pages missing from README's documentation list: {sorted(pages - listed)}"


def test_the_install_sections_give_the_precompile_command() -> None:
    assert PRECOMPILE in section(README, "## Install")
    page = (ROOT / "docs" / "use_it_in_your_project.md").read_text()
    assert PRECOMPILE in section(page, "## Install variants")


def test_the_docs_link_every_example_as_a_file_that_exists() -> None:
    linked: set[str] = set()
    for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]:
        for match in LINK.finditer(page.read_text()):
            target = (page.parent / match["target"]).resolve()
            if (ROOT / "examples") in target.parents or target == ROOT / "examples":
                assert target.exists(), f"{page.name} links {match['target']}, which does not exist"
                linked.add(target.name)
    examples = {p.name for p in (ROOT / "examples").glob("*.py")}
    assert examples <= linked, f"examples no page links: {sorted(examples - linked)}"
