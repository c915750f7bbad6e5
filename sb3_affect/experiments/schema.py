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
``algo``: one ``{algo, kwargs}`` per hunter, independent learners that may mix classes (``sb3_affect.team``)::

      - name: mixed
        team: [{algo: AffectQ}, {algo: QLearning, kwargs: {exploration_rate: $epsilon}}]
        grid: {epsilon: [0.1]}
"""

from __future__ import annotations

import difflib
import hashlib
import importlib
import itertools
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from sb3_affect.experiments.algos import SHORT_NAMES, check_algo, is_tabular, resolve_class

__all__ = ["SHORT_NAMES", "AgentSpec", "Cell", "EnvSpec", "MemberSpec", "Sweep", "SweepError", "load_sweep", "resolve_class"]

_REFERENCE = re.compile(r"^\$([A-Za-z_][A-Za-z0-9_]*)$")


class SweepError(ValueError):
    """A sweep file that can not be run; the message names the file, the key path and what is allowed."""


def is_multi_agent(env_id: str) -> bool:
    """Whether ``env_id`` names one of the package's multi-agent (PettingZoo) envs."""
    from sb3_affect.envs import PARALLEL_ENVS

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

    @field_validator("id")
    @classmethod
    def _registered(cls, value: str) -> str:
        import gymnasium as gym

        import sb3_affect  # noqa: F401  (registers the package's envs)
        from sb3_affect.envs import PARALLEL_ENVS

        module, _, env_id = value.rpartition(":")  # "my_package.envs:MyEnv-v0": import the module that registers it
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


class MemberSpec(BaseModel):
    """One hunter of a team agent: its algorithm and constructor arguments (``$label`` references allowed)."""

    model_config = ConfigDict(extra="forbid")
    algo: str = Field(description="a tabular agent of this package: QLearning, AffectQ or a baseline class path")
    kwargs: dict[str, Any] = Field(
        default_factory=dict, description="its constructor arguments; $label takes the grid label's value"
    )

    @field_validator("algo")
    @classmethod
    def _tabular(cls, value: str) -> str:
        if not is_tabular(value):
            raise ValueError(f"team members are tabular agents of this package (QLearning, AffectQ, baselines), not {value!r}")
        return value


class AgentSpec(BaseModel):
    """One item of ``agents``: an algorithm, its fixed kwargs and the grid of labels it is swept over."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(
        min_length=1,
        pattern=r"^[A-Za-z0-9_.+-]+$",
        description="unique within the file; names the runs (letters, digits, _ . + -) and groups them in the report",
    )
    algo: str | None = Field(
        default=None,
        description="QLearning, AffectQ, DQN, PPO, A2C or an importable 'package.module:Class' (an SB3 algorithm); "
        "give algo or team",
    )
    kwargs: dict[str, Any] = Field(
        default_factory=dict,
        description="constructor arguments of the algorithm; a value written $label takes the grid label's value",
    )
    grid: dict[str, list[Any]] = Field(
        default_factory=dict,
        description="label -> list of values; every combination is one grid point, run once per seed. A label no "
        "kwarg uses only replicates the agent",
    )
    team: list[MemberSpec] | None = Field(
        default=None,
        min_length=1,
        description="instead of algo, on a multi-agent env: one {algo, kwargs} per hunter (below)",
    )

    @field_validator("algo")
    @classmethod
    def _importable(cls, value: str | None) -> str | None:
        if value is not None:
            check_algo(value)
        return value

    @model_validator(mode="after")
    def _one_kind(self) -> AgentSpec:
        if (self.algo is None) == (self.team is None):
            raise ValueError("give either algo (one agent) or team (one {algo, kwargs} per hunter of a multi-agent env)")
        if self.team is not None and self.kwargs:
            raise ValueError("a team agent has no kwargs of its own: give each member's under team[i].kwargs")
        return self

    @field_validator("grid")
    @classmethod
    def _non_empty(cls, value: dict[str, list[Any]]) -> dict[str, list[Any]]:
        for key, values in value.items():
            if not values:
                raise ValueError(f"grid.{key} is empty: give at least one value")
        return value

    @model_validator(mode="after")
    def _references(self) -> AgentSpec:
        places = [("kwargs", self.kwargs)] + [(f"team[{i}].kwargs", m.kwargs) for i, m in enumerate(self.team or [])]
        for where, kwargs in places:
            for key, raw in kwargs.items():
                match = _REFERENCE.match(raw) if isinstance(raw, str) else None
                if match and match.group(1) not in self.grid:
                    raise ValueError(
                        f"{where}.{key}={raw!r} refers to no grid label; the grid has {sorted(self.grid) or 'none'}"
                    )
        return self

    def points(self) -> list[dict[str, Any]]:
        keys = list(self.grid)
        return [dict(zip(keys, values)) for values in itertools.product(*(self.grid[k] for k in keys))]

    def kwargs_at(self, point: dict[str, Any], kwargs: dict[str, Any] | None = None) -> dict[str, Any]:
        out = {}
        for key, raw in (self.kwargs if kwargs is None else kwargs).items():
            match = _REFERENCE.match(raw) if isinstance(raw, str) else None
            out[key] = point[match.group(1)] if match else raw
        return out

    def team_at(self, point: dict[str, Any]) -> list[dict[str, Any]]:
        """The team's members at a grid point, as plain data (``{"algo", "kwargs"}`` per hunter)."""
        return [{"algo": m.algo, "kwargs": self.kwargs_at(point, m.kwargs)} for m in self.team or []]


