"""
What a goal is on envs that are not the package's own: ``sb3_affect.core.goals`` on Gymnasium's
FrozenLake, CliffWalking and Taxi, through AffectQ and through an observing EmotionCallback.
"""

from __future__ import annotations

import gymnasium as gym
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import AffectQ, EmotionCallback, QLearning

FROZEN_HOLES = {5, 7, 11, 12}  # FrozenLake's default 4x4 map "SFFF/FHFH/FFFH/HFFG"
FROZEN_GOAL = 15
CLIFF_GOAL = 47  # CliffWalking: 4 x 12, start 36, cliff 37..46


def _step_from(env_id: str, state: int, action: int, **kwargs) -> tuple[float, bool, dict]:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    env.unwrapped.s = state  # toy-text envs keep their state in ``s``
    _, reward, terminated, _, info = env.step(action)
    return float(reward), bool(terminated), info


def test_default_goal_test_on_real_toy_text_transitions() -> None:
    from sb3_affect.core.goals import every_termination, positive_terminal_reward

    reward, terminated, info = _step_from("FrozenLake-v1", 1, 1, is_slippery=False)  # down into the hole at 5
    assert terminated and not positive_terminal_reward(reward, info)
    reward, terminated, info = _step_from("FrozenLake-v1", 14, 2, is_slippery=False)  # right onto the goal
    assert terminated and positive_terminal_reward(reward, info)

    taxi = gym.make("Taxi-v4").unwrapped
    at_red_with_passenger_for_red = taxi.encode(0, 0, 4, 0)
    reward, terminated, info = _step_from("Taxi-v4", at_red_with_passenger_for_red, 5)  # drop off at the destination
    assert (reward, terminated) == (20.0, True) and positive_terminal_reward(reward, info)

    reward, terminated, info = _step_from("CliffWalking-v1", 35, 2)  # down onto the goal: reward -1 like any step
    assert (reward, terminated) == (-1.0, True)
    assert not positive_terminal_reward(reward, info)
    assert every_termination(reward, info)

    assert positive_terminal_reward(0.0, {"is_success": True})  # an env's own verdict wins
    assert not positive_terminal_reward(5.0, {"is_success": False})


def test_frozenlake_holes_are_not_goals_for_affectq() -> None:
    model = AffectQ("Grid", gym.make("FrozenLake-v1", is_slippery=False), seed=0)
    model.learn(100_000, callback=StopTrainingOnMaxEpisodes(300))
    log = model.episode_log
    fell_in_a_hole = (~log["truncated"]) & (log["reward"] == 0)
    assert fell_in_a_hole.sum() > 0 and (log["reward"] > 0).sum() > 0  # both kinds of termination happened
    assert model.emotion_callback is not None and model.emotion_callback.appraiser is not None
    assert model.emotion_callback.appraiser.known.goals == {FROZEN_GOAL}
    assert not FROZEN_HOLES & model.emotion_callback.appraiser.known.goals


def test_frozenlake_holes_are_not_goals_for_an_observing_emotion_callback() -> None:
    callback = EmotionCallback()
    model = QLearning("Grid", gym.make("FrozenLake-v1", is_slippery=False), seed=0, exploration_rate=0.3)
    model.learn(4000, callback=callback)
    assert callback.appraiser is not None
    assert callback.appraiser.known.goals <= {FROZEN_GOAL}
    terminated = callback.episode_log[~callback.episode_log["truncated"]]
    assert len(terminated) > 0 and (terminated["reward"] == 0).any()  # holes were met


@pytest.mark.parametrize("goal, expected", [(None, set()), ("every_termination", {CLIFF_GOAL})])
def test_cliffwalking_goal_needs_the_every_termination_test(goal, expected) -> None:
    from sb3_affect.core import goals

    callback = EmotionCallback(goal=None if goal is None else getattr(goals, goal))
    model = AffectQ("Grid", "CliffWalking-v1", seed=0, max_episode_decisions=2000, emotion_callback=callback)
    model.learn(100_000, callback=StopTrainingOnMaxEpisodes(10))
    assert (~model.episode_log["truncated"]).sum() > 0  # the goal was reached
    assert callback.appraiser is not None and callback.appraiser.known.goals == expected


