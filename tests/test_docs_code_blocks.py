"""
Every ```` ```python ```` block of the Markdown pages (README.md and docs/*.md) runs as a reader runs it: the blocks of
one page in order, in one namespace, in a scratch folder. What differs from the page is written here and only here:

* **Budgets shrink** (``shrink``): a number of steps given to ``learn`` (``.learn(N`` or ``total_timesteps=N``)
  larger than ``SB3_AFFECT_DOCS_BUDGET`` (an environment variable, default 300) becomes that budget, and
  ``StopTrainingOnMaxEpisodes(N)`` stops after at most 3 episodes. ``SB3_AFFECT_DOCS_BUDGET=0`` runs the pages' own
  budgets (minutes: the README's and the deep agents' examples train for real).
* **A hidden set-up** may precede a block that continues a reader's own code (a ``model``, an ``env`` or a policy of
  theirs): an HTML comment right above the block, which neither GitHub nor the docs site shows::

      <!-- docs-test: before
      env = gym.make("FrozenLake-v1")
      -->

  runs in the page's namespace before the block.
* Nothing reaches the network: ``huggingface_hub.upload_folder`` records its arguments instead of uploading.

A page whose blocks import an optional extra that is not installed is skipped, naming the module.
"""

from __future__ import annotations

import importlib.util
import os
import re
import sys
import warnings
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: A ```python block, with the hidden set-up comment right above it if there is one.
BLOCK = re.compile(r"(?:<!-- docs-test: before\n(?P<before>.*?)-->\n)?^```python\n(?P<code>.*?)^```", re.S | re.M)
#: The modules of the optional extras (and sb3-contrib) a page may import: the page is skipped when one is missing.
OPTIONAL = ("minigrid", "sb3_contrib", "pettingzoo", "huggingface_hub", "huggingface_sb3", "rl_zoo3", "ray")


def blocks(page: Path) -> list[tuple[str, str, int]]:
    """``(hidden set-up, code, line)`` of each python block of ``page``, in order."""
    text = page.read_text()
    return [(m["before"] or "", m["code"], text.count("\n", 0, m.start("code"))) for m in BLOCK.finditer(text)]


def budget() -> int:
    return int(os.environ.get("SB3_AFFECT_DOCS_BUDGET", "300"))


def shrink(code: str, steps: int) -> str:
    """``code`` with its step budgets at most ``steps`` and its episode caps at most 3 (``steps`` 0: unchanged)."""
    if not steps:
        return code

    def cap(match: re.Match[str]) -> str:
        value = eval(match["n"].replace("_", ""), {})  # a literal such as 10**8 or 100_000
        return match["head"] + str(min(int(value), steps))

    code = re.sub(r"(?P<head>\.learn\((?:total_timesteps=)?)(?P<n>[0-9_]+(?:\*\*[0-9]+)?)", cap, code)
    code = re.sub(r"(?P<head>total_timesteps=)(?P<n>[0-9_]+(?:\*\*[0-9]+)?)", cap, code)
    episodes = r"StopTrainingOnMaxEpisodes\((?P<n>[0-9_]+)\)"
    return re.sub(episodes, lambda m: f"StopTrainingOnMaxEpisodes({min(int(m['n']), 3)})", code)


PAGES_WITH_CODE = [page for page in PAGES if blocks(page)]


def test_the_pages_with_code_are_found_and_the_budgets_shrink() -> None:
    names = {page.name for page in PAGES_WITH_CODE}
    assert {"README.md", "deep_agents.md", "extending.md", "use_it_in_your_project.md"} <= names
    assert shrink("m.learn(10**8, callback=StopTrainingOnMaxEpisodes(200))", 300) == (
        "m.learn(300, callback=StopTrainingOnMaxEpisodes(3))")
    assert shrink("m.learn(total_timesteps=100_000)\nm.learn(50)", 300) == "m.learn(total_timesteps=300)\nm.learn(50)"
    assert shrink("m.learn(100_000)", 0) == "m.learn(100_000)"


@pytest.mark.parametrize("page", PAGES_WITH_CODE, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_python_block_of_the_page_runs(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    found = blocks(page)
    source = "\n".join(before + code for before, code, _ in found)
    for module in OPTIONAL:
        if re.search(rf"^\s*(from|import) {module}\b", source, re.M) and importlib.util.find_spec(module) is None:
            pytest.skip(f"{page.name} imports {module}, which is not installed")
    uploads: list[dict[str, Any]] = []
    if importlib.util.find_spec("huggingface_hub") is not None:
        import huggingface_hub

        monkeypatch.setattr(huggingface_hub, "upload_folder", lambda **kwargs: uploads.append(kwargs))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", [page.name])
    namespace: dict[str, Any] = {"__name__": "__docs__"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. SB3's "no goal reached yet" of a run cut short
        for before, code, line in found:
            where = f"{page.relative_to(ROOT)}, the block at line {line}"
            try:
                exec(compile(before + shrink(code, budget()), where, "exec"), namespace)
            except Exception as error:
                raise AssertionError(f"{where} fails: {type(error).__name__}: {error}") from error
    if "upload_folder(" in source:
        assert uploads and Path(uploads[0]["folder_path"]).is_dir()