class Sweep(BaseModel):
    """A whole experiment file (top-level keys)."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(
        min_length=1,
        pattern=r"^[A-Za-z0-9_.+-]+$",
        description="the sweep's name (letters, digits, _ . + -); enters the derived seeds and the run files",
    )
    env: EnvSpec = Field(default_factory=EnvSpec, description="the environment section (below)")
    episodes: int = Field(gt=0, description="episodes per run; a run stops after this many finished episodes")
    seeds: int | list[int] = Field(
        description="a count N (seeds derived by sha256 of sweep, agent, grid point and replicate) or an explicit list "
        "of distinct integers, the same for every grid point"
    )
    max_timesteps: int | None = Field(
        default=None, gt=0, description="optional cap on a run's decisions (env steps), e.g. for DQN; null: no cap"
    )
    logs: list[str] = Field(
        default_factory=list,
        description="SB3 logger formats written per run under DIR/logs/<run>/: csv, tensorboard, stdout, json, log",
    )
    agents: list[AgentSpec] = Field(min_length=1, description="one or more agents (below)")

    @field_validator("seeds")
    @classmethod
    def _some_seeds(cls, value: int | list[int]) -> int | list[int]:
        if isinstance(value, int) and value <= 0:
            raise ValueError(f"seeds={value} must be a positive count or a non-empty list of integers")
        if isinstance(value, list) and (not value or len(set(value)) != len(value)):
            raise ValueError("seeds must be a non-empty list of distinct integers")
        return value

    @field_validator("logs")
    @classmethod
    def _formats(cls, value: list[str]) -> list[str]:
        for fmt in value:
            if fmt not in ("csv", "tensorboard", "stdout", "json", "log"):
                raise ValueError(f"logs: {fmt!r} is not an SB3 logger format (csv, tensorboard, stdout, json, log)")
        return value

    @model_validator(mode="after")
    def _unique_agents(self) -> Sweep:
        names = [a.name for a in self.agents]
        if len(set(names)) != len(names):
            raise ValueError(f"agents: names must be unique, got {names}")
        multi = is_multi_agent(self.env.id)
        for i, agent in enumerate(self.agents):
            if multi and agent.team is None:
                raise ValueError(f"agents[{i}] ({agent.name}): env {self.env.id!r} is multi-agent: give a team, not algo")
            if not multi and agent.team is not None:
                raise ValueError(f"agents[{i}] ({agent.name}): a team needs a multi-agent env id, not {self.env.id!r}")
        if multi and self.max_timesteps is not None:
            raise ValueError("max_timesteps is not supported for teams: their runs are counted in episodes")
        return self

    def cells(self) -> list[Cell]:
        """The sweep as cells: one per agent and grid point, holding every replicate's seed (see ``Cell``)."""
        cells = []
        for agent in self.agents:
            for point in agent.points():
                count = self.seeds if isinstance(self.seeds, int) else len(self.seeds)
                seeds = list(self.seeds) if isinstance(self.seeds, list) else derive_seeds(self.name, agent.name, point, count)
                base: dict[str, Any] = {
                    "sweep": self.name,
                    "agent": agent.name,
                    "algo": agent.algo or "team",
                    "algo_kwargs": agent.kwargs_at(point),
                    "env_id": self.env.id,
                    "env_kwargs": dict(self.env.kwargs),
                    "seed": None,
                    "episodes": self.episodes,
                    "max_timesteps": self.max_timesteps,
                    "labels": dict(point),
                }
                if agent.team is not None:  # only team runs carry the key: other run ids are unchanged
                    base["team"] = agent.team_at(point)
                cells.append(Cell(base, seeds))
        return cells

    def run_configs(self) -> list[dict[str, Any]]:
        """Every run of the sweep as a plain-data config (the unit the launcher executes and stores)."""
        return [cell.config(replicate) for cell in self.cells() for replicate in range(len(cell.seeds))]


