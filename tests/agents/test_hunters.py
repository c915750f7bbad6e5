"""Several hunters: the PettingZoo env, the decision stepper (= learn), teams of independent learners, team sweeps."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from pettingzoo.test import parallel_api_test
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.baselines import Boltzmann, SpeedEpsilonGreedy, UCBQLearning
from sb3_affect.agents.hunter_team import TEAM_COLUMNS, HunterTeam, HunterView
from sb3_affect.agents.stepping import DecisionStepper
from sb3_affect.envs import HUNTER_PURSUIT_ID, make_parallel
from sb3_affect.envs.hunter_pursuit import STAY, HunterPursuitEnv
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.schema import SweepError
from sb3_affect.study.launcher.sweep_file import load_sweep
from sb3_affect.study.report import build_report

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
UP, DOWN, LEFT, RIGHT = 0, 1, 2, 3


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"size": 5, "starts": [(0, 0), (4, 4), (0, 4)], "prey_start": (2, 2), "prey": "random", "observation": "all"},
        {
            "size": 6,
            "starts": [(0, 0), (5, 5)],
            "prey_start": (2, 2),
            "prey": "evade",
            "capture": "surround",
            "max_cycles": 40,
        },
        {"maze": "rooms", "starts": [(1, 1), (1, 2)], "prey": "random"},
    ],
)
def test_env_passes_pettingzoos_parallel_api_test(kwargs: dict) -> None:
    parallel_api_test(make_parallel(HUNTER_PURSUIT_ID, **kwargs), num_cycles=300)


def test_default_is_kuremotos_layout() -> None:
    env = make_parallel(HUNTER_PURSUIT_ID)
    assert (env.size, env.starts, env.prey_start, env.prey, env.capture) == (17, ((2, 2), (14, 14)), (9, 9), "static", "enter")
    assert env.possible_agents == ["hunter_0", "hunter_1"]
    assert env.observation_space("hunter_0") == gym.spaces.Discrete(289)
    assert env.action_space("hunter_1") == gym.spaces.Discrete(5)
    assert env.capture_distance == 10  # from (14, 14)
    obs, _ = env.reset(seed=0)
    assert obs == {"hunter_0": 2 * 17 + 2, "hunter_1": 14 * 17 + 14}


def test_enter_capture_rewards_the_capturer_and_ends_for_everyone() -> None:
    env = HunterPursuitEnv(size=5, starts=[(2, 1), (0, 0)], prey_start=(2, 2))
    env.reset(seed=0)
    _, rewards, terms, truncs, infos = env.step({"hunter_0": RIGHT, "hunter_1": STAY})
    assert rewards == {"hunter_0": 100.0, "hunter_1": 0.0}
    assert terms == {"hunter_0": True, "hunter_1": True} and not any(truncs.values())
    assert infos["hunter_0"]["capturer"] and not infos["hunter_1"]["capturer"] and infos["hunter_1"]["captured"]
    assert env.agents == [] and env.optimal_capture([1, 1], [0]) and not env.optimal_capture([1, 1], [])


def test_surround_capture_needs_every_hunter_next_to_the_prey() -> None:
    env = HunterPursuitEnv(size=5, starts=[(2, 1), (0, 3)], prey_start=(2, 2), capture="surround")
    assert env.capture_distance == 2  # (2, 1) is next to the prey already, (0, 3) walks 2 cells to (1, 2)
    env.reset(seed=0)
    _, rewards, terms, _, infos = env.step({"hunter_0": RIGHT, "hunter_1": STAY})  # a hunter can not enter the prey
    assert infos["hunter_0"]["cell"] == (2, 1) and not any(terms.values()) and set(rewards.values()) == {0.0}
    _, rewards, terms, _, _ = env.step({"hunter_0": STAY, "hunter_1": DOWN})  # (1, 3): diagonal, not next to it
    assert not any(terms.values())
    _, rewards, terms, _, _ = env.step({"hunter_0": STAY, "hunter_1": LEFT})  # (1, 2): above the prey
    assert all(terms.values()) and rewards == {"hunter_0": 100.0, "hunter_1": 100.0}


def test_observations_self_and_all() -> None:
    env = HunterPursuitEnv(size=4, starts=[(0, 0), (3, 3)], prey_start=(1, 2), prey="random", observation="all")
    assert env.observation_space("hunter_0").n == 16**3
    obs, _ = env.reset(seed=1)
    assert obs["hunter_0"] == (0 * 16 + 15) * 16 + 6 and obs["hunter_1"] == (15 * 16 + 0) * 16 + 6
    own = HunterPursuitEnv(size=4, starts=[(0, 0), (3, 3)], prey_start=(1, 2), prey="random")
    assert own.observation_space("hunter_1").n == 16**2 and own.reset(seed=1)[0]["hunter_1"] == 15 * 16 + 6


def test_evading_prey_never_steps_onto_a_hunter_and_flees() -> None:
    env = HunterPursuitEnv(size=7, starts=[(3, 2)], prey_start=(3, 3), prey="evade", prey_speed=1.0)
    env.reset(seed=0)
    _, _, terms, _, infos = env.step({"hunter_0": STAY})
    assert not terms["hunter_0"] and infos["hunter_0"]["prey"] == (3, 4)  # one cell farther from the hunter


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"starts": [(9, 9)]}, "starts[0]=(9, 9) equals prey_start"),
        ({"starts": [(2, 2), (17, 0)]}, "starts[1]"),
        ({"prey": "fast"}, "prey='fast' is not supported"),
        ({"capture": "touch"}, "capture='touch' is not supported"),
        ({"observation": "none"}, "observation='none' is not supported"),
        ({"size": 3, "starts": [(0, 0)] * 5, "prey_start": (1, 1), "capture": "surround"}, "4 free neighbours for 5 hunters"),
        ({"max_cycles": 0}, "max_cycles=0"),
    ],
)
def test_bad_arguments_name_the_field(kwargs: dict, message: str) -> None:
    with pytest.raises((ValueError, TypeError), match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        make_parallel(HUNTER_PURSUIT_ID, **kwargs)
    with pytest.raises(ValueError, match="not registered"):
        make_parallel("sb3_affect/Nope-v0")


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (QLearning, {"exploration_rate": 0.3}),
        (AffectQ, {}),
        (Boltzmann, {"temperature": 3.0}),
        (UCBQLearning, {}),
        (AffectQ, {"multi_cell": "jump", "tie_break": "first"}),
        (SpeedEpsilonGreedy, {"multi_cell": "jump"}),
    ],
)
def test_decision_stepper_is_learn_one_decision_at_a_time(cls: type, kwargs: dict) -> None:
    """Driving one env through the stepper gives learn()'s episode log and Q-table: the same code, the same draws."""

    def make() -> gym.Env:
        return gym.make("sb3_affect/GridPursuit-v0", size=7, goal=(3, 3))

    reference = cls("Grid", make(), seed=5, max_episode_decisions=60, **kwargs)
    reference.learn(10**7, callback=StopTrainingOnMaxEpisodes(40))
    env = make()
    model = cls("Grid", env, seed=5, max_episode_decisions=60, **kwargs)
    stepper = DecisionStepper(model, 10**7)
    episodes = 0
    while episodes < 40:
        action, cells, _ = stepper.decide()
        terminated = truncated = False
        for _ in range(cells):
            obs, reward, terminated, truncated, info = env.step(action)
            stepper.transition(obs, reward, terminated, truncated, info)
            if terminated or truncated:
                break
        episodes += stepper.end_decision(terminated, truncated, reset=lambda: env.reset()[0])
    stepper.close()
    assert reference.episode_log.truncated.any()  # the safety cap was exercised too
    pd.testing.assert_frame_equal(model.episode_log, reference.episode_log)
    np.testing.assert_array_equal(model.q_table, reference.q_table)
    assert model.num_timesteps == reference.num_timesteps


