"""The deep study's sweep files (study: deep): the shipped ones, and what the schema refuses, one line each."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from sb3_affect.study.launcher.deep_schema import STUDY_EVAL_EPISODES, DeepStudy
from sb3_affect.study.launcher.schema import SweepError
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.report.sections.deep_minigrid import STUDY_SEEDS, seeds_needed

ROOT = Path(__file__).resolve().parents[3]


def load(name: str) -> DeepStudy:
    study = load_sweep_file(ROOT / "experiments" / f"{name}.yaml", build=False)
    assert isinstance(study, DeepStudy)
    return study


def test_the_study_has_its_design_and_its_tuning_pass_runs_on_other_seeds() -> None:
    study, tuning, smoke = load("minigrid_dqn"), load("minigrid_dqn_tuning"), load("deep_smoke")
    assert len(study.seeds) >= max(STUDY_SEEDS, seeds_needed()) and study.eval_episodes >= STUDY_EVAL_EPISODES
    assert study.eval_every == 10_000 and {"Empty-8x8", "DoorKey-5x5"} < set(study.tasks) and len(study.tasks) == 3
    assert not set(study.seeds) & set(tuning.seeds)
    assert set(tuning.tasks) == set(study.tasks)
    assert all(tuning.tasks[name].budget == task.budget for name, task in study.tasks.items())
    by_name = {agent.name: agent for agent in study.agents}
    assert by_name["matched-randomness"].replays == "affective"
    assert {by_name[f"ez-greedy-{cap}"].kwargs["max_duration"] for cap in (10, 100)} == {10, 100}
    assert by_name["affective-reversed"].kwargs["behaviour_table"] == "table-iii-reversed"
    assert by_name["affective-four"].kwargs["emotion_callback"]["order"] == "act-first"  # sadness and fear can occur
    assert all(speeds == [1] for _, speeds in by_name["affective-speed-one"].kwargs["behaviour_table"].values())
    assert by_name["count-bonus"].count_bonus == "tuned" and by_name["dqn-linear"].epsilon == "tuned"
    assert {"DQN", "AffectDQN", "EzGreedyDQN", "SpeedEpsilonGreedyDQN", "ReplayedEpsilonDQN"} == {a.algo for a in study.agents}
    assert len(smoke.seeds) < STUDY_SEEDS  # the main job's version is labelled a smoke size by the report


def write(tmp_path: Path, **changes: object) -> Path:
    data = yaml.safe_load((ROOT / "experiments" / "deep_smoke.yaml").read_text())
    data.update(changes)
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(("changes", "message"), [
    ({"eval_every": 3000}, ".budget=4000 is not a multiple of eval_every=3000"),
    ({"seeds": [0, 0]}, "seeds must be distinct integers >= 0"),
    ({"agents": [{"name": "m", "algo": "ReplayedEpsilonDQN", "replays": "affective"}]}, "is not an earlier agent"),
    ({"agents": [{"name": "m", "algo": "ReplayedEpsilonDQN"}]}, "replays=<earlier agent> goes with algo ReplayedEpsilonDQN"),
    ({"agents": [{"name": "a", "algo": "QLearning"}]}, "algo='QLearning' is not one of"),
    ({"agents": [{"name": "a", "algo": "DQN", "kwargs": {"seed": 3}}]}, "kwargs.seed is the study's own"),
    ({"tasks": {"E": {"id": "MiniGrid-Empty-8x8-v0", "budget": 4000}}}, "takes the tuned exploration_fraction: tasks.E"),
    ({"env": "compiled", "tasks": {"K": {"id": "MiniGrid-KeyCorridorS3R1-v0", "budget": 4000, "exploration_fraction": 0.5,
                                         "count_bonus": 0.1}}}, "tasks.K.id='MiniGrid-KeyCorridorS3R1-v0' is not compiled"),
    ({"seeds_per_batch": 0}, "seeds_per_batch"),
])  # fmt: skip
def test_the_schema_refuses_a_bad_file_naming_the_key(tmp_path: Path, changes: dict, message: str) -> None:
    with pytest.raises(SweepError, match="invalid sweep file") as error:
        load_sweep_file(write(tmp_path, **changes), build=False)
    assert message in str(error.value)
