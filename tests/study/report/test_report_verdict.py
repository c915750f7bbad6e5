"""The verdict's statistics on synthetic per-run tables (fast), the refusal rule, and engine studies = launcher runs."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pandas as pd
import pytest

from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.report.reading.run_tables import run_metrics
from sb3_affect.study.report.reading.study_tables import study
from sb3_affect.study.report.sections.evidence import sensitivity
from sb3_affect.study.report.sections.verdict import LONG_RUN_PROTOCOL, protocol_verdict
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts.inference import holm

ROOT = Path(__file__).resolve().parents[3]
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
                        "sadness_1_10_weighted": 0.0, "fear_1_10_weighted": 0.0,
                        "sadness_181_200_weighted": 0.0, "fear_181_200_weighted": 0.0,
                        "eqeps_1_10": 0.3 + rng.normal(0, 0.02), "eqeps_181_200": 0.1 + rng.normal(0, 0.02),
                        "decisions_181_200": steps * 0.5,
                        "cells_per_episode": steps * (1.5 if agent == "affective" else 1.0),
                        "cells_before_optimal": before * (1.5 if agent == "affective" else 1.0),
                    }
                )
    return pd.DataFrame(rows)


def _null(n: int, seed: int = 0, shift: float = 0.0, first_optimal: float = 27.35) -> pd.DataFrame:
    """Both agents drawn from one distribution at every ε (plus ``shift`` steps for ε-greedy): a true null."""
    runs = _runs(n, seed)
    rng = np.random.default_rng(seed + 1)
    steps = 60.0 * rng.lognormal(0, 0.1, len(runs))
    runs["decisions_per_episode"] = steps + np.where(runs.agent == "epsilon-greedy", shift, 0.0)
    runs["decisions_before_optimal"] = 3000 * rng.lognormal(0, 0.2, len(runs))
    runs["decisions_to_greedy_optimal"] = 3000 * rng.lognormal(0, 0.2, len(runs))
    runs["first_optimal"] = first_optimal + rng.normal(0, 3, len(runs))
    return runs


def _by_key(m: pd.DataFrame) -> dict[str, claims.Judgement]:
    return {j.key: j for j in claims.judge_all(m)}


def test_a_crossover_keeps_the_papers_test_quiet_while_the_agents_differ() -> None:
    """The built-in crossover: the paper's t over the 9 ε means is not significant, yet the agents differ on average."""
    judged = _by_key(_runs(30))
    assert judged["fig3"].verdict.startswith("reproduced: a crossover")
    assert judged["table_iv:test"].verdict.startswith("reproduced: the paper's test is not significant")
    assert not judged["table_iv:test"].seed_dependent  # no seeds-needed row for an outcome fixed by the design
    assert judged["table_iv"].verdict.startswith("not reproduced: the agents differ")
    assert "significant at 9 of 9 ε" in judged["table_iv"].verdict
    long = judged["long_run"].verdict
    assert long.startswith("not reproduced: holds only against ε >= 0.5"), long
    assert judged["fig5:mean"].verdict == "reproduced"
    assert judged["fig5:weighted"].verdict.startswith("not reproduced: joy dominates early, joy dominates late")
    assert judged["fig6"].verdict.startswith("reproduced")
    assert judged["four_emotions"].verdict.startswith("not reproduced")
    assert judged["episodes_to_optimal"].verdict.startswith("not reproduced: fewer")  # 21 against 27.35


def test_holm_runs_within_each_claim_and_the_papers_own_test_is_judged_raw() -> None:
    judged = claims.judge_all(_runs(30))
    for j in judged:
        assert all(t.p_holm >= t.p for t in j.tests)  # Holm never lowers a p-value
        if j.tests:
            smallest = min(j.tests, key=lambda t: t.p)
            assert smallest.p_holm == pytest.approx(min(1.0, smallest.p * len(j.tests)))  # first step: p x family size
    fig3 = next(j for j in judged if j.key == "fig3")
    assert len(fig3.tests) == 9  # one family: the ε values of the claim
    table_v = next(j for j in judged if j.key == "table_v:walked")
    assert table_v.primary is table_v.tests[0] and table_v.primary.p < 0.05 <= table_v.primary.p * len(table_v.tests)
    assert table_v.verdict.startswith("direction reproduced: the paper's test significant")  # raw p, as the paper judged it
    assert "size differs (paper / ours 0.09" in table_v.verdict  # synthetic sizes far from the paper's


def test_a_true_null_is_equivalence_not_absence_of_evidence() -> None:
    """Identical agents at 200 seeds: TOST shows equivalence; no per-ε difference; Table V not significant."""
    judged = _by_key(_null(200, seed=1))  # (seed 0 draws one of the 5% family-wise false positives of Holm at one ε)
    assert judged["table_iv"].verdict.startswith("reproduced: equivalent within"), judged["table_iv"].verdict
    assert judged["fig3"].verdict == "not reproduced: no significant difference at any ε"
    assert judged["table_v:walked"].verdict.startswith("not reproduced")
    assert judged["episodes_to_optimal"].verdict.startswith("reproduced: 27.35 lies within")


