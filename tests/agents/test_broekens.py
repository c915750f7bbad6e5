"""BroekensCallback: what follows from joy/distress = TD error and hope/fear = V(s), on real agents and envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3 import A2C, DQN, PPO
from stable_baselines3.common.callbacks import CallbackList, StopTrainingOnMaxEpisodes
from stable_baselines3.common.logger import configure

from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.broekens import BROEKENS_COLUMNS, BroekensCallback


def observe(model, episodes: int, callback: BroekensCallback | None = None, **learn_kwargs) -> pd.DataFrame:
    callback = callback or BroekensCallback()
    model.learn(10**7, callback=CallbackList([callback, StopTrainingOnMaxEpisodes(episodes)]), **learn_kwargs)
    return callback.episode_log


def grid(**kwargs) -> gym.Env:
    return gym.make("sb3_affect/GridPursuit-v0", **{"size": 5, "goal": (2, 2), **kwargs})


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
def test_joy_appears_before_hope_as_values_propagate_back_from_the_goal(cls: type) -> None:
    log = observe(cls("Grid", grid(), seed=0), 30)
    assert tuple(log.columns) == BROEKENS_COLUMNS and len(log) == 30
    # Episode 1: every value is 0 until the goal's reward arrives: joy at the goal, nothing to hope for yet.
    assert log.joy.iloc[0] > 0 and log.hope.iloc[0] == 0 and log.goal_joy.iloc[0] == 100.0
    first_joy, first_hope = (log.joy > 0).idxmax(), (log.hope > 0).idxmax()
    assert log.hope.iloc[-1] > 0 and first_joy < first_hope
    assert (log.fear == 0).all()  # no negative reward anywhere: no value below 0, nothing to fear
    assert (log[["joy", "distress", "hope", "fear"]] >= 0).all().all()


def test_joy_at_the_goal_fades_with_repetition_in_a_deterministic_task() -> None:
    log = observe(QLearning("Grid", grid(), seed=0, exploration_rate=0.0, learning_rate=0.5), 30)
    goal_joy = log.goal_joy.to_numpy()
    assert goal_joy[0] == 100.0
    assert np.all(np.diff(goal_joy[:12]) < 0) and goal_joy[-1] < 0.01  # habituation: 100, 50, 25, ...


def test_fear_learned_from_a_punishment_fades_once_it_is_removed() -> None:
    far = {"size": 7, "goal": (6, 6)}
    model = QLearning("Grid", grid(step_reward=-30.0, **far), seed=0, exploration_rate=0.1, learning_rate=0.2)
    callback = BroekensCallback()
    observe(model, 100, callback)
    model.set_env(grid(**far))  # the punishment is removed
    fear = observe(model, 100, callback, reset_num_timesteps=False).fear.to_numpy()
    learned, just_after, later, last = fear[80:100].mean(), fear[100:110].mean(), fear[110:130].mean(), fear[180:].mean()
    assert learned > 20  # the punished task: values far from the goal are negative
    assert learned > just_after > later > last and last < 0.05 * learned  # extinction


def test_a_noisier_task_keeps_joy_and_distress_larger() -> None:
    def surprise(prey: str, seed: int) -> float:
        env = gym.make("sb3_affect/MovingPursuit-v0", size=4, start=(0, 0), prey_start=(2, 2), prey=prey)
        log = observe(QLearning("Grid", env, seed=seed, exploration_rate=0.1), 300)
        return float((log.joy + log.distress).iloc[-100:].mean())

    for seed in (0, 1):
        assert surprise("random", seed) > 3 * surprise("static", seed)  # a random-walking prey vs a still one


def test_observes_sb3_dqn_ppo_and_a2c_and_logs_affect_keys(tmp_path) -> None:
    th.set_num_threads(1)
    env = grid(max_episode_steps=40)
    models = [
        DQN("MlpPolicy", env, learning_starts=50, seed=0, policy_kwargs={"net_arch": [16]}),
        PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=1, seed=0, policy_kwargs={"net_arch": [16]}),
        A2C("MlpPolicy", env, n_steps=8, seed=0, policy_kwargs={"net_arch": [16]}),
    ]
    for model in models:
        model.set_logger(configure(str(tmp_path / type(model).__name__), ["csv"]))
        log = observe(model, 6, log_interval=1)
        assert len(log) == 6 and log.steps.sum() <= model.num_timesteps
        assert ((log.joy > 0) | (log.distress > 0)).all()  # an untrained network's values are never exact
        assert log.goal_joy.isna().tolist() == (log.reward == 0).tolist()  # cut off by the time limit: no goal joy
        header = (tmp_path / type(model).__name__ / "progress.csv").read_text().splitlines()[0]
        assert {"affect/broekens/joy", "affect/broekens/distress", "affect/broekens/hope", "affect/broekens/fear"} <= set(
            header.split(",")
        )


def test_algorithms_without_values_and_bad_gamma_are_refused() -> None:
    from sb3_contrib import ARS

    with pytest.raises(ValueError, match="gamma=2"):
        BroekensCallback(gamma=2)
    with pytest.raises(TypeError, match="value_fn must be a callable"):
        BroekensCallback(value_fn=3.0)  # type: ignore[arg-type]
    pendulum = gym.make("Pendulum-v1")
    with pytest.raises(TypeError, match=r"needs a value-based algorithm.*ARS has no Q-table.*pass value_fn="):
        ARS("LinearPolicy", pendulum, n_delta=2, seed=0).learn(10, callback=BroekensCallback())


def constant_value(model, obs) -> float:
    """V = 10 everywhere: the TD error of a step is then fixed by its rewards alone."""
    return 10.0


def _episodes(model, callback: BroekensCallback, episodes: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    log = observe(model, episodes, callback)
    return log, model.episode_log


def test_a_wait_fires_no_emotion_and_is_not_a_step() -> None:
    from sb3_affect.agents.baselines import SpeedEpsilonGreedy

    model = SpeedEpsilonGreedy("Grid", grid(step_reward=-1.0), seed=0, gamma=0.9, speeds=(0, 1), engine="python")
    log, agent = _episodes(model, BroekensCallback(value_fn=constant_value), 10)
    assert agent.waits.sum() > 0
    assert (log.steps == agent.decisions - agent.waits).all()  # waits are not steps
    ended = ~agent.truncated
    moves = log.steps[ended]
    # every move but the last: delta = -1 + 0.9 * 10 - 10 = -2; the last enters the goal: 100 - 10 = 90
    assert np.allclose((log.distress * log.steps)[ended], 2.0 * (moves - 1))
    assert np.allclose(log.goal_joy[ended], 90.0) and np.allclose((log.joy * log.steps)[ended], 90.0)
    assert np.allclose((log.hope * log.steps)[ended], 10.0 * (moves - 1))  # a terminal state anticipates nothing


@pytest.mark.parametrize(("multi_cell", "move_delta", "goal_deltas"), [
    ("steps", -1 - 0.9 * 1 + 0.81 * 10 - 10, (100 - 10, -1 + 0.9 * 100 - 10)),  # discounted per cell, as the updates
    ("jump", -2 + 0.9 * 10 - 10, (100 - 10, -1 + 100 - 10)),  # one update for the whole move: discounted once
])
def test_a_two_cell_move_is_discounted_as_the_agent_discounts(multi_cell: str, move_delta: float,
                                                               goal_deltas: tuple[float, float]) -> None:
    from sb3_affect.agents.baselines import SpeedEpsilonGreedy

    model = SpeedEpsilonGreedy("Grid", grid(step_reward=-1.0), seed=0, gamma=0.9, speeds=(2,), multi_cell=multi_cell,
                               engine="python")
    log, agent = _episodes(model, BroekensCallback(value_fn=constant_value), 10)
    ended = ~agent.truncated
    assert ended.any() and (agent.cells > agent.decisions).all()
    steps = log.steps[ended]
    assert np.allclose((log.distress * log.steps)[ended], -move_delta * (steps - 1))
    goal_joy = log.goal_joy[ended].to_numpy()
    assert all(min(abs(g - d) for d in goal_deltas) < 1e-9 for g in goal_joy)


def test_position_gives_the_mean_emotions_per_cell_on_a_vec_env_and_a_tabular_agent() -> None:
    from stable_baselines3.common.env_util import make_vec_env

    th.set_num_threads(1)
    callback = BroekensCallback(position="discrete")
    env = make_vec_env("FrozenLake-v1", n_envs=4, seed=0)
    DQN("MlpPolicy", env, learning_starts=16, batch_size=16, seed=0, policy_kwargs={"net_arch": [8]}).learn(
        400, callback=callback
    )
    cells = callback.cell_log
    assert set(cells.cell) <= set(range(15)) and 0 in set(cells.cell)  # 15, the goal, is never left
    assert cells.steps.sum() == 400
    assert np.isfinite(cells[["joy", "distress", "hope", "fear"]].to_numpy()).all()
    tabular = BroekensCallback(position="discrete")
    model = QLearning("Grid", grid(), seed=0).learn(300, callback=tabular)
    assert tabular.cell_log.steps.sum() == 300 and tabular.cell_log.cell.max() < model.observation_space.n
    with pytest.raises(ValueError, match=r"position='maze' is not supported"):
        BroekensCallback(position="maze")


class Counting:
    """Counts the calls of a module's forward (a forward hook): the passes an algorithm and its callbacks make."""

    def __init__(self, module: th.nn.Module) -> None:
        self.calls = 0
        module.register_forward_hook(self.hook)

    def hook(self, *args) -> None:
        self.calls += 1


