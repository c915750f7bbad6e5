"""
A compiled ``learn`` hands the appraiser's known map and power fit back as the kernel's arrays; the Python objects are
built when something reads them, and the next compiled ``learn`` takes the arrays as they are. Whatever is read, set or
copied in between, the results are the Python loop's.
"""

from __future__ import annotations

import copy
import pickle
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

from sb3_affect import AffectQ
from sb3_affect.core.appraisal import KnownMap

GRID = "sb3_affect/GridPursuit-v0"
MOVING = "sb3_affect/MovingPursuit-v0"
ENVS = [(GRID, {}), (MOVING, {"size": 5, "prey_start": (3, 3), "max_episode_steps": 80})]


def _appraisal(model: AffectQ) -> dict[str, Any]:
    appraiser = model.emotion_callback.appraiser
    fit = appraiser.fit
    return {
        "state": appraiser.get_state(),
        "distance": list(appraiser.known.distance),
        "predecessors": [list(row) for row in appraiser.known.predecessors],
        "fit": (fit.values, fit._sx, fit._sy, fit._sxx, fit._sxy),
        "q": model.q_table.tolist(),
        "log": model.episode_log.fillna(-1.0).to_dict("list"),
    }


def test_the_known_map_and_the_fit_are_built_when_first_read_and_are_the_python_loops() -> None:
    compiled = AffectQ("Grid", gym.make(GRID), seed=3, engine="compiled")
    compiled.learn(6000)
    python = AffectQ("Grid", gym.make(GRID), seed=3, engine="python")
    python.learn(6000)
    appraiser = compiled.emotion_callback.appraiser
    assert appraiser.deferred("known") is not None and appraiser.deferred("fit") is not None
    assert "known" not in vars(appraiser) and "fit" not in vars(appraiser)
    assert len(appraiser.fit.values) == len(python.episode_log) > 50  # read: built now
    assert appraiser.deferred("fit") is None and "fit" in vars(appraiser)
    assert appraiser.deferred("known") is not None  # each attribute is built on its own
    assert _appraisal(compiled) == _appraisal(python)
    assert appraiser.deferred("known") is None
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        appraiser.nothing_here  # noqa: B018


@pytest.mark.parametrize("env_id, env_kwargs", ENVS, ids=["grid", "moving"])
@pytest.mark.parametrize("between", ["nothing", "read", "state"])
def test_a_second_compiled_learn_goes_on_from_the_arrays_or_from_what_was_read(
    env_id: str, env_kwargs: dict[str, Any], between: str
) -> None:
    results = []
    for engine in ("python", "compiled"):
        model = AffectQ("Grid", gym.make(env_id, **env_kwargs), seed=11, engine=engine)
        model.learn(2500)
        appraiser = model.emotion_callback.appraiser
        if between == "read":
            assert appraiser.known.n_states == model.observation_space.n and appraiser.fit is not None
        elif between == "state":  # a full round trip through plain data, as save and load do
            appraiser.set_state(appraiser.get_state())
        model.learn(2500, reset_num_timesteps=False)
        model.learn(1000)  # a new run: the history starts afresh, the known map is kept
        results.append(_appraisal(model))
    assert results[1] == results[0]
    assert len(results[0]["fit"][0]) > 10


def test_a_known_map_set_by_hand_replaces_the_kept_arrays() -> None:
    results = []
    for engine in ("python", "compiled"):
        model = AffectQ("Grid", gym.make(GRID), seed=4, engine=engine)
        model.learn(3000)
        appraiser = model.emotion_callback.appraiser
        appraiser.known = KnownMap(model.observation_space.n)  # forget the map, keep the history
        assert appraiser.deferred("known") is None
        model.learn(3000, reset_num_timesteps=False)
        results.append(_appraisal(model))
    assert results[1] == results[0]


def test_an_appraiser_holding_arrays_copies_pickles_and_saves(tmp_path: Path) -> None:
    model = AffectQ("Grid", gym.make(GRID), seed=8, engine="compiled")
    model.learn(4000)
    appraiser = model.emotion_callback.appraiser
    twins = [copy.deepcopy(appraiser), pickle.loads(pickle.dumps(appraiser))]
    assert all(twin.deferred("known") is not None for twin in twins)
    shallow = copy.copy(appraiser)
    assert shallow.known.state() == twins[0].known.state()  # built on the copy only
    assert appraiser.deferred("known") is not None and shallow.deferred("known") is None
    model.save(tmp_path / "model")  # nothing was read: saving builds what it writes
    assert appraiser.deferred("known") is None
    expected = appraiser.get_state()
    assert [twin.get_state() for twin in twins] == [expected, expected]
    loaded = AffectQ.load(tmp_path / "model", env=gym.make(GRID))
    assert loaded.emotion_callback.appraiser.get_state() == expected
    assert appraiser.known.state()["edges"] and expected["history"]
