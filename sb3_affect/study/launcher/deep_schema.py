"""
The deep study's sections of a sweep file (``schema.Sweep`` with a ``trainer``: its ``kind`` is ``deep``): DQN-family
agents on MiniGrid tasks, many seeds of one agent on one task trained together (the public trainer
``sb3_affect.train_many``), each seed's greedy policy evaluated on its own evaluation envs every ``evaluation.every``
env steps. The launcher (``launcher.run_sweep``) runs its ``cells`` as ``deep_batches.DeepBatch`` jobs::

    name: minigrid-dqn
    seeds: [0, 1, 2]            # one run per seed, in every cell
    trainer:
      vec_env: compiled
      seeds_per_batch: 2        # seeds trained together per worker or Ray task (default: all of a cell's)
      algo_kwargs: {buffer_size: 50000, learning_starts: 1000, policy_kwargs: {net_arch: [64, 64]}}  # every agent's
    evaluation: {every: 10000, episodes: 20}  # env steps between evaluations of the greedy policy, episodes of each
    tasks:
      Empty-8x8: {id: MiniGrid-Empty-8x8-v0, total_timesteps: 50000, tuned: {learning_rate: 0.001, exploration_fraction: 0.2}}
    agents:
      - {name: dqn-linear, algo: DQN, epsilon: tuned}
      - {name: affective, algo: AffectDQN, kwargs: {position: minigrid}}
      - {name: matched-randomness, algo: ReplayedEpsilonDQN, replays: affective}
      - {name: count-bonus, algo: DQN, epsilon: tuned, count_bonus: tuned}

This module holds those sections and the checks of DQN's arguments; ``schema`` the checks of a deep study as a whole.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

#: Fewest evaluation episodes the study's primary metric is read from (a smaller file is labelled a smoke size).
STUDY_EVAL_EPISODES = 20
#: The settings a task holds for every agent that asks for them (``epsilon: tuned``, ``count_bonus: tuned``).
TUNED = "tuned"
#: The evaluation envs of seed s are seeded ``EVAL_SEED_OFFSET + s * eval_episodes + i``: apart from every training env
#: (seeded ``s + i`` for ``i < n_envs``) for seeds below the offset, which is the largest seed a study takes.
EVAL_SEED_OFFSET = 1_000_000
#: A deep study's task ids, its most seeds and env steps per run.
MINIGRID_ID, MAX_DEEP_SEEDS, MAX_TOTAL_TIMESTEPS = r"^MiniGrid-[A-Za-z0-9-]+-v\d+$", 10_000, 100_000_000
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
    ``trainer.algo_kwargs`` or an agent's ``kwargs``: none of the study's own arguments, the integer and real arguments
    it knows of the right type and range, ``policy_kwargs.net_arch`` a list of layer widths (one-line ``ValueError``).
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


class TunedSpec(BaseModel):
    """A task's ``tuned`` settings: what the agents that ask for them take on that task."""

    model_config = ConfigDict(extra="forbid")
    learning_rate: float | None = Field(default=None, gt=0, le=1, description="the tuned learning rate (every agent's)")
    exploration_fraction: float | None = Field(
        default=None, gt=0, le=1, description="the tuned share of training over which ε falls (agents with epsilon: tuned)"
    )
    count_bonus: float | None = Field(
        default=None, gt=0, le=10, description="the tuned scale β of the count bonus β / sqrt(visits of the cell)"
    )


class TrainerSpec(BaseModel):
    """The ``trainer`` section (a deep study): how the seeds of one agent on one task are trained together."""

    model_config = ConfigDict(extra="forbid")
    vec_env: Literal["compiled", "farama"] = Field(
        default="compiled", description="compiled: sb3_affect.minigrid_vec_env; farama: make_vec_env with FlatObsWrapper"
    )
    obs: Literal["flat", "view"] = Field(
        default="view", description="FlatObsWrapper's vector, or its first 147 entries (view: the 7x7x3 view flattened, "
        "minigrid_vec_env's name), for every agent"
    )
    n_envs: int = Field(default=4, ge=1, le=256, description="training envs per seed")
    seeds_per_batch: int | None = Field(
        default=None, ge=1, le=10_000, description="seeds trained together in one batch (one worker process or one Ray "
        "task; the batches of a cell are merged in seed order); default: all the cell's seeds in one batch"
    )
    algo_kwargs: dict[str, Any] = Field(default_factory=dict, description="DQN's arguments shared by every agent")

    @field_validator("obs", mode="before")
    @classmethod
    def _obs(cls, value: Any) -> Any:
        if value == "image":
            raise ValueError("obs='image' is minigrid_vec_env's 7x7x3 image; the flat 147 entries of the agent's view are "
                             "obs: view (or flat: FlatObsWrapper's whole vector)")
        return value

    @field_validator("algo_kwargs")
    @classmethod
    def _algo_kwargs(cls, value: dict[str, Any]) -> dict[str, Any]:
        return check_arguments("algo_kwargs", value)


class EvaluationSpec(BaseModel):
    """The ``evaluation`` section (a deep study): how often and how long each seed's greedy policy is evaluated."""

    model_config = ConfigDict(extra="forbid")
    every: int = Field(gt=0, description="env steps between two evaluations of each seed's greedy policy")
    episodes: int = Field(gt=0, le=1000, description="evaluation episodes per seed and evaluation, one per env")
