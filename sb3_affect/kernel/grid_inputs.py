"""
What a batch of fresh runs feeds the kernel (``BatchInputs``): the agent (``KernelAgent``), its configuration, the
per-episode learning rate and exploration, and the env's transition table as arrays (``TableArrays``). Nothing here
imports torch or SB3.

``batch_inputs`` computes them from an agent's settings object (``sb3_affect.core.settings``: given, or the one a freshly
built model hands over). ``settings_inputs`` is the path without a model: from ``(algo, algo kwargs, env id, env
kwargs)``, it validates the kwargs with the agent's own checks and builds the env with ``gym.make``; anything it can
not vouch for (a class of your own, an argument that is not a setting, a schedule of the training progress, an env
without a transition table) is left to the model-based path (it returns None).

An env runs on the kernel when it describes its moves (``transition_table()``, see
``sb3_affect.envs.transition_table``) and is wrapped only in wrappers that leave a step as it is.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from sb3_affect.envs.transition_table import TransitionTable
from sb3_affect.kernel import grid_arrays
from sb3_affect.kernel.agent_settings import KernelAgent, kernel_agent, kernel_settings, settings_class


class TableArrays:
    """An env's transition table as the kernel's arrays (``trans``, ``tdist``) and scalars, and the predecessor width."""

    #: the last tables made, to share between envs built anew with the same table (each ``gym.make`` builds its own)
    _recent: list[tuple[TransitionTable, TableArrays]] = []

    @classmethod
    def of(cls, base: Any) -> TableArrays:
        """The arrays of ``base``'s table, kept on the env (its moves and rewards are fixed once it is built)."""
        table = base.transition_table()
        source, rewards, made = getattr(base, "_sb3_affect_kernel_table", (None, None, None))
        if made is None or source is not table.transitions or rewards != (table.goal_reward, table.step_reward):
            made = next((kept for known, kept in cls._recent if known == table), None)
            if made is None:
                made = cls(table)
                cls._recent = [(table, made), *cls._recent[:7]]
            base._sb3_affect_kernel_table = (table.transitions, (table.goal_reward, table.step_reward), made)
        return made

    def __init__(self, table: TransitionTable) -> None:
        self.trans = np.asarray(table.transitions, dtype=np.int64)
        self.tdist = np.asarray(table.distances, dtype=np.float64)
        self.start = int(table.start)
        self.goal = int(table.goal)
        self.shortest = int(table.shortest_path_length)
        self.goal_reward = float(table.goal_reward)
        self.step_reward = float(table.step_reward)
        self.width = int(table.width)
        n_states = self.trans.shape[0]
        # the most distinct cells with a move into one cell: the width of the known map's predecessor table
        # (each row's successors sorted; a successor counts once per row, and not when it is the row's own cell)
        successors = np.sort(self.trans, axis=1)
        new = np.ones(successors.shape, dtype=np.bool_)
        new[:, 1:] = successors[:, 1:] != successors[:, :-1]
        new &= successors != np.arange(n_states)[:, None]
        into = np.bincount(successors[new], minlength=n_states)
        self.max_pred = max(1, int(into.max())) if into.size else 1

    @property
    def env(self) -> grid_arrays.EnvTable:
        """The kernel's ``EnvTable``."""
        return grid_arrays.EnvTable(self.trans, self.tdist, self.max_pred)


def kernel_config(agent: KernelAgent, table: TableArrays, time_limit: int) -> grid_arrays.Config:
    """The kernel's ``Config`` for ``agent`` on an env of this table under a time limit of ``time_limit`` (0: none)."""
    return grid_arrays.Config(
        agent=agent.settings,
        goal=table.goal,
        start=table.start,
        shortest=table.shortest,
        time_limit=int(time_limit),
        goal_reward=table.goal_reward,
        step_reward=table.step_reward,
        n_actions=int(table.trans.shape[1]),
    )


# -- the env --------------------------------------------------------------------------------------------------------
def unwrap(env: Any) -> tuple[Any, list[Any]]:
    """The base env and the wrappers around it (outermost first)."""
    wrappers = []
    while isinstance(env, gym.Wrapper):
        wrappers.append(env)
        env = env.env
    return env, wrappers


