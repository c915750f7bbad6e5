"""
The deep study's runs (study/launcher/deep_batches.py, deep_training.py, deep_recording.py) through the one launcher
(``run_sweep``) and results store on a toy study: SB3's real DQN and AffectDQN trained by train_many on the compiled
MiniGrid, in batches of seeds, each batch's evaluations one chunk.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

pytest.importorskip("minigrid")

from sb3_affect.study.cli import main
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.deep_batches import replayed_epsilons
from sb3_affect.study.launcher.deep_recording import GreedyEvaluation
from sb3_affect.study.launcher.deep_schema import EVAL_SEED_OFFSET
from sb3_affect.study.launcher.store import ResultsStore, StoreError

TOY = {
    "name": "toy", "seeds": [0, 1], "evaluation": {"every": 200, "episodes": 2},
    "trainer": {"vec_env": "compiled", "n_envs": 2,
                "algo_kwargs": {"buffer_size": 2000, "learning_starts": 100, "batch_size": 16, "target_update_interval": 100,
                                "policy_kwargs": {"net_arch": [16]}}},
    "tasks": {"Empty-5x5": {"id": "MiniGrid-Empty-5x5-v0", "total_timesteps": 400,
                            "tuned": {"learning_rate": 0.001, "exploration_fraction": 0.5, "count_bonus": 0.05}}},
    "agents": [
        {"name": "dqn-linear", "algo": "DQN", "epsilon": "tuned"},
        {"name": "affective", "algo": "AffectDQN", "kwargs": {"position": "minigrid", "wait_action": 6}},
        {"name": "matched", "algo": "ReplayedEpsilonDQN", "replays": "affective"},
        {"name": "count-bonus", "algo": "DQN", "epsilon": "tuned", "count_bonus": "tuned"},
    ],
}  # fmt: skip
#: The rows of a cell that must not depend on how its seeds were batched or whether its launcher was interrupted.
ROWS = ("success", "return", "random_share", "train_episodes", "train_successes", "first_success", "seeds")


def toy(tmp_path: Path, seeds_per_batch: int | None = None, **changes: object) -> Path:
    """The toy study's file (``toy.yaml``), with ``changes`` (and the trainer's ``seeds_per_batch``)."""
    path = tmp_path / "toy.yaml"
    trainer = {**TOY["trainer"], **({} if seeds_per_batch is None else {"seeds_per_batch": seeds_per_batch})}  # type: ignore[dict-item]
    path.write_text(yaml.safe_dump({**TOY, **changes, "trainer": trainer}))
    return path


def run(path: Path, out: Path, **options: Any) -> Any:
    return run_sweep(path, out, workers=1, progress=False, **options)


def cell(out: Path, agent: str = "dqn-linear") -> dict[str, Any]:
    return ResultsStore(out).evaluations()["Empty-5x5", agent]


def chunks(out: Path) -> list[Path]:
    return sorted((out / "chunks").glob("[!.]*.parquet"))


def status(out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    capsys.readouterr()
    assert main(["status", str(out)]) == 0
    return capsys.readouterr().out


def test_a_toy_study_runs_each_cell_evaluates_greedy_policies_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    done = run(toy(tmp_path), tmp_path / "out")
    assert (done.total, done.skipped, done.finished, done.failed) == (8, 0, 8, 0) and len(chunks(tmp_path / "out")) == 4
    cells = ResultsStore(tmp_path / "out").evaluations()
    assert list(cells) == [("Empty-5x5", agent) for agent in ("dqn-linear", "affective", "matched", "count-bonus")]
    for found in cells.values():
        assert found["eval_steps"] == [200, 400] and found["seeds"] == [0, 1]
        success = np.asarray(found["success"], dtype=float)
        assert success.shape == (2, 2) and ((success >= 0) & (success <= 1)).all()
        assert all(first is None or 0 < first <= 400 for first in found["first_success"])
        assert np.asarray(found["train_episodes"]).shape == (2, 2)
    # the matched control's ε is the affective agent's share of random decisions, averaged over seeds, part by part
    replayed = replayed_epsilons(cells["Empty-5x5", "affective"])
    assert cells["Empty-5x5", "matched"]["epsilons"] == replayed
    np.testing.assert_allclose(np.asarray(cells["Empty-5x5", "matched"]["random_share"], dtype=float), [replayed, replayed])
    assert cells["Empty-5x5", "affective"]["emotions"] is not None and cells["Empty-5x5", "dqn-linear"]["emotions"] is None
    shares = sum(np.asarray(v, dtype=float) for v in cells["Empty-5x5", "affective"]["emotions"].values())
    np.testing.assert_allclose(shares, 1.0)  # each part's emotion shares sum to one
    assert cells["Empty-5x5", "count-bonus"]["count_bonus"] == 0.05
    again = run(toy(tmp_path), tmp_path / "out")
    assert (again.total, again.skipped, again.finished) == (8, 8, 0)
    assert "sweep 'toy' in " in (shown := status(tmp_path / "out", capsys)) and "8/8 runs done, 0 failed" in shown
    with pytest.raises(StoreError, match="already holds the results of a different sweep"):
        run(toy(tmp_path, seeds=[0, 1, 2]), tmp_path / "out")


class Interrupt(KeyboardInterrupt):
    pass


def test_an_interrupted_study_keeps_its_finished_batches_and_gives_the_cells_of_one_batch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Batches of one seed: a Ctrl-C after the first batch loses nothing, and the cell equals one batch of both seeds."""
    run(toy(tmp_path, agents=TOY["agents"][:1]), tmp_path / "whole")  # type: ignore[index]
    study = toy(tmp_path, agents=TOY["agents"][:1], seeds_per_batch=1)  # type: ignore[index]
    write_chunk = ResultsStore.write_chunk

    def write_then_stop(self: ResultsStore, *args: Any) -> None:
        write_chunk(self, *args)
        raise Interrupt

    monkeypatch.setattr(ResultsStore, "write_chunk", write_then_stop)
    with pytest.raises(Interrupt):
        run(study, tmp_path / "out")
    monkeypatch.undo()
    assert len(chunks(tmp_path / "out")) == 1 and "1/2 runs done" in status(tmp_path / "out", capsys)
    shutil.copytree(tmp_path / "out", tmp_path / "replicate" / "minigrid_dqn")
    printed = status(tmp_path / "replicate", capsys)  # a replicate folder lists its deep study as one of its sweeps
    assert f"{tmp_path / 'replicate'}: 1 study\n" in printed and "sweep 'toy' in " in printed and "1/2 runs done" in printed
    done = run(study, tmp_path / "out")
    assert (done.skipped, done.finished) == (1, 1) and len(chunks(tmp_path / "out")) == 2
    merged, one = cell(tmp_path / "out"), cell(tmp_path / "whole")
    for key in ROWS:
        assert merged[key] == one[key], key