def test_too_few_runs_is_inconclusive_not_reproduced() -> None:
    """Identical agents at 5 seeds and a noisy metric: neither a difference nor equivalence: inconclusive."""
    runs = _null(5)
    rng = np.random.default_rng(3)
    runs["decisions_per_episode"] = 60.0 * rng.lognormal(0, 0.8, len(runs))
    verdict = _by_key(runs)["table_iv"].verdict
    assert verdict.startswith("inconclusive"), verdict


def test_a_true_difference_just_inside_the_margin_and_one_outside() -> None:
    """A 1-step shift (margin 5% of ~61) is equivalence at 400 seeds; a 10-step shift is a difference."""
    assert _by_key(_null(400, shift=1.0))["table_iv"].verdict.startswith("reproduced: equivalent")
    assert _by_key(_null(400, shift=10.0))["table_iv"].verdict.startswith("not reproduced: the agents differ")


def test_a_size_mismatch_is_caught_by_the_20_seed_predictive_interval() -> None:
    """ε-greedy at ~101 steps against the paper's 67.02: outside; rescaled to 67.02 on average: inside."""
    runs = _runs(100)
    judged = _by_key(runs)
    mismatch = judged["printed_iv:epsilon-greedy"]
    assert mismatch.size is False and mismatch.verdict.startswith("not reproduced: paper / ours 0.6")
    assert mismatch.ratio == pytest.approx(67.02 / runs[runs.agent == "epsilon-greedy"].decisions_per_episode.mean(), rel=1e-9)
    standard = runs.agent == "epsilon-greedy"
    runs.loc[standard, "decisions_per_episode"] *= 67.02 / runs.loc[standard, "decisions_per_episode"].mean()
    match = _by_key(runs)["printed_iv:epsilon-greedy"]
    assert match.size is True and match.verdict.startswith("reproduced: inside the 20-seed predictive interval [")


def test_seed_sensitivity_uses_the_first_replicates() -> None:
    table = sensitivity(_runs(10), counts=(5, 10, 1000))
    assert list(table.columns) == ["5 seeds", "10 seeds"]  # 1000 is more than there are
    assert len(table) == len(claims.judge_all(_runs(10)))


class Cell(NamedTuple):
    """One configuration run at many seeds through the engine, as the report's engine studies ran it."""

    agent: str
    algo: str
    kwargs: dict[str, Any]
    labels: dict[str, Any]
    sweep: str
    point: dict[str, Any]
    env_id: str
    env_kwargs: dict[str, Any]


def engine_table(cells: list[Cell], seeds: int, episodes: int) -> pd.DataFrame:
    """
    What the engine gives for ``cells`` at ``seeds`` replicates (``derive_seed(sweep, agent, point, r)``): one
    ``simulate`` call per cell and 50 replicates, each run's ``run_metrics`` (moving prey: optimal = a capture within
    the prey's starting distance), run ids ``<agent>-<label values>-r<replicate>``, the cells' tables joined in order.
    """
    from sb3_affect.engine.simulation import simulate
    from sb3_affect.study.launcher.schema import derive_seed
    from sb3_affect.study.report.reading.baseline_ranks import capture_distance
    from sb3_affect.study.report.reading.run_tables import EARLY, LATE

    frames = []
    for cell in cells:
        for start in range(0, seeds, 50):
            replicates = list(range(start, min(seeds, start + 50)))
            drawn = [derive_seed(cell.sweep, cell.agent, cell.point, r) for r in replicates]
            frame = simulate(cell.algo, cell.kwargs, cell.env_id, cell.env_kwargs, drawn, episodes)
            if "MovingPursuit" in cell.env_id:
                bound = capture_distance({"env_id": cell.env_id, "env_kwargs": cell.env_kwargs})
                frame["optimal"] = ~frame.truncated.astype(bool) & (frame.cells <= bound)
            frame["replicate"] = frame.seed.map(dict(zip(drawn, replicates)))
            tag = "-".join(f"{v}" for v in cell.labels.values())
            frame["run_id"] = [f"{cell.agent}-{tag}-r{r}" for r in frame.replicate]
            frame["agent"] = cell.agent
            for key, value in cell.labels.items():
                frame[key] = value
            last = (max(episodes - 199, 1), episodes)
            frames.append(run_metrics(frame, windows=(EARLY, LATE) if last[0] <= LATE[0] else (EARLY, LATE, last)))
    return pd.concat(frames, ignore_index=True)


EPSILONS = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
COMMON = {"learning_rate": 1.0, "gamma": 0.8, "q_init": 0.0}
AFFECT = {**COMMON, "comparison": "literal", "act": "episode", "units": "cells"}
PAPER_ENV = {"size": 15, "start": [0, 0], "goal": [6, 6], "goal_reward": 100.0}


TASKS = (
    ("static grid 15x15 (the paper's task)", "sb3_affect/GridPursuit-v0", PAPER_ENV),
    ("moving prey 7x7 (random walk)", "sb3_affect/MovingPursuit-v0",
     {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "random", "prey_speed": 0.5}),
    ("evading prey 7x7", "sb3_affect/MovingPursuit-v0",
     {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "evade", "prey_speed": 0.5}),
    ("maze: wall", "sb3_affect/MazePursuit-v0", {"maze": "wall"}),
    ("maze: rooms", "sb3_affect/MazePursuit-v0", {"maze": "rooms"}),
)  # fmt: skip
TUNED = (("epsilon-greedy, tuned ε", "QLearning", {}),
         ("speed-epsilon-greedy, tuned ε", "sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": [1, 2]}))
