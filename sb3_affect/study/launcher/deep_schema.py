"""
Sweep files of the deep study (``study: deep``): DQN-family agents on MiniGrid tasks, many seeds of one agent on one
task trained together (the public trainer ``sb3_affect.train_many``), each seed's greedy policy evaluated on its own
evaluation envs every ``eval_every`` env steps. ``sweep_file.load_sweep_file`` validates a file with ``DeepStudy``;
the launcher (``launcher.run_sweep``) runs its ``cells`` as ``deep_batches.DeepBatch`` jobs into a results store::

    name: minigrid-dqn
    study: deep
    seeds: [0, 1, 2]            # one run per seed, in every cell
    seeds_per_batch: 2          # seeds trained together per worker or Ray task (default: all of a cell's)
    eval_every: 10000           # env steps between evaluations of the greedy policy
    eval_episodes: 20           # evaluation episodes per seed and evaluation
    network: {buffer_size: 50000, learning_starts: 1000, policy_kwargs: {net_arch: [64, 64]}}  # every agent's
    tasks:
      Empty-8x8: {id: MiniGrid-Empty-8x8-v0, budget: 50000, learning_rate: 0.001, exploration_fraction: 0.2}
    agents:
      - {name: dqn-linear, algo: DQN, epsilon: tuned}
      - {name: affective, algo: AffectDQN, kwargs: {position: minigrid}}
      - {name: matched-randomness, algo: ReplayedEpsilonDQN, replays: affective}
      - {name: count-bonus, algo: DQN, epsilon: tuned, count_bonus: tuned}
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictInt, field_validator, model_validator

from sb3_affect.core.registry import AGENTS
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS
from sb3_affect.study.launcher.schema import NAME_PATTERN, Cell

#: Fewest evaluation episodes the study's primary metric is read from (a smaller file is labelled a smoke size).
STUDY_EVAL_EPISODES = 20
#: The settings a task holds for every agent that asks for them (``epsilon: tuned``, ``count_bonus: tuned``).
TUNED = "tuned"
#: The evaluation envs of seed s are seeded ``EVAL_SEED_OFFSET + s * eval_episodes + i``: apart from every training env
#: (seeded ``s + i`` for ``i < n_envs``) for seeds below the offset, which is the largest seed a study takes.
EVAL_SEED_OFFSET = 1_000_000
#: The arguments the study sets itself (the env of each seed, its seed, the CPU, SB3's MlpPolicy).
OWN_ARGUMENTS = ("env", "seed", "device", "policy")
#: The widest layer and the most layers of ``policy_kwargs.net_arch`` (the study's networks are 64 wide).
MAX_LAYER_WIDTH, MAX_LAYERS = 4096, 16
#: DQN's integer arguments the study checks before anything runs: (smallest, largest) of each.
INTEGER_ARGUMENTS = {"buffer_size": (1, 10**8), "learning_starts": (0, 10**9), "batch_size": (1, 2**16),
                     "train_freq": (1, 10**6), "gradient_steps": (1, 10**4), "target_update_interval": (1, 10**9),
                     "max_duration": (1, 10**6), "wait_action": (0, 6)}  # fmt: skip
#: DQN's real arguments the study checks: (lowest, highest, whether the lowest is allowed).
REAL_ARGUMENTS = {"learning_rate": (0.0, 1.0, False), "gamma": (0.0, 1.0, True), "tau": (0.0, 1.0, False),
                  "exploration_fraction": (0.0, 1.0, False), "exploration_initial_eps": (0.0, 1.0, True),
                  "exploration_final_eps": (0.0, 1.0, True), "max_grad_norm": (0.0, math.inf, False),
                  "mu": (0.0, math.inf, False)}  # fmt: skip


def check_arguments(where: str, value: dict[str, Any]) -> dict[str, Any]:
    """
    ``network`` or an agent's ``kwargs``: none of the study's own arguments, the integer and real arguments it knows
    of the right type and range, ``policy_kwargs.net_arch`` a list of layer widths (one-line ``ValueError``).
    """
    for key in OWN_ARGUMENTS:
        if key in value:
            raise ValueError(f"{where}.{key} is the study's own: it sets the env, the seed, the CPU and MlpPolicy")
    for key, (low, high) in INTEGER_ARGUMENTS.items():
        given = value.get(key, low)
        if isinstance(given, bool) or not isinstance(given, int) or not low <= given <= high:
            raise ValueError(f"{where}.{key}={given!r} must be an integer from {low} to {high:,}")
    for key, (lowest, highest, closed) in REAL_ARGUMENTS.items():
        if key not in value:
            continue
        given = value[key]
        number = isinstance(given, (int, float)) and not isinstance(given, bool) and math.isfinite(given)
        if not (number and (lowest <= given if closed else lowest < given) and given <= highest):
            bound = f"{'>=' if closed else '>'} {lowest:g}" + (f" and <= {highest:g}" if math.isfinite(highest) else "")
            raise ValueError(f"{where}.{key}={given!r} must be a finite number {bound}")
    policy = value.get("policy_kwargs", {})
    if not isinstance(policy, dict):
        raise ValueError(f"{where}.policy_kwargs={policy!r} must be a mapping of MlpPolicy's arguments")
    layers = policy.get("net_arch", [])
    if not (isinstance(layers, list) and len(layers) <= MAX_LAYERS
            and all(isinstance(w, int) and not isinstance(w, bool) and 1 <= w <= MAX_LAYER_WIDTH for w in layers)):
        raise ValueError(f"{where}.policy_kwargs.net_arch={layers!r} must be a list of at most {MAX_LAYERS} layer "
                         f"widths from 1 to {MAX_LAYER_WIDTH}")
    return value


class DeepTask(BaseModel):
    """One MiniGrid task: its env id, its budget and the settings tuned for it."""

    model_config = ConfigDict(extra="forbid")
    id: str = Field(pattern=r"^MiniGrid-[A-Za-z0-9-]+-v\d+$", description="the MiniGrid env id, e.g. MiniGrid-Empty-8x8-v0")
    budget: int = Field(gt=0, le=100_000_000, description="env steps per run (a multiple of eval_every)")
    learning_rate: float | None = Field(default=None, gt=0, le=1, description="the tuned learning rate (every agent's)")
    exploration_fraction: float | None = Field(
        default=None, gt=0, le=1, description="the tuned share of training over which ε falls (agents with epsilon: tuned)"
    )
    count_bonus: float | None = Field(
        default=None, gt=0, le=10, description="the tuned scale β of the count bonus β / sqrt(visits of the cell)"
    )


class DeepAgent(BaseModel):
    """One agent: an algorithm of the registry and its own arguments on top of the study's ``network``."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(pattern=NAME_PATTERN, description="the agent's name (letters, digits, _ . + -)")
    algo: str = Field(description="DQN or a DQN subclass of the registry: AffectDQN, EzGreedyDQN, SpeedEpsilonGreedyDQN, "
                      "ReplayedEpsilonDQN")  # fmt: skip
    kwargs: dict[str, Any] = Field(default_factory=dict, description="the algorithm's arguments beyond network")
    epsilon: Literal["tuned"] | None = Field(
        default=None, description="tuned: the task's exploration_fraction for SB3's linear ε schedule"
    )
    count_bonus: Annotated[float, Field(gt=0, le=10)] | Literal["tuned"] | None = Field(
        default=None, description="a count bonus β / sqrt(visits) added to the training reward: β, or tuned (the task's)"
    )
    replays: str | None = Field(
        default=None,
        description="an earlier agent whose logged share of random decisions, averaged over its seeds, becomes this "
        "agent's ε, part by part (algo ReplayedEpsilonDQN)",
    )

    @field_validator("algo")
    @classmethod
    def _algo(cls, value: str) -> str:
        deep = [name for name in AGENTS if name.endswith("DQN")]
        if value not in deep:
            raise ValueError(f"algo={value!r} is not one of {', '.join(deep)}")
        return value

    @field_validator("kwargs")
    @classmethod
    def _kwargs(cls, value: dict[str, Any]) -> dict[str, Any]:
        return check_arguments("kwargs", value)


