"""
The deep study's runs (study/launcher/deep_study.py, deep_batches.py, deep_training.py, deep_recording.py) on a toy
study: SB3's real DQN and AffectDQN trained by train_many on the compiled MiniGrid, in batches of seeds.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("minigrid")

from sb3_affect.study.cli import main
from sb3_affect.study.launcher.deep_recording import GreedyEvaluation
from sb3_affect.study.launcher.deep_schema import EVAL_SEED_OFFSET, DeepStudy
from sb3_affect.study.launcher.deep_study import batch_path, cell_path, deep_status, replayed_epsilons, run_deep_study
from sb3_affect.study.launcher.sweep_file import load_sweep_file

TOY = {
    "name": "toy", "study": "deep", "env": "compiled", "seeds": [0, 1], "n_envs": 2, "eval_every": 200, "eval_episodes": 2,
    "network": {"buffer_size": 2000, "learning_starts": 100, "batch_size": 16, "target_update_interval": 100,
                "policy_kwargs": {"net_arch": [16]}},
    "tasks": {"Empty-5x5": {"id": "MiniGrid-Empty-5x5-v0", "budget": 400, "learning_rate": 0.001,
                            "exploration_fraction": 0.5, "count_bonus": 0.05}},
    "agents": [
        {"name": "dqn-linear", "algo": "DQN", "epsilon": "tuned"},
        {"name": "affective", "algo": "AffectDQN", "kwargs": {"position": "minigrid", "wait_action": 6}},
        {"name": "matched", "algo": "ReplayedEpsilonDQN", "replays": "affective"},
        {"name": "count-bonus", "algo": "DQN", "epsilon": "tuned", "count_bonus": "tuned"},
    ],
}  # fmt: skip


def toy(tmp_path: Path, **changes: object) -> DeepStudy:
    path = tmp_path / "toy.yaml"
    path.write_text(yaml.safe_dump({**TOY, **changes}))
    study = load_sweep_file(path, build=False)
    assert isinstance(study, DeepStudy)
    return study


def test_a_toy_study_runs_each_cell_evaluates_greedy_policies_and_resumes(tmp_path: Path) -> None:
    study = toy(tmp_path)
    lines: list[str] = []
    done = run_deep_study(study, tmp_path / "out", workers=1, log=lines.append)
    assert (done.trained, done.reused, done.batches) == (4, 0, 4) and len(lines) == 8
    cells = {agent: json.loads(cell_path(tmp_path / "out", "Empty-5x5", agent).read_text())
             for agent in ("dqn-linear", "affective", "matched", "count-bonus")}  # fmt: skip
    for cell in cells.values():
        assert cell["eval_steps"] == [200, 400] and cell["seeds"] == [0, 1]
        success = np.asarray(cell["success"], dtype=float)
        assert success.shape == (2, 2) and ((success >= 0) & (success <= 1)).all()
        assert all(first is None or 0 < first <= 400 for first in cell["first_success"])
        assert np.asarray(cell["train_episodes"]).shape == (2, 2)
    # the matched control's ε is the affective agent's share of random decisions, averaged over seeds, part by part
    replayed = replayed_epsilons(cells["affective"])
    assert cells["matched"]["epsilons"] == replayed
    np.testing.assert_allclose(np.asarray(cells["matched"]["random_share"], dtype=float), [replayed, replayed])
    assert cells["affective"]["emotions"] is not None and cells["dqn-linear"]["emotions"] is None
    shares = sum(np.asarray(v, dtype=float) for v in cells["affective"]["emotions"].values())
    np.testing.assert_allclose(shares, 1.0)  # each part's emotion shares sum to one
    assert cells["count-bonus"]["count_bonus"] == 0.05
    again = run_deep_study(study, tmp_path / "out", workers=1, log=lines.append)
    assert (again.trained, again.reused, again.batches) == (0, 4, 0)
    assert "4/4 cells done" in deep_status(tmp_path / "out")[0]
    with pytest.raises(RuntimeError, match="holds the results of another deep study"):
        run_deep_study(toy(tmp_path, seeds=[0, 1, 2]), tmp_path / "out", workers=1)


class Interrupt(KeyboardInterrupt):
    pass


def test_an_interrupted_study_keeps_its_finished_batches_and_gives_the_cells_of_one_batch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Batches of one seed: a Ctrl-C after the first batch loses nothing, and the merged cells equal one batch of both."""
    whole = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    run_deep_study(whole, tmp_path / "whole", workers=1, log=lambda line: None)
    study = toy(tmp_path, agents=TOY["agents"][:1], seeds_per_batch=1)  # type: ignore[index]

    def stop_after_first_batch(line: str) -> None:
        if "batch 1/2" in line:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_deep_study(study, tmp_path / "out", workers=1, log=stop_after_first_batch)
    assert batch_path(tmp_path / "out", "Empty-5x5", "dqn-linear", 0).is_file()
    assert deep_status(tmp_path / "out")[1].split()[2:] == ["1/2", "batches", "done"]
    shutil.copytree(tmp_path / "out", tmp_path / "replicate" / "minigrid_dqn")
    assert main(["status", str(tmp_path / "replicate")]) == 0  # a replicate folder lists its deep study
    printed = capsys.readouterr().out
    assert "0 sweeps and the deep study" in printed and "0/1 cells done (task x agent, 2 seeds each in 2 batches)" in printed
    lines: list[str] = []
    done = run_deep_study(study, tmp_path / "out", workers=1, log=lines.append)
    assert (done.trained, done.batches) == (1, 1) and "batch 2/2 (seeds 1)" in lines[0]
    assert not (tmp_path / "out" / "batches" / "Empty-5x5__dqn-linear").exists()
    merged, one = (json.loads(cell_path(tmp_path / name, "Empty-5x5", "dqn-linear").read_text()) for name in ("out", "whole"))
    for key in ("success", "return", "random_share", "train_episodes", "train_successes", "first_success", "seeds"):
        assert merged[key] == one[key], key