def critic_of(model, obs) -> float:
    """A value_fn: the value head of the model on one observation (a pass per env and step, settled at once)."""
    with th.no_grad():
        return float(model.policy.predict_values(model.policy.obs_to_tensor(obs)[0]).reshape(-1)[0])


def q_of(model, obs) -> float:
    with th.no_grad():
        return float(model.q_net(model.policy.obs_to_tensor(obs)[0]).max())


def ppo(env_id: str = "CartPole-v1", n_envs: int = 1) -> PPO:
    from stable_baselines3.common.env_util import make_vec_env

    env = make_vec_env(env_id, n_envs=n_envs, seed=0, env_kwargs={"max_episode_steps": 15})
    return PPO("MlpPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0, policy_kwargs={"net_arch": [16]})


def test_on_policy_values_come_from_the_algorithm_with_the_same_emotions() -> None:
    """PPO values each observation before it acts: the callback makes no pass of its own after the first."""
    th.set_num_threads(1)
    passes = []
    callback = BroekensCallback()
    for observer in (None, callback):  # each model built right before it learns: the same seeded run
        model = ppo(n_envs=2)
        passes.append(Counting(model.policy.value_net))
        model.learn(640, callback=observer)
    log = callback.episode_log
    truncated = int(log.goal_joy.isna().sum())
    assert len(log) > 10 and truncated > 0  # episodes cut off by the time limit among them
    # its own passes: the first observations, and the last observation of each truncated episode (as PPO's own)
    assert passes[1].calls - passes[0].calls == 1 + truncated
    # the same emotions as a value_fn that values every observation itself, at the step
    reference = BroekensCallback(value_fn=critic_of)
    ppo(n_envs=2).learn(640, callback=reference)
    expected = reference.episode_log
    pd.testing.assert_frame_equal(log, expected, rtol=1e-5)


@pytest.mark.parametrize("activation", [th.nn.ELU, th.nn.ReLU])
def test_a_small_discrete_space_is_valued_once_per_update_with_the_same_emotions(activation: type) -> None:
    """ELU is not mirrored in numpy: torch passes, one per update at most; ReLU (SB3's default): no torch pass."""
    th.set_num_threads(1)

    def dqn() -> DQN:
        kwargs = {"net_arch": [16], "activation_fn": activation}
        return DQN("MlpPolicy", gym.make("FrozenLake-v1"), learning_starts=50, seed=0, policy_kwargs=kwargs)

    passes = []
    callback = BroekensCallback()
    for observer in (None, callback):
        model = dqn()
        passes.append(Counting(model.q_net))
        model.learn(600, callback=observer)
    extra = passes[1].calls - passes[0].calls
    if activation is th.nn.ELU:
        assert 0 < extra <= model._n_updates + 1  # a pass per update at most, not per step
    else:
        assert extra == 0
    reference = BroekensCallback(value_fn=q_of)
    dqn().learn(600, callback=reference)
    assert len(callback.episode_log) > 10
    pd.testing.assert_frame_equal(callback.episode_log, reference.episode_log, rtol=1e-5)
