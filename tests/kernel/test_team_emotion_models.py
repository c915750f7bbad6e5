"""
A second emotion model that runs compiled takes its modules and one registry entry: registered beside Broekens', a
"surprise" model (the size of a decision's TD error, ``|delta|`` per decision: Broekens' joy plus distress) keeps team
runs on the team kernel, whose record equals the Python team's for both models, column for column; a model without a
kernel module sends team runs to the Python team, which records it from the registry.

This module is the second model: its observer (``SurpriseCallback``, an SB3 callback) and its kernel functions
(``N_STATE``, ``COLUMNS``, ``start``, ``observe``, ``close_episode``: the protocol of ``kernel.team_emotions``).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd
import pytest
from numba import cfunc

from sb3_affect.agents.broekens import BroekensCallback
from sb3_affect.core.registry import EMOTION_MODELS, EmotionModel
from sb3_affect.envs import HUNTER_PURSUIT_ID
from sb3_affect.kernel.team_batch import team_settings_inputs
from sb3_affect.kernel.team_emotions import CLOSE_EPISODE, OBSERVE, START
from sb3_affect.study.launcher.one_run import execute_run

SMALL = {"size": 7, "starts": [(0, 0), (6, 6)], "prey_start": (3, 3)}
#: The second model's registry entry: its observer and its kernel functions, both in this module.
SURPRISE = EmotionModel(f"{__name__}:SurpriseCallback", __name__, ("surprise",), ("surprise",))
MEMBERS: list[dict[str, Any]] = [{"algo": "AffectQ", "kwargs": {}}, {"algo": "QLearning", "kwargs": {"exploration_rate": 0.1}}]


class SurpriseCallback(BroekensCallback):
    """The Python observer: ``surprise``, the mean of joy and distress per decision summed (``|delta|``)."""

    @property
    def episode_log(self) -> pd.DataFrame:
        frame = super().episode_log
        return frame.assign(surprise=frame["joy"] + frame["distress"])


V, JOY, DISTRESS = range(3)
N_STATE = 3
COLUMNS = ("surprise",)


@cfunc(START, cache=True)
def start(b: np.ndarray, value: float) -> None:
    b[V] = value


@cfunc(OBSERVE, cache=True)
def observe(b: np.ndarray, reward: float, gamma: float, reached: float) -> None:
    delta = float(np.float32(reward)) + gamma * reached - b[V]
    b[JOY] += max(delta, 0.0)
    b[DISTRESS] += max(-delta, 0.0)
    b[V] = reached


@cfunc(CLOSE_EPISODE, cache=True)
def close_episode(b: np.ndarray, out: np.ndarray, decisions: float, cut: bool) -> None:
    out[0] = b[JOY] / decisions + b[DISTRESS] / decisions
    b[JOY] = b[DISTRESS] = 0.0


def _config(members: list[dict[str, Any]], seed: int) -> dict[str, Any]:
    return {
        "agent": "mixed", "algo": "team", "algo_kwargs": {}, "env_id": HUNTER_PURSUIT_ID,
        "env_kwargs": {**SMALL, "prey": "random"}, "episodes": 6, "labels": {}, "max_timesteps": None, "seed": seed,
        "sweep": "t", "team": members,
    }  # fmt: skip


def _python(members: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**m, "kwargs": {**m["kwargs"], "engine": "python"}} for m in members]


@pytest.mark.parametrize("seed", [3, 11])
def test_a_second_model_with_a_kernel_module_keeps_team_runs_compiled(monkeypatch: pytest.MonkeyPatch, seed: int) -> None:
    monkeypatch.setitem(EMOTION_MODELS, "surprise", SURPRISE)
    inputs = team_settings_inputs([(m["algo"], m["kwargs"]) for m in MEMBERS], HUNTER_PURSUIT_ID, SMALL, 6)
    assert inputs is not None  # the team kernel runs it
    assert list(inputs.emotions.columns) == ["broekens", "surprise"]
    compiled = execute_run(_config(MEMBERS, seed))
    python = execute_run(_config(_python(MEMBERS), seed))
    for hunter in ("hunter_0", "hunter_1"):
        columns = compiled["episodes"]
        joy, distress = (np.array(columns[f"{hunter}/broekens_{name}"]) for name in ("joy", "distress"))
        np.testing.assert_array_equal(np.array(columns[f"{hunter}/surprise_surprise"]), joy + distress)
    assert json.dumps(compiled["episodes"]) == json.dumps(python["episodes"])
    assert compiled["timings"]["decisions"] == python["timings"]["decisions"]


def test_a_model_without_a_kernel_module_sends_team_runs_to_the_python_team(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(EMOTION_MODELS, "surprise", SURPRISE._replace(kernel=None))
    assert team_settings_inputs([(m["algo"], m["kwargs"]) for m in MEMBERS], HUNTER_PURSUIT_ID, SMALL, 3) is None
    columns = execute_run(_config(MEMBERS, 2))["episodes"]
    assert columns == execute_run(_config(_python(MEMBERS), 2))["episodes"]
    assert len(columns["hunter_0/surprise_surprise"]) == 6