def test_the_batched_greedy_evaluation_equals_sb3_predict_on_each_seeds_evaluation_envs() -> None:
    import sb3_affect
    from sb3_affect.engine.seed_envs import seed_vec_env

    models = sb3_affect.train_many("DQN", "MiniGrid-Empty-5x5-v0", [0, 1, 2], 2, total_timesteps=400, obs="view",
                                   learning_starts=100, buffer_size=2000, batch_size=16, policy_kwargs={"net_arch": [16]})
    seeds = [EVAL_SEED_OFFSET + 3 * s for s in range(3)]
    evaluate = GreedyEvaluation([seed_vec_env("MiniGrid-Empty-5x5-v0", 3, s, "view", True) for s in seeds], seeds)
    success, returns = evaluate(models)
    for index, model in enumerate(models):
        env = seed_vec_env("MiniGrid-Empty-5x5-v0", 3, seeds[index], "view", True)
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

    env = CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 2, 0, "view"), scale=0.5)
    env.reset()
    rewards = [env.step(np.array([0, 0]))[1] for _ in range(3)]  # turning left: the agent stays in its cell
    np.testing.assert_allclose(rewards, [[0.5, 0.5], [0.5 / np.sqrt(2)] * 2, [0.5 / np.sqrt(3)] * 2], rtol=1e-6)
    with pytest.raises(ValueError, match="count_bonus=0"):
        CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 1, 0, "view"), scale=0)


