"""The deep study's report section (study/report/sections/deep_minigrid.py) on synthetic folders whose answers are known."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from sb3_affect.study.launcher.chunks import encode_evaluations
from sb3_affect.study.launcher.schema import Sweep
from sb3_affect.study.launcher.store import SWEEP_SCHEMA, ResultsStore, cell_run_ids
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.document import Document
from sb3_affect.study.report.sections import deep_minigrid as deep

AGENTS = [{"name": "dqn-linear", "algo": "DQN"}, {"name": "affective", "algo": "AffectDQN"},
          {"name": "matched", "algo": "ReplayedEpsilonDQN", "replays": "affective"}]  # fmt: skip
BUDGET, EVERY = 40_000, 10_000


def write_folder(folder: Path, curves: dict[str, np.ndarray], first: dict[str, list[int | None]],
                 eval_episodes: int = 20) -> Path:
    """
    A deep-study folder of one task written through the results store, as the launcher writes it: each agent's success
    curves ``(seeds, evaluations)`` and first successes, one chunk of evaluations per agent.
    """
    seeds = list(range(next(iter(curves.values())).shape[0]))
    study = Sweep.validate_file({
        "name": "synthetic", "seeds": seeds, "trainer": {"vec_env": "compiled", "obs": "view", "n_envs": 4, "algo_kwargs": {}},
        "evaluation": {"every": EVERY, "episodes": eval_episodes},
        "tasks": {"Empty-8x8": {"id": "MiniGrid-Empty-8x8-v0", "total_timesteps": BUDGET}}, "agents": AGENTS})  # fmt: skip
    cells = study.cells()
    ids = [cell_run_ids(cell) for cell in cells]
    store = ResultsStore(folder)
    folder.mkdir(parents=True)
    resolved = {"schema": SWEEP_SCHEMA, "name": study.name, "sweep": study.model_dump(mode="json"),
                "total_runs": sum(map(len, ids)), "task_order": list(study.tasks or {})}
    store.prepare(resolved, [rid for run in ids for rid in run])
    for cell, run_ids in zip(cells, ids):
        agent = cell.base["agent"]
        success = curves[agent]
        record = {"success": success, "return": success * 0.9, "random_share": np.full(success.shape, 0.3),
                  "train_episodes": np.full(success.shape, 4.0), "train_successes": np.zeros(success.shape),
                  "emotions": {name: np.full(success.shape, 0.25) for name in ("joy", "sadness", "fear", "anger")}
                  if agent == "affective" else None, "first_success": first[agent]}  # fmt: skip
        runs = [(rid, seed, index) for index, (rid, seed) in enumerate(zip(run_ids, cell.seeds))]
        name = f"{agent}-synthetic"
        timings = {"wall_seconds": 1.0, "cpu_seconds": 1.0}
        store.write_chunk(name, encode_evaluations(name, cell.base, runs, record, timings, {}, None), run_ids)
    return folder


def section(folder: Path, out: Path) -> tuple[str, ReportContext]:
    for sub in ("tables", "figures"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(Document("test"), out, folder, None, pd.DataFrame())  # type: ignore[arg-type]
    deep.deep_minigrid_section(ctx)
    return ctx.doc.markdown(out), ctx


def curves(level: float, seeds: int = 8) -> np.ndarray:
    return np.full((seeds, BUDGET // EVERY), level)


def test_the_iqm_table_holds_the_interquartile_mean_of_each_runs_auc_and_final_value(tmp_path: Path) -> None:
    finals = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.0, 1.0])
    ramp = np.linspace(0, 1, BUDGET // EVERY)
    success = np.outer(finals, ramp)  # run i: 0 -> finals[i]
    folder = write_folder(tmp_path / "f", {"dqn-linear": success, "affective": curves(0.5), "matched": curves(0.5)},
                          {agent: [1000] * 8 for agent in ("dqn-linear", "affective", "matched")})
    table = deep.iqm_table(deep.run_scores(deep.load_deep(folder)), [a["name"] for a in AGENTS])
    row = table.loc[("Empty-8x8", "dqn-linear")]
    assert row["final success"] == pytest.approx(sps.trim_mean(finals, 0.25))
    assert row["success AUC"] == pytest.approx(sps.trim_mean(success.mean(axis=1), 0.25))
    assert row["final success low"] <= row["final success"] <= row["final success high"]
    assert table.loc[("Empty-8x8", "affective"), "final success"] == pytest.approx(0.5)


def test_runs_that_never_succeed_are_censored_at_the_budget_not_dropped(tmp_path: Path) -> None:
    reached = [1000, 2000, 3000, 4000]
    folder = write_folder(tmp_path / "f", {a["name"]: curves(0.5, seeds=7) for a in AGENTS},
                          {"dqn-linear": reached + [None] * 3, "affective": reached + reached[:3], "matched": [None] * 7})
    table = deep.first_success_table(deep.run_scores(deep.load_deep(folder))).loc[deep.CLOCKS[0][2]]
    assert table.loc[("Empty-8x8", "dqn-linear"), ["runs", "reached", "censored"]].tolist() == [7, 4, 3]
    assert table.loc[("Empty-8x8", "matched"), ["reached", "censored"]].tolist() == [0, 7]
    # 3 of 7 runs censored at the budget: the Kaplan-Meier curve falls below one half at the 4th event, 4,000 steps;
    # seven runs that all succeed at those times (affective) have their median at 2,000
    assert table.loc[("Empty-8x8", "dqn-linear"), "KM median"] == "4,000"
    assert table.loc[("Empty-8x8", "affective"), "KM median"] == "2,000"
    assert table.loc[("Empty-8x8", "matched"), "KM median"] == f"> {BUDGET:,}"
    # the restricted mean counts a censored run at the budget
    assert table.loc[("Empty-8x8", "matched"), "RMST"] == pytest.approx(BUDGET)


def test_the_first_greedy_success_is_the_first_evaluation_with_a_success_and_never_is_censored(tmp_path: Path) -> None:
    success = curves(0.0, seeds=7)
    for seed, evaluation in enumerate([0, 0, 1, 1, 2, None, None]):  # the evaluation at which each run first succeeds
        if evaluation is not None:
            success[seed, evaluation:] = 0.05
    folder = write_folder(tmp_path / "f", {"dqn-linear": success, "affective": curves(1.0, seeds=7),
                                           "matched": curves(0.0, seeds=7)}, {a["name"]: [500] * 7 for a in AGENTS})
    table = deep.first_success_table(deep.run_scores(deep.load_deep(folder))).loc[deep.CLOCKS[1][2]]
    assert table.loc[("Empty-8x8", "dqn-linear"), ["reached", "censored", "KM median"]].tolist() == [5, 2, "20,000"]
    assert table.loc[("Empty-8x8", "affective"), "KM median"] == f"{EVERY:,}"
    assert table.loc[("Empty-8x8", "matched"), ["reached", "censored", "KM median"]].tolist() == [0, 7, f"> {BUDGET:,}"]


@pytest.mark.parametrize(("affective", "matched", "word", "versus"), [(1.0, 0.0, "above", "below"),
                                                                     (0.0, 1.0, "below", "above")])  # fmt: skip
def test_the_sentence_is_computed_from_the_cis_and_flips_with_the_numbers(
    tmp_path: Path, affective: float, matched: float, word: str, versus: str
) -> None:
    rng = np.random.default_rng(0)
    noisy = {"dqn-linear": curves(0.5) + rng.uniform(-0.01, 0.01, (8, 4)), "affective": curves(affective),
             "matched": curves(matched)}  # fmt: skip
    folder = write_folder(tmp_path / "f", noisy, {a["name"]: [1000] * 8 for a in AGENTS})
    text, _ = section(folder, tmp_path / "out")
    sentence = next(line for line in text.splitlines() if line.startswith("On Empty-8x8"))
    assert f"affective {word}" in sentence and f"matched {versus}" in sentence
    assert f"matched (the same amount of randomness, uniform in time) {versus} affective" in sentence
    equal = write_folder(tmp_path / "g", {a["name"]: curves(0.5) for a in AGENTS}, {a["name"]: [1000] * 8 for a in AGENTS})
    text, _ = section(equal, tmp_path / "out2")
    assert "affective, matched not told apart from it" in text and "not told apart from affective" in text


def test_every_exploratory_section_reads_a_difference_by_one_rule(tmp_path: Path) -> None:
    """The deep study, MiniGrid and the two hunters: the probability of improvement's CI against 0.5, not CI overlap."""
    from sb3_affect.study.report.estimation.bootstrap import EXPLORATORY_RULE, bootstrap_improvement, improvement_outcome
    from sb3_affect.study.report.sections import hunters, minigrid

    rng = np.random.default_rng(3)
    # success AUCs whose IQM CIs overlap while most runs of one agent beat most runs of the other
    levels = {"dqn-linear": 0.45 + rng.uniform(-0.2, 0.2, (8, 1)), "affective": 0.6 + rng.uniform(-0.2, 0.2, (8, 1)),
              "matched": 0.45 + rng.uniform(-0.2, 0.2, (8, 1))}  # fmt: skip
    folder = write_folder(tmp_path / "f", {a: np.repeat(v, 4, axis=1) for a, v in levels.items()},
                          {a["name"]: [1000] * 8 for a in AGENTS})  # fmt: skip
    scores = deep.run_scores(deep.load_deep(folder))
    runs = {a: scores[scores.agent == a].auc_success.to_numpy(float) for a in levels}
    _, low, high = bootstrap_improvement(runs["affective"], runs["dqn-linear"], deep.REPS // 5, seed=0, lower_is_better=False)
    assert deep.comparison(scores, "Empty-8x8", "affective", "dqn-linear") == improvement_outcome(low, high)
    (sentence,) = deep.verdict(scores, deep.load_deep(folder).study)
    assert f"(the rule: {EXPLORATORY_RULE})" in sentence
    tabular = pd.DataFrame([{"task": "t", "agent": agent, "success": float(v), "return": float(v) * 0.9,
                             "steps_to_success": 1.0, "run_id": f"{agent}{i}"}
                            for agent, values in (("affective", runs["affective"]), ("reversed", runs["matched"]))
                            for i, v in enumerate(values)])  # fmt: skip
    tabular_sentence = minigrid.verdict(tabular, "affective")[0]
    assert f"(the rule: {EXPLORATORY_RULE})" in tabular_sentence
    assert "on the success rate" in tabular_sentence and "on the return" in tabular_sentence  # both scores are read
    assert hunters.improvement_outcome is improvement_outcome and improvement_outcome(0.51, 0.9) == "better"
    assert improvement_outcome(0.1, 0.49) == "worse" and improvement_outcome(0.4, 0.6) == "not told apart"


def test_the_power_calculation_gives_the_fewest_seeds_that_detect_its_effect() -> None:
    needed = deep.seeds_needed()
    assert deep.detectable(needed) <= deep.TARGET < deep.detectable(needed - 1)
    assert needed <= deep.STUDY_SEEDS  # the study's 20 seeds per cell are enough
    assert deep.seeds_needed(target=0.9) < needed < deep.seeds_needed(target=0.7)
    assert "this study has 20" in deep.power_sentence(20) and "fewer runs" not in deep.power_sentence(20)
    assert "fewer runs than that calculation asks for" in deep.power_sentence(needed - 1)


def test_the_section_reads_the_folder_labels_a_smoke_size_and_follows_no_symlink(tmp_path: Path) -> None:
    small = write_folder(tmp_path / "deep_smoke", {a["name"]: curves(0.5, seeds=3) for a in AGENTS},
                         {a["name"]: [1000] * 3 for a in AGENTS}, eval_episodes=5)
    text, ctx = section(tmp_path, tmp_path / "out")
    assert "(smoke size): deep_smoke/" in text and "Smoke size: 3 seeds per cell and 5 evaluation episodes" in text
    for name in ("deep_smoke_iqm", "deep_smoke_first_success"):
        assert (ctx.out / "tables" / f"{name}.csv").is_file()
    for name in ("deep_smoke_success", "deep_smoke_random", "deep_smoke_emotions"):
        assert (ctx.out / "figures" / f"{name}.png").is_file()
    full = write_folder(tmp_path / "full", {a["name"]: curves(0.5, seeds=20) for a in AGENTS},
                        {a["name"]: [1000] * 20 for a in AGENTS})
    text, _ = section(full, tmp_path / "out3")
    assert "smoke" not in text.lower() and "fewer than the study's" not in text
    pilot = write_folder(tmp_path / "pilot", {a["name"]: curves(0.5, seeds=5) for a in AGENTS},
                         {a["name"]: [1000] * 5 for a in AGENTS})
    text, _ = section(pilot, tmp_path / "out4")
    assert "smoke" not in text.lower() and "5 seeds per cell, fewer than the study's 20: a tuning pass" in text
    # a chunk that is a symlink is never followed, nor silently dropped: the folder is refused naming it
    from sb3_affect.study.launcher.store import StoreError

    target = small / "chunks" / "matched-synthetic.parquet"
    moved = target.rename(tmp_path / "elsewhere.parquet")
    target.symlink_to(moved)
    with pytest.raises(StoreError, match=f"^{target} is not a regular file \\(a symbolic link\\).*to move it to damaged/"):
        deep.load_deep(small)


def test_report_of_a_deep_study_folder_alone_is_its_section(tmp_path: Path) -> None:
    from sb3_affect.study.cli import main

    levels = {"dqn-linear": 1.0, "affective": 0.0, "matched": 0.5}
    first = {agent: [EVERY] * 8 for agent in levels}
    folder = write_folder(tmp_path / "minigrid_dqn", {agent: curves(v) for agent, v in levels.items()}, first)
    out = tmp_path / "report"
    assert main(["report", str(folder), "--out", str(out)]) == 0
    text = (out / "report.md").read_text()
    alone, _ = section(folder, tmp_path / "section")
    assert text.startswith("# Deep agents on MiniGrid: minigrid_dqn\n")
    assert "## Deep agents on MiniGrid, greedy policies: minigrid_dqn/" in text and "| Empty-8x8 | affective | 8 |" in text
    assert alone.split("\n", 1)[1].strip() in text  # the section as the replicate report holds it, nothing else
    assert (out / "report.html").is_file() and (out / "tables" / "minigrid_dqn_iqm.csv").is_file()


def test_the_paper_loader_reads_a_deep_folders_evaluations_as_no_episodes(tmp_path: Path) -> None:
    from sb3_affect.study.launcher.chunks import EVALUATIONS
    from sb3_affect.study.report.reading.run_tables import load_results

    first = {a["name"]: [EVERY] * 8 for a in AGENTS}
    folder = write_folder(tmp_path / "deep", {a["name"]: curves(0.5) for a in AGENTS}, first)
    store = ResultsStore(folder)
    results = load_results(folder)
    assert results.kinds == {EVALUATIONS}  # told apart by each chunk's footer
    assert results.runs.empty and store.runs_frame().empty and store.load_runs() == []
    assert len(store.evaluations()) == len(AGENTS) and len(store.done_ids()) == 8 * len(AGENTS)  # (the launcher's count)
