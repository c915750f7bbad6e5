"""
``train_many``'s inputs: each bad one refused in one line before any model is built or trained; a seed whose callback
stops training is kept as its own ``learn`` leaves it while the others run on; arguments given per seed are each seed's
own ``learn``'s; a run that does not fit the machine's memory is refused with its figure.
"""

from __future__ import annotations

import re
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback

from sb3_affect import train_many
from sb3_affect.engine.seed_envs import seed_vec_env

pytest.importorskip("minigrid")

ENV_ID = "MiniGrid-Empty-5x5-v0"
SETTINGS: dict[str, Any] = dict(learning_starts=100, buffer_size=5_000, target_update_interval=100, learning_rate=1e-3,
                                batch_size=16, exploration_fraction=0.5)


@pytest.fixture(autouse=True)
def _one_thread() -> object:
    before = th.get_num_threads()
    th.set_num_threads(1)
    yield
    th.set_num_threads(before)


class StopAt(BaseCallback):
    """Stops training at its ``stop``-th ``on_step`` (never with None); counts its calls."""

    def __init__(self, stop: int | None = None) -> None:
        super().__init__()
        self.stop, self.ends = stop, 0

    def _on_step(self) -> bool:
        return self.stop is None or self.n_calls < self.stop

    def _on_training_end(self) -> None:
        self.ends += 1


def _sb3(seed: int, n_envs: int, total_timesteps: int, callback: Any = None, **kwargs: Any) -> DQN:
    model = DQN("MlpPolicy", seed_vec_env(ENV_ID, n_envs, seed, "view"), seed=seed, device="cpu", **kwargs)
    return model.learn(total_timesteps, callback=callback)


def _assert_same_run(ours: DQN, theirs: DQN) -> None:
    a, b = ours.replay_buffer, theirs.replay_buffer
    assert (a.pos, a.full) == (b.pos, b.full) and a.pos > 0
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        np.testing.assert_array_equal(getattr(a, name)[: a.pos], getattr(b, name)[: b.pos], err_msg=name)
    pairs = [*zip(ours.q_net.parameters(), theirs.q_net.parameters()),
             *zip(ours.q_net_target.parameters(), theirs.q_net_target.parameters())]
    assert max((p - q).abs().max().item() for p, q in pairs) < 1e-5
    assert (ours.num_timesteps, ours._n_updates, ours._episode_num) == (theirs.num_timesteps, theirs._n_updates,
                                                                        theirs._episode_num)
    assert ours.exploration_rate == theirs.exploration_rate
    assert sorted(ours.logger.name_to_value) == sorted(theirs.logger.name_to_value)


shared = StopAt()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"train_freq": -1}, "train_freq=-1 must be an integer >= 1"),
    ({"train_freq": 0}, "train_freq=0 must be an integer >= 1"),
    ({"train_freq": (0, "step")}, "train_freq=(0, 'step') must be an integer >= 1"),
    ({"batch_size": 0}, "batch_size=0 must be an integer >= 1"),
    ({"gradient_steps": -2}, "gradient_steps=-2 must be an integer >= -1"),
    ({"env_wrapper": lambda env: None}, "env_wrapper returned NoneType, not a VecEnv"),
    ({"env_id": "CartPole-v1"}, "env_id='CartPole-v1' is not a MiniGrid env"),
    ({"env_id": None}, "env_id=None must be a MiniGrid env id"),
    ({"env_id": gym.make("CartPole-v1")}, "env_id=TimeLimit is an env: train_many builds each seed's envs itself"),
    ({"env_id": seed_vec_env(ENV_ID, 1, 0, "view")}, "env_id=DummyVecEnv is an env"),
    ({"callbacks": [5, 6]}, "callbacks[0]=5 is not a callback"),
    ({"callbacks": [shared, shared]}, "callbacks[1] holds the StopAt of callbacks[0]"),
    ({"callbacks": [[shared], [StopAt(), shared]]}, "callbacks[1] holds the StopAt of callbacks[0]"),
    ({"seeds": [0, 2**32]}, "seeds[]=4294967296 must be below 2**32"),
    ({"per_seed": {"gamma": [0.9]}}, "per_seed['gamma']=[0.9] must be a list of one value per seed (2)"),
    ({"per_seed": {"batch_size": [8, 16]}}, "per_seed['batch_size']: the seeds run in lockstep"),
    ({"per_seed": {"gamma": [0.9, 0.99]}, "gamma": 0.9}, "per_seed['gamma'] and gamma= are both given"),
    ({"per_seed": {"train_freq": [1, 2]}}, "per_seed['train_freq']: the seeds run in lockstep"),
])  # fmt: skip
def test_bad_inputs_refused_in_one_line_before_anything_runs(kwargs: dict[str, Any], message: str) -> None:
    arguments = {"env_id": ENV_ID, "seeds": [0, 1], "n_envs": 1, "total_timesteps": 200, **SETTINGS, **kwargs}
    with pytest.raises(ValueError, match=re.escape(message)) as raised:
        train_many("DQN", **arguments)
    assert "\n" not in str(raised.value)
    assert getattr(shared, "model", None) is None and shared.n_calls == 0  # no callback set up, nothing run