def test_the_batched_greedy_evaluation_equals_sb3_predict_on_each_seeds_evaluation_envs() -> None:
    import sb3_affect
    from sb3_affect.engine.seed_envs import seed_vec_env

    models = sb3_affect.train_many("DQN", "MiniGrid-Empty-5x5-v0", [0, 1, 2], 2, total_timesteps=400, obs="image",
                                   learning_starts=100, buffer_size=2000, batch_size=16, policy_kwargs={"net_arch": [16]})
    seeds = [EVAL_SEED_OFFSET + 3 * s for s in range(3)]
    evaluate = GreedyEvaluation([seed_vec_env("MiniGrid-Empty-5x5-v0", 3, s, "image", True) for s in seeds], seeds)
    success, returns = evaluate(models)
    for index, model in enumerate(models):
        env = seed_vec_env("MiniGrid-Empty-5x5-v0", 3, seeds[index], "image", True)
        obs = env.reset()
        total, reached, finished = np.zeros(env.num_envs), np.zeros(env.num_envs, bool), np.zeros(env.num_envs, bool)
        while not finished.all():
            obs, rewards, dones, infos = env.step(model.predict(obs, deterministic=True)[0])
            total[~finished] += rewards[~finished]
            for e in np.flatnonzero(dones & ~finished):
                finished[e], reached[e] = True, not infos[e].get("TimeLimit.truncated", False)
        assert success[index] == reached.mean() and returns[index] == pytest.approx(total.mean())
    assert evaluate(models)[1].tolist() == returns.tolist()  # each evaluation plays the same episodes


def test_the_count_bonus_pays_scale_over_the_root_of_visits_of_each_envs_cell() -> None:
    from sb3_affect.engine.seed_envs import seed_vec_env
    from sb3_affect.study.launcher.count_bonus import CountBonus

    env = CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 2, 0, "image"), scale=0.5)
    env.reset()
    rewards = [env.step(np.array([0, 0]))[1] for _ in range(3)]  # turning left: the agent stays in its cell
    np.testing.assert_allclose(rewards, [[0.5, 0.5], [0.5 / np.sqrt(2)] * 2, [0.5 / np.sqrt(3)] * 2], rtol=1e-6)
    with pytest.raises(ValueError, match="count_bonus=0"):
        CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 1, 0, "image"), scale=0)


KILL_ON_SECOND_BATCH = """
import os, signal, sys
from pathlib import Path
from sb3_affect.study.launcher import regular_files
from sb3_affect.study.launcher.deep_study import run_deep_study
from sb3_affect.study.launcher.sweep_file import load_sweep_file

fsync = os.fsync
def fsync_then_die(fd):
    written = Path(os.readlink(f"/proc/self/fd/{fd}"))
    if written.parent.parent == Path(sys.argv[2]) / "batches" and (written.parent / "0.json").exists():
        os.kill(os.getpid(), signal.SIGKILL)  # the second batch's file half made: written, not yet renamed
    fsync(fd)
regular_files.os.fsync = fsync_then_die
run_deep_study(load_sweep_file(sys.argv[1], build=False), Path(sys.argv[2]), workers=1, log=lambda line: None)
"""


