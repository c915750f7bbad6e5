"""
The envs of many seeds stepped together: ``SeedEnvs`` holds one SB3 ``VecEnv`` of E envs per seed and steps them as
one ``(S, E)`` batch, and ``seed_vec_env`` builds a seed's VecEnv as SB3 users build it for MiniGrid:
``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)`` (``obs="flat"``), or its first 147 entries,
the agent's 7x7x3 view flattened (``obs="view"``, ``ImageVector``: ``minigrid_vec_env``'s names); ``compiled=True``
gives its compiled twin,
``minigrid_vec_env`` (the same layouts, observations, rewards and infos step for step), for the tasks it implements.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnv

from sb3_affect.agents.minigrid_vec_env import MiniGridBatch, MiniGridVecEnv, minigrid_vec_env
from sb3_affect.kernel.minigrid_view import VIEW_SIZE
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS


class ImageVector(gym.ObservationWrapper):
    """MiniGrid's ``FlatObsWrapper`` vector cut to its first 147 entries: the agent's 7x7x3 view, flattened."""

    def __init__(self, env: gym.Env) -> None:
        from minigrid.wrappers import FlatObsWrapper

        super().__init__(FlatObsWrapper(env))
        self.observation_space = spaces.Box(low=0, high=255, shape=(VIEW_SIZE,), dtype=np.uint8)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        return observation[:VIEW_SIZE]


#: The observations of ``seed_vec_env`` (and ``train_many``), named as ``minigrid_vec_env`` names them.
SEED_OBSERVATIONS = ("flat", "view")


def seed_vec_env(env_id: str, n_envs: int, seed: int, obs: str, compiled: bool = False) -> VecEnv:
    """
    ``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)``, or ``ImageVector`` for ``"view"``;
    ``compiled``: ``minigrid_vec_env`` where it implements ``env_id``.
    """
    check_observation(obs)
    if compiled and env_id in MINIGRID_TASKS:
        return minigrid_vec_env(env_id, n_envs, seed=seed, obs=obs)
    from minigrid.wrappers import FlatObsWrapper

    wrapper: Any = FlatObsWrapper if obs == "flat" else ImageVector
    return make_vec_env(env_id, n_envs, seed=seed, wrapper_class=wrapper)


def check_observation(obs: str) -> None:
    """A one-line ``ValueError`` unless ``obs`` is one of ``SEED_OBSERVATIONS`` (``"image"``: the 7x7x3 image, not here)."""
    if obs == "image":
        raise ValueError("obs='image' is minigrid_vec_env's 7x7x3 image; the flat 147 entries of the agent's view are "
                         "obs='view' (or 'flat': FlatObsWrapper's whole vector)")
    if obs not in SEED_OBSERVATIONS:
        raise ValueError(f"obs={obs!r} is not one of {', '.join(SEED_OBSERVATIONS)}")


class SeedEnvs:
    """
    S VecEnvs of E envs each, stepped as one batch: observations ``(S, E, ...)``, rewards and dones ``(S, E)`` and the
    infos as one list of E dicts per seed. Compiled MiniGrid VecEnvs of one task are stepped by one kernel call
    (``MiniGridBatch``); others one VecEnv after the other.
    """

    def __init__(self, envs: Sequence[VecEnv]) -> None:
        self.envs = list(envs)
        compiled = [env for env in self.envs if isinstance(env, MiniGridVecEnv)]
        one_task = len(compiled) == len(self.envs) and len({(env.env_id, env.obs) for env in compiled}) == 1
        self.batch = MiniGridBatch(compiled) if one_task else None

    def step(self, actions: np.ndarray, all_infos: bool = True
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[list[dict[str, Any]]]]:
        """
        Every seed's ``VecEnv.step`` with its row of ``actions`` ``(S, E)``; without ``all_infos``, the compiled
        batch's infos are those of the seeds where an episode ended only (the other seeds' lists empty).
        """
        if self.batch is not None:
            obs, rewards, dones = self.batch.step(np.ascontiguousarray(actions, dtype=np.int64).reshape(-1))
            shape = actions.shape
            return (obs.reshape(*shape, -1).copy(), rewards.reshape(shape).copy(), dones.reshape(shape).copy(),
                    self.batch.infos(ended_only=not all_infos))
        results = [env.step(a) for env, a in zip(self.envs, actions)]
        obs = np.stack([r[0] for r in results])  # type: ignore[misc]
        rewards = np.stack([r[1] for r in results])
        dones = np.stack([r[2] for r in results])
        return obs, rewards, dones, [r[3] for r in results]
