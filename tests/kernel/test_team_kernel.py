"""
The team kernel's contract: on HunterPursuit, for the same run seed, ``kernel.team_loop`` gives the identical team log,
each hunter's episode log, Q-table, ``random.Random`` state and known map, the env's NumPy generator state and each
hunter's Broekens observations as ``HunterTeam`` driving the agents one decision at a time, over the env's options
(static, random and evading prey; enter and surround captures; own or all cells observed; 2 and 3 hunters; obstacles,
a maze, rewards, time limits) and every agent kind; and the launcher's team runs use it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from sb3_affect import Behaviour, Emotion
from sb3_affect.agents.broekens import BROEKENS_COLUMNS, BroekensCallback
from sb3_affect.agents.hunter_team import HunterTeam
from sb3_affect.envs import HUNTER_PURSUIT_ID, make_parallel
from sb3_affect.kernel.mt19937 import state_from_rng
from sb3_affect.kernel.pcg64 import state_from_generator
from sb3_affect.kernel.team_batch import hunter_columns, run_team, team_columns, team_settings_inputs
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.one_run import execute_run

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
SEEDS = list(range(15))
SMALL = {"size": 7, "starts": [(0, 0), (6, 6)], "prey_start": (3, 3)}
THREE = {"size": 6, "starts": [(0, 0), (5, 5), (0, 5)], "prey_start": (2, 3)}
EPS = ("QLearning", {"exploration_rate": 0.1})
AFFECT = ("AffectQ", {})
TABLE = {
    Emotion.JOY: Behaviour(False, (0, 1, 2)),
    Emotion.SADNESS: Behaviour(True, (1,)),
    Emotion.FEAR: Behaviour(True, (2, 0)),
    Emotion.ANGER: Behaviour(True, (1, 2, 3)),
}

# (id, members, env kwargs, episodes)
CASES: list[tuple[str, list[tuple[str, dict[str, Any]]], dict[str, Any], int]] = [
    ("eps-static", [EPS, EPS], SMALL, 10),
    ("affect-static", [AFFECT, AFFECT], SMALL, 10),
    ("mixed-kuremoto", [AFFECT, EPS], {}, 4),
    ("mixed-random", [EPS, AFFECT], {**SMALL, "prey": "random"}, 10),
    ("affect-evade", [AFFECT, AFFECT], {**SMALL, "prey": "evade", "prey_speed": 0.7}, 10),
    ("surround-static", [AFFECT, EPS], {**SMALL, "capture": "surround", "max_cycles": 150}, 6),
    ("surround-evade-three", [AFFECT, EPS, AFFECT], {**THREE, "prey": "evade", "capture": "surround", "max_cycles": 60}, 6),
    ("all-static", [AFFECT, AFFECT], {**SMALL, "observation": "all"}, 6),
    ("all-random", [AFFECT, EPS], {"size": 5, "starts": [(0, 0), (4, 4)], "prey_start": (2, 2), "prey": "random",
                                   "observation": "all", "max_cycles": 80}, 5),
    ("all-three", [AFFECT, EPS, AFFECT], {**THREE, "observation": "all", "max_cycles": 80}, 5),
    ("random-three", [EPS, AFFECT, EPS], {**THREE, "prey": "random"}, 8),
    ("obstacles-rewards", [AFFECT, EPS], {**SMALL, "obstacles": [(1, 1), (2, 2), (4, 3)], "goal_reward": 50.0,
                                          "step_reward": -1.0}, 8),
    ("maze", [AFFECT, EPS], {"maze": "rooms", "starts": [(1, 1), (1, 2)], "prey": "random"}, 3),
    ("boltzmann-ucb", [("sb3_affect.agents.baselines:Boltzmann", {"temperature": 2.0}),
                       ("UCBQLearning", {"exploration_coef": 2.0})], {**SMALL, "prey": "random"}, 8),
    ("decaying-speed", [("sb3_affect.agents.baselines:DecayingEpsilonGreedy", {"exploration_decay_episodes": 4}),
                        ("sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": [0, 1, 2]})], SMALL, 8),
    ("jump-table-optimistic", [("AffectQ", {"behaviour_table": TABLE, "multi_cell": "jump", "tie_break": "first"}),
                               ("sb3_affect.agents.baselines:OptimisticQLearning", {"q_init": 10.0})], SMALL, 8),
    ("readings-caps", [("AffectQ", {"comparison": "valence", "act": "remaining", "units": "decisions",
                                    "max_episode_decisions": 40}),
                       ("AffectQ", {"personality": "pessimistic", "max_episode_decisions": 60})],
     {**SMALL, "prey": "evade"}, 8),
]  # fmt: skip


def _frame(columns: dict[str, list[Any]], like: pd.DataFrame) -> pd.DataFrame:
    frame = pd.DataFrame({name: [np.nan if v is None else v for v in values] for name, values in columns.items()})
    return frame.astype(like.dtypes.to_dict())


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_team_kernel_equals_the_python_team(case: tuple[str, list[tuple[str, dict[str, Any]]], dict[str, Any], int]) -> None:
    _, members, env_kwargs, episodes = case
    inputs = team_settings_inputs(members, HUNTER_PURSUIT_ID, env_kwargs, episodes)
    assert inputs is not None
    for seed in SEEDS:
        team = HunterTeam(make_parallel(HUNTER_PURSUIT_ID, **env_kwargs), members, seed=seed)
        observers = {agent: BroekensCallback() for agent in team.models}
        team.learn(episodes, callbacks=observers)
        run = run_team(inputs, seed, episodes)
        expected = team.episode_log
        got = team_columns(inputs, run)
        pd.testing.assert_frame_equal(_frame({k: got[k] for k in expected.columns}, expected), expected, obj=f"seed {seed}")
        for m, (agent, model) in enumerate(team.models.items()):
            log = model.episode_log
            pd.testing.assert_frame_equal(_frame(hunter_columns(inputs, run, m), log), log, obj=f"seed {seed} {agent}")
            felt = observers[agent].episode_log
            for name in (n for n in BROEKENS_COLUMNS[3:] if n != "env"):  # a hunter observes one env: no env column
                values = np.array([np.nan if v is None else v for v in got[f"{agent}/broekens_{name}"]])
                np.testing.assert_array_equal(values, felt[name].to_numpy(), err_msg=f"seed {seed} {agent} {name}")
            assert np.array_equal(run.q[m], model.q_table), f"seed {seed} {agent}: Q-table"
            assert np.array_equal(run.mt[m], state_from_rng(model._rng)[0]), f"seed {seed} {agent}: generator"
            callback = getattr(model, "emotion_callback", None)
            if callback is not None:
                assert run.dist[m].tolist() == callback.appraiser.known.distance, f"seed {seed} {agent}: known map"
        assert np.array_equal(run.pcg, state_from_generator(team.env.np_random)), f"seed {seed}: the env's generator"


def test_a_team_run_record_is_the_same_on_the_kernel_and_on_the_python_team() -> None:
    members = [{"algo": "AffectQ", "kwargs": {}}, {"algo": "QLearning", "kwargs": {"exploration_rate": 0.1}}]
    config = {
        "agent": "mixed", "algo": "team", "algo_kwargs": {}, "env_id": HUNTER_PURSUIT_ID,
        "env_kwargs": {**SMALL, "prey": "random"}, "episodes": 6, "labels": {}, "max_timesteps": None, "seed": 7,
        "sweep": "t", "team": members,
    }  # fmt: skip
    compiled = execute_run(config)
    python = execute_run({**config, "team": [{**m, "kwargs": {**m["kwargs"], "engine": "python"}} for m in members]})
    assert json.dumps(compiled["episodes"]) == json.dumps(python["episodes"])
    assert compiled["timings"]["decisions"] == python["timings"]["decisions"]


def test_team_sweeps_run_in_team_batches(tmp_path: Path) -> None:
    overrides = ["episodes=5", "seeds=[0, 1, 2]", "env.kwargs={size: 7, starts: [[0, 0], [6, 6]], prey_start: [3, 3]}"]
    summary = run_sweep(EXPERIMENTS / "hunters.yaml", tmp_path / "h", workers=2, overrides=overrides, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (12, 12, 0)
    files = sorted((tmp_path / "h" / "runs").glob("*.json"))
    assert len(files) == 12 and not list((tmp_path / "h" / "runs").glob(".tmp-*"))
    record = json.loads(files[0].read_text())
    config = record["config"]
    assert record["episodes"] == execute_run(config)["episodes"]
    assert team_settings_inputs([("AffectQ", {"device": "cpu"}), EPS], HUNTER_PURSUIT_ID, {}, 5) is None  # a model's


def test_teams_whose_known_maps_would_not_fit_run_on_the_python_team() -> None:
    """Three affective hunters observing all cells and a moving prey: 25**4 observations, known maps over 1 GB."""
    env_kwargs = {"size": 5, "starts": [(0, 0), (4, 4), (0, 4)], "prey_start": (2, 2), "prey": "random", "observation": "all"}
    members = [AFFECT, AFFECT, AFFECT]
    assert team_settings_inputs(members, HUNTER_PURSUIT_ID, env_kwargs, 2) is None
    config = {
        "agent": "a", "algo": "team", "algo_kwargs": {}, "env_id": HUNTER_PURSUIT_ID, "env_kwargs": env_kwargs,
        "episodes": 2, "labels": {}, "max_timesteps": None, "seed": 1, "sweep": "t",
        "team": [{"algo": a, "kwargs": k} for a, k in members],
    }  # fmt: skip
    assert len(execute_run(config)["episodes"]["decisions"]) == 2


def test_a_team_run_records_every_emotion_model_of_the_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every model of the registry is computed beside each hunter (here Broekens' twice, both on the team kernel)."""
    from sb3_affect.core.registry import EMOTION_MODELS

    monkeypatch.setitem(EMOTION_MODELS, "again", EMOTION_MODELS["broekens"])
    members = [AFFECT, EPS]
    assert team_settings_inputs(members, HUNTER_PURSUIT_ID, SMALL, 3) is not None
    config = {
        "agent": "mixed", "algo": "team", "algo_kwargs": {}, "env_id": HUNTER_PURSUIT_ID, "env_kwargs": SMALL,
        "episodes": 3, "labels": {}, "max_timesteps": None, "seed": 2, "sweep": "t",
        "team": [{"algo": a, "kwargs": k} for a, k in members],
    }  # fmt: skip
    columns = execute_run(config)["episodes"]
    for hunter in ("hunter_0", "hunter_1"):
        for name in EMOTION_MODELS["broekens"].columns:
            assert columns[f"{hunter}/again_{name}"] == columns[f"{hunter}/broekens_{name}"], (hunter, name)
