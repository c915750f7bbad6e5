"""
``CountBonus``: a count-based exploration bonus on a MiniGrid ``VecEnv``, MiniGrid's ``PositionBonus`` with a scale:
each env's training reward gets ``scale / sqrt(n)``, n the number of times that env's agent has stood in its cell
(counted over the whole training run, as ``PositionBonus`` counts). The cell is read after the step; on the step that
ends an episode the VecEnv has already reset the env, so that step gets no bonus (the goal's reward is the env's).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper


class CountBonus(VecEnvWrapper):
    """
    :param venv: the training VecEnv (its envs answer ``get_attr("agent_pos")``)
    :param scale: the bonus scale β > 0
    """

    def __init__(self, venv: VecEnv, scale: float) -> None:
        if not scale > 0:
            raise ValueError(f"count_bonus={scale!r} must be > 0")
        super().__init__(venv)
        self.scale = float(scale)
        self.counts = [Counter[tuple[int, int]]() for _ in range(venv.num_envs)]

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        rewards = np.asarray(rewards, dtype=np.float32).copy()
        for index, cell in enumerate(self.venv.get_attr("agent_pos")):
            if dones[index]:
                continue
            key = (int(cell[0]), int(cell[1]))
            self.counts[index][key] += 1
            rewards[index] += self.scale / np.sqrt(self.counts[index][key])
        return obs, rewards, dones, infos