def test_a_mixed_team_learns_and_every_hunter_keeps_its_own_log() -> None:
    def run() -> HunterTeam:
        env = make_parallel(HUNTER_PURSUIT_ID, size=9, starts=[(0, 0), (8, 8)], prey_start=(4, 4))
        members = [("AffectQ", {}), (QLearning, {"exploration_rate": 0.1})]
        return HunterTeam(env, members, seed=3).learn(60)

    team = run()
    log = team.episode_log
    assert tuple(log.columns) == TEAM_COLUMNS and len(log) == 60
    assert isinstance(team.models["hunter_0"], AffectQ) and isinstance(team.models["hunter_1"], QLearning)
    own = {agent: model.episode_log for agent, model in team.models.items()}
    for i, agent in enumerate(team.models):
        assert len(own[agent]) == 60
        assert (own[agent].decisions == log.decisions).all()  # one decision per hunter per round
        assert (~own[agent].truncated >= (log.capturer == i)).all()  # the capturer's episode ended at the goal ...
        assert (own[agent].optimal == (own[agent].cells == 8) & ~own[agent].truncated).all()
        assert (own[agent].cells <= log.cells).all()
    assert (own["hunter_0"].truncated ^ own["hunter_1"].truncated).mean() > 0.9  # ... the other's was cut off (ties: both)
    assert (own["hunter_1"].cells == own["hunter_1"].decisions).all()  # QLearning: one cell per decision
    assert (log.joy + log.sadness + log.fear + log.anger == log.decisions).all()  # only the affective hunter feels
    assert (~log.truncated).all() and set(log.capturer) <= {0, 1}
    captured_straight = [~own[a].truncated & (own[a].cells <= 8) for a in team.models]  # 8: from either start
    assert (log.optimal == (captured_straight[0] | captured_straight[1])).all() and log.optimal.any()
    assert log.decisions.iloc[-20:].mean() < log.decisions.iloc[:20].mean()  # the team learned
    pd.testing.assert_frame_equal(run().episode_log, log)  # same seed, same numbers
    with pytest.raises(RuntimeError, match="moved by its HunterTeam"):
        team.models["hunter_0"].learn(10)


