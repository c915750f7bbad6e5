"""
``train_many(PPO, ...)`` against SB3's own PPO: the stacked update equals ``PPO.train`` on the same rollout, and a
lockstep run of each seed is its own ``PPO.learn`` (the same actions, rollout, weights and counts) while floating-point
order allows.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from torch import nn

from sb3_affect import train_many
from sb3_affect.engine.seed_envs import seed_vec_env
from sb3_affect.engine.stacked_ppo import StackedActorCritic, StackedRollout

pytest.importorskip("minigrid")

ENV_ID = "MiniGrid-Empty-5x5-v0"
SETTINGS: dict[str, Any] = dict(n_steps=64, batch_size=32, n_epochs=3, learning_rate=3e-4)


@pytest.fixture(autouse=True)
def _one_thread() -> object:
    before = th.get_num_threads()
    th.set_num_threads(1)
    yield
    th.set_num_threads(before)


def _max_difference(ours: PPO, theirs: PPO) -> float:
    return max((p - q).abs().max().item() for p, q in zip(ours.policy.parameters(), theirs.policy.parameters()))


@pytest.mark.parametrize("flushing", [False, True])
@pytest.mark.parametrize("activation", [nn.Tanh, nn.ReLU, nn.ELU])
def test_update_equals_ppo_train_on_the_same_rollout(activation: type[nn.Module], flushing: bool) -> None:
    """Three seeds, two envs each, one rollout of 64 steps: the stacked update (3 epochs of 4 minibatches: the clipped
    surrogate, value and entropy terms, the backward pass written out for Tanh and ReLU and by autograd for ELU,
    clipping, Adam with denormals flushed, see ``stacked_adam``) and SB3's ``PPO.train`` on the same rollout and
    permutations give weights within 1e-5 (measured: at most 3.7e-8) and the same logged losses; the caller's setting
    of ``torch.set_flush_denormal`` is what it was, either way."""
    before = th.tensor(2.0**-127).item() == 0.0
    th.set_flush_denormal(flushing)
    try:
        _update_equals_ppo_train(activation)
        assert (th.tensor(2.0**-127).item() == 0.0) == flushing
    finally:
        th.set_flush_denormal(before)


def _update_equals_ppo_train(activation: type[nn.Module]) -> None:
    settings = {**SETTINGS, "ent_coef": 0.01, "clip_range_vf": 0.2, "policy_kwargs": {"activation_fn": activation}}
    models = [PPO("MlpPolicy", seed_vec_env(ENV_ID, 2, seed, "view"), seed=seed, device="cpu", **settings)
              for seed in range(3)]
    copies = [PPO("MlpPolicy", seed_vec_env(ENV_ID, 2, seed, "view"), seed=seed, device="cpu", **settings)
              for seed in range(3)]
    rollout = StackedRollout(3, 64, 2, models[0].observation_space.shape)
    for index, model in enumerate(models):
        model.set_logger(configure(None, []))
        _, callback = model._setup_learn(10_000, None)
        model.collect_rollouts(model.env, callback, model.rollout_buffer, n_rollout_steps=64)
        for name in ("observations", "rewards", "episode_starts", "values", "log_probs", "advantages", "returns"):
            getattr(rollout, name)[index] = getattr(model.rollout_buffer, name).reshape(getattr(rollout, name)[index].shape)
        rollout.actions[index] = model.rollout_buffer.actions.reshape(64, 2)
    stack = StackedActorCritic(copies)
    assert stack.written == (activation is not nn.ELU)
    rngs = [np.random.RandomState(100 + index) for index in range(3)]
    progress = th.ones(3)
    logs = stack.update(rollout, rngs, {"clip_range": 0.2 * progress, "clip_range_vf": 0.2 * progress,
                                        "ent_coef": 0.01 * progress, "vf_coef": 0.5 * progress,
                                        "max_grad_norm": 0.5 * progress}, 3, 32, True)
    for index, model in enumerate(models):
        np.random.seed(100 + index)
        model.train()
    stack.write_back(copies)
    for index, (ours, theirs) in enumerate(zip(copies, models)):
        assert _max_difference(ours, theirs) < 1e-5
        values = theirs.logger.name_to_value
        for key in ("policy_gradient_loss", "value_loss", "entropy_loss", "approx_kl", "clip_fraction"):
            assert logs[key][index] == pytest.approx(values[f"train/{key}"], rel=1e-4, abs=1e-7), key
        state, reference = ours.policy.optimizer.state_dict()["state"], theirs.policy.optimizer.state_dict()["state"]
        for key in reference:
            np.testing.assert_allclose(state[key]["exp_avg"], reference[key]["exp_avg"], rtol=1e-4, atol=1e-8)
            assert float(state[key]["step"]) == float(reference[key]["step"]) == 12


def _sb3(seed: int, n_envs: int, total: int, callback: Any = None, **kwargs: Any) -> PPO:
    model = PPO("MlpPolicy", seed_vec_env(ENV_ID, n_envs, seed, "view"), seed=seed, device="cpu", **kwargs)
    return model.learn(total, callback=callback)


def _assert_same_run(ours: PPO, theirs: PPO) -> None:
    a, b = ours.rollout_buffer, theirs.rollout_buffer
    for name in ("observations", "actions", "rewards", "episode_starts"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in ("values", "log_probs", "advantages", "returns"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-4, atol=1e-5, err_msg=name)
    assert _max_difference(ours, theirs) < 1e-5
    assert (ours.num_timesteps, ours._n_updates) == (theirs.num_timesteps, theirs._n_updates)
    assert len(ours.ep_info_buffer) == len(theirs.ep_info_buffer) > 0
    episodes = [[(info["r"], info["l"]) for info in model.ep_info_buffer] for model in (ours, theirs)]
    assert episodes[0] == episodes[1]
    assert sorted(ours.logger.name_to_value) == sorted(theirs.logger.name_to_value)


def test_one_seed_one_env_is_ppo_learn() -> None:
    """One seed, one env, 20 rollouts of 64 steps (1,280 env steps): the same actions (each seed's torch generator as
    SB3's global one), the same last rollout and the weights within 1e-5."""
    (ours,) = train_many(PPO, ENV_ID, [3], 1, total_timesteps=1_280, obs="view", **SETTINGS)
    _assert_same_run(ours, _sb3(3, 1, 1_280, **SETTINGS))


def test_seeds_and_envs_are_their_own_learn() -> None:
    """Two seeds x two envs, and seed 1's callback stopping it at its 100th step: each is its own ``PPO.learn``."""

    class StopAt(BaseCallback):
        def _on_step(self) -> bool:
            return self.n_calls < 100

    ours = train_many("PPO", ENV_ID, [5, 1], 2, total_timesteps=1_024, obs="view",
                      callbacks=[None, StopAt()], per_seed={"gamma": [0.9, 0.99]}, **SETTINGS)
    _assert_same_run(ours[0], _sb3(5, 2, 1_024, gamma=0.9, **SETTINGS))
    theirs = _sb3(1, 2, 1_024, StopAt(), gamma=0.99, **SETTINGS)
    assert ours[1].num_timesteps == theirs.num_timesteps == 200
    assert _max_difference(ours[1], theirs) < 1e-5