def test_a_run_too_large_for_the_memory_is_refused_with_its_figure() -> None:
    """64 seeds x a million flat rows (about 360 GB) is refused before any model is built, saying what it needs."""
    with pytest.raises(ValueError, match=r"^train_many needs about [\d,]+ MB for 64 seeds .* more than the [\d,]+ MB of "
                                         r"memory available") as raised:
        train_many("DQN", ENV_ID, list(range(64)), 4, total_timesteps=10**6, obs="flat", buffer_size=10**6)
    assert "\n" not in str(raised.value)
    need = int(re.search(r"about ([\d,]+) MB", str(raised.value)).group(1).replace(",", ""))  # type: ignore[union-attr]
    assert need > 64 * 10**6 * 2 * 2835 / 2**20  # at least the observations and next observations


def test_a_seed_whose_callback_stops_is_kept_as_its_learn_leaves_it() -> None:
    """Seed 1's callback stops it at its 300th VecEnv step: its model is SB3's ``learn`` with that callback (the buffer,
    weights, counts and logs); seed 0 runs on to the end as its own ``learn``."""
    callbacks = [StopAt(), StopAt(300)]
    ours = train_many("DQN", ENV_ID, [0, 1], 2, total_timesteps=1_200, obs="view", callbacks=callbacks, **SETTINGS)
    theirs_stopped = StopAt(300)
    _assert_same_run(ours[1], _sb3(1, 2, 1_200, theirs_stopped, **SETTINGS))
    assert ours[1].num_timesteps == 600 and callbacks[1].ends == theirs_stopped.ends == 1
    _assert_same_run(ours[0], _sb3(0, 2, 1_200, **SETTINGS))
    assert ours[0].num_timesteps == 1_200 and callbacks[0].ends == 1


def test_every_seed_stopped_ends_the_run() -> None:
    callbacks = [StopAt(40), StopAt(10)]
    ours = train_many("DQN", ENV_ID, [0, 1], 1, total_timesteps=1_000, obs="view", callbacks=callbacks, **SETTINGS)
    assert [m.num_timesteps for m in ours] == [40, 10]


def test_arguments_per_seed_are_each_seeds_own_learn() -> None:
    """Learning rate, gamma, tau, gradient clipping and exploration given per seed: each seed's run is SB3's ``learn``
    with its own values."""
    per_seed = {"learning_rate": [1e-3, 3e-4], "gamma": [0.9, 0.99], "tau": [1.0, 0.5], "max_grad_norm": [10.0, 0.5],
                "exploration_fraction": [0.5, 0.2]}
    settings = {key: value for key, value in SETTINGS.items() if key not in per_seed}
    ours = train_many("DQN", ENV_ID, [2, 3], 2, total_timesteps=1_000, obs="view", per_seed=per_seed, **settings)
    for index, seed in enumerate([2, 3]):
        own = {key: values[index] for key, values in per_seed.items()}
        theirs = _sb3(seed, 2, 1_000, **settings, **own)
        _assert_same_run(ours[index], theirs)
        assert ours[index].gamma == own["gamma"] and ours[index].policy.optimizer.param_groups[0]["lr"] == pytest.approx(
            own["learning_rate"])
