"""The episode log kept in columnar blocks: the same DataFrame as the rows it replaces, and model files of either layout."""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

from sb3_affect import AffectQ, QLearning
from sb3_affect.core.episode_blocks import EpisodeBlocks
from sb3_affect.core.episode_log import EPISODE_COLUMNS, make_frame

DATA = Path(__file__).resolve().parents[1] / "data"


def _row(episode: int, optimal: object = True, greedy: object = False, norm: float = math.nan) -> list[object]:
    return [episode, 12, 12, 100.0, optimal, False, 1, 0, 3, 2, 1, 0, greedy, norm]


@pytest.mark.parametrize(
    "rows",
    [
        [],
        [_row(1)],
        [_row(i, optimal=i % 2 == 0, norm=float(i)) for i in range(1, 30)],
        [_row(i, optimal=math.nan, greedy=math.nan) for i in range(1, 5)],  # an env without geometry
        [_row(1), _row(2, optimal=math.nan)],  # flags and NaN in one column
    ],
)
def test_blocks_give_the_frame_and_rows_of_the_rows(rows: list[list[object]]) -> None:
    blocks = EpisodeBlocks.from_rows(rows)
    assert len(blocks) == len(rows)
    pd.testing.assert_frame_equal(blocks.frame(), make_frame(rows))
    assert json.dumps(blocks.rows()) == json.dumps(rows)
    if rows:
        assert json.dumps(blocks.last()) == json.dumps(rows[-1])
        assert blocks.value("episode") == len(rows)


def test_row_buffer_and_column_blocks_keep_their_order() -> None:
    blocks = EpisodeBlocks.from_rows([_row(1), _row(2)])
    n = 3
    block = {name: np.array([v] * n) for name, v in zip(EPISODE_COLUMNS, _row(0))}
    block["episode"] = np.arange(3, 3 + n)
    block["optimal"] = np.zeros(n, dtype=bool)
    block["greedy_optimal"] = np.zeros(n, dtype=bool)
    blocks.append_columns(block)
    blocks.append_row(_row(6))
    assert len(blocks) == 6
    assert blocks.last() == _row(6)
    rows = blocks.rows()
    assert [r[0] for r in rows] == [1, 2, 3, 4, 5, 6]
    assert all(type(v) is type(w) for r in rows for v, w in zip(r, _row(0)) if not isinstance(w, bool))
    pd.testing.assert_frame_equal(blocks.frame(), make_frame(rows))
    with pytest.raises(ValueError, match="same length"):
        blocks.append_columns({**block, "cells": np.zeros(1, dtype=np.int64)})


def test_many_small_blocks_are_joined() -> None:
    blocks = EpisodeBlocks()
    for i in range(600):
        block = {name: np.array([v]) for name, v in zip(EPISODE_COLUMNS, _row(i + 1, norm=0.5))}
        blocks.append_columns(block)
    assert len(blocks._blocks) < 256
    assert blocks.frame()["episode"].tolist() == list(range(1, 601))


@pytest.mark.parametrize("cls, kwargs", [(QLearning, {"exploration_rate": 0.2}), (AffectQ, {})])
def test_both_engines_keep_the_same_log(cls: type, kwargs: dict[str, object]) -> None:
    logs = {}
    for engine in ("python", "compiled"):
        model = cls("Grid", gym.make("sb3_affect/GridPursuit-v0", size=6, goal=[4, 4]), seed=5, engine=engine, **kwargs)
        model.learn(3000)
        model.learn(1000, reset_num_timesteps=False)
        logs[engine] = model.episode_log
        pd.testing.assert_frame_equal(make_frame(model._episode_blocks.rows()), logs[engine])
    pd.testing.assert_frame_equal(logs["python"], logs["compiled"])


@pytest.mark.parametrize("name, cls", [("qlearning", QLearning), ("affectq", AffectQ)])
def test_files_of_the_row_layout_load_and_save_the_same(name: str, cls: type, tmp_path: Path) -> None:
    """Files saved before the columnar log (the log as a list of rows in ``data``) load with the same log, and a model
    saved now stores the log in that same form."""
    path = DATA / f"main_layout_{name}.zip"
    saved_rows = json.loads(zipfile.ZipFile(path).read("data"))["_episode_rows"]
    assert saved_rows
    for safe in (True, False):
        model = cls.load(path, safe=safe)
        pd.testing.assert_frame_equal(model.episode_log, make_frame(saved_rows))
    model.save(tmp_path / "again.zip")
    again = json.loads(zipfile.ZipFile(tmp_path / "again.zip").read("data"))
    assert json.dumps(again["_episode_rows"]) == json.dumps(saved_rows)
    assert "_episode_blocks" not in again and not hasattr(model, "_episode_rows")
    pd.testing.assert_frame_equal(cls.load(tmp_path / "again.zip").episode_log, make_frame(saved_rows))


def test_a_learnt_model_round_trips_its_log(tmp_path: Path) -> None:
    model = AffectQ("Grid", gym.make("sb3_affect/GridPursuit-v0", size=6, goal=[4, 4]), seed=2)
    model.learn(2000)
    model.save(tmp_path / "m.zip")
    loaded = AffectQ.load(tmp_path / "m.zip", env=gym.make("sb3_affect/GridPursuit-v0", size=6, goal=[4, 4]))
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    loaded.learn(500, reset_num_timesteps=False)
    assert len(loaded.episode_log) > len(model.episode_log)


@pytest.mark.parametrize("step_reward", [0.0, -0.1])
def test_the_monitor_sees_the_same_returns_on_both_engines(step_reward: float) -> None:
    seen = []
    for engine in ("python", "compiled"):
        env = gym.make("sb3_affect/GridPursuit-v0", size=6, goal=[4, 4], step_reward=step_reward, max_episode_steps=40)
        model = QLearning("Grid", env, exploration_rate=0.3, seed=8, engine=engine)
        model.learn(3000)
        monitor = model.env.envs[0]
        seen.append((repr(monitor.episode_returns), monitor.episode_lengths, [e["r"] for e in model.ep_info_buffer]))
    assert seen[0] == seen[1]
    assert len(seen[0][1]) > 20


def test_a_chunk_of_few_episodes_keeps_no_large_buffer() -> None:
    """The kernel's output rows are handed to the log when a chunk fills them well, and copied when it does not."""
    model = QLearning("Grid", gym.make("sb3_affect/GridPursuit-v0"), seed=0, exploration_rate=0.1)
    model.learn(600)  # a handful of episodes in the room of a whole chunk
    few = model._episode_blocks._blocks[-1]
    assert few["decisions"].base.shape[0] == len(few["decisions"]) < 100  # a copy of just the rows
    model.learn(200_000, reset_num_timesteps=False)  # thousands of episodes: the rows themselves, no copy
    many = model._episode_blocks._blocks[-1]
    assert many["decisions"].base.shape[0] >= len(many["decisions"]) > 4000
    python = QLearning("Grid", gym.make("sb3_affect/GridPursuit-v0"), seed=0, exploration_rate=0.1, engine="python")
    python.learn(600)
    python.learn(200_000, reset_num_timesteps=False)
    pd.testing.assert_frame_equal(model.episode_log, python.episode_log)
