"""
SB3-compatibility defects, one test each (each fails on the code before the fix): the tabular agents behave as SB3
algorithms and lose nothing a user sets.
"""

from __future__ import annotations

import inspect

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3.common.callbacks import BaseCallback, StopTrainingOnMaxEpisodes
from stable_baselines3.common.logger import Logger

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.baselines import SpeedEpsilonGreedy

GRID = "sb3_affect/GridPursuit-v0"


class InMemoryLogger(Logger):
    def __init__(self) -> None:
        super().__init__("", [])

    def dump(self, step: int = 0) -> None:
        pass


class Recorder(BaseCallback):
    """Keeps every decision's callback locals."""

    def __init__(self) -> None:
        super().__init__()
        self.steps: list[dict] = []

    def _on_step(self) -> bool:
        self.steps.append({key: self.locals[key] for key in ("new_obs", "rewards", "dones", "infos", "actions")})
        return True


# 1 ---------------------------------------------------------------------------------------------------------------------
def test_1_save_keeps_what_the_user_set_after_learn(tmp_path) -> None:
    model = QLearning("Grid", GRID, seed=0)
    model.learn(500)
    params = model.get_parameters()
    params["policy"]["q_table"] = th.full_like(params["policy"]["q_table"], 7.0)
    model.set_parameters(params)
    model.save(tmp_path / "a")
    assert (model.q_table == 7.0).all()
    assert (QLearning.load(tmp_path / "a").q_table == 7.0).all()

    with th.no_grad():
        model.policy.q_table[3, 1] = -5.0  # an edit of the policy's tensor
    model.save(tmp_path / "b")
    assert model.q_table[3, 1] == -5.0
    assert QLearning.load(tmp_path / "b").q_table[3, 1] == -5.0
    # learning continues from the edited table (one decision updates one or two entries)
    model.learn(1, reset_num_timesteps=False)
    assert (model.q_table == 7.0).sum() >= model.q_table.size - 3


# 2 ---------------------------------------------------------------------------------------------------------------------
def test_2_a_wait_reports_itself_and_each_terminal_info_reaches_callbacks_once() -> None:
    model = SpeedEpsilonGreedy("Grid", GRID, speeds=(0, 1), seed=0)
    recorder = Recorder()
    model.learn(100_000, callback=[recorder, StopTrainingOnMaxEpisodes(30)])
    log = model.episode_log
    infos = [step["infos"][0] for step in recorder.steps]
    assert sum("episode" in info for info in infos) == len(log) == 30  # Monitor's terminal info: once per episode
    waits = [info for info in infos if info.get("wait")]
    assert len(waits) == int(log["waits"].sum()) > 0
    assert all(float(step["rewards"][0]) == 0.0 for step in recorder.steps if step["infos"][0].get("wait"))
    assert sum("terminal_observation" in info for info in infos) == len(log)
    assert sum(bool(step["dones"][0]) for step in recorder.steps) == len(log)
    assert sum(float(step["rewards"][0]) for step in recorder.steps) == pytest.approx(float(log["reward"].sum()))


# 3 ---------------------------------------------------------------------------------------------------------------------
def test_3_callback_locals_are_numpy_arrays_as_in_sb3s_off_policy_algorithms() -> None:
    recorder = Recorder()
    AffectQ("Grid", GRID, seed=0).learn(50, callback=recorder)
    for step in recorder.steps:
        for key in ("new_obs", "rewards", "dones", "actions"):
            assert isinstance(step[key], np.ndarray), key
            assert step[key].shape == (1,), key
        assert step["rewards"].dtype == np.float32
        step["rewards"].mean()  # what a user's callback does


