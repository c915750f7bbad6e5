"""
One grammar for every sweep file (``schema.Sweep``): its kinds (``Sweep.kind``), the old forms refused in a file and
read in a saved folder (``old_forms``), whose cells and run ids are the ones the old models made.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from sb3_affect.study.cli import main
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.old_forms import new_form, old_key
from sb3_affect.study.launcher.schema import Sweep, SweepError, kind_of
from sb3_affect.study.launcher.store import SWEEP_SCHEMA, ResultsStore, StoreError, cell_run_ids
from sb3_affect.study.launcher.sweep_file import load_sweep, load_sweep_file

ROOT = Path(__file__).resolve().parents[3]
OLD = Path(__file__).parent / "old_sweeps"
#: The shipped files whose saved sweep the old models wrote (``old_sweeps/<name>.json``) and the kind of each.
KINDS = {"deep_smoke": "deep", "minigrid_dqn": "deep", "forensics": "forensics", "smoke": "sweep"}


def run_ids(sweep: Sweep) -> list[str]:
    return [rid for cell in sweep.cells() for rid in cell_run_ids(cell)]


@pytest.mark.parametrize("name", KINDS)
def test_an_old_saved_sweep_reads_in_the_new_form_with_the_cells_and_run_ids_of_the_old_models(name: str) -> None:
    old = json.loads((OLD / f"{name}.json").read_text())
    new = load_sweep(ROOT / "experiments" / f"{name}.yaml", build=False, deep=True)
    assert new.kind == KINDS[name] == kind_of(new_form(old["sweep"]))
    converted = Sweep.validate_saved(new_form(old["sweep"]))
    assert new_form(old["sweep"]) == new.model_dump(mode="json")  # the identity a resume compares
    by_id = {rid: cell.base for cell in converted.cells() for rid in cell_run_ids(cell)}
    assert by_id == {rid: cell.base for cell in new.cells() for rid in cell_run_ids(cell)}
    recorded = json.loads((OLD / "run_ids.json").read_text())[name]  # the old models' run ids, in their cell order
    assert hashlib.sha256("\n".join(run_ids(new)).encode()).hexdigest() == recorded
    assert old["total_runs"] == len(run_ids(new)) and old.get("task_order") == (list(new.tasks) if new.tasks else None)


def test_kind_is_the_section_a_file_gives() -> None:
    assert [kind_of(data) for data in ({"name": "a"}, {"trainer": {}}, {"forensics": {}}, {"trainer": None}, [1])] == [
        "sweep", "deep", "forensics", "sweep", "sweep"]  # fmt: skip
    assert load_sweep_file(ROOT / "experiments" / "minigrid_dqn_tuning.yaml", build=False).kind == "deep"


@pytest.mark.parametrize(("old", "line"), [
    ("study: deep\n", "study: deep is the old form of a sweep file; give a trainer (and evaluation) section instead "
                      "(docs/experiment_files.md)"),
    ("study: forensics\n", "study: forensics is the old form of a sweep file; give a forensics section instead "
                           "(docs/experiment_files.md)"),
    ("eval_every: 2000\n", "eval_every is the old form of a sweep file's key; write evaluation.every"),
    ("network: {gamma: 0.9}\n", "network is the old form of a sweep file's key; write trainer.algo_kwargs"),
    ("env: farama\n", "env is the old form of a sweep file's key; write trainer.vec_env"),
    ("screen_reps: 2\n", "screen_reps is the old form of a sweep file's key; write forensics.screen_reps"),
    ("tasks: {E: {id: MiniGrid-Empty-8x8-v0, budget: 4000}}\n",
     "tasks.E.budget is the old form of a sweep file's key; write tasks.E.total_timesteps"),
    ("tasks: {E: {id: MiniGrid-Empty-8x8-v0, learning_rate: 0.001}}\n",
     "tasks.E.learning_rate is the old form of a sweep file's key; write tasks.E.tuned.learning_rate"),
])  # fmt: skip
def test_a_file_in_an_old_form_is_refused_in_one_line_naming_the_new_key(tmp_path: Path, old: str, line: str) -> None:
    path = tmp_path / "old.yaml"
    path.write_text(f"name: old\n{old}")
    with pytest.raises(SweepError) as error:
        load_sweep_file(path, build=False)
    assert str(error.value) == f"{path}: {line}"
    assert old_key({"name": "x", "env": {"id": "sb3_affect/GridPursuit-v0"}, "tasks": {"a": {"id": "x"}}}) is None


def test_a_shipped_old_deep_folder_is_read_by_status_and_resumed_as_the_same_sweep(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = json.loads((OLD / "deep_smoke.json").read_text())
    folder = tmp_path / "deep_smoke"
    folder.mkdir()
    (folder / "sweep.json").write_text(json.dumps(old))
    store = ResultsStore(folder)
    name, progress, rejected = store.progress()
    assert name == "deep-smoke" and rejected == [] and sum(total for total, _, _ in progress.values()) == 24
    new = load_sweep(ROOT / "experiments" / "deep_smoke.yaml", build=False, deep=True)
    ids = run_ids(new)
    resolved = {"schema": SWEEP_SCHEMA, "name": new.name, "sweep": new.model_dump(mode="json"), "total_runs": len(ids),
                "task_order": list(new.tasks or {})}  # fmt: skip
    assert store.prepare(resolved, ids) == []  # the same sweep: claimed, nothing set aside
    assert json.loads((folder / "sweep.json").read_text()) == old  # the saved record is left as it was
    assert main(["status", str(folder)]) == 0 and "0/24 runs done" in capsys.readouterr().out
    smoke = load_sweep(ROOT / "experiments" / "smoke.yaml", build=False)
    tabular = {"schema": SWEEP_SCHEMA, "name": "smoke", "sweep": smoke.model_dump(mode="json")}
    with pytest.raises(StoreError, match=r"holds a deep study \(sweep.json\), which a sweep run into it would mix with"):
        store.claim(tabular)
    (folder / "sweep.json").write_text(json.dumps({**old, "sweep": {**old["sweep"], "n_envs": 0}}))
    with pytest.raises(StoreError, match=r"sweep.json: the saved sweep is not valid \(trainer.n_envs: Input should be "):
        store.saved_sweep()


#: A toy deep study in the new form, and the saved sweep the old models wrote for it (every key, as they dumped it).
TOY: dict[str, Any] = {
    "name": "toy", "seeds": [0, 1], "evaluation": {"every": 200, "episodes": 2},
    "trainer": {"vec_env": "compiled", "n_envs": 2, "algo_kwargs": {"buffer_size": 2000, "learning_starts": 100,
                                                                   "batch_size": 16, "policy_kwargs": {"net_arch": [8]}}},
    "tasks": {"Empty-5x5": {"id": "MiniGrid-Empty-5x5-v0", "total_timesteps": 400, "tuned": {"exploration_fraction": 0.5}}},
    "agents": [{"name": "dqn-linear", "algo": "DQN", "epsilon": "tuned"}],
}  # fmt: skip
TOY_OLD: dict[str, Any] = {
    "name": "toy", "study": "deep", "env": "compiled", "obs": "view", "n_envs": 2, "seeds": [0, 1], "seeds_per_batch": None,
    "eval_every": 200, "eval_episodes": 2, "network": TOY["trainer"]["algo_kwargs"],
    "tasks": {"Empty-5x5": {"id": "MiniGrid-Empty-5x5-v0", "budget": 400, "learning_rate": None,
                            "exploration_fraction": 0.5, "count_bonus": None}},
    "agents": [{"name": "dqn-linear", "algo": "DQN", "kwargs": {}, "epsilon": "tuned", "count_bonus": None, "replays": None}],
}  # fmt: skip


def _to_old_form(folder: Path, sweep: dict[str, Any]) -> None:
    """Rewrite a folder's saved sweep (sweep.json and its copies) as the old models saved it."""
    for name in ("sweep.json", "chunks/.sweep", "runs/.sweep"):
        saved = json.loads((folder / name).read_text())
        (folder / name).write_text(json.dumps({**saved, "sweep": sweep}, sort_keys=True, indent=1))


