"""
What a batch of fresh runs feeds the kernel (``BatchInputs``): the agent (``AgentSpec``), its configuration arrays, the
per-episode learning rate and exploration, and the env's geometry. Nothing here imports torch or SB3.

``batch_inputs`` computes them from an *agent*, which is either a freshly built model or the agent's settings object
(``sb3_affect.settings``): both carry the same attributes under the same names, so both go through the same code.
``settings_inputs`` is the path without a model: from ``(algo, algo kwargs, env id, env kwargs)``, it validates the
kwargs with the agent's own checks and builds the env with ``gym.make``; anything it can not vouch for (a class of
your own, an argument that is not a setting, a schedule of the training progress, an env the kernel can not step) is
left to the model-based path (it returns None).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit

from sb3_affect.kernel import loop
from sb3_affect.kernel.agents import COMPENSATED_SUM, AgentSpec, agent_spec, episode_schedule
from sb3_affect.registry import known_settings


class Geometry:
    """The env's dynamics as arrays: ``trans[s, a]``, true distances, start, goal, rewards, predecessor capacity."""

    @classmethod
    def of(cls, base: Any) -> Geometry:
        """The geometry of ``base``, kept on the env (its moves and rewards are fixed once it is built)."""
        cached = getattr(base, "_sb3_affect_kernel_geometry", None)
        if cached is None or cached.source is not base.transitions or cached.rewards != (base.goal_reward, base.step_reward):
            cached = cls(base)
            base._sb3_affect_kernel_geometry = cached
        return cached

    def __init__(self, base: Any) -> None:
        self.source = base.transitions
        self.rewards = (base.goal_reward, base.step_reward)
        self.trans = np.asarray(base.transitions, dtype=np.int64)
        self.tdist = np.asarray(base.distances, dtype=np.float64)
        self.start = int(base.start_state)
        self.goal = int(base.goal_state)
        self.shortest = int(base.shortest_path_length)
        self.goal_reward = float(base.goal_reward)
        self.step_reward = float(base.step_reward)
        self.size = int(base.size)
        n_states = self.trans.shape[0]
        # the most distinct cells with a move into one cell: the width of the known map's predecessor table
        into = np.zeros(n_states, dtype=np.int64)
        for s in range(n_states):
            for t in set(self.trans[s].tolist()) - {s}:
                into[t] += 1
        self.max_pred = max(1, int(into.max()))


def config_arrays(agent: Any, spec: AgentSpec, geo: Geometry, time_limit: int) -> tuple[np.ndarray, np.ndarray]:
    """``icfg`` and ``fcfg`` of the kernel for ``agent`` (a model or its settings) on an env of geometry ``geo``."""
    icfg = np.zeros(loop.N_ICFG, dtype=np.int64)
    icfg[loop.C_KIND] = spec.kind
    icfg[loop.C_GOAL] = geo.goal
    icfg[loop.C_START] = geo.start
    icfg[loop.C_SHORTEST] = geo.shortest
    icfg[loop.C_TIME_LIMIT] = time_limit
    icfg[loop.C_CAP] = agent.max_episode_decisions
    icfg[loop.C_ACT_EPISODE] = spec.act_episode
    icfg[loop.C_UNITS_CELLS] = spec.units_cells
    icfg[loop.C_VALENCE] = spec.valence
    icfg[loop.C_TIE_FIRST] = getattr(agent, "tie_break", "random") == "first"
    icfg[loop.C_JUMP] = getattr(agent, "multi_cell", "steps") == "jump"
    icfg[loop.C_COMPENSATED_SUM] = COMPENSATED_SUM
    fcfg = np.zeros(loop.N_FCFG)
    fcfg[loop.F_GAMMA] = agent.gamma
    fcfg[loop.F_GOAL_REWARD] = geo.goal_reward
    fcfg[loop.F_STEP_REWARD] = geo.step_reward
    fcfg[loop.F_NORM_SCALE] = spec.norm_scale
    fcfg[loop.F_UCB_COEF] = spec.ucb_coef
    return icfg, fcfg


