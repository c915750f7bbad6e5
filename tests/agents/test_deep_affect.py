"""
The emotions steering SB3's off-policy deep agents: ``AffectDQN`` (SB3's DQN) and ``AffectQRDQN`` (sb3-contrib's
QR-DQN). Real algorithms on real envs: FrozenLake (Discrete observations, so the appraisal has cells) on one env and
on a 4-env VecEnv.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from scipy.stats import chisquare
from stable_baselines3 import DQN
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import configure

from sb3_affect import AffectDQN, AffectQRDQN, Behaviour, Emotion

AGENTS = (AffectDQN, AffectQRDQN)
N_ACTIONS = 4  # FrozenLake's


def table(random_direction: bool, speeds: tuple[int, ...]) -> dict[Emotion, Behaviour]:
    """Every emotion with the same behaviour."""
    return {emotion: Behaviour(random_direction, speeds) for emotion in Emotion}


class ActionLog(gym.Wrapper):
    """Records each executed action with the step of the episode it was taken at."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.steps: list[tuple[int, int, bool]] = []  # (episode step, action, episode ended)
        self._t = 0

    def reset(self, **kwargs: Any) -> Any:
        self._t = 0
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.steps.append((self._t, int(action), bool(terminated or truncated)))
        self._t += 1
        return obs, reward, terminated, truncated, info


def frozen_lake(n_envs: int, slippery: bool = True) -> Any:
    return make_vec_env(
        "FrozenLake-v1", n_envs=n_envs, seed=0, wrapper_class=ActionLog, env_kwargs={"is_slippery": slippery}
    )


def _action_log(env: gym.Env) -> ActionLog:
    while not isinstance(env, ActionLog):
        env = env.env  # type: ignore[attr-defined]
    return env


def action_logs(venv: Any) -> list[list[tuple[int, int, bool]]]:
    return [_action_log(env).steps for env in venv.envs]


def small(agent: type, env: Any, **kwargs: Any) -> Any:
    th.set_num_threads(1)
    kwargs.setdefault("learning_starts", 16)
    return agent("MlpPolicy", env, batch_size=16, train_freq=4, seed=0, policy_kwargs={"net_arch": [16]}, **kwargs)


@pytest.mark.parametrize("n_envs", [1, 4])
def test_all_greedy_speed_one_is_dqn_without_epsilon_step_for_step(n_envs: int) -> None:
    """Every emotion greedy at speed 1: the same actions, replay buffer and weights as DQN with epsilon 0."""
    runs = []
    for agent, kwargs in ((DQN, {"exploration_initial_eps": 0.0, "exploration_final_eps": 0.0}),
                          (AffectDQN, {"behaviour_table": table(False, (1,))})):
        env = frozen_lake(n_envs)
        model = small(agent, env, target_update_interval=50, **kwargs).learn(400)
        runs.append((model, action_logs(env)))
    (dqn, dqn_actions), (affect, affect_actions) = runs
    assert dqn_actions == affect_actions and len(dqn_actions[0]) == 400 // n_envs
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        np.testing.assert_array_equal(getattr(dqn.replay_buffer, name), getattr(affect.replay_buffer, name), err_msg=name)
    for (key, a), b in zip(dqn.policy.state_dict().items(), affect.policy.state_dict().values()):
        assert th.equal(a, b), key
    assert affect.logger.name_to_value.get("affect/random_share", 0.0) == 0.0


@pytest.mark.parametrize("agent", AGENTS)
def test_all_joy_takes_uniform_actions_and_stores_them_as_executed(agent: type) -> None:
    env = frozen_lake(4)
    model = small(agent, env, learning_starts=0, buffer_size=5000, behaviour_table=table(True, (1,))).learn(4000)
    executed = np.array([[action for _, action, _ in log] for log in action_logs(env)])  # (env, step)
    stored = model.replay_buffer.actions[: model.replay_buffer.pos, :, 0]  # (step, env)
    np.testing.assert_array_equal(stored, executed.T)
    counts = np.bincount(executed.reshape(-1), minlength=N_ACTIONS)
    assert chisquare(counts).pvalue > 0.001, counts  # uniform at the 0.1% level


@pytest.mark.parametrize("agent", AGENTS)
def test_speed_two_repeats_each_decision_twice_per_env_and_an_episode_end_ends_it(agent: type) -> None:
    env = frozen_lake(4)
    small(agent, env, learning_starts=0, behaviour_table=table(True, (2,))).learn(2000)
    odd_endings = 0
    for log in action_logs(env):
        actions = {}
        for t, action, ended in log:
            actions[t] = action
            if t % 2 == 1:
                assert actions[t] == actions[t - 1], "the second step of a decision repeats its action"
            odd_endings += ended and t % 2 == 0
    assert odd_endings > 0  # episodes that ended mid-repeat (the repeat then did not carry into the next episode)
    # the next decision draws a new action: consecutive decisions agree by chance only (1 in 4)
    logs = action_logs(env)
    same = np.mean([a[1] == b[1] for log in logs for a, b in itertools.pairwise(log) if a[0] % 2 and b[0] == a[0] + 1])
    assert 0.15 < same < 0.35, same