class DeepStudy(BaseModel):
    """A sweep file of the deep study (top-level keys)."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(pattern=NAME_PATTERN, description="the study's name")
    study: Literal["deep"] = Field(description="marks the file as the deep study: many seeds per agent and task together")
    env: Literal["compiled", "farama"] = Field(
        default="compiled", description="compiled: sb3_affect.minigrid_vec_env; farama: make_vec_env with FlatObsWrapper"
    )
    obs: Literal["flat", "view"] = Field(
        default="view", description="FlatObsWrapper's vector, or its first 147 entries (view: the 7x7x3 view flattened, "
        "minigrid_vec_env's name), for every agent"
    )
    n_envs: int = Field(default=4, ge=1, le=256, description="training envs per seed")
    seeds: list[StrictInt] = Field(
        min_length=1, max_length=10_000, description=f"one run per seed in every cell (distinct, 0 to {EVAL_SEED_OFFSET - 1})"
    )
    seeds_per_batch: int | None = Field(
        default=None, ge=1, le=10_000, description="seeds trained together in one batch (one worker process or one Ray "
        "task; the batches of a cell are merged in seed order); default: all the cell's seeds in one batch"
    )
    eval_every: int = Field(gt=0, description="env steps between two evaluations of each seed's greedy policy")
    eval_episodes: int = Field(gt=0, le=1000, description="evaluation episodes per seed and evaluation, one per env")
    network: dict[str, Any] = Field(default_factory=dict, description="DQN's arguments shared by every agent")
    tasks: dict[str, DeepTask] = Field(min_length=1, description="task name -> task")
    agents: list[DeepAgent] = Field(min_length=1, description="the agents, run on every task in this order")

    @property
    def logs(self) -> list[str]:
        """No SB3 logs: the study records its own curves (a sweep's ``logs``)."""
        return []

    def cells(self) -> list[Cell]:
        """
        The study as the launcher's cells, one per task and agent (tasks first, agents in the file's order): its base
        run config holds all a run's training and evaluation depends on (its run ids hash it), its seeds the study's.
        A ``replays`` agent's cell waits for the cell of the agent it replays on the same task (``launcher.plan_jobs``).
        """
        cells = []
        for task, spec in self.tasks.items():
            for agent in self.agents:
                base = {"sweep": self.name, "study": "deep", "agent": agent.name, "algo": agent.algo, "seed": None,
                        "labels": {"task": task}, "env_id": spec.id, "env": self.env, "obs": self.obs,
                        "n_envs": self.n_envs, "budget": spec.budget, "eval_every": self.eval_every,
                        "eval_episodes": self.eval_episodes, "algo_kwargs": agent_kwargs(self, task, agent),
                        "count_bonus": bonus_scale(self, task, agent), "replays": agent.replays}  # fmt: skip
                cells.append(Cell(base, list(self.seeds), self.seeds_per_batch or len(self.seeds)))
        return cells

    @field_validator("obs", mode="before")
    @classmethod
    def _obs(cls, value: Any) -> Any:
        if value == "image":
            raise ValueError("obs='image' is minigrid_vec_env's 7x7x3 image; the flat 147 entries of the agent's view are "
                             "obs: view (or flat: FlatObsWrapper's whole vector)")
        return value

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, value: list[int]) -> list[int]:
        twice = sorted({seed for seed in value if value.count(seed) > 1})
        if twice or min(value) < 0:
            raise ValueError(f"seeds must be distinct integers >= 0 (got {twice[0] if twice else min(value)!r})")
        if max(value) >= EVAL_SEED_OFFSET:
            raise ValueError(f"seeds: {max(value)} is too large; seeds go from 0 to {EVAL_SEED_OFFSET - 1} (the "
                             f"evaluation envs are seeded from {EVAL_SEED_OFFSET:,} on)")
        return value

    @field_validator("network")
    @classmethod
    def _network(cls, value: dict[str, Any]) -> dict[str, Any]:
        return check_arguments("network", value)

    @field_validator("tasks")
    @classmethod
    def _task_names(cls, value: dict[str, DeepTask]) -> dict[str, DeepTask]:
        for name in value:
            if not re.match(NAME_PATTERN, name):
                raise ValueError(f"task name {name!r} must be letters, digits, _ . + - (at most 64 characters)")
        return value

    @model_validator(mode="after")
    def _consistent(self) -> DeepStudy:
        for name, task in self.tasks.items():
            if self.env == "compiled" and task.id not in MINIGRID_TASKS:
                compiled = ", ".join(MINIGRID_TASKS)
                raise ValueError(f"tasks.{name}.id={task.id!r} is not compiled ({compiled}): give env: farama")
            if task.budget % self.eval_every:
                raise ValueError(f"tasks.{name}.budget={task.budget} is not a multiple of eval_every={self.eval_every}")
        names = [agent.name for agent in self.agents]
        for index, agent in enumerate(self.agents):
            if agent.name in names[:index]:
                raise ValueError(f"agents[{index}].name={agent.name!r} is given twice")
            if (agent.replays is None) != (agent.algo != "ReplayedEpsilonDQN"):
                raise ValueError(f"agents[{index}] ({agent.name}): replays=<earlier agent> goes with algo ReplayedEpsilonDQN")
            if agent.replays is not None and agent.replays not in names[:index]:
                earlier = ", ".join(names[:index])
                raise ValueError(f"agents[{index}].replays={agent.replays!r} is not an earlier agent ({earlier})")
            for field, wanted in (("exploration_fraction", agent.epsilon), ("count_bonus", agent.count_bonus)):
                missing = [task for task, spec in self.tasks.items() if wanted == TUNED and getattr(spec, field) is None]
                if missing:
                    raise ValueError(f"agents[{index}] ({agent.name}) takes the tuned {field}: tasks.{missing[0]} has none")
        return self


def agent_kwargs(study: DeepStudy, task: str, agent: DeepAgent) -> dict[str, Any]:
    """The agent's arguments on ``task``: the study's network, the task's tuned learning rate, then the agent's own."""
    spec = study.tasks[task]
    kwargs: dict[str, Any] = dict(study.network)
    if spec.learning_rate is not None:
        kwargs["learning_rate"] = spec.learning_rate
    if agent.epsilon == TUNED:
        kwargs["exploration_fraction"] = spec.exploration_fraction
    kwargs.update(agent.kwargs)
    return kwargs


def bonus_scale(study: DeepStudy, task: str, agent: DeepAgent) -> float | None:
    """The count bonus's scale of ``agent`` on ``task`` (None: no bonus)."""
    return study.tasks[task].count_bonus if agent.count_bonus == TUNED else agent.count_bonus  # type: ignore[return-value]