GRID = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
CAP = {"max_episode_decisions": 2000}
#: The ε of each tuned agent on each task in experiments/beyond.yaml, in the order of TASKS x TUNED.
BEYOND_EPS = (0.000125, 0.002, 0.001, 0.002, 0.5, 0.2, 0.02, 0.002, 0.1, 0.02)


def study_cells(name: str) -> list[Cell]:
    """
    The cells of a shipped study file, written out as the report's engine studies ran them (the seeds' sweep and grid
    point; the tuning and the tasks beyond the paper: each task its own seeds, the same for every ε).
    """
    env = ("sb3_affect/GridPursuit-v0", PAPER_ENV)
    if name == "tuning":
        return [Cell(agent, algo, {**kwargs, "exploration_rate": e, **CAP}, {"task": task, "epsilon": e}, "beyond-tuning",
                     {"task": task}, env_id, env_kwargs)
                for task, env_id, env_kwargs in TASKS for agent, algo, kwargs in TUNED for e in GRID]  # fmt: skip
    if name == "beyond":
        fixed = (("affective", "AffectQ", {}), ("epsilon-greedy 0.1", "QLearning", {"exploration_rate": 0.1}))
        tuned = dict(zip(((t, a) for t, _, _ in TASKS for a, _, _ in TUNED), BEYOND_EPS))
        cells = []
        for task, env_id, env_kwargs in TASKS:
            cells += [Cell(a, algo, {**kw, **CAP}, {"task": task}, "beyond", {"task": task}, env_id, env_kwargs)
                      for a, algo, kw in fixed]  # fmt: skip
            cells += [Cell(a, algo, {**kw, "exploration_rate": tuned[task, a], **CAP},
                           {"task": task, "epsilon": tuned[task, a]}, "beyond", {"task": task}, env_id, env_kwargs)
                      for a, algo, kw in TUNED]  # fmt: skip
        return cells
    if name == "speed_one":

        table = {"joy": [True, [1]], "sadness": [False, [1]], "fear": [False, [1]], "anger": [False, [1]]}
        return [Cell("affective-speed-1", "AffectQ", {**AFFECT, "behaviour_table": table}, {"epsilon": e}, "speed-one",
                     {"epsilon": e}, *env) for e in EPSILONS]
    cells = [Cell("epsilon-greedy", "QLearning", {**COMMON, "exploration_rate": e}, {"epsilon": e}, "paper", {"epsilon": e},
                  *env) for e in EPSILONS]
    cells += [Cell("affective", "AffectQ", AFFECT, {"epsilon": e}, "paper", {"epsilon": e}, *env) for e in EPSILONS]
    speed = {**COMMON, "exploration_rate": 0.01, "speeds": [1, 2]}
    return [*cells, Cell("speed-epsilon-greedy", "sb3_affect.agents.baselines:SpeedEpsilonGreedy", speed, {"epsilon": 0.01},
                         "large", {}, *env)]


@pytest.mark.parametrize(("name", "seeds", "episodes"),
                         [("large", 2, 12), ("speed_one", 55, 3), ("tuning", 2, 4), ("beyond", 3, 5)])
def test_a_study_run_by_the_launcher_reads_as_the_engine_table(tmp_path: Path, name: str, seeds: int, episodes: int) -> None:
    """
    A study's sweep file through the launcher gives, row for row, the table the engine gives for its cells: the same
    seeds (``seeds_from``: the paper sweep's; ``seeds_by: [task]``: each task's own, the same for every ε), fixed
    labels, a behaviour table by emotion names, tasks in the file's order, moving prey's optimal episodes, the rows in
    the cells' order (more than one ``CHUNK`` of replicates), the run ids, column order and dtypes the report reads.
    """
    run_sweep(ROOT / "experiments" / f"{name}.yaml", tmp_path / name, workers=1, progress=False,
              overrides=[f"seeds={seeds}", f"episodes={episodes}"])
    found = study(tmp_path, name)
    assert found is not None
    table, meta = found
    assert (meta["seeds"], meta["episodes"], meta["runs"]) == (seeds, episodes, len(table))
    pd.testing.assert_frame_equal(table, engine_table(study_cells(name), seeds, episodes))


def test_seeds_needed_and_adastop_on_a_clear_difference() -> None:
    from sb3_affect.study.report.sections.evidence import adastop_table, seeds_needed

    runs = _runs(30)
    needed = seeds_needed(runs, n=10, repetitions=4)
    share = "share of 4 10-seed subsamples with that verdict"
    assert set(needed.columns) >= {"verdict at 30 seeds", share, "reading"}  # (30: no thousands separator)
    assert needed.loc["Four emotions shape behaviour (sadness and fear included)", share] == 1.0  # always the same
    assert np.isnan(needed.loc["Table IV, the paper's test: paired t over the 9 ε values not significant", share])
    table = adastop_table(runs, "decisions_per_episode")
    decisions = table["decision (affective is ... than ε-greedy)"]
    assert decisions["affective vs epsilon-greedy 0.9"] == "smaller"  # 50 vs ~2,200 steps per episode
    assert decisions["affective vs epsilon-greedy 0.1"] == "larger"  # 50 vs ~21