def test_teams_of_baselines_and_surrounding_hunters() -> None:
    env = make_parallel(HUNTER_PURSUIT_ID, size=6, starts=[(0, 0), (5, 5)], prey_start=(2, 2), capture="surround")
    team = HunterTeam(
        env, [("sb3_affect.agents.baselines:UCBQLearning", {}), ("sb3_affect.agents.baselines:SpeedEpsilonGreedy", {})], seed=0
    )
    log = team.learn(15).episode_log
    assert len(log) == 15 and (log.capturer == 0).all()  # surround: every hunter is rewarded, the first is named
    own = {agent: model.episode_log for agent, model in team.models.items()}
    assert env.capture_distance == 5 and (log.optimal == (np.maximum(own["hunter_0"].cells, own["hunter_1"].cells) <= 5)).all()
    assert (~log.truncated).all() and (log.reward == 200.0).all()  # both rewarded for every capture


def test_team_errors_name_the_problem() -> None:
    env = make_parallel(HUNTER_PURSUIT_ID)
    with pytest.raises(ValueError, match="members: 1 given for 2 hunters"):
        HunterTeam(env, [("QLearning", {})])
    with pytest.raises(TypeError, match="members\\[1\\]: 'DQN' is not a tabular agent"):
        HunterTeam(env, [("QLearning", {}), ("DQN", {})])
    assert isinstance(HunterView(env, "hunter_1").observation_space, gym.spaces.Discrete)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def test_team_sweep_schema_errors(tmp_path: Path) -> None:
    head = "name: t\nepisodes: 3\nseeds: 1\n"
    cases = {
        "env: {id: sb3_affect/GridPursuit-v0}\nagents: [{name: a, team: [{algo: QLearning}]}]": "a team needs a multi-agent",
        "env: {id: sb3_affect/HunterPursuit-v0}\nagents: [{name: a, algo: QLearning}]": "give a team, not algo",
        "env: {id: sb3_affect/HunterPursuit-v0}\nagents: [{name: a, team: [{algo: DQN}, {algo: DQN}]}]": "team members",
        "env: {id: sb3_affect/HunterPursuit-v0}\nagents: [{name: a, team: [{algo: AffectQ, kwargs: {q_init: $x}}]}]": (
            "team\\[0\\].kwargs.q_init='\\$x' refers to no grid label"
        ),
        "env: {id: sb3_affect/HunterPursuit-v0}\nagents: [{name: a, team: [{algo: QLearning}]}]": "members: 1 given for 2",
    }
    for body, message in cases.items():
        with pytest.raises(SweepError, match=message):
            load_sweep(_write(tmp_path, head + body))


