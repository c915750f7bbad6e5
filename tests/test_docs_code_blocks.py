"""
Every ```` ```python ```` block of the Markdown pages (README.md and docs/*.md) runs as a reader pastes it: alone (its
own process and namespace, in an empty folder: no set-up the page does not show, nothing from an earlier block), as
written (the budgets are the page's own: a block that would train for minutes gives a smaller budget on the page), from
the wheel installed in a fresh virtual environment with no checkout on its path (``wheel_venvs``).

A block that imports no optional extra runs in the **core** venv (the plugin's own requirements only, as after
``pip install sb3-affect``); one that does (``minigrid``, ``pettingzoo`` through the hunters' env, the Hub's libraries,
...) runs in the **full** venv. Both have the kernels' numba cache, as after ``python -m sb3_affect.kernel``. What
differs from a reader's machine is set here and only here: one torch thread (the suite shares the cores), and nothing
reaches the network (``huggingface_hub.upload_folder`` records its arguments; ``docs_blocks_runner``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest
from wheel_venvs import build_wheel, core_venv, full_venv, run

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(?P<code>.*?)^```", re.S | re.M)
#: The modules outside the core install a block may import (the extras' and sb3-contrib's): such a block runs in the
#: full venv. The hunters' env (``make_parallel``) needs PettingZoo, and SB3's ``VecVideoRecorder`` moviepy, without the
#: block importing them.
OPTIONAL = ("minigrid", "sb3_contrib", "pettingzoo", "huggingface_hub", "huggingface_sb3", "rl_zoo3", "ray", "matplotlib",
            "scipy", "yaml", "sb3_affect.study", "sb3_affect.integrations.zoo")
NEEDS_AN_EXTRA = re.compile(
    rf"^\s*(from|import) ({'|'.join(map(re.escape, OPTIONAL))})\b|\bmake_parallel\(|\bVecVideoRecorder\(", re.M
)


def blocks(page: Path) -> list[tuple[str, str]]:
    """``(id, code)`` of each python block of ``page``, in order; the id is the page and the block's first line."""
    text = page.read_text()
    return [(f"{page.relative_to(ROOT)}:{text.count(chr(10), 0, m.start('code')) + 1}", m["code"])
            for m in BLOCK.finditer(text)]


BLOCKS = [block for page in PAGES for block in blocks(page)]


def needs_an_extra(code: str) -> bool:
    return NEEDS_AN_EXTRA.search(code) is not None


def test_the_blocks_are_found_and_sorted_by_the_install_they_need() -> None:
    pages = {name.split(":")[0] for name, _ in BLOCKS}
    assert {"README.md", "docs/deep_agents.md", "docs/extending.md", "docs/use_it_in_your_project.md"} <= pages
    assert needs_an_extra("from minigrid.wrappers import FlatObsWrapper\n")
    assert needs_an_extra("env = make_parallel('sb3_affect/HunterPursuit-v0')\n")
    assert needs_an_extra("venv = VecVideoRecorder(venv, 'videos', lambda step: step == 0)\n")
    assert not needs_an_extra("from sb3_affect import AffectQ\nimport gymnasium as gym\n")


def test_no_page_hides_a_set_up() -> None:
    """What a block needs is on the page, in the block: no hidden comment runs code before it."""
    hiding = [str(page.relative_to(ROOT)) for page in PAGES if "docs-test" in page.read_text()]
    assert hiding == []


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    """Every block, run once: the core blocks in the core venv, the others in the full one."""
    base = tmp_path_factory.mktemp("docs_blocks")
    wheel = build_wheel(base / "dist")
    runner = str(Path(__file__).with_name("docs_blocks_runner.py"))
    out: dict[str, dict[str, Any]] = {}
    for venv, extra in (("core", False), ("full", True)):
        chosen = [(name, code) for name, code in BLOCKS if needs_an_extra(code) == extra]
        python = full_venv(wheel, base / venv) if extra else core_venv(wheel, base / venv, compiled=True)
        spec = [{"id": name, "code": code, "folder": str(base / "blocks" / re.sub(r"\W", "_", name))}
                for name, code in chosen]
        (base / f"{venv}.json").write_text(json.dumps(spec))
        done = run(python, [runner, str(base / f"{venv}.json"), str(base / f"{venv}_results.json")], base,
                   timeout=1800, env={"OMP_NUM_THREADS": "1", "MPLBACKEND": "Agg"})
        assert done.returncode == 0, done.stderr[-3000:]
        for name, result in json.loads((base / f"{venv}_results.json").read_text()).items():
            out[name] = {**result, "venv": venv, "folder": base / "blocks" / re.sub(r"\W", "_", name)}
    return out


@pytest.mark.parametrize("name", [name for name, _ in BLOCKS])
def test_the_block_runs_alone_from_the_installed_wheel(name: str, results: dict[str, dict[str, Any]]) -> None:
    result = results[name]
    assert result["status"] == 0, f"{name} fails in the {result['venv']} venv: {result['error']}{result['output']}"
    for upload in result["uploads"]:  # the Hub block: the folder it would upload was written
        assert (result["folder"] / upload["folder_path"]).is_dir(), upload