#: Gymnasium's wrappers that ``gym.make`` adds and the kernel steps as they do, by where they are defined: a library may
#: rebind ``gymnasium.wrappers.TimeLimit`` to a subclass of its own (rl_zoo3 does, on import), which is not one of them.
STANDARD_WRAPPERS = frozenset(
    f"gymnasium.wrappers.common.{name}" for name in ("TimeLimit", "OrderEnforcing", "PassiveEnvChecker")
)


def env_reason(env: Any, also_allowed: tuple[type, ...] = ()) -> str | None:
    """
    Why the kernel can not step ``env`` (None: it can): its base env gives no transition table, or a wrapper other
    than Gymnasium's standard ones (and ``also_allowed``) may change what a step does.
    """
    base, wrappers = unwrap(env)
    describe = getattr(base, "transition_table", None)
    table = describe() if callable(describe) else None
    if isinstance(table, str):
        return table
    if not isinstance(table, TransitionTable):
        return f"the env {type(base).__name__} does not describe its moves as a transition table (transition_table())"
    return wrapper_reason(wrappers, also_allowed)


def wrapper_reason(wrappers: list[Any], also_allowed: tuple[type, ...] = ()) -> str | None:
    """Why the kernel can not step through ``wrappers`` (None: it can): one that is not standard nor ``also_allowed``."""
    for wrapper in wrappers:
        kind = type(wrapper)
        if f"{kind.__module__}.{kind.__qualname__}" not in STANDARD_WRAPPERS and kind not in also_allowed:
            return f"the env is wrapped in {kind.__name__}, which may change what a step does"
    return None


# -- a batch's inputs -------------------------------------------------------------------------------------------------
class BatchInputs(NamedTuple):
    """Everything ``kernel.grid_batch.simulate_batch`` needs besides the seeds: the same for every run of the batch."""

    agent: KernelAgent
    table: TableArrays
    config: grid_arrays.Config
    alpha: np.ndarray  # learning rate per episode
    p: np.ndarray  # exploration parameter per episode
    n_actions: int


def time_limit_of(wrappers: list[Any]) -> int:
    """The ``max_episode_steps`` of the outermost time limit among ``wrappers`` (0: none)."""
    limits = [int(w._max_episode_steps) for w in wrappers if hasattr(w, "_max_episode_steps")]
    return limits[0] if limits else 0


def batch_inputs(settings: Any, env: Any, episodes: int) -> BatchInputs:
    """
    The kernel inputs of fresh runs of an agent of these ``settings`` on ``env`` (a model's env, or the one
    ``gym.make`` builds); the agent and the env must be ones the kernel runs.
    """
    agent = kernel_agent(settings)
    assert isinstance(agent, KernelAgent), agent
    base, wrappers = unwrap(env)
    table = TableArrays.of(base)
    config = kernel_config(agent, table, time_limit_of(wrappers))
    parameters = settings.episode_parameters(0, episodes)
    assert parameters is not None
    alpha, p = parameters
    n_actions = int(env.action_space.n)
    return BatchInputs(agent, table, config, alpha, p, n_actions)


def settings_inputs(
    algo: str | type, kwargs: Mapping[str, Any], env_id: str, env_kwargs: Mapping[str, Any] | None, episodes: int
) -> BatchInputs | None:
    """
    The kernel inputs of fresh runs of ``algo`` with ``kwargs`` on ``gym.make(env_id, **env_kwargs)``, without a model;
    None where the model-based path must decide (see the module docstring). Bad kwargs raise the constructor's error.
    """
    settings_cls = settings_class(algo, kwargs)
    if settings_cls is None:
        return None
    env = gym.make(env_id, **dict(env_kwargs or {}))  # first, as for a model: a bad env is the first error
    try:
        settings = kernel_settings(settings_cls, kwargs)
        if settings is None:
            return None
        if env_reason(env) is not None or not isinstance(env.observation_space, gym.spaces.Discrete):
            return None
        if not isinstance(env.action_space, gym.spaces.Discrete):
            return None
        return batch_inputs(settings, env, episodes)
    finally:
        env.close()
