"""
The kernel speaks one vocabulary: every index constant of its state arrays and episode rows, every field of an agent's
settings and every prey mode is defined once, read from the source of the kernel's modules (and the envs').
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import sb3_affect.envs as envs
import sb3_affect.kernel as kernel
from sb3_affect.kernel.agent_settings import AgentSettings

KERNEL = sorted(Path(kernel.__file__).parent.glob("*.py"))
ENVS = sorted(Path(envs.__file__).parent.glob("*.py"))
#: index constants (ints ``I_``, floats ``S_``, a row's ``O_``/``F_``, a team's ``T_``) and table sizes (``N_``)
INDEX = re.compile(r"[ISOFT]_[A-Z0-9_]+|N_[A-Z0-9_]+")


def assigned(tree: ast.Module) -> Iterator[str]:
    """The names a module assigns at its top level (tuple unpacking included)."""
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        for target in targets:
            yield from (name.id for name in ast.walk(target) if isinstance(name, ast.Name))


def record_fields(tree: ast.Module) -> Iterator[tuple[str, str]]:
    """``(class, field)`` of every class whose body declares annotated fields (the kernel's named tuples)."""
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    yield node.name, item.target.id


def parse(path: Path) -> ast.Module:
    return ast.parse(path.read_text(), filename=str(path))


def index_definitions(paths: list[Path]) -> dict[str, list[str]]:
    """Each index constant the modules at ``paths`` define, with the modules that define it."""
    where: dict[str, list[str]] = {}
    for path in paths:
        for name in assigned(parse(path)):
            if INDEX.fullmatch(name):
                where.setdefault(name, []).append(path.name)
    return where


def test_each_index_constant_is_defined_in_one_module_only() -> None:
    found = index_definitions(KERNEL)
    twice = {name: modules for name, modules in found.items() if len(modules) > 1}
    assert not twice, f"defined more than once: {twice}"
    where = {name: modules[0] for name, modules in found.items()}
    # the shared heads are state_layout's; a world's tail is its own
    assert {where[name] for name in ("I_STATE", "I_NFIT", "S_FIT0", "O_DECISIONS", "F_NORM", "N_IST")} == {"state_layout.py"}
    assert where["I_HUNTER"] == "moving_loop.py" and where["I_WALKS"] == "team_loop.py"


def test_each_agent_setting_is_declared_by_agent_settings_only() -> None:
    fields = set(AgentSettings._fields)
    for path in KERNEL:
        for record, field in record_fields(parse(path)):
            if record != "AgentSettings":
                assert field not in fields, f"{path.name}: {record}.{field} repeats a field of AgentSettings"


def test_the_prey_modes_are_listed_once_for_kernels_and_envs() -> None:
    listings = []
    for path in [*KERNEL, *ENVS]:
        for node in ast.walk(parse(path)):
            items: list[ast.expr | None] = []
            if isinstance(node, ast.Dict):
                items = list(node.keys)
            elif isinstance(node, (ast.Tuple, ast.List, ast.Set)):
                items = list(node.elts)
            if any(isinstance(item, ast.Constant) and item.value == "evade" for item in items):
                listings.append(path.name)
    assert listings == ["grid_pursuit.py"], listings


def test_a_second_definition_is_found(tmp_path: Path) -> None:
    world = tmp_path / "another_loop.py"
    world.write_text("(I_HUNTER, I_STATE) = range(20, 22)\nN_IST = 22\n")
    found = index_definitions([*KERNEL, world])
    assert {name for name, modules in found.items() if len(modules) > 1} == {"I_HUNTER", "I_STATE", "N_IST"}
