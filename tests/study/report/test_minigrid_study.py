"""
MiniGrid through the launcher and the report: sweep files naming MiniGrid envs, the registry's wrappers and tasks, a
tiny real sweep of tabular and deep agents run by the launcher, and the report's MiniGrid section on the tabular folder
(the deep study, a sweep with a ``trainer``, has its own section: test_deep_study_report.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("minigrid")  # the [minigrid] extra

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher import SweepError, load_sweep, run_sweep
from sb3_affect.study.launcher.schema import Sweep
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.document import Document
from sb3_affect.study.report.sections.minigrid import minigrid_sections

TABULAR = """
name: tiny-minigrid
tasks:
  Empty-5x5: {id: MiniGrid-Empty-5x5-v0, wrappers: [TabularMiniGrid]}
  Empty-6x6: {id: MiniGrid-Empty-6x6-v0, wrappers: [TabularMiniGrid]}
episodes: 1000
max_timesteps: 300
seeds: [0, 1]
agents:
  - {name: epsilon-greedy, algo: QLearning, kwargs: {exploration_rate: 0.1}}
  - {name: affective, algo: AffectQ}
"""

DEEP = """
name: tiny-minigrid-dqn
tasks:
  Empty-5x5: {id: MiniGrid-Empty-5x5-v0, wrappers: [FlatObsWrapper], position: minigrid}
  Empty-5x5-bonus: {id: MiniGrid-Empty-5x5-v0, wrappers: [PositionBonus, FlatObsWrapper], position: minigrid}
episodes: 1000
max_timesteps: 120
seeds: [0]
agents:
  - name: dqn
    algo: DQN
    kwargs: &small {learning_starts: 40, policy_kwargs: {net_arch: [16]}}
  - name: affective
    algo: AffectDQN
    kwargs: {<<: *small, position: minigrid, wait_action: 6}
  - name: ez-greedy
    algo: EzGreedyDQN
    kwargs: {<<: *small, exploration_initial_eps: 0.5, exploration_final_eps: 0.5}
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def report(folders: dict[str, Path], out: Path) -> str:
    for sub in ("tables", "figures"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(Document("MiniGrid"), out, out, None, None, folders=folders)  # type: ignore[arg-type]
    minigrid_sections(ctx)
    return ctx.doc.markdown(out)


def test_tiny_minigrid_sweeps_run_through_the_launcher_and_the_report_reads_them(tmp_path: Path) -> None:
    tabular = run_sweep(write(tmp_path, "tabular", TABULAR), tmp_path / "minigrid", workers=1, progress=False)
    deep = run_sweep(write(tmp_path, "deep", DEEP), tmp_path / "minigrid_dqn", workers=1, progress=False)
    assert (tabular.total, tabular.failed, deep.total, deep.failed) == (8, 0, 6, 0)
    saved = json.loads((tmp_path / "minigrid_dqn" / "sweep.json").read_text())["sweep"]
    assert Sweep.validate_saved(saved).tasks is not None  # the saved sweep reads back without importing anything
    text = report({"minigrid": tmp_path / "minigrid"}, tmp_path / "report")
    assert "## MiniGrid: the tabular agents" in text and "deep agents and their controls" not in text
    assert "The deep study (DQN, AffectDQN and their controls on MiniGrid) is not part of this folder" in text
    scores = __import__("pandas").read_csv(tmp_path / "report" / "tables" / "minigrid_scores.csv")
    assert sorted(zip(scores.task, scores.agent)) == sorted(
        (task, agent) for task in ("Empty-5x5", "Empty-6x6") for agent in ("affective", "epsilon-greedy")
    )
    for task in ("Empty-5x5", "Empty-6x6"):  # one computed sentence per task, naming an agent of the folder
        assert any(f"On {task}, " in line and ("affective" in line or "epsilon-greedy" in line) for line in text.splitlines())
    emotions = __import__("pandas").read_csv(tmp_path / "report" / "tables" / "minigrid_emotions.csv")
    assert set(emotions.agent) == {"affective"}  # QLearning feels nothing; AffectQ's decisions each feel one emotion
    np.testing.assert_allclose(emotions[list(EMOTION_NAMES)].sum(axis=1), 1.0)


@pytest.mark.parametrize(
    ("env", "message"),
    [
        ("{id: MiniGrid-Empty-5x5-v0, wrappers: [subprocess:Popen]}",
         r"env wrapper 'subprocess:Popen' is not known; the wrappers are TabularMiniGrid"),
        ("{id: MiniGrid-Empty-5x5-v0, position: cell}",
         r"position 'cell' is not a preset; the presets are discrete, multidiscrete, minigrid"),
    ],
)
def test_a_bad_env_section_is_one_line_naming_what_is_allowed(tmp_path: Path, env: str, message: str) -> None:
    text = f"name: bad\nenv: {env}\nepisodes: 1\nseeds: 1\nagents: [{{name: a, algo: QLearning}}]\n"
    with pytest.raises(SweepError, match=message):
        load_sweep(write(tmp_path, "bad", text), build=False)


def test_env_and_tasks_are_exclusive_and_task_is_a_reserved_grid_label(tmp_path: Path) -> None:
    both = "name: bad\nenv: {id: MiniGrid-Empty-5x5-v0}\ntasks: {a: {id: MiniGrid-Empty-5x5-v0}}\nepisodes: 1\nseeds: 1\n" \
        "agents: [{name: a, algo: QLearning}]\n"
    with pytest.raises(SweepError, match="give either env \\(one env\\) or tasks"):
        load_sweep(write(tmp_path, "both", both), build=False)
    label = "name: bad\ntasks: {a: {id: MiniGrid-Empty-5x5-v0}}\nepisodes: 1\nseeds: 1\n" \
        "agents: [{name: a, algo: QLearning, grid: {task: [1]}}]\n"
    with pytest.raises(SweepError, match=r"grid\.task names the tasks' label"):
        load_sweep(write(tmp_path, "label", label), build=False)


def test_a_sweep_of_one_env_saves_as_before_tasks_and_wrappers_existed() -> None:
    dumped = load_sweep("experiments/dqn.yaml", build=False).model_dump(mode="json")
    assert "tasks" not in dumped and set(dumped["env"]) == {"id", "kwargs"}


def test_shipped_minigrid_sweeps_validate_with_the_agents_and_tasks_they_name() -> None:
    tabular = load_sweep("experiments/minigrid.yaml", build=False)
    assert all(c["env_wrappers"] == ["TabularMiniGrid"] for c in tabular.run_configs())


def test_replicate_skips_a_part_whose_package_is_missing_with_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    from sb3_affect.study import studies

    assert "minigrid" in dict(studies.PARTS) and studies.missing_package("minigrid") is None  # installed here
    monkeypatch.setattr(studies, "PART_PACKAGES", (("minigrid", "no_such_package_xyz", "minigrid"),))
    assert studies.missing_package("minigrid") == 'no_such_package_xyz is not installed: pip install "sb3-affect[minigrid]"'
    assert studies.missing_package("paper") is None


def test_an_agents_unknown_wrapper_is_one_line_naming_the_agent_and_what_is_allowed(tmp_path: Path) -> None:
    text = ("name: bad\nenv: {id: MiniGrid-Empty-5x5-v0}\nepisodes: 1\nseeds: 1\n"
            "agents: [{name: a, algo: DQN, wrappers: [os:system]}]\n")
    with pytest.raises(SweepError, match=r"agents\[0\] \(a\)\.wrappers: env wrapper 'os:system' is not known; the wrappers"):
        load_sweep(write(tmp_path, "bad", text), build=False)