KILL_ON_SECOND_BATCH = """
import os, signal, sys
from pathlib import Path
from sb3_affect.study.launcher import regular_files, run_sweep

fsync = os.fsync
def fsync_then_die(fd):
    written = Path(os.readlink(f"/proc/self/fd/{fd}"))
    chunks = Path(sys.argv[2]) / "chunks"
    if written.parent == chunks and any(chunks.glob("[!.]*.parquet")):
        os.kill(os.getpid(), signal.SIGKILL)  # the second batch's chunk half made: written, not yet renamed
    fsync(fd)
regular_files.os.fsync = fsync_then_die
run_sweep(sys.argv[1], sys.argv[2], workers=1, progress=False)
"""


def test_a_batch_killed_mid_write_resumes_to_the_results_of_an_uninterrupted_run(tmp_path: Path) -> None:
    """SIGKILL while the second batch's chunk is written: its temporary file is cleared and the batch run again."""
    import subprocess
    import sys

    run(toy(tmp_path, agents=TOY["agents"][:1]), tmp_path / "whole")  # type: ignore[index]
    study = toy(tmp_path, agents=TOY["agents"][:1], seeds_per_batch=1)  # type: ignore[index]  # (toy.yaml: this one)
    out = tmp_path / "out"
    killed = subprocess.run([sys.executable, "-c", KILL_ON_SECOND_BATCH, str(study), str(out)])
    assert killed.returncode == -9
    assert any(p.name.startswith(".tmp-") for p in (out / "chunks").iterdir()) and len(chunks(out)) == 1
    done = run(study, out)
    assert (done.skipped, done.finished) == (1, 1) and len(chunks(out)) == 2
    assert not any(p.name.startswith(".tmp-") for p in (out / "chunks").iterdir())
    merged, one = cell(out), cell(tmp_path / "whole")
    for key in ROWS:
        assert merged[key] == one[key], key


def nan_success(path: Path) -> bytes:
    """The chunk at ``path`` with its success rates NaN (its footer as it was)."""
    table = pq.read_table(path)
    index = table.column_names.index("success")
    table = table.set_column(index, "success", pa.array(np.full(table.num_rows, np.nan)))
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)
    return sink.getvalue().to_pybytes()


def test_damaged_chunks_are_named_not_counted_refused_by_the_report_and_redone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truncated, garbage, {}, symlinked or NaN-success chunk counts as not done: status names it, the report refuses it,
    a rerun moves it to damaged/ and runs its batch again, to the same results."""
    from sb3_affect.study.report.sections.deep_minigrid import load_deep

    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    out = tmp_path / "out"
    run(study, out)
    (path,) = chunks(out)
    good = path.read_bytes()
    success = cell(out)["success"]
    for damage, why in [(good[: len(good) // 2], "is not a readable chunk"), (b"garbage", "is not a readable chunk"),
                        (b"{}", "is not a readable chunk"), (None, "a symbolic link"),
                        (nan_success(path), "has a success or return that no evaluation gives")]:  # fmt: skip
        path.unlink()
        if damage is None:
            (tmp_path / "elsewhere.parquet").write_bytes(good)
            path.symlink_to(tmp_path / "elsewhere.parquet")
        else:
            path.write_bytes(damage)
        shown = status(out, capsys)
        assert "0/2 runs done" in shown and f"not counted: {path}" in shown and why in shown
        with pytest.raises(StoreError, match=f"^{re.escape(str(path))} .*{why}.*to move it to damaged/"):
            load_deep(out)
        done = run(study, out)
        assert done.finished == 2 and f"{path} " in capsys.readouterr().err and path.is_file()
        assert cell(out)["success"] == success
    assert len(list((out / "damaged").iterdir())) == 5


def test_a_failed_batch_leaves_failure_records_and_a_second_launcher_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    out = tmp_path / "out"

    def broken(*args: object) -> None:
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr("sb3_affect.study.launcher.deep_training.run_batch", broken)
    assert run(study, out).failed == 2
    records = sorted((out / "failed").glob("*.json"))
    assert len(records) == 2 and all("ZeroDivisionError" in path.read_text() for path in records)
    assert "0/2 runs done, 2 failed" in status(out, capsys)
    monkeypatch.undo()
    with ResultsStore(out).lock():  # another launcher holds the folder: refused at once, in one line
        with pytest.raises(StoreError, match="is in use by another launcher"):
            run(study, out)
        assert main(["run", str(study), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is in use by another launcher" in err
    assert run(study, out).finished == 2
    assert not list((out / "failed").glob("*.json")) and "2/2 runs done, 0 failed" in status(out, capsys)
