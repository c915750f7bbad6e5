"""
The ``algo`` field of a sweep file: a short name (``QLearning``, ``AffectQ``, ``DQN``, ``PPO``, ``A2C``) or a
``package.module:Class`` path. The package's own tabular agents are known by name (``known_settings``), without
importing them (nor torch); any other class is imported to be checked.
"""

from __future__ import annotations

import importlib

from sb3_affect.settings import TabularSettings, settings_class

#: Algorithms known by short name; anything else is a dotted path ``package.module:Class``.
SHORT_NAMES: dict[str, str] = {
    "QLearning": "sb3_affect:QLearning",
    "AffectQ": "sb3_affect:AffectQ",
    "DQN": "stable_baselines3:DQN",
    "PPO": "stable_baselines3:PPO",
    "A2C": "stable_baselines3:A2C",
}


def split_algo(algo: str) -> tuple[str, str]:
    """``(module, class name)`` of an ``algo`` field (either may be empty when the field names neither)."""
    target = SHORT_NAMES.get(algo, algo)
    if ":" in target:
        module_name, _, attr = target.partition(":")
    else:
        module_name, _, attr = target.rpartition(".")
    return module_name, attr


def known_settings(algo: str) -> type[TabularSettings] | None:
    """The settings class of the package's tabular agent ``algo`` names, or None (another class), without importing."""
    module_name, attr = split_algo(algo)
    return settings_class(module_name, attr) if module_name and attr else None


def resolve_class(algo: str) -> type:
    """The class an ``algo`` field names (short name or ``package.module:Class``); imports it."""
    module_name, attr = split_algo(algo)
    if not module_name or not attr:
        raise ValueError(f"{algo!r} is not a known algorithm ({', '.join(SHORT_NAMES)}) nor a 'package.module:Class' path")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ValueError(f"{algo!r}: module {module_name!r} can not be imported ({error})") from None
    cls = getattr(module, attr, None)
    if not isinstance(cls, type):
        raise ValueError(f"{algo!r}: {module_name} has no class {attr!r}")
    return cls


def check_algo(algo: str) -> None:
    """That ``algo`` names a class (the package's agents by name, others by importing them); ValueError if not."""
    if known_settings(algo) is None:
        resolve_class(algo)


def is_tabular(algo: str) -> bool:
    """Whether ``algo`` names a tabular agent (a ``TabularQAlgorithm``); imports only classes of other packages."""
    if known_settings(algo) is not None:
        return True
    from sb3_affect.tabular import TabularQAlgorithm

    return issubclass(resolve_class(algo), TabularQAlgorithm)