def test_an_old_form_deep_folder_resumes_with_nothing_run_again(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "toy.yaml").write_text(yaml.safe_dump(TOY))
    out = tmp_path / "out"
    first = run_sweep(tmp_path / "toy.yaml", out, workers=1, progress=False)
    assert (first.total, first.finished, first.failed) == (2, 2, 0)
    _to_old_form(out, TOY_OLD)
    again = run_sweep(tmp_path / "toy.yaml", out, workers=1, progress=False)
    assert (again.total, again.skipped, again.finished) == (2, 2, 0)
    assert main(["status", str(out)]) == 0 and "2/2 runs done, 0 failed" in capsys.readouterr().out
    from sb3_affect.study.report.sections.deep_minigrid import load_deep

    results = load_deep(out)
    assert ResultsStore(out).study_kind() == "deep" and len(results.cells) == 1
    assert results.study["evaluation"] == {"every": 200, "episodes": 2}
    assert results.study["tasks"]["Empty-5x5"]["total_timesteps"] == 400


TINY_OLD = {"name": "tiny-forensics", "study": "forensics", "screen_reps": 2, "leaders": 1, "reps": 2, "alphas": [1.0],
            "gammas": [0.8], "protocol": {"epsilons": [0.2, 0.6], "seeds": 2, "episodes": 10}}  # fmt: skip