@pytest.mark.slow
def test_replicate_writes_every_part_and_the_record(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """replicate end to end at toy size: launcher sweeps, the tuning rounds and beyond, one report with their sections."""
    from sb3_affect.study import replicate, studies
    from sb3_affect.study.replicate import main

    studied = tuple(part for part in replicate.PARTS if part[0] in studies.SIZED)
    toys = (("paper", "toy paper"), ("dqn", "toy dqn"), ("baselines", "toy baselines"))
    monkeypatch.setattr(replicate, "PARTS", (*toys, *studied))

    experiments = tmp_path / "experiments"
    experiments.mkdir()
    smoke = (ROOT / "experiments" / "smoke.yaml").read_text()
    for name in ("paper", "dqn", "baselines"):
        text = smoke.replace("name: smoke", f"name: {name}").replace("episodes: 20", "episodes: 5")
        (experiments / f"{name}.yaml").write_text(text)
    for name in (*studies.SIZED, *(name for name, _ in studies.TUNED_PARTS)):  # the shipped studies, sized down
        (experiments / f"{name}.yaml").write_text((ROOT / "experiments" / f"{name}.yaml").read_text())
    report = main(tmp_path / "out", workers=1, experiments=experiments, large_seeds=1, ablation_seeds=1, beyond_seeds=1,
                  engine_episodes=5, forensics=False)
    text = _pages(report)
    assert "No verdict: too few runs" in text
    for part in studies.SIZED:  # launcher folders
        assert json.loads((tmp_path / "out" / part / "sweep.json").read_text())["sweep"]["episodes"] in (5, 50), part
    assert json.loads((tmp_path / "out" / "beyond" / "sweep.json").read_text())["name"] == "beyond"  # launcher folders
    long = study(tmp_path / "out", "long")
    assert long is not None and int(long[0].episodes.max()) == 50  # 10 x the engine episodes
    assert "evading prey 7x7 / affective" in text and "maze: rooms / speed-epsilon-greedy, tuned ε (" in text
    assert (tmp_path / "out" / "tuning" / "round0" / "sweep.json").exists() and "ε tuned on each task" in text
    assert "evading prey 7x7 / epsilon-greedy, tuned ε (" in text and ") (" not in text.split("tuned ε (")[1].split("|")[0]
    assert "Readings ranked by distance" in text
    wall = pd.read_csv(tmp_path / "out" / "tables" / "wall_times.csv")
    assert len(wall) == 9 and (wall["wall seconds"] >= 0).all()  # 3 sweeps + 4 studies + tuning + beyond
    assert "Replication forensics: not run" in text


def test_claims_by_reading_judges_each_reading_with_the_verdict_logic() -> None:
    """Two readings: one whose affective runs match the crossover data, one that never finds the path (censored)."""
    from sb3_affect.study.report.sections.readings import claims_by_reading, emotion_shares, reading_runs

    runs = _runs(20)
    standard = runs[runs.agent == "epsilon-greedy"]
    found = runs[runs.agent == "affective"].assign(comparison="literal", act="episode", units="cells")
    never = found.assign(
        act="remaining", first_optimal=np.nan, censored=True, fear_1_10=0.4, fear_1_10_weighted=0.2, sadness_1_10_weighted=0.1,
        joy_1_10_weighted=0.4,
    )
    table = claims_by_reading(reading_runs(pd.concat([found, never], ignore_index=True), standard))
    assert list(table.columns) == ["literal / episode / cells", "literal / remaining / cells"]
    row = table.loc["27.35 episodes until the optimal path (affective)"]
    mean = found.first_optimal.mean()  # no censoring: the KM restricted mean is the plain mean
    assert row["literal / episode / cells"].startswith(f"not reproduced ({mean:.1f} [")
    assert row["literal / remaining / cells"].startswith("not reproduced (200")  # all censored at the last episode
    four = table.loc["Four emotions shape behaviour (sadness and fear included)"]
    assert four["literal / episode / cells"] == "not reproduced" and four["literal / remaining / cells"] == "reproduced"
    shares = emotion_shares(pd.concat([found, never], ignore_index=True))
    assert shares.at["literal / remaining / cells", "fear 1-10"] == pytest.approx(0.2)


@pytest.mark.parametrize(
    ("sadness", "fear", "verdict"),
    [
        (0.05, 0.2, "reproduced: each of the four emotions takes at least 1%"),
        (0.0, 0.2, "not reproduced: sadness below 1%"),  # fear alone is not "four emotions"
        (0.2, 0.0, "not reproduced: fear below 1%"),
        (0.009, 0.009, "not reproduced: sadness and fear below 1%"),  # just under the stated share
        (0.0, 0.0, "not reproduced: sadness and fear below 1%"),
    ],
)
def test_four_emotions_needs_each_emotion_above_its_share(sadness: float, fear: float, verdict: str) -> None:
    """Synthetic decision-weighted shares: every one of the four emotions must reach 1% early or late."""
    runs = _runs(5)
    affective = runs.agent == "affective"
    runs.loc[affective, "sadness_1_10_weighted"] = sadness  # early only: one window is enough
    runs.loc[affective, "fear_181_200_weighted"] = fear  # late only
    runs.loc[~affective, ["sadness_1_10_weighted", "fear_181_200_weighted"]] = 0.5  # ε-greedy's rows never count
    judged = _by_key(runs)["four_emotions"]
    assert judged.verdict.startswith(verdict), judged.verdict
    assert judged.direction is verdict.startswith("reproduced")


def test_the_speed_ablation_concludes_per_epsilon() -> None:
    """Speed 1 at ~3,800 decisions before the optimal path against ε-greedy's 3,000 + 30,000 ε^4: ε-greedy fewer at ε
    0.1-0.3, no difference at 0.4 (3,768), speed 1 fewer from 0.5 (4,875) on."""
    from sb3_affect.study.report.sections.speed_ablation import per_eps_conclusion, speed_one_per_eps

    runs = _runs(200)
    rng = np.random.default_rng(5)
    slow = runs[runs.agent == "affective"].assign(agent="affective-speed-1")
    slow["decisions_before_optimal"] = 3800 * rng.lognormal(0, 0.2, len(slow)) / np.exp(0.02)  # mean 3,800
    slow["decisions_to_greedy_optimal"] = 1000.0 * rng.lognormal(0, 0.2, len(slow))  # far ahead everywhere
    runs["greedy_censored"] = slow["greedy_censored"] = False
    table = speed_one_per_eps(runs, slow)
    assert list(table.index) == [f"{e:.1f}" for e in EPS]
    walked = ["ε-greedy fewer"] * 3 + ["no significant difference"] + ["speed 1 fewer"] * 5
    assert list(table["at this ε, walked"]) == walked
    text = per_eps_conclusion(table, "walked")
    assert text.startswith("walked: the direction rule alone beats ε-greedy only against ε >= 0.5"), text
    assert "significantly more at ε 0.1, 0.2, 0.3" in text and "neither at ε 0.4" in text
    assert per_eps_conclusion(table, "greedy").startswith("greedy: the direction rule alone beats ε-greedy at every ε")


def test_the_speed_ablation_table_puts_decisions_beside_cells() -> None:
    from sb3_affect.study.report.sections.speed_ablation import speed_table

    runs = _runs(20)
    standard = runs.agent == "epsilon-greedy"  # ε-greedy moves one cell per decision
    runs.loc[standard, "cells_per_episode"] = runs.loc[standard, "decisions_per_episode"]
    runs.loc[standard, "cells_before_optimal"] = runs.loc[standard, "decisions_before_optimal"]
    slow = runs[runs.agent == "affective"].assign(agent="affective-speed-1")
    slow["cells_per_episode"] = slow.decisions_per_episode  # one cell per decision
    slow["cells_before_optimal"] = slow.decisions_before_optimal
    table = speed_table(runs, slow)
    walked, cells = "decisions before the optimal path (walked)", "cells before the optimal path (walked)"
    assert list(table.index) == [
        "decisions per episode", "cells per episode", walked, cells,
        "decisions until the greedy policy stays optimal (greedy)",
    ]  # fmt: skip
    # at speed 1 a decision is a cell: its lead is the same in both units
    one = "ε-greedy minus affective, speed fixed at 1"
    assert table.at[walked, one] == table.at[cells, one]
    two = "ε-greedy minus affective (1 or 2 cells)"
    assert table.at[walked, two] != table.at[cells, two]


def test_fig5_and_fig6_windows_move_the_verdicts() -> None:
    from sb3_affect.study.report.sections.window_verdicts import EARLY_WINDOWS, LATE_WINDOWS, window_verdicts

    runs = _runs(20)
    aff = runs[runs.agent == "affective"].copy()
    for lo, hi in (*EARLY_WINDOWS, *LATE_WINDOWS):
        early = hi <= 30
        for suffix in ("", "_weighted"):
            aff[f"joy_{lo}_{hi}{suffix}"] = 0.3 if early else 0.1  # only joy and anger: joy share = equivalent ε
            aff[f"anger_{lo}_{hi}{suffix}"] = 0.7 if early else 0.9
        aff[f"eqeps_{lo}_{hi}"] = (0.3 if early else 0.1) + np.random.default_rng(lo + hi).normal(0, 0.01, len(aff))
    table = window_verdicts(aff)
    assert len(table) == len(EARLY_WINDOWS) * len(LATE_WINDOWS)
    assert (table["Fig. 5 (per-episode)"] == "not reproduced").all()  # a joy share of 0.3 is not dominance
    assert (table["Fig. 6"] == "reproduced").all()  # while 0.3 -> 0.1 is Fig. 6 exactly


def _tuning_runs(response, replicates: int = 20, noise: float = 0.05):  # type: ignore[no-untyped-def]
    """A ``run_round`` for ``tuning.tune``: runs whose mean decisions per episode is ``response(ε)`` (known optimum)."""

    def run_round(k: int, values: dict[tuple[str, str], list[float]]) -> pd.DataFrame:
        rng = np.random.default_rng(k)
        rows = [
            {"task": task, "agent": agent, "epsilon": eps, "replicate": r,
             "decisions_per_episode": response(eps) + noise * rng.standard_normal(), "cells_per_episode": response(eps),
             "truncated": 0}
            for (task, agent), epsilons in values.items() for eps in epsilons for r in range(replicates)
        ]  # fmt: skip
        return pd.DataFrame(rows)

    return run_round


def test_tuning_chooses_an_interior_best_in_one_round() -> None:
    from sb3_affect.study.launcher.epsilon_tuning import tune

    choices, rounds = tune(_tuning_runs(lambda e: 100 + 50 * (np.log10(e) - np.log10(0.05)) ** 2), [("task", "agent")], GRID)
    t = choices[("task", "agent")]
    assert rounds == 1 and t.best == 0.05 and t.interior and t.added == ()
    assert list(t.curve.index) == list(GRID) and t.note == "interior (best inside the grid)"
    assert t.within_noise == []  # neighbours differ by 50 x 0.16 decisions, far beyond the noise


def test_tuning_extends_a_grid_whose_best_is_at_an_edge() -> None:
    from sb3_affect.study.launcher.epsilon_tuning import MAX_EXTENSIONS, extension, tune

    assert extension([0.001, 0.002, 0.5], 0.001) == 0.0005 and extension([0.001, 0.2, 0.5], 0.5) == 1.0
    assert extension([0.001, 0.2, 0.5], 0.2) is None and extension([0.5, 1.0], 1.0) is None  # inside; end of range
    with pytest.raises(ValueError, match="not one of the values run"):
        extension([0.1, 0.2], 0.3)
    # optimum below the grid (0.0005 lies between 0.00025 and 0.001): extended twice, then interior
    choices, rounds = tune(_tuning_runs(lambda e: 100 + 50 * (np.log10(e) - np.log10(0.0005)) ** 2), [("task", "agent")], GRID)
    t = choices[("task", "agent")]
    assert rounds == 3 and t.best == 0.0005 and t.interior and t.added == (0.0005, 0.00025)
    assert t.note == "interior (best at the edge of the grid, extended to 0.0005, 0.00025)"
    # better and better towards ε = 1: extended to the end of the range and said to be not interior
    choices, rounds = tune(_tuning_runs(lambda e: 100 - 10 * e), [("task", "agent")], GRID)
    t = choices[("task", "agent")]
    assert rounds == 2 and t.best == 1.0 and not t.interior and t.note.startswith("not interior")
    assert "still at the edge of the range" in t.note
    # better and better towards ε = 0: extensions stop after MAX_EXTENSIONS, still not interior
    choices, rounds = tune(_tuning_runs(lambda e: 100 + 10 * np.log10(e)), [("task", "agent")], GRID)
    t = choices[("task", "agent")]
    assert rounds == MAX_EXTENSIONS + 1 and not t.interior and t.added == (0.0005, 0.00025, 0.000125)
    assert t.best == 0.000125 and t.note.startswith("not interior") and "flat" not in t.note


def test_a_flat_edge_is_said_to_be_flat() -> None:
    """Best at the edge by a difference the paired CI can not tell from 0: not interior, and flat there."""
    from sb3_affect.study.launcher.epsilon_tuning import choose

    decisions = {0.001: [10, 12, 10, 12], 0.002: [12, 10, 13, 10], 0.005: [20, 20, 20, 20]}
    runs = pd.DataFrame(
        [{"epsilon": e, "replicate": r, "decisions_per_episode": v, "cells_per_episode": v, "truncated": 0}
         for e, values in decisions.items() for r, v in enumerate(values)]
    )  # fmt: skip
    t = choose(runs, "task", "agent", grid=(0.001, 0.002, 0.005))
    assert t.best == 0.001 and not t.interior and t.within_noise == [0.002]
    flat = "(the curve is flat there: 0.002 is indistinguishable from it)"
    assert t.note == f"not interior: best at the edge of the grid; still at the edge {flat}"


def test_the_tuning_section_reads_the_rounds_replicate_ran(tmp_path: Path) -> None:
    """
    ``replicate.tune_rounds`` runs a tuning sweep through the launcher round by round (an extension where the best
    value sits at an edge); the report's subsection recomputes the same choice from the round folders alone, says
    whether the evaluation's seeds are disjoint from the tuning's, and shows nothing while a needed round is missing.
    """
    import shutil

    from sb3_affect.study.replicate import tune_rounds
    from sb3_affect.study.report.rendering.document import Document
    from sb3_affect.study.report.sections.tuning import tuning_section

    static = "static grid 15x15 (the paper's task)"
    sweep = tmp_path / "tuning.yaml"
    sweep.write_text(
        "name: beyond-tuning\n"
        f'tasks: {{"{static}": {{id: sb3_affect/GridPursuit-v0, kwargs: {json.dumps(PAPER_ENV)}}}}}\n'
        "episodes: 12\nseeds: 4\nagents:\n"
        "  - {name: 'epsilon-greedy, tuned ε', algo: QLearning, seeds_by: [task], grid: {epsilon: [0.5, 0.9]},\n"
        "     kwargs: {exploration_rate: $epsilon, max_episode_decisions: 2000}}\n"
    )
    tuned, summaries = tune_rounds(sweep, tmp_path / "run" / "tuning", [], workers=1)
    key = (static, "epsilon-greedy, tuned ε")
    assert len(summaries) >= 2 and tuned[key].added  # 0.5 beats 0.9 at the edge: 0.278 run next (and so on)
    assert sorted(p.name for p in (tmp_path / "run" / "tuning").iterdir()) == [f"round{k}" for k in range(len(summaries))]

    class Ctx:
        root, doc = tmp_path / "run", Document("tuning")

        def table(self, name: str, frame: pd.DataFrame, caption: str) -> None:
            self.doc.table(frame, caption)

    evaluation = pd.DataFrame({"task": [static] * 3, "agent": [key[1]] * 3, "seed": [1, 2, 3], "replicate": [0, 1, 2]})
    ctx = Ctx()
    choices = tuning_section(ctx, evaluation)
    assert choices is not None and list(choices) == [key]
    assert (choices[key].best, choices[key].added, choices[key].interior) == (tuned[key].best, tuned[key].added,
                                                                              tuned[key].interior)  # fmt: skip
    pd.testing.assert_frame_equal(choices[key].curve, tuned[key].curve)
    text = ctx.doc.markdown(tmp_path)
    assert "4 tuning seeds per value (sweep `beyond-tuning`" in text and "disjoint from the 3 evaluation seeds" in text
    assert f"| {static} / epsilon-greedy, tuned ε | " in text and "each episode counts at most 2,000 decisions" in text
    found = study(tmp_path / "run" / "tuning", "round0")
    assert found is not None
    shared = evaluation.assign(seed=[int(found[0].seed.iloc[0]), 2, 3])  # one tuning seed among the evaluation's
    ctx = Ctx()
    tuning_section(ctx, shared)
    assert "but 1 of them are also evaluation seeds" in ctx.doc.markdown(tmp_path)
    shutil.rmtree(tmp_path / "run" / "tuning" / f"round{len(summaries) - 1}")  # a round the tuning needs: not run yet
    assert tuning_section(Ctx(), evaluation) is None


def test_the_launcher_tuning_table_says_whether_its_best_is_interior() -> None:
    """``baseline_summary.tuning_choice``: a best value at the edge of its grid is flagged as not interior."""
    from sb3_affect.study.report.reading.baseline_ranks import tuning_choice

    def record(agent: str, eps: float, decisions: int, seed: int) -> dict:  # type: ignore[type-arg]
        episodes = {"decisions": [decisions] * 3, "cells": [decisions] * 3, "optimal": [True] * 3,
                    "greedy_optimal": [True] * 3, "truncated": [False] * 3}  # fmt: skip
        config = {"env_id": "sb3_affect/GridPursuit-v0", "agent": agent, "seed": seed, "labels": {"epsilon": eps}}
        return {"config": config, "episodes": episodes}

    steps = {"edge": {0.01: 20, 0.05: 25, 0.1: 30}, "inside": {0.01: 30, 0.05: 20, 0.1: 25}}
    records = [record(agent, eps, d, seed) for agent, curve in steps.items() for eps, d in curve.items() for seed in (0, 1)]
    table = tuning_choice(records).set_index(["agent", "value"])
    assert table.loc[("edge", 0.01), "best"] and not table.loc[("edge", 0.01), "interior"]
    assert table.loc[("inside", 0.05), "best"] and table.loc[("inside", 0.05), "interior"]
    assert table["interior"].sum() == 1


def test_the_html_page_has_contents_cards_and_folded_appendix_tables(tmp_path: Path) -> None:
    """Contents links every heading; a card table shows one card per row; only the appendix's long tables fold."""
    import matplotlib.pyplot as plt

    from sb3_affect.study.report.rendering.document import APPENDIX_HEADING, FOLD_ROWS, CardSpec, Document

    fig, ax = plt.subplots()
    ax.plot([0, 1])
    fig.savefig(tmp_path / "fig.png")
    plt.close(fig)
    doc = Document("report")
    doc.h("Verdict")
    verdicts = pd.DataFrame(
        {"quote": ["q1", "q2"], "verdict": ["reproduced: yes", "not reproduced: no"], "ours": ["1", "2"]},
        index=pd.Index(["claim one", "claim two"], name="claim"),
    )
    doc.cards(verdicts, "verdicts", CardSpec("quote", ("verdict",), {"claim two": tmp_path / "fig.png"}))
    long = pd.DataFrame({"x": range(FOLD_ROWS + 1)})
    doc.table(long, "a long main-text table")
    doc.md("## Forensics from a layer above\n\nIts text.")  # a Markdown fragment's heading joins the contents
    doc.h(APPENDIX_HEADING, 1)
    doc.table(long, "a long appendix table")
    doc.table(long.head(FOLD_ROWS), "a short appendix table")
    page = doc.html()
    assert page.count("<a href='#") == 3 and "id='verdict'" in page and "id='appendix'" in page
    assert "<a href='#forensics-from-a-layer-above'>" in page
    assert page.count("<article class='card'>") == 2 and page.count("data:image/png;base64,") == 1
    assert "<blockquote>q1</blockquote>" in page and "class='verdict no'>verdict: not reproduced: no" in page
    assert page.count("<details>") == 1 and f"a long appendix table ({FOLD_ROWS + 1} rows)</summary>" in page
    markdown = doc.markdown(tmp_path)
    assert "| claim | quote | verdict | ours |" in markdown  # the Markdown keeps the table, every column


def test_the_wall_time_record_keeps_each_runs_own_times(tmp_path: Path) -> None:
    """A first run does a part's work, a resumed run reads it back: the results' time stays the first run's, each run
    keeps its own seconds, report step and total, and the record section tabulates one column per run."""
    from sb3_affect.study.replicate import _Record
    from sb3_affect.study.report.sections.reproducibility import replicate_runs, runs_table

    first = _Record(tmp_path)
    first.part("paper", 60.0, done_before=0, todo=360)
    first.set("forensics", 65.5)
    first.finish(97.6)
    second = _Record(tmp_path)
    assert second.part("paper", 0.2, done_before=360, todo=0) == 60.0  # nothing left: the first run's time
    second.set("forensics", 17.0)
    second.finish(40.0)
    runs = replicate_runs(tmp_path)
    assert [r["parts"] for r in runs] == [{"paper": 60.0, "forensics": 65.5}, {"paper": 0.2, "forensics": 17.0}]
    assert [r["report"] for r in runs] == [97.6, 40.0] and all(r["total"] >= 0 for r in runs)
    table = runs_table(runs)
    assert list(table.index) == ["paper", "forensics", "report", "total"] and table.shape[1] == 2
    assert table.iloc[:, 0]["forensics"] == 65.5 and table.iloc[:, 1]["forensics"] == 17.0


def _pages(report: Path) -> str:
    """report.md and every appendix page it links to, in order (a link to a missing page fails here)."""
    main = report.read_text()
    linked = re.findall(r"^- \[[^\]]+\]\(([\w-]+\.md)\)$", main, re.M)
    return "\n".join([main, *((report.parent / name).read_text() for name in linked)])


def test_the_abstract_states_the_main_finding_once_within_its_word_limit() -> None:
    """The abstract's main finding is the short one; the section's full sentence does not repeat it verbatim."""
    from sb3_affect.study.report.sections.abstract import MAX_WORDS, abstract_sentences, abstract_words
    from sb3_affect.study.report.sections.main_finding import comparison, finding_sentence, finding_short

    rng = np.random.default_rng(4)
    aff = pd.DataFrame({"decisions_before_optimal": 2100 + rng.normal(0, 300, 400), "censored": False,
                        "decisions_per_episode": 49.0})  # fmt: skip
    speed = pd.DataFrame({"decisions_before_optimal": 1900 + rng.normal(0, 300, 200), "censored": np.arange(200) < 3,
                          "decisions_per_episode": 19.0})  # fmt: skip
    found = comparison(aff, speed)
    judged = claims.judge_all(_runs(30))
    for j in judged:
        j.verdict = j.decide(j) if j.decide else j.verdict
    paragraphs = abstract_sentences(judged, 1000, 19000, finding_short(found), "With its speed fixed at 1 cell, ...")
    text = " ".join(paragraphs)
    assert abstract_words(paragraphs) <= MAX_WORDS
    assert text.count("Main finding:") == 1 and "needs fewer decisions before the first optimal path" in text
    assert not finding_sentence(found).startswith("Main finding") and finding_sentence(found) not in text
    assert "rules fixed in code and applied alike at every seed count" in text and "written down before" not in text


def test_table_v_marks_a_difference_that_censored_runs_enter_as_a_bound_and_its_ratio_the_other_way() -> None:
    runs = _runs(10)
    runs["greedy_censored"] = False
    censored = (runs.agent == "epsilon-greedy") & (runs.epsilon == 0.9) & (runs.replicate < 3)
    runs.loc[censored, "censored"] = True
    walked, greedy = claims.judge_table_v(runs), claims.judge_table_v(runs, "decisions_to_greedy_optimal", "greedy")
    assert walked.bound == "lower" and walked.ours.startswith(">= ") and "difference >= " in walked.ours
    assert "3 ε-greedy and 0 affective runs censored: bounds" in walked.ours
    difference = walked.ours.split("difference ")[1]  # the bound's mark and Kaplan-Meier's interval, not one of the bound
    assert difference.startswith(">= ") and "; Kaplan-Meier to " in difference
    assert difference.index("[") > difference.index(";")
    printed = claims.judge_printed_mean(runs, "v", "epsilon-greedy")
    assert printed.ours.startswith(">= ") and "; Kaplan-Meier restricted mean to " in printed.ours
    assert greedy.bound == "" and not greedy.ours.startswith(">=")
    holm(walked.tests)
    verdict = walked.decide(walked) if walked.decide else ""
    assert "paper / ours <= " in verdict or verdict.startswith("reproduced")


def test_the_protocol_column_names_the_runs_it_judges_the_long_run_on() -> None:
    """The paper protocol has only 200-episode runs: its long-run verdict is judged on the first 20 long runs, and says so."""
    long = claims.Judgement("long_run", "Long run", "", "")
    long.verdict = "not reproduced: holds only against ε >= 0.7"
    other = claims.Judgement("fig3", "Fig. 3", "", "")
    other.verdict = "reproduced: a crossover"
    assert protocol_verdict(long) == f"not reproduced {LONG_RUN_PROTOCOL}: holds only against ε >= 0.7"
    assert claims.verdict_word(protocol_verdict(long)) == f"not reproduced {LONG_RUN_PROTOCOL}"
    assert protocol_verdict(other) == other.verdict
