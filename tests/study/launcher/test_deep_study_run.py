"""The deep study's runs (study/launcher/deep_study.py) on a toy study: SB3's real DQN and AffectDQN on Farama's MiniGrid."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("minigrid")

from sb3_affect.study.launcher.deep_schema import DeepStudy
from sb3_affect.study.launcher.deep_study import (
    build_cell,
    cell_path,
    replayed_epsilons,
    run_deep_study,
)
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
    assert (done.trained, done.reused) == (4, 0) and len(lines) == 4
    cells = {agent: json.loads(cell_path(tmp_path / "out", "Empty-5x5", agent).read_text())
             for agent in ("dqn-linear", "affective", "matched", "count-bonus")}  # fmt: skip
    for cell in cells.values():
        assert cell["eval_steps"] == [200, 400]
        success = np.asarray(cell["success"], dtype=float)
        assert success.shape == (2, 2) and ((success >= 0) & (success <= 1)).all()
        assert all(first is None or 0 < first <= 400 for first in cell["first_success"])
    # the matched control's ε is the affective agent's share of random decisions, averaged over seeds, part by part
    replayed = replayed_epsilons(cells["affective"])
    assert cells["matched"]["epsilons"] == replayed
    np.testing.assert_allclose(np.asarray(cells["matched"]["random_share"], dtype=float), [replayed, replayed])
    assert cells["affective"]["emotions"] is not None and cells["dqn-linear"]["emotions"] is None
    shares = sum(np.asarray(v, dtype=float) for v in cells["affective"]["emotions"].values())
    np.testing.assert_allclose(shares, 1.0)  # each part's emotion shares sum to one
    assert cells["count-bonus"]["count_bonus"] == 0.05
    again = run_deep_study(study, tmp_path / "out", workers=1, log=lines.append)
    assert (again.trained, again.reused) == (0, 4)
    with pytest.raises(ValueError, match="holds the results of another deep study"):
        run_deep_study(toy(tmp_path, seeds=[0, 1, 2]), tmp_path / "out", workers=1)


def test_the_batched_greedy_evaluation_equals_sb3_predict_on_each_seeds_evaluation_envs(tmp_path: Path) -> None:
    study = toy(tmp_path, agents=[TOY["agents"][0]])  # type: ignore[index]
    trainer = build_cell(study, "Empty-5x5", study.agents[0])
    trainer.learn(400)  # the stacked weights are written back into the models; the stack keeps them too
    success, returns = trainer.evaluate()
    for index, model in enumerate(trainer.models):
        env = trainer.eval_envs.envs[index]
        env.seed(trainer.eval_seeds[index])
        obs = env.reset()
        total, reached, finished = np.zeros(env.num_envs), np.zeros(env.num_envs, bool), np.zeros(env.num_envs, bool)
        while not finished.all():
            obs, rewards, dones, infos = env.step(model.predict(obs, deterministic=True)[0])
            total[~finished] += rewards[~finished]
            for e in np.flatnonzero(dones & ~finished):
                finished[e], reached[e] = True, not infos[e].get("TimeLimit.truncated", False)
        assert success[index] == reached.mean() and returns[index] == pytest.approx(total.mean())


def test_the_count_bonus_pays_scale_over_the_root_of_visits_of_each_envs_cell() -> None:
    from sb3_affect.engine.seed_envs import seed_vec_env
    from sb3_affect.study.launcher.count_bonus import CountBonus

    env = CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 2, 0, "image"), scale=0.5)
    env.reset()
    rewards = [env.step(np.array([0, 0]))[1] for _ in range(3)]  # turning left: the agent stays in its cell
    np.testing.assert_allclose(rewards, [[0.5, 0.5], [0.5 / np.sqrt(2)] * 2, [0.5 / np.sqrt(3)] * 2], rtol=1e-6)
    with pytest.raises(ValueError, match="count_bonus=0"):
        CountBonus(seed_vec_env("MiniGrid-Empty-5x5-v0", 1, 0, "image"), scale=0)
