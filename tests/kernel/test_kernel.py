"""The compiled engine: its random stream, the engine option, continuing across engines, callbacks and the logger."""

from __future__ import annotations

import csv
import random
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from stable_baselines3.common.callbacks import BaseCallback, StopTrainingOnMaxEpisodes
from stable_baselines3.common.logger import configure

from sb3_affect import AffectQ, EmotionCallback, QLearning
from sb3_affect.agents.baselines import Boltzmann, SpeedEpsilonGreedy, UCBQLearning, softmax_action
from sb3_affect.core.appraisal import Appraiser
from sb3_affect.engine.simulation import simulate
from sb3_affect.envs import TransitionTable
from sb3_affect.envs.grid_pursuit import RIGHT
from sb3_affect.kernel import choice
from sb3_affect.kernel.agent_settings import COMPENSATED_SUM
from sb3_affect.kernel.mt19937 import STATE_SIZE, randbelow, random01, seed_key, seed_state, state_from_rng

GRID = "sb3_affect/GridPursuit-v0"
SMALL = {"size": 6, "goal": (3, 4)}


# -- the random stream ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 7, -7, 2**32 - 1, 2**32, 2**64 + 12345, 10**30])
def test_mt19937_seeds_and_draws_as_python_random(seed: int) -> None:
    reference = random.Random(seed)
    key = np.array(seed_key(seed), dtype=np.int64)
    mt = np.zeros(STATE_SIZE, dtype=np.int64)
    seed_state(mt, key, len(key))
    assert mt.tolist() == list(reference.getstate()[1])
    for i in range(2000):  # more than 624 words: the twist runs several times
        n = 1 + i % 9
        if i % 3 == 0:
            assert random01(mt) == reference.random()
        elif i % 3 == 1:
            assert randbelow(mt, n) == reference.randrange(n)
        else:
            assert randbelow(mt, n) == reference.choice(range(n))
    assert mt.tolist() == list(reference.getstate()[1])
    copied, _ = state_from_rng(reference)
    assert np.array_equal(copied, mt)


def test_softmax_matches_the_python_draw_and_its_sum() -> None:
    rng = np.random.default_rng(0)
    weights = np.empty(4)
    for _ in range(500):
        q = rng.normal(0, 30, size=(1, 4))
        inv_t, u = float(rng.uniform(0.01, 3)), float(rng.random())
        expected = softmax_action(q[0].tolist(), inv_t, u)
        assert choice.softmax_action(q, 0, inv_t, u, COMPENSATED_SUM, weights) == expected


# -- the engine option ------------------------------------------------------------------------------------------------
def test_engine_options_are_validated_and_saved(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="engine='fast' is not supported"):
        QLearning("Grid", GRID, engine="fast")
    with pytest.raises(ValueError, match="tie_break='last'"):
        AffectQ("Grid", GRID, tie_break="last")
    with pytest.raises(ValueError, match="multi_cell='teleport'"):
        SpeedEpsilonGreedy("Grid", GRID, multi_cell="teleport")
    model = AffectQ("Grid", GRID, engine="python", tie_break="first", multi_cell="jump", seed=1)
    model.save(tmp_path / "m.zip")
    loaded = AffectQ.load(tmp_path / "m.zip")
    assert (loaded.engine, loaded.tie_break, loaded.multi_cell) == ("python", "first", "jump")


class EveryDecision(BaseCallback):
    def __init__(self) -> None:
        super().__init__()
        self.calls = 0

    def _on_step(self) -> bool:
        self.calls += 1
        return True


class AtEpisodeEnds(BaseCallback):
    episode_level = True

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[tuple[int, bool, int]] = []

    def _on_step(self) -> bool:
        self.seen.append((self.num_timesteps, bool(self.locals["dones"][0]), len(self.model.episode_log)))
        return True


