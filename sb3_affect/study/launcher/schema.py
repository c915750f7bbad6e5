"""
Experiment files: a sweep of agents x parameter grid x seeds, validated before anything runs.

A file names the env, the episode budget, the seeds and the agents; each agent has fixed ``kwargs`` and a ``grid``
of labels whose Cartesian product it runs. A kwargs value written ``$name`` takes the grid value ``name``; grid
labels that no kwarg references only replicate the agent (the paper's affective agent "per epsilon")::

    name: paper
    env: {id: sb3_affect/GridPursuit-v0, kwargs: {}}
    episodes: 200
    seeds: 20                       # a count (seeds derived per agent and grid point) or an explicit list
    agents:
      - name: epsilon-greedy
        algo: QLearning
        grid: {epsilon: [0.1, 0.5, 0.9]}
        kwargs: {exploration_rate: $epsilon}

A multi-agent env (``sb3_affect/HunterPursuit-v0``, one hunter per ``team`` member) takes ``team`` agents instead of
``algo``: one ``{algo, kwargs}`` per hunter, independent learners that may mix classes (``sb3_affect.agents.hunter_team``)::

      - name: mixed
        team: [{algo: AffectQ}, {algo: QLearning, kwargs: {exploration_rate: $epsilon}}]
        grid: {epsilon: [0.1]}

The same grammar states the package's two studies (``Sweep.kind``, from ``kind_of``): a file with a ``trainer`` is the
deep study (``deep_schema``: DQN-family agents on MiniGrid tasks, ``Sweep.deep_cells``), a file with ``forensics`` the
replication forensics (``ForensicsSpec``); each kind takes its own top-level keys (``KIND_KEYS``). Files and saved
folders of the forms before this grammar: ``old_forms``.

Reading a file, its ``--set`` overrides and the messages of a file that does not validate: ``sweep_file``.

Validating a file imports the modules its ``algo`` and ``env.id`` paths name (as rl-zoo3's ``--gym-packages`` does):
only run sweep files you trust. A results folder's saved sweep is validated without importing anything
(``Sweep.validate_saved``), so ``status`` and ``report`` run no code a folder names. Sizes are checked from the
numbers before anything is allocated: ``MAX_SEEDS``, ``MAX_GRID_POINTS``, ``MAX_RUNS``, ``MAX_EPISODES``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import itertools
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import gymnasium as gym
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from sb3_affect.core.episode_log import TRACE_COLUMNS
from sb3_affect.core.positions import POSITION_PRESETS
from sb3_affect.core.registry import (
    AGENTS,
    ENV_WRAPPERS,
    check_algo,
    check_wrapper,
    import_env_package,
    known_settings,
    resolve_class,
)
from sb3_affect.core.settings import AffectQSettings
from sb3_affect.envs import PARALLEL_ENVS
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS
from sb3_affect.study.launcher.deep_schema import (
    EVAL_SEED_OFFSET,
    MAX_DEEP_SEEDS,
    MAX_TOTAL_TIMESTEPS,
    MINIGRID_ID,
    TUNED,
    EvaluationSpec,
    TrainerSpec,
    TunedSpec,
    check_arguments,
)
from sb3_affect.study.launcher.forensics_candidates import CandidateSpace, Protocol
from sb3_affect.study.launcher.run_ids import RESERVED_LABELS

#: Wrapper names (the env section's and an agent's own), each checked against the registry's ``ENV_WRAPPERS``.
WrapperNames = Annotated[list[str], AfterValidator(lambda names: [check_wrapper(name) for name in names])]

__all__ = ["AgentSpec", "Cell", "EnvSpec", "ForensicsSpec", "MemberSpec", "Sweep", "SweepError", "kind_of"]

KWARG_REFERENCE = re.compile(r"^\$([A-Za-z_][A-Za-z0-9_]*)$")
#: Names of sweeps: they name files, so no leading dot (hidden files) and at most 64 characters.
NAME_PATTERN = r"^[A-Za-z0-9_+-][A-Za-z0-9_.+-]{0,63}$"
#: Names of agents and tasks: text of at most 64 characters, not starting with a dot or a space nor ending with a space
#: (``"a b"`` and ``"a b "`` would read alike), without a slash, a backslash or a control character (they name runs
#: through run ids, which keep only ``[A-Za-z0-9_.+-]``).
LABEL_PATTERN = r"^[^\s./\\\x00-\x1f\x7f](?:[^/\\\x00-\x1f\x7f]{0,62}[^\s/\\\x00-\x1f\x7f])?$"
#: Limits checked from the numbers before anything is allocated.
MAX_SEEDS = 1_000_000  # seeds per grid point (a count, or the length of a list)
MAX_SEED = 2**32 - 1  # seeds are NumPy seeds: integers in [0, 2**32 - 1]
MAX_GRID_POINTS = 100_000  # grid points per agent (the product of its grid's lengths)
MAX_RUNS = 2_000_000  # runs per sweep (grid points x seeds, summed over the agents)
MAX_EPISODES = 1_000_000  # episodes per run
MAX_TIMESTEPS = 10**10  # decisions per run
_NONE = object()
#: The validation context of a saved sweep: nothing is imported (``Sweep.validate_saved``).
SAVED = {"imports": False}


def _imports(info: ValidationInfo) -> bool:
    """Whether this validation may import the modules a file names (not for a results folder's saved sweep)."""
    return not (isinstance(info.context, dict) and info.context.get("imports") is False)


class SweepError(ValueError):
    """A sweep file that can not be run; the message names the file, the key path and what is allowed."""


def is_tabular(algo: str) -> bool:
    """Whether ``algo`` names a tabular agent (a ``TabularQAlgorithm``); imports only classes of other packages."""
    if known_settings(algo) is not None:
        return True
    from sb3_affect.agents.tabular import TabularQAlgorithm  # (torch: off the tabular sweep path)

    return issubclass(resolve_class(algo), TabularQAlgorithm)


def is_multi_agent(env_id: str) -> bool:
    """Whether ``env_id`` names one of the package's multi-agent (PettingZoo) envs."""
    return env_id in PARALLEL_ENVS


class EnvSpec(BaseModel):
    """The ``env`` section: which Gymnasium env every run builds (``gym.make(id, **kwargs)``)."""

    model_config = ConfigDict(extra="forbid")
    id: str = Field(
        default="sb3_affect/GridPursuit-v0",
        description="a registered Gymnasium id: sb3_affect/GridPursuit-v0, sb3_affect/MazePursuit-v0, "
        "sb3_affect/MovingPursuit-v0, or 'your_module:YourEnv-v0' for an env that importing your_module registers",
    )
    kwargs: dict[str, Any] = Field(
        default_factory=dict, description="keyword arguments of the env, e.g. {size: 15, goal: [6, 6]}"
    )
    wrappers: WrapperNames = Field(
        default_factory=list,
        description=f"wrappers put around the env, innermost first, by name: {', '.join(ENV_WRAPPERS)}",
    )
    position: str | None = Field(
        default=None,
        description=f"where the agent is, for the emotion callback that watches an agent of SB3 (not for the tabular "
        f"agents, whose observation is the cell): {', '.join(POSITION_PRESETS)} or null (the observation)",
    )

    total_timesteps: int | None = Field(
        default=None, gt=0, le=MAX_TOTAL_TIMESTEPS,
        description="a deep study's task: env steps per run (a multiple of evaluation.every)",
    )
    tuned: TunedSpec | None = Field(default=None, description="a deep study's task: the settings tuned for it (below)")

    @field_validator("position")
    @classmethod
    def _preset(cls, value: str | None) -> str | None:
        if value is not None and value not in POSITION_PRESETS:
            raise ValueError(f"position {value!r} is not a preset; the presets are {', '.join(POSITION_PRESETS)} (or null)")
        return value

    @model_serializer(mode="wrap")
    def _dump(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """Without the wrappers and position when not given: a saved sweep of one env reads as before they existed."""
        return _without_unset(handler(self), {"wrappers": [], "position": None, "total_timesteps": None, "tuned": None})

    def config(self) -> dict[str, Any]:
        """The run config's env keys (the wrappers and position only when given: other run ids are unchanged)."""
        config: dict[str, Any] = {"env_id": self.id, "env_kwargs": dict(self.kwargs)}
        if self.wrappers:
            config["env_wrappers"] = list(self.wrappers)
        if self.position is not None:
            config["env_position"] = self.position
        return config

    @field_validator("id")
    @classmethod
    def _registered(cls, value: str, info: ValidationInfo) -> str:
        if not _imports(info):
            return value

        module, _, env_id = value.rpartition(":")  # "my_package.envs:MyEnv-v0": import the module that registers it
        import_env_package(env_id)  # MiniGrid-*: the package of the registry's allow-list
        if module:
            try:
                importlib.import_module(module)
            except ImportError as error:
                raise ValueError(f"env id {value!r}: module {module!r} can not be imported ({error})") from None
        if env_id not in gym.registry and env_id not in PARALLEL_ENVS:
            known = sorted([*(k for k in gym.registry if k.startswith("sb3_affect/")), *PARALLEL_ENVS])
            raise ValueError(
                f"env id {value!r} is not registered; the package registers {', '.join(known)} (an env of your own: "
                "'your_module:YourEnv-v0', where importing your_module registers YourEnv-v0)"
            )
        return value


#: What a label's value may be: it is a column of the results (one value a run), compared and grouped as it is.
LABEL_TYPES = (str, int, float, bool, type(None))


def check_label_value(where: str, value: Any) -> None:
    """A label's value is a string, a number, true/false or null (a list or mapping is not one column value)."""
    if not isinstance(value, LABEL_TYPES):
        kind = "a list" if isinstance(value, list) else "a mapping" if isinstance(value, dict) else type(value).__name__
        raise ValueError(
            f"{where}: {value!r} is {kind}; a label's value is one column value of the results: a string, a number, "
            "true/false or null (name the choice, e.g. 'wide', and map it to kwargs with one grid label per kwarg)"
        )


def _checked_grid(value: dict[str, list[Any]]) -> dict[str, list[Any]]:
    """
    A grid's labels are not result columns, its value lists not empty, of label values (``check_label_value``), each
    given once (two equal values, ``0.1`` twice or ``1`` and ``1.0`` and ``true``, would label the same results), its
    points at most ``MAX_GRID_POINTS``.
    """
    points = 1
    for key, values in value.items():
        if key in RESERVED_LABELS:
            raise ValueError(
                f"grid.{key}: {key!r} names a column of the results; a grid label may be any name but "
                f"{', '.join(sorted(RESERVED_LABELS))}"
            )
        if not values:
            raise ValueError(f"grid.{key} is empty: give at least one value")
        for index, item in enumerate(values):
            check_label_value(f"grid.{key}[{index}]", item)
            earlier = next((other for other in values[:index] if other == item), _NONE)
            if earlier is not _NONE:
                same = "repeats" if type(earlier) is type(item) else f"equals {earlier!r} (an equal value of another type)"
                raise ValueError(f"grid.{key}[{index}]: {item!r} {same}; give each value of a grid label once")
        points *= len(values)
        if points > MAX_GRID_POINTS:
            sizes = " x ".join(str(len(v)) for v in value.values())
            raise ValueError(f"the grid has {sizes} points, more than the {MAX_GRID_POINTS:,} allowed per agent")
    return value


class MemberSpec(BaseModel):
    """One hunter of a team agent: its algorithm and constructor arguments (``$label`` references allowed)."""

    model_config = ConfigDict(extra="forbid")
    algo: str = Field(description="a tabular agent of this package: QLearning, AffectQ or a baseline class path")
    kwargs: dict[str, Any] = Field(
        default_factory=dict, description="its constructor arguments; $label takes the grid label's value"
    )

    @field_validator("algo")
    @classmethod
    def _tabular(cls, value: str, info: ValidationInfo) -> str:
        if _imports(info) and not is_tabular(value):
            raise ValueError(f"team members are tabular agents of this package (QLearning, AffectQ, baselines), not {value!r}")
        return value


class AgentSpec(BaseModel):
    """One item of ``agents``: an algorithm, its fixed kwargs and the grid of labels it is swept over."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(
        pattern=LABEL_PATTERN,
        description="unique within the file; names the runs and groups them in the report, and enters the derived seeds "
        "(at most 64 characters, not starting with a dot or a space nor ending with a space, no slash, backslash or control "
        "character)",
    )
    algo: str | None = Field(
        default=None,
        description="QLearning, AffectQ, DQN, PPO, A2C or an importable 'package.module:Class' (a subclass of SB3's "
        "BaseAlgorithm; validating the file imports that module, so run only files you trust); give algo or team",
    )
    kwargs: dict[str, Any] = Field(
        default_factory=dict,
        description="constructor arguments of the algorithm; a value written $label takes the grid label's value",
    )
    grid: dict[str, list[Any]] = Field(
        default_factory=dict,
        description="label -> list of values; every combination is one grid point, run once per seed. A label no "
        f"kwarg uses only replicates the agent. At most {MAX_GRID_POINTS:,} grid points per agent",
    )
    team: list[MemberSpec] | None = Field(
        default=None,
        min_length=1,
        description="instead of algo, on a multi-agent env: one {algo, kwargs} per hunter (below)",
    )
    labels: dict[str, Any] = Field(
        default_factory=dict,
        description="fixed labels of every run of the agent (columns of the results beside the grid's); unlike a grid "
        "label they do not enter the derived seeds",
    )
    grid_by_task: dict[str, dict[str, list[Any]]] | None = Field(
        default=None,
        description="instead of grid, on a sweep with tasks: the agent's grid on each task, by task name (e.g. the ε "
        "tuned on each task); the agent runs on the tasks named only",
    )
    seeds_by: list[str] | None = Field(
        default=None,
        description="the labels whose values derive the agent's seeds (default: its grid labels): [task] gives each "
        "task its own seeds and every grid value the same seeds (paired comparisons); grid labels, fixed labels or task",
    )
    seeds_from: str | None = Field(
        default=None,
        pattern=NAME_PATTERN,
        description="derive the agent's seeds as the sweep of this name does (default: this sweep's name): an agent "
        "of the same name and grid point there has the same seeds, so a larger study extends that sweep's runs",
    )
    wrappers: WrapperNames = Field(
        default_factory=list,
        description=f"wrappers of this agent's env only, outside the env section's, by name: {', '.join(ENV_WRAPPERS)} "
        "(e.g. a count bonus for one agent of the sweep)",
    )

    trace: bool = Field(
        default=False,
        description=f"record each decision's emotion and act (AffectQ only; on the Python loop, one run at a time): "
        f"per episode {', '.join(TRACE_COLUMNS)} beside the episode log",
    )

    epsilon: Literal["tuned"] | None = Field(
        default=None, description="a deep study's agent: tuned takes the task's exploration_fraction for SB3's linear ε "
        "schedule"
    )
    count_bonus: Annotated[float, Field(gt=0, le=10)] | Literal["tuned"] | None = Field(
        default=None, description="a deep study's agent: a count bonus β / sqrt(visits) added to the training reward: β, "
        "or tuned (the task's)"
    )
    replays: str | None = Field(
        default=None,
        description="a deep study's agent: an earlier agent whose logged share of random decisions, averaged over its "
        "seeds, becomes this agent's ε, part by part (algo ReplayedEpsilonDQN)",
    )

    @model_serializer(mode="wrap")
    def _dump(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """Without the keys added later when not given: a saved sweep reads (and resumes) as before they existed."""
        return _without_unset(handler(self), {"wrappers": [], "trace": False, "grid_by_task": None, "seeds_by": None,
                                              "epsilon": None, "count_bonus": None, "replays": None})  # fmt: skip

    @model_validator(mode="after")
    def _traced_affectq(self) -> AgentSpec:
        if self.trace and known_settings(self.algo or "") is not AffectQSettings:
            raise ValueError(f"trace: only AffectQ's runs can be traced (its emotion callback), not {self.algo or 'a team'!r}")
        if self.trace and self.kwargs.get("personality", "neutral") != "neutral":
            raise ValueError("trace: a traced run's appraisal is the neutral one; give no personality with trace: true")
        return self

    @field_validator("algo")
    @classmethod
    def _importable(cls, value: str | None, info: ValidationInfo) -> str | None:
        if value is not None and _imports(info):
            check_algo(value)
        return value

    @model_validator(mode="after")
    def _one_kind(self) -> AgentSpec:
        if (self.algo is None) == (self.team is None):
            raise ValueError("give either algo (one agent) or team (one {algo, kwargs} per hunter of a multi-agent env)")
        if self.team is not None and (self.kwargs or self.wrappers):
            raise ValueError("a team agent has no kwargs or wrappers of its own: give each member's under team[i].kwargs")
        return self

    @field_validator("grid")
    @classmethod
    def _non_empty(cls, value: dict[str, list[Any]]) -> dict[str, list[Any]]:
        return _checked_grid(value)

    @field_validator("grid_by_task")
    @classmethod
    def _task_grids(cls, value: dict[str, dict[str, list[Any]]] | None) -> dict[str, dict[str, list[Any]]] | None:
        if value is not None and not value:
            raise ValueError("grid_by_task is empty: name at least one task (task: {label: [values]})")
        for task, grid in (value or {}).items():
            try:
                _checked_grid(grid)
            except ValueError as error:
                raise ValueError(f"grid_by_task.{task}: {error}") from None
        return value

    def grids(self) -> list[dict[str, list[Any]]]:
        """Every grid the agent runs: ``grid``, or each task's of ``grid_by_task``."""
        return list(self.grid_by_task.values()) if self.grid_by_task is not None else [self.grid]

    def grid_on(self, task: str | None) -> dict[str, list[Any]] | None:
        """The agent's grid on ``task`` (None: the agent does not run there)."""
        if self.grid_by_task is None:
            return self.grid
        return self.grid_by_task.get(task) if task is not None else None

    @model_validator(mode="after")
    def _fixed_labels(self) -> AgentSpec:
        if self.grid_by_task is not None and self.grid:
            raise ValueError("give either grid or grid_by_task (a grid per task), not both")
        grid_labels = {key for grid in self.grids() for key in grid}
        for key in self.labels:
            check_label_value(f"labels.{key}", self.labels[key])
            if key in RESERVED_LABELS or key in grid_labels:
                taken = "a grid label" if key in grid_labels else "a column of the results"
                raise ValueError(f"labels.{key}: {key!r} is {taken}; a fixed label needs a name of its own")
        for key in self.seeds_by or []:
            if key != "task" and key not in grid_labels and key not in self.labels:
                known = sorted({*grid_labels, *self.labels}) or "none"
                raise ValueError(f"seeds_by: {key!r} is not a label of the agent (its labels: {known}; or task)")
        return self

    def point_count(self, tasks: int = 1) -> int:
        """The number of grid points on ``tasks`` tasks (from the grids' lengths, nothing built)."""
        if self.grid_by_task is not None:
            return sum(math.prod(len(values) for values in grid.values()) for grid in self.grid_by_task.values())
        return math.prod(len(values) for values in self.grid.values()) * tasks

    def seed_point(self, point: dict[str, Any], task: str | None) -> dict[str, Any]:
        """What derives a run's seeds: its grid point, or the labels ``seeds_by`` names (``task`` among them)."""
        if self.seeds_by is None:
            return point
        labels = {**point, **self.labels, "task": task}
        return {key: labels[key] for key in self.seeds_by}

    @model_validator(mode="after")
    def _references(self) -> AgentSpec:
        places = [("kwargs", self.kwargs)] + [(f"team[{i}].kwargs", m.kwargs) for i, m in enumerate(self.team or [])]
        for where, kwargs in places:
            for key, raw in kwargs.items():
                match = KWARG_REFERENCE.match(raw) if isinstance(raw, str) else None
                for grid in self.grids():
                    if match and match.group(1) not in grid:
                        raise ValueError(
                            f"{where}.{key}={raw!r} refers to no grid label; the grid has {sorted(grid) or 'none'}"
                        )
        return self

    def points(self, grid: dict[str, list[Any]] | None = None) -> list[dict[str, Any]]:
        """The grid points of ``grid`` (default: the agent's ``grid``) in order, the last label fastest."""
        grid = self.grid if grid is None else grid
        keys = list(grid)
        return [dict(zip(keys, values)) for values in itertools.product(*(grid[k] for k in keys))]

    def kwargs_at(self, point: dict[str, Any], kwargs: dict[str, Any] | None = None) -> dict[str, Any]:
        out = {}
        for key, raw in (self.kwargs if kwargs is None else kwargs).items():
            match = KWARG_REFERENCE.match(raw) if isinstance(raw, str) else None
            out[key] = point[match.group(1)] if match else raw
        return out

    def team_at(self, point: dict[str, Any]) -> list[dict[str, Any]]:
        """The team's members at a grid point, as plain data (``{"algo", "kwargs"}`` per hunter)."""
        return [{"algo": m.algo, "kwargs": self.kwargs_at(point, m.kwargs)} for m in self.team or []]


#: Replications of one simulation of the forensics (``ForensicsSpec``).
MAX_REPS = 10_000
#: The forensics' stages as cell labels: the pre-screen's replication 0 (maybe stopped early), then every replication.
PRESCREEN, REPLICATIONS = "prescreen", "replications"


def _check_range(values: list[float] | None, what: str, low_open: bool) -> None:
    """
    Each value in [0, 1] (``low_open``: in (0, 1]) and given once (a value twice would be one simulation counted as
    two), or a one-line error naming the first that is not.
    """
    for index, value in enumerate(values or []):
        if not (0 < value <= 1 if low_open else 0 <= value <= 1):
            raise ValueError(f"{value!r} is not {what}; each is in {'(0, 1]' if low_open else '[0, 1]'}")
        if value in (values or [])[:index]:
            raise ValueError(f"{value!r} is given twice; give each {what.removeprefix('an ').removeprefix('a ')} once")


class ProtocolSpec(BaseModel):
    """The forensics' ``protocol``: what one replication of a simulation runs (a key left out: the paper's)."""

    model_config = ConfigDict(extra="forbid")
    epsilons: list[float] | None = Field(
        default=None,
        min_length=2,
        description="the ε values, each in [0, 1]; the affective agent runs once per value (null: the paper's 0.1, "
        "0.2, ..., 0.9)",
    )
    seeds: int | None = Field(
        default=None, gt=0, le=MAX_SEEDS, description="simulations per ε and agent (null: the paper's 20)"
    )
    episodes: int | None = Field(
        default=None, gt=0, le=MAX_EPISODES, description="episodes per simulation (null: the paper's 200)"
    )

    @field_validator("epsilons")
    @classmethod
    def _epsilons(cls, value: list[float] | None) -> list[float] | None:
        _check_range(value, "an ε", low_open=False)
        return value


class ForensicsSpec(BaseModel):
    """
    The ``forensics`` section: the replication forensics, its sizes and its candidate grid.

    Which candidate implementation could have printed the paper's numbers: its runs are (simulation, replication)
    units (``cells``), run in stages by the launcher (``plan_jobs`` with the forensics' ``stages``)::

        name: forensics
        forensics:
          screen_reps: 2          # replications of every simulation in the screen
          leaders: 4              # affective simulations replicated in full
          reps: 30                # replications of each leader
          alphas: [0.5, 1.0]      # the candidate grid's learning rates
          gammas: [0.7, 0.8, 0.9] # and discounts
    """

    model_config = ConfigDict(extra="forbid")
    screen_reps: int = Field(
        ge=2, le=MAX_REPS, description="replications of every simulation in the screen (a spread needs two)"
    )
    leaders: int = Field(ge=1, description="affective simulations, best first after the screen, replicated in full")
    reps: int = Field(
        ge=2, le=MAX_REPS, description=f"replications of each leader, at least screen_reps (at most {MAX_REPS:,})"
    )
    alphas: list[float] = Field(min_length=1, description="the learning rates of the candidate grid, each in (0, 1]")
    gammas: list[float] = Field(min_length=1, description="the discounts of the candidate grid, each in [0, 1]")
    protocol: ProtocolSpec = Field(
        default_factory=ProtocolSpec, description="what one replication runs (below; default: the paper's protocol)"
    )

    def space(self) -> CandidateSpace:
        """The candidate space of the file: the default space with the file's alphas and gammas."""
        return dataclasses.replace(CandidateSpace.default(), alphas=tuple(self.alphas), gammas=tuple(self.gammas))

    def paper_protocol(self) -> Protocol:
        """The protocol of the file: the paper's, with the keys its ``protocol`` section gives."""
        given = self.protocol.model_dump(exclude_none=True)
        if "epsilons" in given:
            given["epsilons"] = tuple(given["epsilons"])
        return Protocol(**given)

    def cells(self, name: str) -> list[Cell]:
        """
        The study ``name`` as the launcher's cells, two per simulation of the grid: its pre-screen (replication 0, which may
        stop early) and its replications (``reps``; the stages ask for those they need). A replication is a run: its
        ``seed`` and replicate are its index, its base the simulation and the protocol (its run id hashes them).
        """
        space, protocol = self.space(), self.paper_protocol()
        cells = []
        for stage, count in ((PRESCREEN, 1), (REPLICATIONS, self.reps)):
            for sim in space.standard_simulations() + space.affective_simulations():
                base = {"sweep": name, "study": "forensics", "agent": sim.key, "algo": sim.algo, "seed": None,
                        "labels": {"stage": stage}, "simulation": dataclasses.asdict(sim), "algo_kwargs": {},
                        "env_id": protocol.env_id, "env_kwargs": protocol.env_kwargs,
                        "protocol": protocol.as_dict()}  # fmt: skip
                cells.append(Cell(base, list(range(count))))
        return cells

    @field_validator("alphas")
    @classmethod
    def _alphas(cls, value: list[float]) -> list[float]:
        _check_range(value, "a learning rate", low_open=True)
        return value

    @field_validator("gammas")
    @classmethod
    def _gammas(cls, value: list[float]) -> list[float]:
        _check_range(value, "a discount", low_open=False)
        return value

    @field_validator("reps")
    @classmethod
    def _enough_reps(cls, value: int, info: ValidationInfo) -> int:
        screen_reps = info.data.get("screen_reps")
        if screen_reps is not None and value < screen_reps:
            raise ValueError(f"fewer than screen_reps ({screen_reps}); give reps >= {screen_reps}")
        return value


#: The kinds of sweep file (``kind_of``): what a refusal calls each, the top-level keys it takes and those it needs.
KINDS = {"sweep": "a sweep of runs", "deep": "a deep study (a sweep with a trainer)",
         "forensics": "the forensics (a sweep with forensics)"}  # fmt: skip
KIND_KEYS = {"sweep": ("name", "env", "tasks", "episodes", "seeds", "max_timesteps", "logs", "agents"),
             "deep": ("name", "trainer", "evaluation", "tasks", "seeds", "agents"), "forensics": ("name", "forensics")}
REQUIRED_KEYS = {"sweep": ("episodes", "seeds", "agents"), "deep": ("evaluation", "tasks", "seeds", "agents"),
                 "forensics": ()}  # fmt: skip
#: The keys of an agent and of a task that only a deep study takes, and those a deep study's do not take.
DEEP_AGENT_KEYS, DEEP_TASK_KEYS = ("epsilon", "count_bonus", "replays"), ("total_timesteps", "tuned")
TABULAR_AGENT_KEYS = ("grid", "team", "labels", "grid_by_task", "seeds_by", "seeds_from", "wrappers", "trace")
TABULAR_TASK_KEYS = ("kwargs", "wrappers", "position")


def kind_of(data: Any) -> str:
    """
    The kind of a sweep's data (a file's, a saved sweep's, a ``Sweep``'s fields): ``deep`` when it gives a
    ``trainer``, ``forensics`` when it gives ``forensics``, else ``sweep`` (a sweep of runs).
    """
    if not isinstance(data, Mapping):
        return "sweep"
    return "deep" if data.get("trainer") is not None else "forensics" if data.get("forensics") is not None else "sweep"


def _given(model: BaseModel, keys: tuple[str, ...]) -> list[str]:
    """The ``keys`` of ``model`` whose value is not their default (those a file or a saved sweep gives)."""
    fields = type(model).model_fields
    return [key for key in keys if getattr(model, key) != fields[key].get_default(call_default_factory=True)]


class Sweep(BaseModel):
    """
    A whole experiment file (top-level keys): a sweep of runs, a deep study or the forensics (``kind``).

    A deep study gives a ``trainer`` (below), the forensics a ``forensics`` section (below); each takes its own keys.
    """

    model_config = ConfigDict(extra="forbid")
    name: str = Field(
        pattern=NAME_PATTERN,
        description="the sweep's name (letters, digits, _ . + -, not starting with a dot, at most 64 characters); "
        "enters the derived seeds and the run files",
    )
    env: EnvSpec = Field(default_factory=EnvSpec, description="the environment section (below)")
    tasks: dict[str, EnvSpec] | None = Field(
        default=None,
        description="instead of env: several envs by task name (each an env section); every agent runs on each task "
        "with the same seeds, its runs labelled task",
    )
    episodes: int | None = Field(
        default=None, gt=0, le=MAX_EPISODES,
        description=f"episodes per run (1 to {MAX_EPISODES:,}); a run stops after this many (a sweep of runs needs it)",
    )
    seeds: int | list[int] | None = Field(
        default=None,
        description=f"a count N (1 to {MAX_SEEDS:,}; seeds derived by sha256 of sweep, agent, grid point and replicate) "
        f"or an explicit list of distinct integers in [0, 2**32 - 1], the same for every grid point; at most "
        f"{MAX_RUNS:,} runs in all (grid points x seeds over the agents); a deep study: a list, each below "
        f"{EVAL_SEED_OFFSET:,}",
    )
    max_timesteps: int | None = Field(
        default=None,
        gt=0,
        le=MAX_TIMESTEPS,
        description="optional cap on a run's decisions (env steps), e.g. for DQN; null: no cap",
    )
    logs: list[str] = Field(
        default_factory=list,
        description="SB3 logger formats written per run under DIR/logs/<run>/: csv, tensorboard, stdout, json, log",
    )
    agents: list[AgentSpec] = Field(default_factory=list, description="one or more agents (below)")
    trainer: TrainerSpec | None = Field(
        default=None, description="makes the file a deep study: DQN-family agents, many seeds of each trained together"
    )
    evaluation: EvaluationSpec | None = Field(
        default=None, description="a deep study's greedy evaluations: every (env steps) and episodes"
    )
    forensics: ForensicsSpec | None = Field(
        default=None, description="makes the file the replication forensics (its only other key: name)"
    )

    @property
    def kind(self) -> str:
        """``sweep``, ``deep`` or ``forensics`` (``kind_of``)."""
        return kind_of(self.__dict__)

    @field_validator("seeds", mode="before")
    @classmethod
    def _no_flags(cls, value: Any) -> Any:
        """true/false is no seed (pydantic would take it for 1/0)."""
        flags = [i for i, seed in enumerate(value if isinstance(value, list) else [value]) if isinstance(seed, bool)]
        if flags:
            where = f"seeds[{flags[0]}]" if isinstance(value, list) else "seeds"
            raise ValueError(f"{where}={(value[flags[0]] if isinstance(value, list) else value)!r} is not an integer; "
                             "seeds are integers in [0, 2**32 - 1]")
        return value

    @field_validator("seeds")
    @classmethod
    def _some_seeds(cls, value: int | list[int] | None) -> int | list[int] | None:
        if isinstance(value, int) and value <= 0:
            raise ValueError(f"seeds={value} must be a positive count or a non-empty list of integers")
        if isinstance(value, int) and value > MAX_SEEDS:
            raise ValueError(f"seeds={value:,} is more than the {MAX_SEEDS:,} seeds allowed per grid point")
        bad = [seed for seed in value if not 0 <= seed <= MAX_SEED] if isinstance(value, list) else []
        if bad:
            raise ValueError(f"seeds: {bad[0]} is not a seed; seeds are integers in [0, 2**32 - 1] (NumPy's)")
        if isinstance(value, list) and (not value or len(set(value)) != len(value)):
            raise ValueError("seeds must be a non-empty list of distinct integers")
        if isinstance(value, list) and len(value) > MAX_SEEDS:
            raise ValueError(f"seeds: {len(value):,} seeds, more than the {MAX_SEEDS:,} allowed")
        return value

    @classmethod
    def validate_saved(cls, data: Any) -> Sweep:
        """Validate a results folder's saved sweep without importing any module it names (no algo or env check)."""
        return cls.model_validate(data, context=SAVED)

    @classmethod
    def validate_file(cls, data: Any) -> Sweep:
        """
        Validate a sweep file's data: a sweep of runs imports the modules its algo and env ids name; a deep study or
        the forensics names none (its algos are the registry's, its tasks MiniGrid's: checked by name).
        """
        return cls.model_validate(data, context=None if kind_of(data) == "sweep" else SAVED)

    @field_validator("logs")
    @classmethod
    def _formats(cls, value: list[str]) -> list[str]:
        for fmt in value:
            if fmt not in ("csv", "tensorboard", "stdout", "json", "log"):
                raise ValueError(f"logs: {fmt!r} is not an SB3 logger format (csv, tensorboard, stdout, json, log)")
        return value

    @model_validator(mode="after")
    def _unique_agents(self) -> Sweep:
        kind = self.kind
        given = _given(self, tuple(type(self).model_fields))
        stray = [key for key in given if key not in KIND_KEYS[kind]]
        if stray:
            raise ValueError(f"{stray[0]} is not a key of {KINDS[kind]}; its keys are {', '.join(KIND_KEYS[kind])}")
        missing = [key for key in REQUIRED_KEYS[kind] if key not in given]
        if missing:
            what = "missing or empty" if missing[0] == "agents" else "missing"
            raise ValueError(f"{missing[0]} is {what}: {KINDS[kind]} needs {', '.join(REQUIRED_KEYS[kind])}")
        if kind == "forensics":
            return self
        names = [a.name for a in self.agents]
        if len(set(names)) != len(names):
            raise ValueError(f"agents: names must be unique, got {names}")
        if self.tasks is not None:
            self._check_tasks()
        if kind == "deep":
            self._check_deep()
            return self
        for i, agent in enumerate(self.agents):
            deep_keys = _given(agent, DEEP_AGENT_KEYS)
            if deep_keys:
                raise ValueError(f"agents[{i}] ({agent.name}): {deep_keys[0]} is a key of a deep study's agents (a sweep "
                                 "with a trainer), not of a sweep of runs'")
            if self.tasks is None and (agent.grid_by_task is not None or "task" in (agent.seeds_by or [])):
                key = "grid_by_task" if agent.grid_by_task is not None else "seeds_by: [task]"
                raise ValueError(f"agents[{i}] ({agent.name}): {key} needs tasks (several envs by name) instead of env")
        for task, env in (self.tasks or {}).items():
            deep_keys = _given(env, DEEP_TASK_KEYS)
            if deep_keys:
                raise ValueError(f"tasks.{task}.{deep_keys[0]} is a key of a deep study's tasks (a sweep with a trainer), "
                                 "not of a sweep of runs'")
        multi = is_multi_agent(self.env.id)
        for i, agent in enumerate(self.agents):
            if multi and agent.team is None:
                raise ValueError(f"agents[{i}] ({agent.name}): env {self.env.id!r} is multi-agent: give a team, not algo")
            if not multi and agent.team is not None:
                raise ValueError(f"agents[{i}] ({agent.name}): a team needs a multi-agent env id, not {self.env.id!r}")
        if multi and self.max_timesteps is not None:
            raise ValueError("max_timesteps is not supported for teams: their runs are counted in episodes")
        self._check_label_types()
        replicates = self.seeds if isinstance(self.seeds, int) else len(self.seeds or [])
        runs = sum(agent.point_count(len(self.tasks or [None])) for agent in self.agents) * replicates
        if runs > MAX_RUNS:
            raise ValueError(f"the sweep has {runs:,} runs (grid points x seeds), more than the {MAX_RUNS:,} allowed")
        return self

    def _check_deep(self) -> None:
        """A deep study's seeds (a list, below ``EVAL_SEED_OFFSET``), its MiniGrid tasks and its DQN-family agents."""
        assert self.trainer is not None and self.evaluation is not None and self.tasks is not None
        if not isinstance(self.seeds, list) or len(self.seeds) > MAX_DEEP_SEEDS:
            given = f"{len(self.seeds):,} seeds" if isinstance(self.seeds, list) else f"seeds={self.seeds!r}"
            raise ValueError(f"{given}: a deep study takes an explicit list of at most {MAX_DEEP_SEEDS:,} seeds (e.g. [0, "
                             "1, 2]), not a count")
        if max(self.seeds) >= EVAL_SEED_OFFSET:
            raise ValueError(f"seeds: {max(self.seeds)} is too large; seeds go from 0 to {EVAL_SEED_OFFSET - 1} (the "
                             f"evaluation envs are seeded from {EVAL_SEED_OFFSET:,} on)")
        every = self.evaluation.every
        for name, task in self.tasks.items():
            stray = _given(task, TABULAR_TASK_KEYS)
            if not re.fullmatch(NAME_PATTERN, name):
                raise ValueError(f"task name {name!r} must be letters, digits, _ . + - (at most 64 characters)")
            if stray:
                raise ValueError(f"tasks.{name}.{stray[0]} is not a key of a deep study's task (id, total_timesteps, tuned)")
            if not re.fullmatch(MINIGRID_ID, task.id):
                raise ValueError(f"tasks.{name}.id={task.id!r} is not a MiniGrid env id (e.g. MiniGrid-Empty-8x8-v0)")
            if self.trainer.vec_env == "compiled" and task.id not in MINIGRID_TASKS:
                compiled = ", ".join(MINIGRID_TASKS)
                raise ValueError(f"tasks.{name}.id={task.id!r} is not compiled ({compiled}): give trainer.vec_env: farama")
            if task.total_timesteps is None or task.total_timesteps % every:
                raise ValueError(f"tasks.{name}.total_timesteps={task.total_timesteps} is not a multiple of "
                                 f"evaluation.every={every}")
        names = [agent.name for agent in self.agents]
        deep = [name for name in AGENTS if name.endswith("DQN")]
        for index, agent in enumerate(self.agents):
            where, stray = f"agents[{index}] ({agent.name})", _given(agent, TABULAR_AGENT_KEYS)
            if not re.fullmatch(NAME_PATTERN, agent.name):
                raise ValueError(f"agents[{index}].name={agent.name!r} must be letters, digits, _ . + - (at most 64)")
            if stray:
                raise ValueError(f"{where}: {stray[0]} is not a key of a deep study's agent (name, algo, kwargs, "
                                 f"{', '.join(DEEP_AGENT_KEYS)})")
            if agent.algo not in deep:
                raise ValueError(f"{where}: algo={agent.algo!r} is not one of {', '.join(deep)}")
            check_arguments(f"{where}.kwargs", agent.kwargs)
            if (agent.replays is None) != (agent.algo != "ReplayedEpsilonDQN"):
                raise ValueError(f"{where}: replays=<earlier agent> goes with algo ReplayedEpsilonDQN")
            if agent.replays is not None and agent.replays not in names[:index]:
                earlier = ", ".join(names[:index])
                raise ValueError(f"agents[{index}].replays={agent.replays!r} is not an earlier agent ({earlier})")
            for field, wanted in (("exploration_fraction", agent.epsilon), ("count_bonus", agent.count_bonus)):
                missing = [task for task, spec in self.tasks.items()
                           if wanted == TUNED and getattr(spec.tuned, field, None) is None]  # fmt: skip
                if missing:
                    raise ValueError(f"{where} takes the tuned {field}: tasks.{missing[0]}.tuned has none")

    def _check_label_types(self) -> None:
        """
        One label's values over the agents are never equal values of different types (``1``, ``1.0`` and ``true``):
        the results' column of the label would hold them as one value.
        """
        seen: dict[str, dict[Any, tuple[Any, str]]] = {}
        for agent in self.agents:
            given = [(key, value) for grid in agent.grids() for key, values in grid.items() for value in values]
            for key, value in [*given, *agent.labels.items()]:
                values = seen.setdefault(key, {})
                if isinstance(value, float) and math.isnan(value):
                    continue
                earlier = values.setdefault(value, (value, agent.name))
                if type(earlier[0]) is not type(value):
                    raise ValueError(
                        f"label {key!r}: {value!r} (agent {agent.name!r}) equals {earlier[0]!r} (agent {earlier[1]!r}), "
                        "a value of another type; write one label's values alike"
                    )

    @model_serializer(mode="wrap")
    def _dump(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        """
        A sweep of runs without ``tasks`` when not given (a saved sweep of one env reads, and resumes, as before tasks
        existed) nor the other kinds' keys; a deep study or the forensics: the keys it gives only.
        """
        dumped = handler(self)
        if self.kind != "sweep":
            return {key: dumped[key] for key in _given(self, KIND_KEYS[self.kind]) if key in dumped}
        return _without_unset(dumped, {"tasks": None, "trainer": None, "evaluation": None, "forensics": None})

    def _check_tasks(self) -> None:
        """``tasks`` instead of ``env``: named tasks of single-agent envs, agents without a grid label ``task``."""
        if self.env.config() != EnvSpec.model_construct().config():  # (a saved sweep holds the default env)
            raise ValueError("give either env (one env) or tasks (several, by name), not both")
        if not self.tasks:
            raise ValueError("tasks is empty: give at least one task (name: {id: ..., kwargs: ...})")
        for task, env in self.tasks.items():
            if not re.fullmatch(LABEL_PATTERN, task):
                raise ValueError(
                    f"tasks: {task!r} is not a task name (at most 64 characters, not starting with a dot or a space nor "
                    "ending with a space, no slash, backslash or control character)"
                )
            if is_multi_agent(env.id):
                raise ValueError(f"tasks.{task}: {env.id!r} is multi-agent; tasks are single-agent envs")
        for i, agent in enumerate(self.agents):
            if any("task" in grid for grid in agent.grids()) or "task" in agent.labels:
                where = "labels" if "task" in agent.labels else "grid"
                raise ValueError(f"agents[{i}] ({agent.name}): {where}.task names the tasks' label; rename the label")
            unknown = [task for task in agent.grid_by_task or {} if task not in self.tasks]
            if unknown:
                raise ValueError(
                    f"agents[{i}] ({agent.name}): grid_by_task names {unknown[0]!r}, not a task of the sweep "
                    f"({', '.join(self.tasks)})"
                )

    def cells(self) -> list[Cell]:
        """
        The sweep as cells: one per (task,) agent and grid point, holding every replicate's seed (see ``Cell``). The
        seeds do not depend on the task (each task runs an agent on the same seeds) unless the agent's ``seeds_by``
        names it. A deep study: ``deep_cells``; the forensics: ``ForensicsSpec.cells``.
        """
        if self.forensics is not None:
            return self.forensics.cells(self.name)
        if self.trainer is not None:
            return self.deep_cells()
        cells = []
        envs: list[tuple[str | None, EnvSpec]] = list(self.tasks.items()) if self.tasks else [(None, self.env)]
        for task, env in envs:
            for agent in self.agents:
                grid = agent.grid_on(task)
                for point in agent.points(grid) if grid is not None else []:
                    count = self.seeds if isinstance(self.seeds, int) else len(self.seeds or [])
                    named = agent.seeds_from or self.name
                    at = agent.seed_point(point, task)
                    seeds = list(self.seeds) if isinstance(self.seeds, list) else derive_seeds(named, agent.name, at, count)
                    labels = {**point, **agent.labels}
                    base: dict[str, Any] = {
                        "sweep": self.name,
                        "agent": agent.name,
                        "algo": agent.algo or "team",
                        "algo_kwargs": agent.kwargs_at(point),
                        **env.config(),
                        "seed": None,
                        "episodes": self.episodes,
                        "max_timesteps": self.max_timesteps,
                        "labels": labels if task is None else {**labels, "task": task},
                    }
                    if agent.team is not None:  # only team runs carry the key: other run ids are unchanged
                        base["team"] = agent.team_at(point)
                    if agent.wrappers:
                        base["env_wrappers"] = [*base.get("env_wrappers", []), *agent.wrappers]
                    if agent.trace:  # only traced runs carry the key: other run ids are unchanged
                        base["trace"] = True
                    cells.append(Cell(base, seeds))
        return cells

    def deep_cells(self) -> list[Cell]:
        """
        A deep study as the launcher's cells, one per task and agent (tasks first, agents in the file's order): its base
        run config holds all a run's training and evaluation depends on (its run ids hash it), its seeds the study's.
        A ``replays`` agent's cell waits for the cell of the agent it replays on the same task (``launcher.plan_jobs``).
        """
        trainer, evaluation, seeds = self.trainer, self.evaluation, self.seeds
        assert trainer is not None and evaluation is not None and isinstance(seeds, list)  # (``_check_deep``)
        cells = []
        for task, spec in (self.tasks or {}).items():
            tuned = spec.tuned or TunedSpec()
            for agent in self.agents:
                kwargs: dict[str, Any] = dict(trainer.algo_kwargs)  # the study's, the task's tuned, the agent's own
                if tuned.learning_rate is not None:
                    kwargs["learning_rate"] = tuned.learning_rate
                if agent.epsilon == TUNED:
                    kwargs["exploration_fraction"] = tuned.exploration_fraction
                kwargs.update(agent.kwargs)
                bonus = tuned.count_bonus if agent.count_bonus == TUNED else agent.count_bonus
                base = {"sweep": self.name, "study": "deep", "agent": agent.name, "algo": agent.algo, "seed": None,
                        "labels": {"task": task}, "env_id": spec.id, "env": trainer.vec_env, "obs": trainer.obs,
                        "n_envs": trainer.n_envs, "budget": spec.total_timesteps, "eval_every": evaluation.every,
                        "eval_episodes": evaluation.episodes, "algo_kwargs": kwargs, "count_bonus": bonus,
                        "replays": agent.replays}  # fmt: skip
                cells.append(Cell(base, seeds, trainer.seeds_per_batch or len(seeds)))
        return cells

    def run_configs(self) -> list[dict[str, Any]]:
        """Every run of the sweep as a plain-data config (the unit the launcher executes and stores)."""
        return [cell.config(replicate) for cell in self.cells() for replicate in range(len(cell.seeds))]


def _without_unset(dumped: dict[str, Any], defaults: dict[str, Any]) -> dict[str, Any]:
    """A model's dump without the keys whose value is their default (keys added after folders were saved)."""
    return {key: value for key, value in dumped.items() if key not in defaults or value != defaults[key]}


@dataclass
class Cell:
    """
    The runs of one agent at one grid point: configs equal but for ``seed`` and ``labels["replicate"]``.

    :param base: the run config with ``seed`` None and ``labels`` without ``replicate``
    :param seeds: the seed of each replicate, in replicate order
    :param batch_size: the most runs a batch of the cell holds (None: the launcher's choice, ``batches.batch_size``)
    """

    base: dict[str, Any]
    seeds: list[int]
    batch_size: int | None = None

    def config(self, replicate: int) -> dict[str, Any]:
        """The full run config of one replicate."""
        base = self.base
        return {
            **base,
            "algo_kwargs": dict(base["algo_kwargs"]),
            "env_kwargs": dict(base["env_kwargs"]),
            "seed": self.seeds[replicate],
            "labels": {**base["labels"], "replicate": replicate},
        }


def derive_seed(sweep: str, agent: str, point: dict[str, Any], replicate: int) -> int:
    """A stable seed (sha256, never Python's ``hash``) for one replicate of one agent at one grid point."""
    text = json.dumps([sweep, agent, point, replicate], sort_keys=True)
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big") & 0x7FFFFFFF


def derive_seeds(sweep: str, agent: str, point: dict[str, Any], count: int) -> list[int]:
    """``derive_seed`` of replicates ``0..count-1``, encoding the JSON once (the text differs only in its last number)."""
    head = json.dumps([sweep, agent, point, 0], sort_keys=True)[: -len("0]")]
    return [
        int.from_bytes(hashlib.sha256(f"{head}{replicate}]".encode()).digest()[:4], "big") & 0x7FFFFFFF
        for replicate in range(count)
    ]
