"""The deep study's sweep files (a sweep with a trainer): the shipped ones, and what the schema refuses, one line each."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from sb3_affect.study.launcher.deep_schema import STUDY_EVAL_EPISODES
from sb3_affect.study.launcher.schema import Sweep, SweepError
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.report.sections.deep_minigrid import STUDY_SEEDS, seeds_needed

ROOT = Path(__file__).resolve().parents[3]


def load(name: str) -> Sweep:
    study = load_sweep_file(ROOT / "experiments" / f"{name}.yaml", build=False)
    assert study.kind == "deep" and study.evaluation is not None and study.tasks is not None
    return study


def test_the_study_has_its_design_and_its_tuning_pass_runs_on_other_seeds() -> None:
    study, tuning, smoke = load("minigrid_dqn"), load("minigrid_dqn_tuning"), load("deep_smoke")
    assert study.evaluation is not None and study.tasks is not None and tuning.tasks is not None
    assert isinstance(study.seeds, list) and isinstance(tuning.seeds, list) and isinstance(smoke.seeds, list)
    assert len(study.seeds) >= max(STUDY_SEEDS, seeds_needed()) and study.evaluation.episodes >= STUDY_EVAL_EPISODES
    assert study.evaluation.every == 10_000 and {"Empty-8x8", "DoorKey-5x5"} < set(study.tasks) and len(study.tasks) == 3
    assert not set(study.seeds) & set(tuning.seeds)
    assert set(tuning.tasks) == set(study.tasks)
    assert all(tuning.tasks[name].total_timesteps == task.total_timesteps for name, task in study.tasks.items())
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
    """deep_smoke.yaml with ``changes`` (a key path with dots: a key of a section, e.g. ``evaluation.every``)."""
    data = yaml.safe_load((ROOT / "experiments" / "deep_smoke.yaml").read_text())
    for path, value in changes.items():
        *sections, key = path.split(".")
        target = data
        for section in sections:
            target = target[section]
        target[key] = value
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(("changes", "message"), [
    ({"evaluation.every": 3000}, ".total_timesteps=4000 is not a multiple of evaluation.every=3000"),
    ({"seeds": [0, 0]}, "seeds must be a non-empty list of distinct integers"),
    ({"seeds": -1}, "seeds=-1 must be a positive count or a non-empty list of integers"),
    ({"seeds": 3}, "(top level): seeds=3: a deep study takes an explicit list of at most 10,000 seeds (e.g. [0, 1, 2]), "
                   "not a count"),
    ({"agents": [{"name": "m", "algo": "ReplayedEpsilonDQN", "replays": "affective"}]}, "is not an earlier agent"),
    ({"agents": [{"name": "m", "algo": "ReplayedEpsilonDQN"}]}, "replays=<earlier agent> goes with algo ReplayedEpsilonDQN"),
    ({"agents": [{"name": "a", "algo": "QLearning"}]}, "agents[0] (a): algo='QLearning' is not one of "),
    ({"agents": [{"name": "a", "algo": "DQN", "grid": {"e": [1]}}]},
     "agents[0] (a): grid is not a key of a deep study's agent (name, algo, kwargs, epsilon, count_bonus, replays)"),
    ({"agents": [{"name": "a b", "algo": "DQN"}]}, "agents[0].name='a b' must be letters, digits, _ . + -"),
    ({"episodes": 5}, "(top level): episodes is not a key of a deep study (a sweep with a trainer); its keys are name, "
                      "trainer, evaluation, tasks, seeds, agents"),
    ({"evaluation": None}, "(top level): evaluation is missing: a deep study (a sweep with a trainer) needs evaluation, "
                           "tasks, seeds, agents"),
    ({"tasks.Empty-8x8.kwargs": {"size": 5}}, "tasks.Empty-8x8.kwargs is not a key of a deep study's task (id, "
                                              "total_timesteps, tuned)"),
    ({"tasks.Empty-8x8.id": "Empty-8x8"}, "tasks.Empty-8x8.id='Empty-8x8' is not a MiniGrid env id"),
    ({"tasks.Empty-8x8.total_timesteps": None}, "tasks.Empty-8x8.total_timesteps=None is not a multiple of "
                                                "evaluation.every=2000"),
    ({"agents": [{"name": "a", "algo": "DQN", "kwargs": {"seed": 3}}]}, "kwargs.seed is the study's own"),
    ({"tasks": {"E": {"id": "MiniGrid-Empty-8x8-v0", "total_timesteps": 4000}}},
     "agents[0] (dqn-linear) takes the tuned exploration_fraction: tasks.E.tuned has none"),
    ({"trainer.vec_env": "compiled", "tasks": {"K": {"id": "MiniGrid-KeyCorridorS3R1-v0", "total_timesteps": 4000,
                                                     "tuned": {"exploration_fraction": 0.5, "count_bonus": 0.1}}}},
     "tasks.K.id='MiniGrid-KeyCorridorS3R1-v0' is not compiled"),
    ({"trainer.seeds_per_batch": 0}, "trainer.seeds_per_batch: Input should be greater than or equal to 1 (got 0)"),
    ({"trainer.obs": "image"}, "trainer.obs: obs='image' is minigrid_vec_env's 7x7x3 image; the flat 147 entries of the "
                               "agent's view are obs: view"),
])  # fmt: skip
def test_the_schema_refuses_a_bad_file_naming_the_key(tmp_path: Path, changes: dict, message: str) -> None:
    with pytest.raises(SweepError, match="invalid sweep file") as error:
        load_sweep_file(write(tmp_path, **changes), build=False)
    assert message in str(error.value)


NETWORK = yaml.safe_load((ROOT / "experiments" / "deep_smoke.yaml").read_text())["trainer"]["algo_kwargs"]
AFFECTIVE = {"name": "a", "algo": "AffectDQN", "kwargs": {"position": "minigrid", "wait_action": 6}}


@pytest.mark.parametrize(("changes", "message"), [
    *[({"trainer.algo_kwargs": {**NETWORK, key: 1}}, f"trainer.algo_kwargs: algo_kwargs.{key} is the study's own")
      for key in ("seed", "policy", "device", "env")],
    ({"trainer.algo_kwargs": {**NETWORK, "buffer_size": "x"}},
     "algo_kwargs.buffer_size='x' must be an integer from 1 to 100,000,000"),
    ({"trainer.algo_kwargs": {**NETWORK, "train_freq": 0}}, "algo_kwargs.train_freq=0 must be an integer from 1 to 1,000,000"),
    ({"trainer.algo_kwargs": {**NETWORK, "train_freq": -1}}, "algo_kwargs.train_freq=-1 must be an integer from 1"),
    ({"trainer.algo_kwargs": {**NETWORK, "policy_kwargs": {"net_arch": [60000, 60000]}}},
     "algo_kwargs.policy_kwargs.net_arch=[60000, 60000] must be a list of at most 16 layer widths from 1 to 4096"),
    ({"agents": [{**AFFECTIVE, "kwargs": {"wait_action": 99}}]}, "kwargs.wait_action=99 must be an integer from 0 to 6"),
    ({"agents": [{"name": "e", "algo": "EzGreedyDQN", "kwargs": {"mu": -1}}]}, "kwargs.mu=-1 must be a finite number > 0"),
    ({"agents": [{"name": "b", "algo": "DQN", "count_bonus": -1}]},
     "agents[0] (b).count_bonus.constrained-float: Input should be greater than 0 (got -1)"),
    ({"seeds": [1_000_000]}, "seeds: 1000000 is too large; seeds go from 0 to 999999"),
    ({"seeds": [4294967296]}, "seeds: 4294967296 is not a seed; seeds are integers in [0, 2**32 - 1]"),
    ({"seeds": [True]}, "seeds: seeds[0]=True is not an integer; seeds are integers in [0, 2**32 - 1]"),
    ({"seeds": list(range(10_001))}, "(top level): 10,001 seeds: a deep study takes an explicit list of at most 10,000 seeds"),
])  # fmt: skip
def test_the_deep_fields_are_refused_in_one_line_naming_field_and_value(tmp_path: Path, changes: dict, message: str) -> None:
    with pytest.raises(SweepError, match="invalid sweep file") as error:
        load_sweep_file(write(tmp_path, **changes), build=False)
    assert message in str(error.value)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"position": "os:system"}, "position='os:system' is not supported"),
    ({"behaviour_table": "nonsense"}, "nonsense"),
])  # fmt: skip
def test_what_an_agent_refuses_is_refused_before_the_folder_is_claimed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kwargs: dict, message: str
) -> None:
    from sb3_affect.study.cli import main

    path = write(tmp_path, agents=[{**AFFECTIVE, "kwargs": {**AFFECTIVE["kwargs"], **kwargs}}])
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sb3-affect: error: agents[0] (a) on DoorKey-5x5: ") and message in err
    assert not (tmp_path / "out").exists()


def test_a_study_larger_than_the_machines_memory_is_refused_saying_the_figure(tmp_path: Path) -> None:
    from sb3_affect.study.launcher import run_sweep

    path = write(tmp_path, **{"seeds": list(range(10_000)), "trainer.algo_kwargs": {**NETWORK, "buffer_size": 10**6}})
    with pytest.raises(ValueError, match=r"^the deep study needs about [0-9.]+ GiB \(10000 seeds a batch x 1 batches .*"
                                         r"more than this machine's [0-9.]+ GiB"):
        run_sweep(path, tmp_path / "out", workers=1, progress=False)
    assert not (tmp_path / "out").exists()


def test_a_folder_of_one_study_kind_refuses_another_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from sb3_affect.study.launcher import run_sweep
    from sb3_affect.study.launcher.store import StoreError

    old = tmp_path / "deep"
    old.mkdir()
    (old / "deep_study.json").write_text("{}")  # a deep study of the layout before the results store
    for path in (ROOT / "experiments" / "smoke.yaml", write(tmp_path)):
        with pytest.raises(StoreError, match=rf"^{old} holds a deep study of an earlier layout \(deep_study.json, cells/\), "
                                             rf"which is no longer read: rerun the study into a new folder, e.g. "
                                             rf"--out {old}-new$"):
            run_sweep(path, old, workers=1, progress=False)
    assert sorted(p.name for p in old.iterdir()) == ["deep_study.json"]
    from sb3_affect.study.cli import main

    assert main(["status", str(old)]) == 2  # status refuses it too, in the same one line
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{old} holds a deep study of an earlier layout" in err and "rerun the study" in err
    sweep = tmp_path / "sweep"
    sweep.mkdir()
    (sweep / "sweep.json").write_text(json.dumps({"name": "smoke", "sweep": {"name": "smoke"}}))
    with pytest.raises(StoreError, match=rf"^{sweep} holds a sweep \(sweep.json\), which a deep study run into it "
                                         rf"would mix with; give the deep study a folder of its own, e.g. "
                                         rf"--out {sweep}/deep-smoke$"):
        run_sweep(write(tmp_path), sweep, workers=1, progress=False)
    assert sorted(p.name for p in sweep.iterdir()) == ["sweep.json"]
    deep = tmp_path / "new-deep"
    deep.mkdir()
    (deep / "sweep.json").write_text((Path(__file__).parent / "old_sweeps" / "deep_smoke.json").read_text())  # old form
    with pytest.raises(StoreError, match=rf"^{deep} holds a deep study \(sweep.json\), which a sweep run into it would mix "
                                         rf"with; give the sweep a folder of its own, e.g. --out {deep}/smoke$"):
        run_sweep(ROOT / "experiments" / "smoke.yaml", deep, workers=1, progress=False)
    assert sorted(p.name for p in deep.iterdir()) == ["sweep.json"]