def test_a_wait_takes_the_wait_action_and_without_one_moves_at_speed_one() -> None:
    env = frozen_lake(4, slippery=False)
    small(AffectDQN, env, learning_starts=0, behaviour_table=table(True, (0,)), wait_action=1).learn(200)
    assert {action for log in action_logs(env) for _, action, _ in log} == {1}
    env = frozen_lake(4, slippery=False)
    model = small(AffectDQN, env, learning_starts=0, behaviour_table=table(True, (0,))).learn(400)
    executed = [action for log in action_logs(env) for _, action, _ in log]
    assert set(executed) == set(range(N_ACTIONS))
    assert model._decisions == 0 or model._speed_sum == model._decisions  # speed 1 each


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("n_envs", [1, 4])
def test_learn_logs_the_emotions_the_random_share_and_the_mean_repeat(agent: type, n_envs: int, tmp_path: Path) -> None:
    model = small(agent, frozen_lake(n_envs))
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(1200, log_interval=1)
    progress = pd.read_csv(tmp_path / "progress.csv")
    for key in ("affect/joy", "affect/sadness", "affect/fear", "affect/anger", "affect/random_share", "affect/mean_repeat"):
        values = progress[key].dropna()
        assert len(values) and np.isfinite(values).all(), key
    assert progress["affect/random_share"].dropna().between(0, 1).all()
    assert progress["affect/mean_repeat"].dropna().between(0, 2).all()
    log = model.emotion_callback.episode_log
    assert set(log.env) == set(range(n_envs))
    assert (log.decisions <= log.cells).all() and (log.decisions < log.cells).any()  # speed 2 decisions span 2 steps


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("n_envs", [1, 4])
def test_save_load_predict_and_evaluate_policy(agent: type, n_envs: int, tmp_path: Path) -> None:
    env = frozen_lake(n_envs)
    model = small(agent, env, behaviour_table=table(False, (1, 2)), wait_action=0, position="discrete").learn(300)
    model.save(tmp_path / "model.zip")
    loaded = agent.load(tmp_path / "model.zip", env=env)
    assert loaded.wait_action == 0 and loaded.position == "discrete"
    assert loaded._behaviour == model._behaviour
    for (key, a), b in zip(model.policy.state_dict().items(), loaded.policy.state_dict().values()):
        assert th.equal(a, b), key
    observations = np.arange(16)
    np.testing.assert_array_equal(model.predict(observations, deterministic=True)[0],
                                  loaded.predict(observations, deterministic=True)[0])
    # outside learn there is no emotion: predict is greedy with deterministic=False too
    np.testing.assert_array_equal(loaded.predict(observations)[0], loaded.predict(observations, deterministic=True)[0])
    actions, _ = loaded.predict(env.reset())
    assert actions.shape == (n_envs,)
    mean, _ = evaluate_policy(loaded, env, n_eval_episodes=4)
    assert 0.0 <= mean <= 1.0
    loaded.learn(100, reset_num_timesteps=False)  # continues from the loaded model
    assert loaded.num_timesteps >= 400


def test_bad_input_gets_one_line() -> None:
    cases = [
        (lambda: AffectDQN("MlpPolicy", gym.make("Pendulum-v1")), AssertionError, "Box"),
        (lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", wait_action=4), ValueError, "wait_action=4 is outside"),
        (lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", wait_action=1.5), TypeError, "wait_action must be"),
        (lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", exploration_final_eps=0.1), TypeError, "has no epsilon"),
        (lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", position="grid"), ValueError, "position='grid' is not"),
        (lambda: AffectDQN("MlpPolicy", "FrozenLake-v1", behaviour_table={}), ValueError, "behaviour_table has no"),
        (lambda: AffectDQN("MlpPolicy", "CartPole-v1", learning_starts=0).learn(8), TypeError, "no position= hook"),
        (lambda: AffectDQN("MlpPolicy", "CartPole-v1", position="minigrid").learn(8), ValueError, "no agent_pos"),
    ]
    for make, error, text in cases:
        with pytest.raises(error) as raised:
            make()
        message = str(raised.value)
        assert text in message and "\n" not in message, message


def test_a_callable_position_gives_a_map_on_box_observations() -> None:
    """CartPole's cart position, in tenths: the appraisal learns a map and Table II runs."""
    env = make_vec_env("CartPole-v1", n_envs=2, seed=0)
    model = small(AffectDQN, env, position=lambda obs, info: round(float(obs[0]) * 10)).learn(600)
    appraiser = model.emotion_callback.appraiser
    assert appraiser is not None and len(appraiser.known.successors.seen()) > 1
    assert len(model.emotion_callback.episode_log) > 2


def test_the_mixin_goes_on_a_users_own_algorithm() -> None:
    from sb3_affect import AffectiveExploration

    class MyDQN(DQN):
        """A user's DQN variant."""

    class AffectMyDQN(AffectiveExploration, MyDQN):
        pass

    env = frozen_lake(2)
    model = AffectMyDQN("MlpPolicy", env, learning_starts=0, seed=0, behaviour_table=table(True, (2,))).learn(200)
    assert model.exploration_rate == 0.0 and model._decisions > 0
    assert all(log[1][1] == log[0][1] for log in action_logs(env))