# -- the env --------------------------------------------------------------------------------------------------------
def unwrap(env: Any) -> tuple[Any, list[Any]]:
    """The base env and the wrappers around it (outermost first)."""
    wrappers = []
    while isinstance(env, gym.Wrapper):
        wrappers.append(env)
        env = env.env
    return env, wrappers


def _monitor_class() -> Any:
    """SB3's ``Monitor`` if SB3 is imported (otherwise no env can be wrapped in one: nothing to import)."""
    module = sys.modules.get("stable_baselines3.common.monitor")
    return None if module is None else module.Monitor


def env_reason(env: Any) -> str | None:
    """Why the kernel can not step ``env`` (None: it can)."""
    from sb3_affect.envs import GridPursuitEnv, MazePursuitEnv, MovingPursuitEnv

    base, wrappers = unwrap(env)
    if type(base) is MovingPursuitEnv:
        return (
            "MovingPursuit runs on its own kernel in simulate (sb3_affect.kernel.moving); learn steps it on the "
            "Python loop"
        )
    if type(base) not in (GridPursuitEnv, MazePursuitEnv):
        return f"the env {type(base).__name__} is not one of the package's own grid envs (GridPursuit, MazePursuit)"
    monitor = _monitor_class()
    known = (TimeLimit, OrderEnforcing, PassiveEnvChecker) + (() if monitor is None else (monitor,))
    for wrapper in wrappers:
        if type(wrapper) not in known:
            return f"the env is wrapped in {type(wrapper).__name__}, which may change what a step does"
        if monitor is not None and isinstance(wrapper, monitor) and wrapper.info_keywords:
            return "the Monitor records info_keywords, which the kernel does not produce"
    return None


# -- a batch's inputs -------------------------------------------------------------------------------------------------
class BatchInputs(NamedTuple):
    """Everything ``kernel.batch.simulate_batch`` needs besides the seeds: the same for every run of the batch."""

    spec: AgentSpec
    geometry: Geometry
    icfg: np.ndarray
    fcfg: np.ndarray
    alpha: np.ndarray  # learning rate per episode
    p: np.ndarray  # exploration parameter per episode
    q_init: float
    n_actions: int
    cap: int  # max_episode_decisions


def batch_inputs(agent: Any, env: Any, episodes: int) -> BatchInputs:
    """
    The kernel inputs of fresh runs of ``agent`` (a freshly built model, or the agent's settings) on ``env`` (the
    model's env, or the one ``gym.make`` builds); the agent and the env must be ones the kernel runs.
    """
    spec = agent_spec(agent)
    assert isinstance(spec, AgentSpec), spec
    base, wrappers = unwrap(env)
    geo = Geometry.of(base)
    limits = [int(w._max_episode_steps) for w in wrappers if hasattr(w, "_max_episode_steps")]
    icfg, fcfg = config_arrays(agent, spec, geo, limits[0] if limits else 0)
    schedule = episode_schedule(agent, spec.kind, 0, episodes)
    assert schedule is not None
    alpha, p = schedule
    n_actions = int(env.action_space.n)
    return BatchInputs(spec, geo, icfg, fcfg, alpha, p, float(agent.q_init), n_actions, int(agent.max_episode_decisions))


def settings_inputs(
    algo: str | type, kwargs: Mapping[str, Any], env_id: str, env_kwargs: Mapping[str, Any] | None, episodes: int
) -> BatchInputs | None:
    """
    The kernel inputs of fresh runs of ``algo`` with ``kwargs`` on ``gym.make(env_id, **env_kwargs)``, without a model;
    None where the model-based path must decide (see the module docstring). Bad kwargs raise the constructor's error.
    """
    settings_cls = known_settings(algo)
    if settings_cls is None or not set(kwargs) <= set(settings_cls.names()):
        return None
    env = gym.make(env_id, **dict(env_kwargs or {}))  # first, as for a model: a bad env is the first error
    try:
        settings = settings_cls(**kwargs)
        spec = agent_spec(settings)
        if isinstance(spec, str) or episode_schedule(settings, spec.kind, 0, 1) is None:
            return None
        if env_reason(env) is not None or not isinstance(env.observation_space, gym.spaces.Discrete):
            return None
        if not isinstance(env.action_space, gym.spaces.Discrete):
            return None
        return batch_inputs(settings, env, episodes)
    finally:
        env.close()