def test_taxi_goals_are_drop_offs_at_the_destination() -> None:
    taxi = gym.make("Taxi-v4").unwrapped
    model = AffectQ("Grid", "Taxi-v4", seed=0)
    model.learn(100_000, callback=StopTrainingOnMaxEpisodes(20))
    log = model.episode_log
    assert model.emotion_callback is not None and model.emotion_callback.appraiser is not None
    found = model.emotion_callback.appraiser.known.goals
    assert 0 < len(found) <= (~log["truncated"]).sum()  # a goal per distinct drop-off state reached
    for state in found:
        _, _, passenger, destination = taxi.decode(state)
        assert passenger == destination


def test_a_user_goal_test_is_used_and_validated() -> None:
    with pytest.raises(TypeError, match="goal"):
        EmotionCallback(goal="the exit")  # type: ignore[arg-type]
    seen = []

    def goal(reward: float, info: dict) -> bool:
        seen.append(reward)
        return False

    model = AffectQ("Grid", gym.make("FrozenLake-v1", is_slippery=False), seed=0, emotion_callback=EmotionCallback(goal=goal))
    model.learn(100_000, callback=StopTrainingOnMaxEpisodes(20))
    terminations = int((~model.episode_log["truncated"]).sum())
    assert terminations > 0
    assert len(seen) == 2 * terminations  # asked for the transition and for the episode's end
    assert model.emotion_callback is not None and model.emotion_callback.appraiser is not None
    assert model.emotion_callback.appraiser.known.goals == set()


def test_affectq_warns_once_when_no_goal_is_ever_known_naming_the_goal_option() -> None:
    """CliffWalking's goal gives reward -1: by default no termination is a goal, so the appraisal can only give joy."""
    model = AffectQ("Grid", gym.make("CliffWalking-v1", max_episode_steps=50), seed=0,
                    emotion_callback=EmotionCallback(warn_after=5))
    message = r"AffectQ: none of the first 5 episodes reached the goal.*pass AffectQ\(\.\.\., emotion_callback=Emotion"
    message += r"Callback\(goal="
    with pytest.warns(RuntimeWarning, match=message) as record:
        model.learn(100_000, callback=StopTrainingOnMaxEpisodes(12))
    assert model.engine_used == "python" and len([w for w in record if "reached the goal" in str(w.message)]) == 1


def test_affectq_on_the_compiled_engine_warns_after_the_run_and_not_once_the_goal_is_known() -> None:
    import warnings

    far = gym.make("sb3_affect/GridPursuit-v0", size=6, goal=(5, 5), max_episode_steps=3)  # cut off before the goal
    model = AffectQ("Grid", far, seed=0, emotion_callback=EmotionCallback(warn_after=5))
    with pytest.warns(RuntimeWarning, match=r"AffectQ: none of the first \d+ episodes reached the goal"):
        model.learn(60)
    assert model.engine_used == "compiled" and len(model.episode_log) >= 5
    near = AffectQ("Grid", gym.make("sb3_affect/GridPursuit-v0", size=4, goal=(1, 1)), seed=0,
                   emotion_callback=EmotionCallback(warn_after=1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        near.learn(2000)
    assert near.engine_used == "compiled"


def _cartpole_run(**kwargs) -> tuple[list[str], EmotionCallback]:
    import warnings

    import torch as th
    from stable_baselines3 import PPO

    th.set_num_threads(1)
    callback = EmotionCallback(position=lambda obs, info: int(obs[2] > 0), warn_after=None, **kwargs)  # the pole's side
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        PPO("MlpPolicy", "CartPole-v1", n_steps=128, batch_size=64, n_epochs=1, seed=0).learn(256, callback=callback)
    return [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)], callback


def test_cartpoles_falling_pole_taken_for_the_goal_by_the_default_warns_once() -> None:
    messages, callback = _cartpole_run()
    told = [m for m in messages if "the same sign as the rest of the return" in m]
    assert len(told) == 1 and "CartPole's pole falling" in told[0] and "goal=lambda reward, info" in told[0], messages
    assert told[0].startswith("EmotionCallback: an episode terminated with reward 1 after rewards summing to ")
    assert callback.appraiser is not None and callback.appraiser.known.goals  # (what it warns about: a map to the fall)


def test_a_goal_test_given_tells_the_failure_apart_and_silences_the_warning() -> None:
    messages, callback = _cartpole_run(goal=lambda reward, info: False)
    assert not [m for m in messages if "the same sign as the rest of the return" in m], messages
    assert callback.appraiser is not None and not callback.appraiser.known.goals


def test_a_goal_rewarded_apart_from_the_steps_before_it_does_not_warn() -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("error", message=".*the same sign as the rest of the return.*")
        test_frozenlake_holes_are_not_goals_for_an_observing_emotion_callback()  # FrozenLake: 0 a step, 1 at the goal
