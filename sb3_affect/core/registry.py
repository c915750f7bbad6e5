"""
The one registry of agent names: the short names a sweep file, ``simulate``, a hunter team or the CLI may give for an
algorithm, and what each name stands for. Nothing here imports torch or SB3.

A name is either a short name of ``AGENTS`` (``"QLearning"``, ``"AffectQ"``, a baseline's class name, ``"DQN"``, ...)
or a ``package.module:Class`` path (``package.module.Class`` is accepted too). The package's own tabular agents are
known without importing them (``known_settings``: their settings class, ``sb3_affect.core.settings``); any other class is
imported to be checked (``resolve_class``): a dotted name imports code, as rl-zoo3's ``--gym-packages`` does, and must
name a subclass of SB3's ``BaseAlgorithm`` (checked before anything is made of it).

Env wrappers are named only (``ENV_WRAPPERS``: MiniGrid's observation wrappers, its count bonus and the package's
``TabularMiniGrid``), never given as module paths; the env ids of ``ENV_PACKAGES`` (``MiniGrid-*``) import the one
package that registers them.
"""

from __future__ import annotations

import importlib
from typing import Any, NamedTuple

from sb3_affect.core.behaviour import BEHAVIOUR_TABLES, MAX_SPEED
from sb3_affect.core.settings import AGENT_SETTINGS, TabularSettings, settings_class


class Suggest(NamedTuple):
    """
    One argument an agent's Optuna sampler draws in rl-zoo3: ``trial.suggest_<kind>(name, ...)``, ``kind`` "float"
    or "int" between the two ``bounds`` (``log``: on a log scale), "categorical" among the ``bounds`` (a dict's
    labels, standing for its values). ``into``: the argument it goes in (``policy_kwargs``), else the agent's own.
    """

    kind: str
    name: str
    bounds: tuple[Any, ...] | dict[str, Any]
    log: bool = False
    into: str | None = None


class ZooRecipe(NamedTuple):
    """
    An agent in rl-zoo3 (``sb3_affect.integrations.zoo``; its zoo name is its lower-case name): its hyperparameters
    and the search space of its Optuna sampler. What it ``shares`` of DQN's: "" nothing (its own file,
    ``integrations/zoo_hyperparams/<zoo name>.yml``); "network" DQN's MiniGrid settings (``dqn.yml`` with the deep
    study's ``network``) and sampled arguments without epsilon; "epsilon" those and DQN's epsilon schedule.
    """

    #: the arguments its sampler draws (after DQN's, when it shares them)
    space: tuple[Suggest, ...]
    shares: str = ""
    #: its own keywords on every MiniGrid task, added to DQN's settings (for an agent that shares them)
    minigrid: dict[str, Any] | None = None


class AgentEntry(NamedTuple):
    """
    One agent of the package, registered once: its short name (sweep files, ``simulate``, the CLI), where it lives,
    what the package root exports of it, its rl-zoo3 recipe, whether the deep study trains it and, for a control of
    the deep agents, its row of the controls' table (docs/deep_agents.md, written from it).
    (A tabular agent's defaults and checks are its settings class, ``sb3_affect.core.settings``.)
    """

    #: the class, and its short name
    name: str
    #: the module it lives in
    module: str
    #: the names of that module ``sb3_affect`` exports (imported on first use): the class, its mixin; () for none
    exports: tuple[str, ...] = ()
    #: rl-zoo3 (``sb3_affect.integrations.zoo``): its hyperparameters and sampler. None: not in the zoo
    zoo: ZooRecipe | None = None
    #: a DQN of the deep study (a sweep file with a ``trainer``), which the lockstep trainer (``train_many``) trains
    deep: bool = False
    #: a control's row of the controls' table: (the control, what it is); how to run it is the class with ``zoo``'s
    #: MiniGrid keywords
    docs_row: tuple[str, str] | None = None


#: The tabular agents' Eq. 1 rates, as their samplers draw them.
_RATES = (Suggest("float", "learning_rate", (0.05, 1.0)), Suggest("float", "gamma", (0.5, 0.999)))
#: The behaviour table the deep affective agents' emotions follow, as their samplers draw it.
_TABLE = Suggest("categorical", "behaviour_table", tuple(sorted(BEHAVIOUR_TABLES)))
#: The deep affective agents' keywords on MiniGrid: the cell read from the env and MiniGrid's done (6) as the wait.
_ON_MINIGRID = {"position": "minigrid", "wait_action": 6}