def test_a_batch_killed_mid_write_resumes_to_the_results_of_an_uninterrupted_run(tmp_path: Path) -> None:
    """SIGKILL while the second batch's file is written: its temporary file is cleared and the batch run again."""
    import subprocess
    import sys

    run_deep_study(toy(tmp_path, agents=TOY["agents"][:1]), tmp_path / "whole", workers=1, log=lambda line: None)  # type: ignore[index]
    study = toy(tmp_path, agents=TOY["agents"][:1], seeds_per_batch=1)  # type: ignore[index]  # (toy.yaml: this one)
    out = tmp_path / "out"
    killed = subprocess.run([sys.executable, "-c", KILL_ON_SECOND_BATCH, str(tmp_path / "toy.yaml"), str(out)])
    assert killed.returncode == -9
    cell = out / "batches" / "Empty-5x5__dqn-linear"
    assert sorted(p.name for p in cell.iterdir())[0].startswith(".tmp-") and (cell / "0.json").is_file()
    assert not (cell / "1.json").exists() and not cell_path(out, "Empty-5x5", "dqn-linear").exists()
    first = (cell / "0.json").read_text()
    done = run_deep_study(study, out, workers=1, log=lambda line: None)
    assert (done.trained, done.batches) == (1, 1) and not cell.exists()
    cell.mkdir()  # a launcher stopped between writing the cell and removing its batches: they are removed, not rerun
    (cell / "0.json").write_text(first)
    assert "1/1 cells done" in deep_status(out)[0]
    again = run_deep_study(study, out, workers=1, log=lambda line: None)
    assert (again.trained, again.reused, again.batches) == (0, 1, 0) and not cell.exists()
    merged, one = (json.loads(cell_path(tmp_path / name, "Empty-5x5", "dqn-linear").read_text()) for name in ("out", "whole"))
    for key in ("success", "return", "random_share", "train_episodes", "train_successes", "first_success", "seeds"):
        assert merged[key] == one[key], key


def test_damaged_cells_are_named_not_counted_refused_by_the_report_and_redone(tmp_path: Path) -> None:
    """A truncated, garbage, {}, symlinked or NaN-success cell counts as not done: status names it, the report refuses it, a
    rerun moves it to damaged/ and runs its batches again, to the same results."""
    from sb3_affect.study.launcher.deep_study import read_cells
    from sb3_affect.study.launcher.store import StoreError

    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    out = tmp_path / "out"
    run_deep_study(study, out, workers=1, log=lambda line: None)
    path = cell_path(out, "Empty-5x5", "dqn-linear")
    good = path.read_text()
    for damage, why in [(good[: len(good) // 2], "is not valid JSON"), ("garbage", "is not valid JSON"),
                        ("{}", "is not a record of Empty-5x5 x dqn-linear"), (None, "a symbolic link"),
                        (json.dumps({**json.loads(good), "success": [[None, None], [None, None]]}),
                         "has a success that no evaluation gives")]:  # fmt: skip
        path.unlink()
        if damage is None:
            (tmp_path / "elsewhere.json").write_text(good)
            path.symlink_to(tmp_path / "elsewhere.json")
        else:
            path.write_text(damage)
        lines = deep_status(out)
        assert "0/1 cells done" in lines[0] and any(f"not counted: {path}" in line and why in line for line in lines)
        with pytest.raises(StoreError, match=f"^{re.escape(str(path))} .*{why}.*to move it to damaged/"):
            read_cells(out)
        log: list[str] = []
        done = run_deep_study(study, out, workers=1, log=log.append)
        assert (done.trained, done.batches) == (1, 1) and f"{path} " in log[0] and "moved to" in log[0]
        assert json.loads(path.read_text())["success"] == json.loads(good)["success"]
    assert len(list((out / "damaged").iterdir())) == 5


def test_a_failed_batch_leaves_a_failure_record_and_a_second_launcher_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from sb3_affect.study.launcher.store import ResultsStore, StoreError

    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    out = tmp_path / "out"

    def broken(*args: object) -> None:
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr("sb3_affect.study.launcher.deep_training.run_batch", broken)
    with pytest.raises(StoreError, match=r"1 batches of the deep study failed .*ZeroDivisionError: division by zero"):
        run_deep_study(study, out, workers=1, log=lambda line: None)
    record = json.loads((out / "failed" / "Empty-5x5__dqn-linear__0.json").read_text())
    assert record["status"] == "failed" and "ZeroDivisionError" in record["error"]
    assert "1 failed" in deep_status(out)[1]
    monkeypatch.undo()
    with ResultsStore(out).lock():  # another launcher holds the folder: refused at once, in one line
        with pytest.raises(StoreError, match="is in use by another launcher"):
            run_deep_study(study, out, workers=1, log=lambda line: None)
        assert main(["run", str(tmp_path / "toy.yaml"), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is in use by another launcher" in err
    run_deep_study(study, out, workers=1, log=lambda line: None)
    assert not (out / "failed" / "Empty-5x5__dqn-linear__0.json").exists() and "1/1 cells done" in deep_status(out)[0]