def test_auto_falls_back_and_compiled_names_the_reason() -> None:
    every = EveryDecision()
    model = QLearning("Grid", gym.make(GRID, **SMALL), seed=0).learn(500, callback=every)  # auto: the Python loop
    assert every.calls == 500
    with pytest.raises(ValueError, match="EveryDecision is called after every decision"):
        QLearning("Grid", gym.make(GRID, **SMALL), engine="compiled").learn(10, callback=EveryDecision())
    with pytest.raises(ValueError, match="wrapped in TransformReward"):
        env = gym.wrappers.TransformReward(gym.make(GRID, **SMALL), lambda r: 2 * r)
        QLearning("Grid", env, engine="compiled").learn(10)
    with pytest.raises(ValueError, match="custom emotion_rule"):
        rule = EmotionCallback(emotion_rule=lambda appraisal: 0)
        AffectQ("Grid", GRID, emotion_callback=rule, engine="compiled").learn(10)
    with pytest.raises(ValueError, match="the appraiser is a Mine"):

        class Mine(Appraiser):
            pass

        AffectQ("Grid", GRID, emotion_callback=EmotionCallback(appraiser=Mine(225)), engine="compiled").learn(10)
    assert model.num_timesteps == 500


class Ring(gym.Env[Any, Any]):
    """A grid env that is no class of the package: a ring of ``n`` cells, left and right, the goal opposite the start."""

    def __init__(self, n: int = 10, described: bool = True) -> None:
        self.n, self.described = n, described
        self.observation_space = gym.spaces.Discrete(n)
        self.action_space = gym.spaces.Discrete(2)
        self.moves = [[(s - 1) % n, (s + 1) % n] for s in range(n)]
        self.distances = [float(min(abs(s - n // 2), n - abs(s - n // 2))) for s in range(n)]
        self.state = 0

    def transition_table(self) -> TransitionTable | str:
        if not self.described:
            return "the ring keeps its moves to itself"
        return TransitionTable(self.moves, self.distances, 0, self.n // 2, 10.0, -1.0, self.n)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.state = 0
        return 0, {"cell": (0, 0)}

    def step(self, action: Any) -> tuple[int, float, bool, bool, dict[str, Any]]:
        s, t = self.state, self.moves[self.state][int(action)]
        self.state = t
        terminated = t == self.n // 2
        return t, 10.0 if terminated else -1.0, terminated, False, {"cell": divmod(t, self.n), "moved": t != s}


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
def test_an_env_that_describes_its_moves_runs_compiled_with_the_same_results(cls: type) -> None:
    models = {}
    for engine in ("python", "compiled"):
        model = cls("Grid", Ring(), seed=3, engine=engine)
        models[engine] = model.learn(10**5, callback=StopTrainingOnMaxEpisodes(40))
    pd.testing.assert_frame_equal(models["python"].episode_log, models["compiled"].episode_log)
    np.testing.assert_array_equal(models["python"].q_table, models["compiled"].q_table)
    assert models["python"]._rng.getstate() == models["compiled"]._rng.getstate()
    with pytest.raises(ValueError, match="the ring keeps its moves to itself"):
        cls("Grid", Ring(described=False), engine="compiled").learn(10)
    with pytest.raises(ValueError, match="does not describe its moves as a transition table"):
        cls("Grid", gym.make("FrozenLake-v1"), engine="compiled").learn(10)


def test_episode_level_callbacks_and_progress_bar_on_the_kernel() -> None:
    ends = AtEpisodeEnds()
    model = AffectQ("Grid", gym.make(GRID, **SMALL), seed=3, engine="compiled")
    model.learn(10**6, callback=[ends, StopTrainingOnMaxEpisodes(7)], progress_bar=True)
    log = model.episode_log
    assert len(log) == 7 and [episodes for _, _, episodes in ends.seen] == list(range(1, 8))
    assert all(done for _, done, _ in ends.seen)
    assert [t for t, _, _ in ends.seen] == log.decisions.cumsum().tolist()
    assert ends.n_calls == model.num_timesteps
    reference = AffectQ("Grid", gym.make(GRID, **SMALL), seed=3, engine="python")
    reference.learn(10**6, callback=StopTrainingOnMaxEpisodes(7))
    pd.testing.assert_frame_equal(log, reference.episode_log)


def _csv_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "progress.csv").open() as handle:
        return [{k: v for k, v in row.items() if not k.startswith("time/")} for row in csv.DictReader(handle)]


@pytest.mark.parametrize("cls", [QLearning, AffectQ, Boltzmann])
def test_logger_output_is_the_python_engines(cls: type, tmp_path: Path) -> None:
    rows = []
    for engine in ("python", "compiled"):
        model = cls("Grid", gym.make(GRID, **SMALL), seed=2, engine=engine)
        model.set_logger(configure(str(tmp_path / engine), ["csv"]))
        model.learn(3000, log_interval=3)
        rows.append(_csv_rows(tmp_path / engine))
        assert {row.pop("train/engine") for row in rows[-1]} == {engine}  # the one key that says which engine ran
    assert len(rows[0]) >= 5 and rows[1] == rows[0]


# -- continuing across engines ----------------------------------------------------------------------------------------
def _everything(model: Any) -> dict[str, Any]:
    env = model.env.envs[0]
    state = {
        "log": model.episode_log.fillna(-1.0).to_dict("list"),  # NaN != NaN
        "q": model.q_table.tolist(),
        "rng": model._rng.getstate(),
        "t": model.num_timesteps,
        "episode_state": model._episode_state,
        "last_obs": model._last_obs.tolist(),
        "episodes": model._episode_num,
        "ep_info": [(e["r"], e["l"], e["c"]) for e in model.ep_info_buffer],
        "env": env.unwrapped.state,
        "monitor": (env.rewards, env.episode_returns, env.episode_lengths, env.total_steps, env.needs_reset),
        "time_limit": env.env._elapsed_steps,
    }
    if isinstance(model, AffectQ):
        state["appraisal"] = model.emotion_callback.appraiser.get_state()
        state["counts"] = model.emotion_callback.counts
    if isinstance(model, UCBQLearning):
        state["ucb"] = (model.counts, model._totals)
    return state


@pytest.mark.parametrize("cls", [QLearning, AffectQ, UCBQLearning])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_learning_continues_on_either_engine(cls: type, seed: int) -> None:
    results = []
    for first, second in (("python", "python"), ("python", "compiled"), ("compiled", "python"), ("compiled", "compiled")):
        model = cls("Grid", gym.make(GRID, max_episode_steps=60, **SMALL), seed=seed, engine=first)
        model.learn(537)  # stops in the middle of an episode
        model.engine = second
        model.learn(1000, reset_num_timesteps=False, callback=StopTrainingOnMaxEpisodes(4))
        model.engine = first
        model.learn(211, reset_num_timesteps=False)
        results.append(_everything(model))
    assert results[1] == results[0] and results[2] == results[0] and results[3] == results[0]


def test_a_known_map_with_a_move_the_env_does_not_have_is_refused_by_the_kernel() -> None:
    model = AffectQ("Grid", gym.make(GRID, **SMALL), seed=0, engine="python")
    model.learn(300)
    known = model.emotion_callback.appraiser.known
    known.successors[0].add(35)  # cell (0, 0) -> (5, 5): no move of a 6 x 6 grid does that
    model.engine = "compiled"
    with pytest.raises(ValueError, match="has a move 0 -> 35 that this env does not have"):
        model.learn(10, reset_num_timesteps=False)


# -- tie_break and multi_cell (both engines) --------------------------------------------------------------------------
@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_tie_break_first_takes_the_lowest_action_without_a_draw(engine: str) -> None:
    model = QLearning(
        "Grid", gym.make(GRID, **SMALL), exploration_rate=0.0, tie_break="first", max_episode_decisions=50, seed=4,
        engine=engine,
    )  # fmt: skip
    model.learn(50)
    row = model.episode_log.iloc[0]
    assert bool(row.truncated) and row.decisions == 50 and row.cells == 50  # always "up" from the top row: stuck
    reference = random.Random(4)
    for _ in range(50):  # the epsilon draws only: no draw for the four-way ties
        reference.random()
    assert model._rng.getstate() == reference.getstate()


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("multi_cell", ["steps", "jump"])
def test_jump_makes_one_update_from_the_start_to_the_end_cell(engine: str, multi_cell: str) -> None:
    for seed in range(100):  # find a seed whose first decision moves right twice, into the goal
        model = SpeedEpsilonGreedy(
            "Grid", gym.make(GRID, size=3, goal=(0, 2)), speeds=(2,), exploration_rate=1.0, multi_cell=multi_cell,
            seed=seed, engine=engine,
        )  # fmt: skip
        model.learn(100, callback=StopTrainingOnMaxEpisodes(1))
        first = model.episode_log.iloc[0]
        if first.decisions == 1 and first.cells == 2 and not first.truncated:
            break
    else:
        pytest.fail("no seed moved right first")
    q = model.q_table
    if multi_cell == "jump":  # one update: (0, 0) -> (0, 2) with the goal's reward; (0, 1) untouched
        assert q[0, RIGHT] == 100.0 and q[1, RIGHT] == 0.0
    else:  # two updates: (0, 0) -> (0, 1) bootstraps a zero row, then (0, 1) -> goal
        assert q[0, RIGHT] == 0.0 and q[1, RIGHT] == 100.0


def test_simulate_engine_choice() -> None:
    python = simulate("AffectQ", {}, GRID, SMALL, [5, 6], 5, engine="python")
    compiled = simulate("AffectQ", {}, GRID, SMALL, [5, 6], 5, engine="compiled")
    pd.testing.assert_frame_equal(compiled, python)
    moving = "sb3_affect/MovingPursuit-v0"
    pd.testing.assert_frame_equal(
        simulate("QLearning", {}, moving, None, [1], 2, engine="compiled"),
        simulate("QLearning", {}, moving, None, [1], 2, engine="python"),
    )
    with pytest.raises(ValueError, match="depends on the training progress"):
        simulate("QLearning", {"exploration_rate": lambda p: 0.1 * p}, moving, None, [1], 2, engine="compiled")
    with pytest.raises(ValueError, match="engine='turbo'"):
        simulate("QLearning", {}, GRID, None, [1], 2, engine="turbo")
    assert len(simulate("QLearning", {}, GRID, None, [], 3)) == 0


def test_the_kernels_cache_is_dropped_when_any_kernel_source_changes(tmp_path: Path) -> None:
    """numba checks a cached function against its own file only: a change in a file it calls must drop the cache too."""
    from sb3_affect.kernel import refresh_cache

    sources, cache = tmp_path / "kernel", tmp_path / "kernel" / "__pycache__"
    cache.mkdir(parents=True)
    (sources / "loop.py").write_text("a = 1\n")
    (sources / "batch.py").write_text("b = 1\n")
    cached = [cache / "batch.run_seeds-20.py311.nbi", cache / "batch.run_seeds-20.py311.1.nbc"]
    for path in cached:
        path.write_bytes(b"compiled")
    assert refresh_cache(sources, cache)  # no digest yet: the cache's origin is unknown
    assert not any(path.exists() for path in cached)
    for path in cached:
        path.write_bytes(b"compiled")
    assert not refresh_cache(sources, cache) and all(path.exists() for path in cached)  # same sources: kept
    (sources / "loop.py").write_text("a = 2\n")  # a callee changed, batch.py did not
    assert refresh_cache(sources, cache)
    assert not any(path.exists() for path in cached)
    assert not refresh_cache(sources, cache)


def test_envs_built_anew_with_the_same_table_share_its_arrays_and_others_get_their_own() -> None:
    from sb3_affect.kernel.grid_inputs import TableArrays

    def arrays_of(**kwargs: Any) -> TableArrays:
        return TableArrays.of(gym.make("sb3_affect/GridPursuit-v0", **kwargs).unwrapped)

    first, again = arrays_of(), arrays_of()
    assert again is first  # two gym.make of one table: its arrays made once
    other_goal, other_reward = arrays_of(goal=(3, 3)), arrays_of(step_reward=-1.0)
    assert other_goal is not first and other_reward is not first
    assert other_goal.goal != first.goal and other_reward.step_reward == -1.0 and first.step_reward == 0.0
    table = gym.make("sb3_affect/GridPursuit-v0", goal=(3, 3)).unwrapped.transition_table()
    assert np.array_equal(other_goal.trans, np.asarray(table.transitions)) and other_goal.goal == table.goal