#: The package's agents: every name, export, zoo registration and docs row of each comes from its one entry here.
AGENT_ENTRIES: tuple[AgentEntry, ...] = (
    AgentEntry(
        "QLearning", "sb3_affect.agents.qlearning", ("QLearning",),
        ZooRecipe((*_RATES, Suggest("float", "exploration_rate", (0.01, 0.5), log=True))),
    ),
    AgentEntry(
        "AffectQ", "sb3_affect.agents.affectq", ("AffectQ",),
        ZooRecipe((
            *_RATES, Suggest("categorical", "comparison", ("literal", "valence")),
            Suggest("categorical", "act", ("episode", "remaining")), Suggest("categorical", "units", ("cells", "decisions")),
        )),
    ),
    AgentEntry(
        "AffectDQN", "sb3_affect.agents.deep_affect", ("AffectDQN", "AffectiveExploration"),
        ZooRecipe((_TABLE,), "network", _ON_MINIGRID), deep=True,
    ),
    AgentEntry(
        "AffectQRDQN", "sb3_affect.agents.deep_affect_qrdqn", ("AffectQRDQN",),
        ZooRecipe((_TABLE, Suggest("int", "n_quantiles", (5, 200), into="policy_kwargs")), "network", _ON_MINIGRID),
    ),
    AgentEntry(
        "EzGreedyDQN", "sb3_affect.agents.deep_controls", ("EzGreedyDQN", "EzGreedyExploration"),
        ZooRecipe(
            (Suggest("float", "mu", (1.1, 3.0)), Suggest("int", "max_duration", (2, min(20, MAX_SPEED)))), "epsilon",
            {"mu": 2.0, "max_duration": 10},  # Dabney et al.'s
        ),
        deep=True,
        docs_row=(
            "ez-greedy (Dabney et al. 2021)",
            "with probability epsilon a random action repeated for n steps, P(n) ~ n^-mu on 1..`max_duration` (default "
            "mu 2, at most 10); else the greedy action for one step: repeats without emotions",
        ),
    ),
    AgentEntry(
        "SpeedEpsilonGreedyDQN", "sb3_affect.agents.deep_controls",
        ("SpeedEpsilonGreedyDQN", "SpeedEpsilonGreedyExploration"),
        ZooRecipe(
            (Suggest("categorical", "speeds", {"1": [1], "1-2": [1, 2], "0-2": [0, 1, 2], "1-3": [1, 2, 3]}),), "epsilon",
            {"speeds": [1, 2]},  # the affective agent's
        ),
        deep=True,
        docs_row=(
            "epsilon-greedy with the affective speeds",
            "an epsilon-greedy direction, every decision lasting a speed drawn from `speeds` (default 1 or 2 steps), "
            "the deep twin of the tabular `SpeedEpsilonGreedy`",
        ),
    ),
    AgentEntry("ReplayedEpsilonDQN", "sb3_affect.agents.replayed_epsilon", deep=True),
)

#: The package's tabular agents by short name, each where its settings say it is exported from.
_TABULAR = {s.agent.partition(":")[2]: f"{s.exported_from[0]}:{s.agent.partition(':')[2]}" for s in AGENT_SETTINGS}
#: Short names: the package's tabular agents (from their settings), its other agents (``AGENT_ENTRIES``) and SB3's
#: algorithms a study compares with.
AGENTS: dict[str, str] = {
    **_TABULAR,
    "DQN": "stable_baselines3:DQN",
    "PPO": "stable_baselines3:PPO",
    "A2C": "stable_baselines3:A2C",
    **{entry.name: f"{entry.module}:{entry.name}" for entry in AGENT_ENTRIES if entry.name not in _TABULAR},
}
#: The algorithms a deep study trains: SB3's DQN and the package's DQNs that keep its ``train``.
DEEP_AGENTS: tuple[str, ...] = ("DQN", *(entry.name for entry in AGENT_ENTRIES if entry.deep))

#: Env wrappers a sweep file may name (``env.wrappers``), applied in the order given: only these, by name.
ENV_WRAPPERS: dict[str, str] = {
    "TabularMiniGrid": "sb3_affect.agents.minigrid_tabular:TabularMiniGrid",
    "FlatObsWrapper": "minigrid.wrappers:FlatObsWrapper",
    "ImgObsWrapper": "minigrid.wrappers:ImgObsWrapper",
    "PositionBonus": "minigrid.wrappers:PositionBonus",
}

#: Env ids registered by importing a package: (id prefix, package, the extra that installs it).
ENV_PACKAGES: tuple[tuple[str, str, str], ...] = (("MiniGrid-", "minigrid", "minigrid"),)

#: Where the package's agents lived before its modules moved into layer folders: sweep files and model files written
#: then name these modules, read as the ones the agents live in now.
FORMER_MODULES: dict[str, str] = {
    "sb3_affect.qlearning": "sb3_affect.agents.qlearning",
    "sb3_affect.affectq": "sb3_affect.agents.affectq",
    "sb3_affect.tabular": "sb3_affect.agents.tabular",
    "sb3_affect.policies": "sb3_affect.agents.policies",
    "sb3_affect.baselines": "sb3_affect.agents.baselines",
    **{f"sb3_affect.baselines.{leaf}": f"sb3_affect.agents.baselines.{leaf}"
       for leaf in ("boltzmann", "decaying", "optimistic", "speed", "ucb")},
}


def split_algo(algo: str) -> tuple[str, str]:
    """``(module, class name)`` of an algorithm's name (either may be empty when the name gives neither)."""
    target = AGENTS.get(algo, algo)
    if ":" in target:
        module_name, _, attr = target.partition(":")
    else:
        module_name, _, attr = target.rpartition(".")
    return FORMER_MODULES.get(module_name, module_name), attr


