"""
Deep model files saved before the deep description was built on the tabular one (``tests/data/earlier_*.zip``, saved
by that code: an ``AffectDQN`` with a Tanh network on FrozenLake, an ``EzGreedyDQN`` on CartPole) still load safely,
with their settings, and saving them again writes the same plain description.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.buffers import ReplayBuffer

from sb3_affect import AffectDQN
from sb3_affect.agents.deep_controls import EzGreedyDQN
from sb3_affect.agents.serialization import PLAIN_MEMBER

DATA = Path(__file__).resolve().parents[1] / "data"


def plain(path: Path) -> dict:
    with zipfile.ZipFile(path) as archive:
        return json.loads(archive.read(PLAIN_MEMBER))


@pytest.mark.parametrize(("agent", "name"), [(AffectDQN, "affectdqn"), (EzGreedyDQN, "ezgreedydqn")])
def test_an_earlier_deep_file_loads_and_saves_the_same_description(agent: type, name: str, tmp_path: Path) -> None:
    th.set_num_threads(1)
    source = DATA / f"earlier_{name}.zip"
    model = agent.load(source)  # safe loading: nothing unpickled
    assert type(model) is agent
    assert model.replay_buffer_class is ReplayBuffer
    assert (model.train_freq.frequency, model.learning_starts, model.batch_size) == (4, 16, 16)
    assert model.policy_kwargs["net_arch"] == [8]
    action, _ = model.predict(np.asarray(model.observation_space.sample()), deterministic=True)
    assert model.action_space.contains(np.asarray(action).item())
    model.save(tmp_path / "again.zip")
    assert plain(tmp_path / "again.zip") == plain(source)


def test_the_earlier_files_keep_their_own_settings() -> None:
    dqn = AffectDQN.load(DATA / "earlier_affectdqn.zip")
    assert dqn.policy_kwargs["activation_fn"] is th.nn.Tanh and dqn.wait_action == 0
    assert EzGreedyDQN.load(DATA / "earlier_ezgreedydqn.zip").mu == 1.5