@dataclass
class Cell:
    """
    The runs of one agent at one grid point: configs equal but for ``seed`` and ``labels["replicate"]``.

    :param base: the run config with ``seed`` None and ``labels`` without ``replicate``
    :param seeds: the seed of each replicate, in replicate order
    """

    base: dict[str, Any]
    seeds: list[int]

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


def _override_path(assignment: str, data: dict[str, Any]) -> tuple[list[Any], Any]:
    """
    Check the key path of one ``--set key.path=value`` against the schema; return the path (list items as ints) and
    the parsed value. A key the schema does not know is named with the keys allowed there (and the closest one).
    A kwarg bound to a grid label (``$label``) can not be overridden: run ids and labels come from the grid, so the
    override would run one value under another value's label; the error says which grid to set instead.
    """
    if "=" not in assignment:
        raise SweepError(f"--set {assignment!r}: use key=value, e.g. --set seeds=5")
    raw_path, _, raw = assignment.partition("=")
    keys: list[Any] = raw_path.strip().split(".")
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError as error:
        raise SweepError(f"--set {assignment!r}: the value is not valid YAML ({error})") from None

    def unknown(key: str, allowed: list[str], where: str) -> SweepError:
        close = difflib.get_close_matches(key, allowed, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        return SweepError(
            f"--set {assignment!r}: {key!r} is not a key of {where}{hint} (allowed: {', '.join(allowed)})"
        )

    top = list(Sweep.model_fields)
    if keys[0] not in top:
        raise unknown(keys[0], top, "a sweep file")
    if keys[0] == "env" and len(keys) > 1 and keys[1] not in EnvSpec.model_fields:
        raise unknown(keys[1], list(EnvSpec.model_fields), "env")
    if keys[0] in ("name", "episodes", "seeds", "max_timesteps", "logs") and len(keys) > 1:
        raise SweepError(f"--set {assignment!r}: {keys[0]!r} is a single value; use --set {keys[0]}=VALUE")
    if keys[0] == "agents" and len(keys) > 1:
        agents: list[Any] = data["agents"] if isinstance(data.get("agents"), list) else []
        names = [a.get("name") if isinstance(a, dict) else None for a in agents]
        if keys[1] in names:  # an agent by name: agents.affective.kwargs.gamma=0.9
            keys[1] = names.index(keys[1])
        elif keys[1].isdigit() and int(keys[1]) < len(agents):
            keys[1] = int(keys[1])
        else:
            raise SweepError(
                f"--set {assignment!r}: no agent {keys[1]!r}; give an index 0..{len(agents) - 1} or a name "
                f"({', '.join(str(n) for n in names)})"
            )
        if len(keys) > 2 and keys[2] not in AgentSpec.model_fields:
            raise unknown(keys[2], list(AgentSpec.model_fields), f"agents[{keys[1]}]")
        if len(keys) == 4 and keys[2] == "kwargs":
            agent = agents[keys[1]] if isinstance(agents[keys[1]], dict) else {}
            bound = (agent.get("kwargs") or {}).get(keys[3])
            match = _REFERENCE.match(bound) if isinstance(bound, str) else None
            if match and value != bound:
                label = match.group(1)
                raise SweepError(
                    f"--set {assignment!r}: kwargs.{keys[3]} of agent {names[keys[1]]!r} takes its value from the grid "
                    f"label {label!r}, which names its runs and labels its results; set the grid instead, e.g. "
                    f"--set agents.{names[keys[1]]}.grid.{label}=[{raw.strip()}]"
                )
    return keys, value


def _apply_override(data: dict[str, Any], assignment: str) -> list[Any]:
    """
    ``key.path=value`` (value parsed as YAML; list items by index or agent name, e.g. ``agents.0.kwargs.gamma=0.9``).

    :return: the key path it set (agents by index), to tell which validation errors the override caused
    """
    keys, value = _override_path(assignment, data)
    target: Any = data
    for key in keys[:-1]:
        target = target[int(key)] if isinstance(target, list) else target.setdefault(key, {})
    last = keys[-1]
    if isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value
    return keys


def _overlaps(location: tuple[Any, ...], keys: list[Any]) -> bool:
    """Whether a validation error at ``location`` concerns the key path an override set (one is a prefix of the other)."""
    n = min(len(location), len(keys))
    return n > 0 and [str(k) for k in location[:n]] == [str(k) for k in keys[:n]]


def _key_path(location: tuple[Any, ...], data: dict[str, Any]) -> str:
    """Render a pydantic error location as a readable key path, naming agents by their name."""
    parts: list[str] = []
    node: Any = data
    for item in location:
        if isinstance(item, int) and isinstance(node, list) and item < len(node):
            name = node[item].get("name") if isinstance(node[item], dict) else None
            parts[-1] = f"{parts[-1]}[{item}]" + (f" ({name})" if name else "") if parts else f"[{item}]"
            node = node[item]
        else:
            parts.append(str(item))
            node = node.get(item) if isinstance(node, dict) else None
    return ".".join(parts)


def load_sweep(path: str | Path, overrides: tuple[str, ...] | list[str] = (), *, build: bool = True) -> Sweep:
    """
    Read, override and validate a sweep file; every problem is a ``SweepError`` naming the file and the key.

    :param build: also build the env and each agent once (without training, in a short-lived child process), so
        that an unknown or impossible kwarg is reported now rather than by every run of the sweep
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise SweepError(f"{path}: can not read the sweep file ({error.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error)
        raise SweepError(f"{path}: malformed YAML{where}: {problem}") from None
    if not isinstance(data, dict):
        raise SweepError(f"{path}: a sweep file must be a YAML mapping with name, episodes, seeds and agents")
    overridden: list[tuple[str, list[Any]]] = []
    for assignment in overrides:
        try:
            overridden.append((assignment, _apply_override(data, assignment)))
        except SweepError as error:
            raise SweepError(f"{error} [sweep file: {path}]") from None
        except (KeyError, IndexError, ValueError, TypeError, AttributeError) as error:
            raise SweepError(f"--set {assignment!r} does not apply to {path} ({error})") from None
    try:
        sweep = Sweep.model_validate(data)
    except ValidationError as error:
        lines, from_file = [], False
        for item in error.errors():
            location = tuple(item["loc"])
            key = _key_path(location, data) or "(top level)"
            value = item.get("input")
            shown = "" if isinstance(value, (dict, list)) or item["type"] == "missing" else f" (got {value!r})"
            message = item["msg"].removeprefix("Value error, ")
            setters = [a for a, keys in overridden if _overlaps(location, keys)]
            from_file = from_file or not setters
            lines.append(f"  {key}: {message}{shown}" + (f" [from --set {setters[-1]}]" if setters else ""))
        allowed = "allowed top-level keys: " + ", ".join(Sweep.model_fields)
        what = "invalid sweep file" if from_file else "invalid --set value"
        raise SweepError(f"{path}: {what}\n" + "\n".join(lines) + f"\n  ({allowed})") from None
    if build:
        from sb3_affect.experiments.runner import check_configs_in_child

        index = {agent.name: i for i, agent in enumerate(sweep.agents)}
        problems = check_configs_in_child([cell.config(0) for cell in sweep.cells()])
        if problems:
            lines = [
                f"  {f'agents[{index[agent]}] ({agent}).kwargs' if agent in index else 'env.kwargs'}: {message}"
                for agent, message in problems
            ]
            raise SweepError(f"{path}: invalid sweep file\n" + "\n".join(lines))
    return sweep
