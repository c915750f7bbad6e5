"""
One registration per agent (``sb3_affect.core.registry.AGENT_ENTRIES``): the registry's short names, the package
root's exports and rl-zoo3's tables all come from it, and what it says holds for the classes themselves.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import sb3_affect
from sb3_affect.core.registry import AGENT_ENTRIES, AGENTS, DEEP_AGENTS, known_settings, split_algo


def _type_checking_names() -> set[str]:
    """The names ``sb3_affect/__init__.py`` imports under ``if TYPE_CHECKING:`` (what type checkers see)."""
    tree = ast.parse(Path(sb3_affect.__file__).read_text(encoding="utf-8"))
    block = next(node for node in tree.body if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING")
    return {alias.name for node in block.body if isinstance(node, ast.ImportFrom) for alias in node.names}


def test_each_agent_is_registered_once_and_names_its_own_module() -> None:
    names = [entry.name for entry in AGENT_ENTRIES]
    assert len(names) == len(set(names))
    for entry in AGENT_ENTRIES:
        module, attr = split_algo(entry.name)
        settings = known_settings(entry.name)
        if settings is None:  # a deep agent: the registry's name is its entry's module
            assert (module, attr) == (entry.module, entry.name), entry
        else:  # a tabular agent: its settings say where it lives, and agree with the entry
            assert settings.agent == f"{entry.module}:{entry.name}", entry
        assert isinstance(getattr(importlib.import_module(entry.module), entry.name), type), entry


def test_the_package_root_exports_what_the_entries_say() -> None:
    checked = _type_checking_names()
    for entry in AGENT_ENTRIES:
        for name in entry.exports:
            assert name in sb3_affect.__all__ and name in checked, name
            assert getattr(sb3_affect, name) is getattr(importlib.import_module(entry.module), name)


def test_the_deep_agents_are_dqns_the_lockstep_trainer_takes() -> None:
    from stable_baselines3 import DQN

    assert DEEP_AGENTS[0] == "DQN" and set(DEEP_AGENTS) <= set(AGENTS)
    for entry in AGENT_ENTRIES:
        cls = getattr(importlib.import_module(entry.module), entry.name)
        assert entry.deep == (issubclass(cls, DQN) and cls.train is DQN.train), entry


def test_the_zoo_tables_come_from_the_entries() -> None:
    pytest.importorskip("rl_zoo3")
    from sb3_affect.integrations import zoo

    names = ("QLearning", "AffectQ", "AffectDQN", "AffectQRDQN", "EzGreedyDQN", "SpeedEpsilonGreedyDQN")
    assert {name.lower(): name for name in names}.items() <= zoo.ZOO_ALGOS.items()  # the agents the zoo had before
    assert {entry.name.lower(): entry.name for entry in AGENT_ENTRIES if entry.zoo is not None} == zoo.ZOO_ALGOS
    assert set(zoo.SAMPLERS) == set(zoo.ZOO_ALGOS)
    assert all(sampler.__name__ == f"sample_{name}_params" for name, sampler in zoo.SAMPLERS.items())
    for name, recipe in zoo.ZOO_RECIPES.items():  # a table for each: its own file, or DQN's with its keywords
        assert (zoo.HYPERPARAMS_FOLDER / f"{name}.yml").is_file() != bool(recipe.shares), name
        assert all(zoo.hyperparams(name).values()), name


def test_a_docs_row_is_a_control_the_deep_study_trains_with_its_own_keywords() -> None:
    rows = [entry for entry in AGENT_ENTRIES if entry.docs_row is not None]
    assert {entry.name for entry in rows} >= {"EzGreedyDQN", "SpeedEpsilonGreedyDQN"}
    assert all(entry.deep and entry.zoo is not None and entry.zoo.minigrid for entry in rows)
