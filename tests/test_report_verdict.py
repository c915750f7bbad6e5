"""The verdict's statistics on synthetic per-run tables (fast), the refusal rule, and engine studies = launcher runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_affect.experiments import run_sweep
from sb3_affect.report import claims
from sb3_affect.report.evidence import sensitivity
from sb3_affect.report.largen import Cell, run_cells
from sb3_affect.report.metrics import load_results, run_metrics

ROOT = Path(__file__).resolve().parents[1]
EPS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


def _runs(n: int, seed: int = 0) -> pd.DataFrame:
    """Per-run rows with a built-in crossover (ε-greedy better below 0.5, worse above 0.6) and a joy-then-anger profile."""
    rng = np.random.default_rng(seed)
    rows = []
    for eps in EPS:
        for r in range(n):
            for agent, steps, before in (
                ("epsilon-greedy", 20 + 120 * eps**3 * 3, 3000 + 30000 * eps**4),
                ("affective", 50.0, 2300.0),
            ):
                rows.append(
                    {
                        "agent": agent,
                        "epsilon": eps,
                        "replicate": r,
                        "run_id": f"{agent}-{eps}-{r}",
                        "episodes": 200,
                        "decisions_per_episode": steps * rng.lognormal(0, 0.1),
                        "decisions_before_optimal": before * rng.lognormal(0, 0.2),
                        "decisions_to_greedy_optimal": before * rng.lognormal(0, 0.2),
                        "first_optimal": 21 + rng.normal(0, 3),
                        "censored": False,
                        "joy_1_10": 0.7, "anger_1_10": 0.3, "joy_181_200": 0.1, "anger_181_200": 0.9,
                        "joy_1_10_weighted": 0.7, "anger_1_10_weighted": 0.3,
                        "joy_181_200_weighted": 0.8, "anger_181_200_weighted": 0.2,
                        "sadness_1_10": 0.0, "fear_1_10": 0.0, "sadness_181_200": 0.0, "fear_181_200": 0.0,
                        "eqeps_1_10": 0.3 + rng.normal(0, 0.02), "eqeps_181_200": 0.1 + rng.normal(0, 0.02),
                        "decisions_181_200": steps * 0.5,
                    }
                )
    return pd.DataFrame(rows)


def test_judge_all_calls_a_crossover_a_crossover_and_applies_holm() -> None:
    judged = {j.label.split(":")[0]: j for j in claims.judge_all(_runs(30))}
    fig3 = judged["Fig. 3"]
    assert fig3.verdict.startswith(("reproduced: a crossover", "crossover reproduced"))
    assert "no difference" not in fig3.verdict
    tests = [t for j in judged.values() for t in j.tests]
    assert len(tests) > 30
    assert all(t.p_holm >= t.p for t in tests)  # Holm never lowers a p-value
    smallest = min(tests, key=lambda t: t.p)
    assert smallest.p_holm == pytest.approx(min(1.0, smallest.p * len(tests)))  # Holm's first step: p times m
    assert judged["Fig. 5 (mean of per-episode fractions)"].verdict == "reproduced"
    assert judged["Fig. 5 (decision-weighted)"].verdict.startswith("partly: joy dominates early, but joy")
    assert judged["Fig. 6"].verdict == "reproduced"
    assert judged["Four emotions shape behaviour (sadness and fear included)"].verdict.startswith("not reproduced")
    assert judged["27.35 episodes until the optimal path (affective)"].verdict.startswith("not reproduced: fewer")


def test_seed_sensitivity_uses_the_first_replicates() -> None:
    table = sensitivity(_runs(10), counts=(5, 10, 1000))
    assert list(table.columns) == ["5 seeds", "10 seeds"]  # 1000 is more than there are
    assert len(table) == len(claims.judge_all(_runs(10)))


def test_engine_study_gives_the_launchers_runs(tmp_path: Path) -> None:
    """A cell run through the engine with the sweep's seed derivation equals the launcher's run files."""
    run_sweep(ROOT / "experiments" / "smoke.yaml", tmp_path / "smoke", workers=1, progress=False)
    results = load_results(tmp_path / "smoke")
    launcher = run_metrics(results.episodes, results.runs)
    launcher = launcher[(launcher.agent == "epsilon-greedy") & (launcher.epsilon == 0.9)].sort_values("replicate")
    cell = Cell("epsilon-greedy", "QLearning", {"exploration_rate": 0.9}, {"epsilon": 0.9}, "smoke", {"epsilon": 0.9},
                "sb3_affect/GridPursuit-v0", {})
    engine, meta = run_cells(tmp_path / "engine", [cell], seeds=2, episodes=20, workers=1)
    engine = engine.sort_values("replicate")
    for column in ("decisions_per_episode", "decisions_before_optimal", "first_optimal", "eqeps_1_10"):
        assert np.allclose(engine[column].to_numpy(float), launcher[column].to_numpy(float), equal_nan=True), column
    assert meta["seeds"] == 2
    again, _ = run_cells(tmp_path / "engine", [cell], seeds=2, episodes=20, workers=1)  # reused, not recomputed
    pd.testing.assert_frame_equal(again.reset_index(drop=True), pd.read_csv(tmp_path / "engine" / "runs.csv.gz"))
    with pytest.raises(ValueError, match="seeds=0"):
        run_cells(tmp_path / "engine", [cell], seeds=0)


def test_seeds_needed_and_adastop_on_a_clear_difference() -> None:
    from sb3_affect.report.evidence import adastop_table, seeds_needed

    runs = _runs(30)
    needed = seeds_needed(runs, grid=(5, 10), repetitions=2)
    assert set(needed.columns) >= {"agreement at 5", "agreement at 10", "seeds needed"}
    assert needed.loc["Four emotions shape behaviour (sadness and fear included)", "seeds needed"] == 5  # always the same
    table = adastop_table(runs, "decisions_per_episode")
    decisions = table["decision (affective is ... than ε-greedy)"]
    assert decisions["affective vs epsilon-greedy 0.9"] == "smaller"  # 50 vs ~2,200 steps per episode
    assert decisions["affective vs epsilon-greedy 0.1"] == "larger"  # 50 vs ~21


@pytest.mark.slow
def test_replicate_writes_every_part_and_the_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """replicate end to end at toy size: launcher sweeps, the three engine studies, one report with their sections."""
    from sb3_affect import replicate
    from sb3_affect.replicate import main

    monkeypatch.setattr(replicate, "PARTS", (("paper", "toy paper"), ("dqn", "toy dqn"), ("baselines", "toy baselines")))

    experiments = tmp_path / "experiments"
    experiments.mkdir()
    smoke = (ROOT / "experiments" / "smoke.yaml").read_text()
    for name in ("paper", "dqn", "baselines"):
        text = smoke.replace("name: smoke", f"name: {name}").replace("episodes: 20", "episodes: 5")
        (experiments / f"{name}.yaml").write_text(text)
    report = main(tmp_path / "out", workers=1, experiments=experiments, large_seeds=1, ablation_seeds=1, beyond_seeds=1,
                  engine_episodes=5)
    text = report.read_text()
    assert "No verdict: too few runs" in text
    for part in ("large", "ablation_engine", "beyond"):
        assert (tmp_path / "out" / part / "runs.csv.gz").exists(), part
    assert "evading prey 7x7 / affective" in text and "maze: rooms / speed-epsilon-greedy" in text
    assert "Readings ranked by distance" in text
    wall = pd.read_csv(tmp_path / "out" / "tables" / "wall_times.csv")
    assert len(wall) == 6 and (wall["wall seconds"] >= 0).all()  # 3 sweeps + 3 engine studies
