"""
A model file does not choose where ``learn`` writes: ``tensorboard_log`` and the emotion callback's
``episode_log_path`` come from the caller of ``load`` (tabular and deep agents, the safe loader and SB3's), never from
the file. Real models, real files: one naming an existing ``notes.txt`` and a folder that does not exist.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest
import torch as th

from sb3_affect import AffectDQN, AffectQ, QLearning
from sb3_affect.envs import GRID_PURSUIT_ID


def _deep_file(tmp_path: Path) -> Path:
    """An AffectDQN file whose emotion callback appends to ``notes.txt`` and whose TensorBoard folder is missing."""
    th.set_num_threads(1)
    model = AffectDQN("MlpPolicy", "FrozenLake-v1", learning_starts=16, batch_size=16, seed=0,
                      policy_kwargs={"net_arch": [16]})
    assert model.emotion_callback is not None
    model.emotion_callback.episode_log_path = str(tmp_path / "notes.txt")
    model.tensorboard_log = str(tmp_path / "missing" / "tb")
    model.save(tmp_path / "deep.zip")
    (tmp_path / "notes.txt").write_text("my notes\n")
    return tmp_path / "deep.zip"


@pytest.mark.parametrize("safe", [True, False])
def test_a_deep_model_file_names_no_file_learn_appends_to(safe: bool, tmp_path: Path) -> None:
    path = _deep_file(tmp_path)
    model = AffectDQN.load(path, env=gym.make("FrozenLake-v1"), safe=safe)
    assert model.tensorboard_log is None and model.emotion_callback.episode_log_path is None
    model.learn(300)  # FrozenLake's episodes end within a few steps: the callback writes its rows where it is told
    assert (tmp_path / "notes.txt").read_text() == "my notes\n" and not (tmp_path / "missing").exists()
    mine = tmp_path / "mine.csv"
    model = AffectDQN.load(path, env=gym.make("FrozenLake-v1"), safe=safe, episode_log_path=mine,
                           tensorboard_log=str(tmp_path / "tb"))
    assert model.tensorboard_log == str(tmp_path / "tb") and model.emotion_callback.episode_log_path == mine
    model.tensorboard_log = None  # (the caller's folder is taken; no TensorBoard needed here)
    model.learn(300)
    assert len(mine.read_text().splitlines()) > 2 and (tmp_path / "notes.txt").read_text() == "my notes\n"


@pytest.mark.parametrize("agent", [QLearning, AffectQ])
@pytest.mark.parametrize("safe", [True, False])
def test_a_tabular_model_file_names_no_folder_learn_creates(agent: type, safe: bool, tmp_path: Path) -> None:
    model = agent("Grid", gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2)), seed=0)
    model.tensorboard_log = str(tmp_path / "missing" / "tb")
    model.save(tmp_path / "m.zip")
    loaded = agent.load(tmp_path / "m.zip", env=gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2)), safe=safe)
    assert loaded.tensorboard_log is None
    loaded.learn(200)
    assert not (tmp_path / "missing").exists()
    given = agent.load(tmp_path / "m.zip", safe=safe, tensorboard_log=str(tmp_path / "tb"))
    assert given.tensorboard_log == str(tmp_path / "tb")
