"""The numpy mirror of SB3's Q-network: the network's values, on its live parameters, and None where it does not apply."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3 import DQN

from sb3_affect.agents.numpy_values import q_values_fn


def torch_q(model: DQN, obs: np.ndarray) -> np.ndarray:
    with th.no_grad():
        return model.q_net(model.policy.obs_to_tensor(obs)[0]).numpy()


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [("FrozenLake-v1", {}), ("CartPole-v1", {}), ("CartPole-v1", {"activation_fn": th.nn.Tanh, "net_arch": [8, 8, 8]})],
)
def test_the_mirror_gives_the_networks_values_before_and_after_learning(env_id: str, kwargs: dict) -> None:
    model = DQN("MlpPolicy", gym.make(env_id), learning_starts=20, train_freq=1, seed=0, policy_kwargs=kwargs)
    mirror = q_values_fn(model)
    assert mirror is not None
    space = model.observation_space
    obs = np.arange(space.n) if isinstance(space, gym.spaces.Discrete) else np.stack([space.sample() for _ in range(7)])
    before = torch_q(model, obs)
    np.testing.assert_allclose(mirror(obs), before, rtol=1e-5, atol=1e-6)
    model.learn(200)  # the optimiser updates the parameters in place: the mirror follows without being remade
    after = torch_q(model, obs)
    assert not np.allclose(after, before)
    assert not mirror.stale()
    np.testing.assert_allclose(mirror(obs), after, rtol=1e-5, atol=1e-6)
    if isinstance(space, gym.spaces.Discrete):  # one state's value, without a batch: the row's maximum
        np.testing.assert_allclose([mirror.state_value(s) for s in obs.tolist()], after.max(axis=1), rtol=1e-5, atol=1e-6)


def test_a_replaced_parameter_makes_the_mirror_stale() -> None:
    model = DQN("MlpPolicy", gym.make("CartPole-v1"), seed=0)
    mirror = q_values_fn(model)
    assert mirror is not None and not mirror.stale()
    model.q_net.q_net[0].weight = th.nn.Parameter(model.q_net.q_net[0].weight.detach().clone())
    assert mirror.stale()
    mirror = q_values_fn(model)
    assert mirror is not None and not mirror.stale()
    model.q_net.q_net[-1].bias = th.nn.Parameter(model.q_net.q_net[-1].bias.detach().clone())
    assert mirror.stale()


def test_networks_it_does_not_mirror_get_none() -> None:
    elu = DQN("MlpPolicy", gym.make("CartPole-v1"), policy_kwargs={"activation_fn": th.nn.ELU})
    assert q_values_fn(elu) is None
    box_image = gym.spaces.Box(0, 255, (36, 36, 3), np.uint8)

    class Images(gym.Env):
        observation_space, action_space = box_image, gym.spaces.Discrete(2)

    assert q_values_fn(DQN("CnnPolicy", Images(), buffer_size=10)) is None
    assert q_values_fn(DQN("MlpPolicy", gym.make("CartPole-v1"), policy_kwargs={"net_arch": []})) is not None
    assert q_values_fn(object()) is None


def test_one_states_value_is_the_plain_row_pass_to_the_last_bit() -> None:
    """``state_value`` writes into rows it keeps; it equals ``row @ weight + bias`` and the activation done afresh on
    1-d rows (what it computed before), exactly, for every state, before and after learning, and on one Linear."""
    for kwargs in ({}, {"net_arch": [16, 8], "activation_fn": th.nn.Tanh}, {"net_arch": []}):
        model = DQN("MlpPolicy", "sb3_affect/GridPursuit-v0", learning_starts=20, train_freq=1, seed=0, policy_kwargs=kwargs)
        mirror = q_values_fn(model)
        assert mirror is not None
        for steps in (0, 200):
            model.learn(steps)
            layers = list(model.q_net.q_net)
            for state in range(225):
                row = layers[0].weight.detach().numpy().T[state] + layers[0].bias.detach().numpy()
                for layer in layers[1:]:
                    if isinstance(layer, th.nn.Linear):
                        row = row @ layer.weight.detach().numpy().T + layer.bias.detach().numpy()
                    else:
                        row = np.maximum(row, 0.0) if isinstance(layer, th.nn.ReLU) else np.tanh(row)
                assert mirror.state_value(state) == float(row.max())