# 4 ---------------------------------------------------------------------------------------------------------------------
class SuccessFrozenLake(gym.Wrapper):
    """FrozenLake reporting ``is_success`` at each episode end (as robotics envs do)."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated or truncated:
            info = {**info, "is_success": bool(reward > 0)}
        return obs, reward, terminated, truncated, info


def test_4_is_success_feeds_rollout_success_rate() -> None:
    logger = InMemoryLogger()
    model = QLearning("Grid", SuccessFrozenLake(gym.make("FrozenLake-v1", is_slippery=False)), seed=0)
    model.set_logger(logger)
    model.learn(3000, log_interval=1)
    assert model.ep_success_buffer is not None and len(model.ep_success_buffer) > 0
    rewards = [ep["r"] for ep in model.ep_info_buffer]
    assert list(model.ep_success_buffer) == [r > 0 for r in rewards][-len(model.ep_success_buffer) :]
    assert logger.name_to_value["rollout/success_rate"] == pytest.approx(np.mean(model.ep_success_buffer))


# 5 ---------------------------------------------------------------------------------------------------------------------
def test_5_a_logger_without_output_formats_receives_the_records() -> None:
    logger = InMemoryLogger()
    model = AffectQ("Grid", GRID, seed=0)
    model.set_logger(logger)
    model.learn(3000, log_interval=1)
    assert logger.name_to_value["time/fps"] > 0
    assert logger.name_to_value["time/episodes"] == len(model.episode_log)
    assert "affect/joy" in logger.name_to_value
    assert "affect/equivalent_epsilon" in logger.name_to_value


# 6 ---------------------------------------------------------------------------------------------------------------------
def test_6_learn_zero_is_accepted() -> None:
    model = AffectQ("Grid", GRID, seed=0)
    assert model.learn(0) is model
    assert model.num_timesteps == 0


# 7 ---------------------------------------------------------------------------------------------------------------------
def test_7_set_random_seed_reseeds_the_agents_generator() -> None:
    logs = []
    for construction_seed in (1, 2):
        model = QLearning("Grid", GRID, seed=construction_seed)
        model.set_random_seed(5)
        model.learn(100_000, callback=StopTrainingOnMaxEpisodes(20))
        logs.append((model.episode_log, model.q_table))
    reference = QLearning("Grid", GRID, seed=5)
    reference.learn(100_000, callback=StopTrainingOnMaxEpisodes(20))
    for log, table in logs:
        assert log.equals(reference.episode_log)
        assert np.array_equal(table, reference.q_table)


# 8 ---------------------------------------------------------------------------------------------------------------------
def test_8_affectq_keeps_the_emotion_counts_of_the_episode_that_spans_a_save(tmp_path) -> None:
    model = AffectQ("Grid", GRID, seed=3)
    model.learn(100_000, callback=StopTrainingOnMaxEpisodes(5))
    model.learn(7, reset_num_timesteps=False)  # stop in the middle of episode 6
    assert model._episode_state is not None and model._episode_state["decisions"] > 0
    env = model.get_env()
    model.save(tmp_path / "affect")
    loaded = AffectQ.load(tmp_path / "affect", env=env, force_reset=False)
    loaded.learn(100_000, reset_num_timesteps=False, callback=StopTrainingOnMaxEpisodes(3))
    log = loaded.episode_log
    assert len(log) >= 8
    emotions = log[["joy", "sadness", "fear", "anger"]].sum(axis=1)
    assert (emotions == log["decisions"]).all()


# 9 ---------------------------------------------------------------------------------------------------------------------
def test_9_predict_deterministic_is_deterministic_and_exploration_is_sb3s() -> None:
    model = QLearning("Grid", GRID, seed=0, exploration_rate=0.0)
    obs = np.arange(100)
    first, _ = model.predict(obs, deterministic=True)  # all ties in a fresh table
    for _ in range(3):
        assert np.array_equal(model.predict(obs, deterministic=True)[0], first)
    assert (first == 0).all()

    with th.no_grad():
        model.policy.q_table[:, 2] = 1.0  # action 2 is greedy everywhere
    model.exploration_rate = 1.0  # as with DQN: takes effect at once
    actions = [int(model.predict(5, deterministic=False)[0]) for _ in range(60)]
    assert set(actions) != {2}
    action, _ = model.predict(5, deterministic=False)
    assert isinstance(action, np.ndarray) and action.shape == ()
    batch, _ = model.predict(np.array([1, 2, 3]), deterministic=False)
    assert isinstance(batch, np.ndarray) and batch.shape == (3,)
    env = gym.make(GRID)
    with pytest.raises(ValueError, match="mixing Gym API"):
        model.predict(env.reset(), deterministic=False)

    model.exploration_rate = 0.0  # and for learning
    model.learn(300)
    assert (model.episode_log["random_moves"] == 0).all()


# 10 --------------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("model_class", [QLearning, AffectQ])
def test_10_tensorboard_run_names_and_learn_signature(tmp_path, model_class) -> None:
    pytest.importorskip("tensorboard")
    model_class("Grid", GRID, tensorboard_log=str(tmp_path)).learn(20)
    assert (tmp_path / f"{model_class.__name__}_1").is_dir()
    assert "tb_log_name" in inspect.signature(model_class.learn).parameters


# 11 --------------------------------------------------------------------------------------------------------------------
def test_11_policy_device_is_the_tables_device() -> None:
    model = QLearning("Grid", GRID)
    policy = model.policy.to("meta")  # any device other than the CPU shows it (no GPU needed)
    assert policy.device.type == "meta"


# found while porting ---------------------------------------------------------------------------------------------------
def test_an_episode_ending_at_the_goal_is_not_reported_as_truncated_to_callbacks() -> None:
    """A terminal info says ``TimeLimit.truncated`` only for a truncation (SB3's VecEnv convention)."""
    recorder = Recorder()
    model = QLearning("Grid", GRID, seed=0, max_episode_decisions=200)
    model.learn(100_000, callback=[recorder, StopTrainingOnMaxEpisodes(20)])
    ends = [step["infos"][0] for step in recorder.steps if step["dones"][0]]
    truncated = [bool(info.get("TimeLimit.truncated", False)) for info in ends]
    assert truncated == model.episode_log["truncated"].tolist()
    assert not all(truncated) and any(truncated)


def test_the_decision_stepper_gives_callbacks_what_learn_gives_them() -> None:
    """``sb3_affect.agents.stepping.DecisionStepper`` mirrors ``learn``: the same callback locals, waits and terminal infos."""
    from stable_baselines3.common.monitor import Monitor

    from sb3_affect.agents.stepping import DecisionStepper

    def make() -> gym.Env:
        return gym.make(GRID, size=7, goal=(3, 3))

    kwargs = {"speeds": (0, 1, 2), "seed": 5, "max_episode_decisions": 60}
    learnt = Recorder()
    SpeedEpsilonGreedy("Grid", make(), **kwargs).learn(10**7, callback=[learnt, StopTrainingOnMaxEpisodes(15)])
    env = Monitor(make())
    stepped = Recorder()
    model = SpeedEpsilonGreedy("Grid", env, **kwargs)
    stepper = DecisionStepper(model, 10**7, callback=stepped)
    episodes = 0
    while episodes < 15:
        action, cells, _ = stepper.decide()
        terminated = truncated = False
        for _ in range(cells):
            obs, reward, terminated, truncated, info = env.step(action)
            stepper.transition(obs, reward, terminated, truncated, info)
            if terminated or truncated:
                break
        episodes += stepper.end_decision(terminated, truncated, reset=lambda: env.reset()[0])
    stepper.close()
    assert len(stepped.steps) == len(learnt.steps)
    for a, b in zip(stepped.steps, learnt.steps):
        for key in ("new_obs", "rewards", "dones", "actions"):
            assert isinstance(a[key], np.ndarray) and np.array_equal(a[key], b[key]), key
        info_a, info_b = a["infos"][0], b["infos"][0]
        assert info_a.keys() == info_b.keys()
        assert {k: v for k, v in info_a.items() if k != "episode"} == {k: v for k, v in info_b.items() if k != "episode"}