def test_two_hunter_sweep_runs_from_yaml_and_the_report_gets_both_sections(tmp_path: Path) -> None:
    overrides = ["episodes=25", "seeds=[0, 1]", "env.kwargs={size: 7, starts: [[0, 0], [6, 6]], prey_start: [3, 3]}"]
    summary = run_sweep(EXPERIMENTS / "hunters.yaml", tmp_path / "hunters", workers=2, overrides=overrides, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (8, 8, 0)
    record = json.loads(next((tmp_path / "hunters" / "runs").glob("mixed-affective-far-*.json")).read_text())
    assert record["config"]["team"] == [
        {"algo": "AffectQ", "kwargs": {}},
        {"algo": "QLearning", "kwargs": {"exploration_rate": 0.1}},
    ]
    columns = record["episodes"]
    assert len(columns["decisions"]) == 25 and columns["hunter_0/decisions"] == columns["decisions"]
    assert {"capturer", "hunter_1/optimal", "hunter_0/broekens_joy", "hunter_1/broekens_fear"} <= set(columns)
    assert sum(columns["hunter_1/joy"]) == 0 < sum(columns["hunter_0/joy"])  # QLearning has no emotions of its own

    # the report: a results folder holding hunters/ gets the two sections (tables, verdict lines, figures)
    run_sweep(EXPERIMENTS / "smoke.yaml", tmp_path, workers=2, overrides=["episodes=3"], progress=False)
    main = build_report(tmp_path)
    report = "\n".join(page.read_text() for page in [main, *sorted(tmp_path.glob("appendix-*.md"))])
    assert "## Beyond the paper: two hunters" in report and "## Two emotion models on the same runs" in report
    teams = pd.read_csv(tmp_path / "tables" / "hunters.csv")
    assert list(teams.team) == ["affective", "epsilon-greedy", "mixed-affective-far", "mixed-affective-near"]
    assert (teams.runs == 2).all() and teams["decisions per episode"].str.match(r"^[\d.,]+ \[[\d.,]+, [\d.,]+\]$").all()
    verdicts = [
        line
        for line in report.splitlines()
        if line.startswith(("- **Supported**: hunters-static", "- **Not supported**: hunters-static"))
    ]
    assert len(verdicts) == 9  # 3 teams x 3 metrics against the epsilon-greedy team, each with a verdict line
    profiles = pd.read_csv(tmp_path / "tables" / "emotion_models.csv")
    assert len(profiles) == 8 and (profiles[profiles.hunter.str.contains("QLearning")]["paper joy"] == "-").all()
    for name in ("hunters_learning.png", "emotion_models.png"):
        assert (tmp_path / "figures" / name).stat().st_size > 10_000
        assert f"figures/{name}" in report


def test_the_hunters_section_of_runs_shorter_than_a_block(tmp_path: Path) -> None:
    """Runs of fewer than 10 episodes (one block of 10 can not be formed): the figure has one block of them all."""
    from sb3_affect.study.report.sections.hunters import hunters_section

    overrides = ["episodes=4", "seeds=[0, 1]", "env.kwargs={size: 5, starts: [[0, 0], [4, 4]], prey_start: [2, 2]}"]
    run_sweep(EXPERIMENTS / "hunters.yaml", tmp_path / "hunters", workers=1, overrides=overrides, progress=False)
    text, figures = hunters_section([tmp_path / "hunters"], tmp_path / "out")
    assert "two hunters" in text and figures and all(path.stat().st_size > 10_000 for path, _ in figures)