def test_an_old_form_forensics_folder_resumes_with_nothing_simulated_again(tmp_path: Path) -> None:
    from sb3_affect.study.forensics.study_run import run_study

    new = {"name": TINY_OLD["name"], "forensics": {k: v for k, v in TINY_OLD.items() if k not in ("name", "study")}}
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(new))
    first = run_study(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=False)
    assert first.simulated > 0
    _to_old_form(tmp_path / "f", TINY_OLD)
    again = run_study(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=False)
    assert (again.simulated, again.reused) == (0, first.simulated)
    assert main(["status", str(tmp_path / "f")]) == 0


def test_set_reaches_the_keys_of_every_section(tmp_path: Path) -> None:
    deep = load_sweep_file(ROOT / "experiments" / "deep_smoke.yaml", ["evaluation.every=1000", "trainer.n_envs=2",
                           "tasks.Empty-8x8.total_timesteps=3000", "tasks.Empty-8x8.tuned.count_bonus=0.02"], build=False)
    assert deep.evaluation is not None and deep.trainer is not None and deep.tasks is not None
    assert (deep.evaluation.every, deep.trainer.n_envs) == (1000, 2)
    assert deep.tasks["Empty-8x8"].total_timesteps == 3000 and deep.tasks["Empty-8x8"].tuned is not None
    assert deep.tasks["Empty-8x8"].tuned.count_bonus == 0.02
    with pytest.raises(SweepError, match=r"'evry' is not a key of evaluation; did you mean 'every'\? \(allowed: every, "):
        load_sweep_file(ROOT / "experiments" / "deep_smoke.yaml", ["evaluation.evry=1000"], build=False)
    with pytest.raises(SweepError, match=r"'budget' is not a key of tasks.Empty-8x8 \(allowed: id, kwargs, "):
        load_sweep_file(ROOT / "experiments" / "deep_smoke.yaml", ["tasks.Empty-8x8.budget=1000"], build=False)
    with pytest.raises(SweepError, match=r"'eval_every' is not a key of a deep study \(a sweep with a trainer\); did you "
                                         r"mean 'evaluation.every'\?"):
        load_sweep_file(ROOT / "experiments" / "deep_smoke.yaml", ["eval_every=1000"], build=False)
    with pytest.raises(SweepError, match=r"'reps' is not a key of a sweep of runs \(allowed: name, env, tasks, "):
        load_sweep_file(ROOT / "experiments" / "smoke.yaml", ["reps=3"], build=False)  # (no forensics.reps: not its key)
    with pytest.raises(SweepError, match=r"'trainer.n_envs' is a single value; use --set trainer.n_envs=VALUE"):
        load_sweep_file(ROOT / "experiments" / "deep_smoke.yaml", ["trainer.n_envs.x=1"], build=False)


@pytest.mark.parametrize(("text", "line"), [
    ("seeds: 2\nagents: [{name: q, algo: QLearning, epsilon: tuned}]\n",
     "agents[0] (q): epsilon is a key of a deep study's agents (a sweep with a trainer), not of a sweep of runs'"),
    ("seeds: 2\ntasks: {a: {id: sb3_affect/GridPursuit-v0, total_timesteps: 5}}\nagents: [{name: q, algo: QLearning}]\n",
     "tasks.a.total_timesteps is a key of a deep study's tasks (a sweep with a trainer), not of a sweep of runs'"),
    ("seeds: 2\nforensics: {screen_reps: 2, leaders: 1, reps: 2, alphas: [1.0], gammas: [0.8]}\n",
     "seeds is not a key of the forensics (a sweep with forensics); its keys are name, forensics"),
])  # fmt: skip
def test_a_key_of_another_kind_is_refused_in_one_line(tmp_path: Path, text: str, line: str) -> None:
    path = tmp_path / "mixed.yaml"
    path.write_text(f"name: mixed\nepisodes: 3\n{text}" if "forensics" not in text else f"name: mixed\n{text}")
    with pytest.raises(SweepError) as error:
        load_sweep_file(path, build=False)
    assert f"  (top level): {line}\n" in str(error.value)
