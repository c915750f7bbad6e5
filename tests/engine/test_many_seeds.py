"""
``train_many`` against SB3's own DQN: its gradient step equals ``DQN.train``, its runs take SB3's actions and fill SB3's
replay buffers, and its models are SB3 models (save, load, predict, ``evaluate_policy``). The equivalence of the
greedy-evaluation curves over 20 seeds is a benchmark (``benchmarks/bench_many_seeds.py --equivalence``): it trains 40
runs.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3 import A2C, DQN
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import configure
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from sb3_affect import EmotionCallback, train_many
from sb3_affect.core.registry import resolve_class
from sb3_affect.engine.seed_envs import seed_vec_env
from sb3_affect.engine.stacked_q import StackedQ

pytest.importorskip("minigrid")

ENV_ID = "MiniGrid-Empty-5x5-v0"
#: a DQN that learns within a few thousand steps: every part of the loop (warm-up, epsilon, training, target copies)
SETTINGS = dict(learning_starts=200, buffer_size=10_000, target_update_interval=100, learning_rate=1e-3, batch_size=16)
#: epsilon over the first half of training (AffectDQN has none)
EPSILON = dict(exploration_fraction=0.5)


@pytest.fixture(autouse=True)
def _one_thread() -> object:
    """One torch thread, as the launcher runs each run: two threads per process on a busy machine wait on each other."""
    before = th.get_num_threads()
    th.set_num_threads(1)
    yield
    th.set_num_threads(before)


def _sb3(seed: int, n_envs: int, total_timesteps: int, obs: str = "view", cls: type = DQN, **kwargs) -> DQN:
    model = cls("MlpPolicy", seed_vec_env(ENV_ID, n_envs, seed, obs), seed=seed, device="cpu", **{**SETTINGS, **kwargs})
    return model.learn(total_timesteps)


def _assert_same_buffer(ours: DQN, theirs: DQN) -> None:
    a, b = ours.replay_buffer, theirs.replay_buffer
    assert (a.pos, a.full) == (b.pos, b.full) and a.pos > 0
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        np.testing.assert_array_equal(getattr(a, name)[: a.pos], getattr(b, name)[: b.pos], err_msg=name)


def _max_weight_difference(ours: DQN, theirs: DQN) -> float:
    pairs = [*zip(ours.q_net.parameters(), theirs.q_net.parameters()),
             *zip(ours.q_net_target.parameters(), theirs.q_net_target.parameters())]
    return max((p - q).abs().max().item() for p, q in pairs)


def test_gradient_step_equals_dqn_train() -> None:
    """100 steps of three seeds on the same batches: the stacked step and SB3's ``DQN.train`` (its Huber loss, gradient
    clipping, Adam and target copies) give weights within 1e-6 and the same losses."""
    models = [DQN("MlpPolicy", seed_vec_env(ENV_ID, 1, seed, "view"), seed=seed, device="cpu", max_grad_norm=0.5,
                  learning_rate=1e-3) for seed in range(3)]
    for model in models:
        model.set_logger(configure(None, []))
    stack = StackedQ(models)
    rng = np.random.default_rng(0)
    batch_size, n_obs = 32, models[0].observation_space.shape[0]
    for step in range(100):
        batches = []
        for model in models:
            arrays = (rng.integers(0, 11, size=(batch_size, n_obs), dtype=np.uint8), rng.integers(7, size=(batch_size, 1)),
                      rng.integers(0, 11, size=(batch_size, n_obs), dtype=np.uint8),
                      (rng.random((batch_size, 1)) < 0.1).astype(np.float32), rng.random((batch_size, 1), dtype=np.float32))
            batch = ReplayBufferSamples(*(th.as_tensor(a) for a in arrays))
            batches.append(batch)
            model.replay_buffer.sample = lambda *_, batch=batch, **__: batch  # type: ignore[method-assign]
            model.train(gradient_steps=1, batch_size=batch_size)
        losses = stack.train_step(*(th.stack([b[i] for b in batches]) for i in range(5)))
        np.testing.assert_allclose(losses.numpy(), [m.logger.name_to_value["train/loss"] for m in models], rtol=1e-5)
        if step % 10 == 9:
            stack.update_target()
            for model in models:
                model.target_update_interval, model._n_calls = 1, 0
                model._on_step()
    copies = [DQN("MlpPolicy", seed_vec_env(ENV_ID, 1, seed, "view"), seed=seed, device="cpu") for seed in range(3)]
    stack.write_back(copies)
    for ours, theirs in zip(copies, models):
        assert _max_weight_difference(ours, theirs) < 1e-6
        state, reference = ours.policy.optimizer.state_dict()["state"], theirs.policy.optimizer.state_dict()["state"]
        for key in reference:
            np.testing.assert_allclose(state[key]["exp_avg_sq"], reference[key]["exp_avg_sq"], rtol=1e-4, atol=1e-12)
            assert float(state[key]["step"]) == float(reference[key]["step"]) == 100


def test_one_seed_one_env_takes_sb3s_actions() -> None:
    """
    One seed, one env: the trainer's replay buffer equals SB3's ``learn`` transition for transition (the same
    warm-up and epsilon actions, greedy actions, terminal observations and timeouts), and the weights agree to 1e-6.

    How long this lasts: the greedy actions are argmax of Q-values that the stacked network sums in another order
    than SB3's ``addmm`` (``baddbmm`` over a batch of one seed), so the two Q-values differ by about 1e-7 and the
    weights drift apart at that level (3e-7 after 625 updates). The runs part when an argmax flips: when two
    actions' Q-values are closer than the drift, after which the two runs are different samples of the same process.
    Measured on Empty-8x8 (obs="view", one env, learning_starts 1,000, learning rate 1e-3, target copy every 500
    steps, epsilon over the first 30% of 20,000 steps): the first different transition at env step 4,592, 6,754 and
    9,048 for seeds 0, 1 and 2 (after 900 to 2,000 gradient steps).
    """
    theirs = _sb3(3, 1, 1_500, **EPSILON)
    (ours,) = train_many(DQN, ENV_ID, [3], 1, total_timesteps=1_500, obs="view", **SETTINGS, **EPSILON)
    _assert_same_buffer(ours, theirs)
    assert _max_weight_difference(ours, theirs) < 1e-6
    assert (ours.num_timesteps, ours._n_updates, ours._episode_num) == (theirs.num_timesteps, theirs._n_updates,
                                                                        theirs._episode_num)
    assert ours.exploration_rate == theirs.exploration_rate
    for key in ("train/loss", "train/n_updates", "train/learning_rate", "rollout/exploration_rate"):
        assert key in ours.logger.name_to_value and key in theirs.logger.name_to_value
    assert len(ours.ep_info_buffer) == len(theirs.ep_info_buffer) > 0


def test_seeds_and_envs_counted_as_sb3_counts_them() -> None:
    """Three seeds x three envs, training every 2 VecEnv steps with 2 gradient steps and a target copy every
    ``30 // 3`` VecEnv steps: each seed's buffer is the buffer of its own ``learn``."""
    settings = dict(train_freq=2, gradient_steps=2, target_update_interval=30, **EPSILON)
    ours = train_many("DQN", ENV_ID, [5, 0, 9], 3, total_timesteps=900, obs="view", **{**SETTINGS, **settings})
    for seed, model in zip([5, 0, 9], ours):
        theirs = _sb3(seed, 3, 900, **settings)
        _assert_same_buffer(model, theirs)
        assert _max_weight_difference(model, theirs) < 1e-6
        assert model._n_updates == theirs._n_updates and model.num_timesteps == theirs.num_timesteps