def known_settings(algo: str | type) -> type[TabularSettings] | None:
    """
    The settings class of the package's tabular agent ``algo`` names (a name, not imported; or the class itself, not
    a subclass, which may change the loop and inherits its parent's settings), or None for anything else.
    """
    if isinstance(algo, str):
        module_name, attr = split_algo(algo)
        return settings_class(module_name, attr) if module_name and attr else None
    settings: Any = getattr(algo, "settings_class", None)
    if settings not in AGENT_SETTINGS or settings.agent != f"{algo.__module__}:{algo.__qualname__}":
        return None
    return settings


_BASE_ALGORITHM = "stable_baselines3.common.base_class.BaseAlgorithm"


def is_algorithm(cls: type) -> bool:
    """Whether ``cls`` subclasses SB3's ``BaseAlgorithm`` (by its MRO: SB3 is not imported to tell)."""
    return any(f"{base.__module__}.{base.__qualname__}" == _BASE_ALGORITHM for base in cls.__mro__)


def resolve_class(algo: str) -> type:
    """
    The algorithm class ``algo`` names (a short name or ``package.module:Class``); imports its module. ValueError if
    it names none, or a class that is not an SB3 algorithm (a ``BaseAlgorithm`` subclass).
    """
    module_name, attr = split_algo(algo)
    if not module_name or not attr:
        raise ValueError(f"{algo!r} is not a known algorithm ({', '.join(AGENTS)}) nor a 'package.module:Class' path")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ValueError(f"{algo!r}: module {module_name!r} can not be imported ({error})") from None
    cls = getattr(module, attr, None)
    if not isinstance(cls, type):
        raise ValueError(f"{algo!r}: {module_name} has no class {attr!r}")
    if not is_algorithm(cls):
        raise ValueError(
            f"{algo!r} is not a Stable-Baselines3 algorithm: the class must subclass "
            "stable_baselines3.common.base_class.BaseAlgorithm"
        )
    return cls


def check_algo(algo: str) -> None:
    """That ``algo`` names a class (the package's agents by name, others by importing them); ValueError if not."""
    if known_settings(algo) is None:
        resolve_class(algo)


def env_package(env_id: str) -> tuple[str, str] | None:
    """``(package, extra)`` of an env id that a package of ``ENV_PACKAGES`` registers, else None."""
    return next(((package, extra) for prefix, package, extra in ENV_PACKAGES if env_id.startswith(prefix)), None)


def import_env_package(env_id: str) -> None:
    """Import the package that registers ``env_id`` (``ENV_PACKAGES``), if any; ValueError naming the extra if missing."""
    found = env_package(env_id)
    if found is None:
        return
    package, extra = found
    try:
        importlib.import_module(package)
    except ImportError:
        raise ValueError(f"env id {env_id!r} needs {package}: pip install \"sb3-affect[{extra}]\"") from None


def check_wrapper(name: str) -> str:
    """A wrapper's name of ``ENV_WRAPPERS`` as given, or a one-line ValueError naming those allowed (nothing imported)."""
    if name not in ENV_WRAPPERS:
        raise ValueError(f"env wrapper {name!r} is not known; the wrappers are {', '.join(ENV_WRAPPERS)}")
    return name


def resolve_wrapper(name: str) -> type:
    """The wrapper class of a name of ``ENV_WRAPPERS`` (imports its module; ValueError naming the extra if missing)."""
    module_name, _, attr = ENV_WRAPPERS[check_wrapper(name)].partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError:
        package = module_name.partition(".")[0]
        raise ValueError(f"env wrapper {name!r} needs {package}: pip install \"sb3-affect[{package}]\"") from None
    cls: type = getattr(module, attr)
    return cls


class EmotionModel(NamedTuple):
    """
    An emotion model besides the paper's (which every tabular agent's episode log holds): where its observer and,
    if the team kernel runs it, its kernel module live, its emotions and the columns a team run records of it per
    hunter and episode (``<hunter>/<name>_<column>``).
    """

    observer: str  # ``module:Class`` of its SB3 callback
    kernel: str | None  # the module the team kernel computes it with (None: Python teams only)
    emotions: tuple[str, ...]
    columns: tuple[str, ...]


#: The emotion models a team run records beside the paper's, by name (the prefix of their columns): the launcher's
#: Python teams attach their observers, the team kernel computes them, the report reads their columns.
EMOTION_MODELS: dict[str, EmotionModel] = {
    "broekens": EmotionModel(
        observer="sb3_affect.agents.broekens:BroekensCallback",
        kernel="sb3_affect.kernel.td_emotions",
        emotions=("joy", "distress", "hope", "fear"),
        columns=("joy", "distress", "hope", "fear", "goal_joy"),
    ),
}


def observer_class(name: str) -> type:
    """The SB3 callback class of the emotion model ``name`` (``EMOTION_MODELS``); imports its module."""
    module_name, _, attr = EMOTION_MODELS[name].observer.partition(":")
    return getattr(importlib.import_module(module_name), attr)