@pytest.mark.parametrize(("algo", "kwargs"), [
    ("EzGreedyDQN", EPSILON),
    ("SpeedEpsilonGreedyDQN", {**EPSILON, "wait_action": 6, "speeds": [0, 1, 2]}),
    ("AffectDQN", {"position": "minigrid", "wait_action": 6}),
])
def test_deep_controls_and_affect_dqn_as_their_own_learn(algo, kwargs, tmp_path) -> None:
    """The classes that decide their own actions (repeats, waits, emotions) run their own ``_sample_action`` and
    ``_store_transition`` per seed: each seed's buffer, logged keys and episode log are those of its ``learn``; the
    model saves and loads as its class does."""
    cls = resolve_class(algo)
    ours = train_many(algo, ENV_ID, [4, 2], 2, total_timesteps=800, obs="view", **{**SETTINGS, **kwargs})
    for seed, model in zip([4, 2], ours):
        assert type(model) is cls
        theirs = _sb3(seed, 2, 800, cls=cls, **kwargs)
        _assert_same_buffer(model, theirs)
        assert _max_weight_difference(model, theirs) < 1e-6
        assert sorted(model.logger.name_to_value) == sorted(theirs.logger.name_to_value)
        if algo == "AffectDQN":
            assert len(model.emotion_callback.episode_log) > 0
            pd.testing.assert_frame_equal(model.emotion_callback.episode_log, theirs.emotion_callback.episode_log)
    ours[0].save(tmp_path / "model.zip")
    loaded = cls.load(tmp_path / "model.zip", env=seed_vec_env(ENV_ID, 2, 4, "view"), device="cpu")
    observations = ours[0].replay_buffer.observations[:50, 0]
    np.testing.assert_array_equal(loaded.predict(observations, deterministic=True)[0],
                                  ours[0].predict(observations, deterministic=True)[0])


def test_returned_models_are_sb3_models(tmp_path) -> None:
    """A returned model saves, loads, predicts and evaluates as one trained by ``learn``; the load predicts alike."""
    models = train_many("DQN", ENV_ID, [0, 1], 2, total_timesteps=400, obs="flat", **SETTINGS, **EPSILON)
    assert [type(m) for m in models] == [DQN, DQN] and [m.seed for m in models] == [0, 1]
    env = seed_vec_env(ENV_ID, 1, 123, "flat")
    path = tmp_path / "model.zip"
    models[1].save(path)
    loaded = DQN.load(path, device="cpu")
    observations = np.stack([env.reset()[0] for _ in range(3)])
    np.testing.assert_array_equal(models[1].predict(observations, deterministic=True)[0],
                                  loaded.predict(observations, deterministic=True)[0])
    mean, _ = evaluate_policy(loaded, env, n_eval_episodes=2)
    assert 0.0 <= mean <= 1.0
    assert loaded.num_timesteps == 400 and "predict" not in vars(models[1])


def test_returned_buffers_are_each_models_own() -> None:
    """Each returned model's buffer has SB3's rows (``buffer_size // n_envs``, more than the run reached) and keeps
    training past them, wrapping as SB3's does, while the other seeds' buffers stay as the run left them."""
    models = train_many("DQN", ENV_ID, [0, 1], 2, total_timesteps=400, obs="view", **{**SETTINGS, "buffer_size": 1000})
    buffers = [m.replay_buffer for m in models]
    assert [(b.buffer_size, len(b.observations), b.pos, b.full) for b in buffers] == [(500, 500, 200, False)] * 2
    kept = {name: getattr(buffers[0], name).copy() for name in ("observations", "next_observations", "actions")}
    models[1].learn(800, reset_num_timesteps=False)
    assert models[1].replay_buffer is buffers[1] and (buffers[1].pos, buffers[1].full) == (100, True)
    assert (buffers[1].observations[200:500] != 0).any()
    for name, array in kept.items():
        np.testing.assert_array_equal(getattr(buffers[0], name), array)


@pytest.mark.parametrize(("algo", "kwargs", "message"), [
    ("NoSuchAgent", {}, "not a known algorithm"),
    (A2C, {}, "algo=A2C is on-policy but not PPO"),
    ("QLearning", {}, "algo=QLearning is not a DQN"),
    ("DQN", {"seed": 3}, "seed= is train_many's own argument"),
    ("DQN", {"policy": "CnnPolicy"}, "policy='CnnPolicy'"),
    ("DQN", {"obs": "rgb"}, "obs='rgb' is not one of flat, view"),
    ("DQN", {"obs": "image"}, "obs='image' is minigrid_vec_env's 7x7x3 image; the flat 147 entries of the agent's"),
    ("DQN", {"n_envs": 0}, "n_envs=0 must be an integer >= 1"),
    ("DQN", {"seeds": [1, 1]}, "seeds has 1 twice"),
    ("DQN", {"seeds": []}, "seeds=[] must be a non-empty list"),
    ("DQN", {"env_id": "NoSuchEnv-v0"}, "env_id='NoSuchEnv-v0' is not a registered env"),
    ("DQN", {"train_freq": (1, "episode"), "n_envs": 1}, "counts episodes"),
    ("DQN", {"optimize_memory_usage": True, "replay_buffer_kwargs": {"handle_timeout_termination": False}},
     "optimize_memory_usage=True"),
    ("AffectDQN", {"emotion_callback": EmotionCallback()}, "emotion_callback= is one EmotionCallback for every seed"),
])
def test_bad_arguments_refused_with_one_line(algo, kwargs, message) -> None:
    arguments = {"env_id": ENV_ID, "seeds": [0], "n_envs": 1, "total_timesteps": 10, **kwargs}
    with pytest.raises(ValueError, match=re.escape(message)) as raised:
        train_many(algo, **arguments)
    assert "\n" not in str(raised.value)
