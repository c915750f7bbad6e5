"""
Replication forensics: the statistics agree with the report's, its stages run through the launcher and its results
store (resume, failed/, damaged/, status), the method recovers a candidate.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_affect.engine.simulation import simulate
from sb3_affect.study.cli import build_parser, main
from sb3_affect.study.forensics import (
    STATISTICS,
    CandidateSpace,
    Protocol,
    Reading,
    Simulation,
    printed_numbers,
    run_study,
)
from sb3_affect.study.forensics.analysis import _interval_table
from sb3_affect.study.forensics.scoring import (
    MIN_REACH_REPS,
    NOT_REACHED,
    NOT_RULED_OUT,
    REACHED,
    log_likelihood,
    monte_carlo_error,
    posterior,
    reach_findings,
)
from sb3_affect.study.forensics.section import findings_lines, forensics_section, report_section
from sb3_affect.study.forensics.stages import REJECT_FACTOR, steps_ratio
from sb3_affect.study.forensics.statistics import candidate_statistics, cell_summary
from sb3_affect.study.forensics.units import ForensicsBatch, simulate_unit
from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.launcher.schema import PRESCREEN, ForensicsSpec, SweepError
from sb3_affect.study.launcher.store import StoreError
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.report import build_report
from sb3_affect.study.report.reading.run_tables import run_metrics
from sb3_affect.study.report.verdicts import paper_numbers as paper

ROOT = Path(__file__).resolve().parents[3]
ENV = "sb3_affect/GridPursuit-v0"
AFFECTIVE = Simulation("affective", 1.0, 0.8, None, "literal", "episode", "cells")
TINY = Protocol(epsilons=(0.2, 0.6), seeds=4, episodes=25)


def test_cell_summary_matches_the_report_definitions() -> None:
    log = simulate("AffectQ", AFFECTIVE.algo_kwargs(0.1), ENV, None, [3, 4, 5], 30)
    summary = cell_summary(log)
    episodes = log.assign(run_id=log.seed.astype(str), agent="affective")
    metrics = run_metrics(episodes)
    assert summary["n"] == 3
    assert summary["decisions"] == pytest.approx(metrics.decisions_per_episode.sum())
    assert summary["cells"] == pytest.approx(metrics.cells_per_episode.sum())
    assert summary["walked_found"] == (~metrics.censored).sum()
    assert summary["walked_first"] == pytest.approx(metrics.first_optimal.sum())
    assert summary["walked_decisions_before"] == pytest.approx(metrics.decisions_before_optimal.sum())
    assert summary["walked_cells_before"] == pytest.approx(metrics.cells_before_optimal.sum())
    assert summary["greedy_found"] == (~metrics.greedy_censored).sum()
    assert summary["greedy_first"] == pytest.approx(np.nansum(metrics.greedy_stays_optimal_from))


def test_printed_numbers_are_the_papers() -> None:
    printed = dict(zip(STATISTICS, printed_numbers()))
    assert printed["IV mean ε-greedy"] == paper.TABLE_IV["Mean"][0] == 67.02
    assert printed["V variance affective"] == paper.TABLE_V["Variance"][1] == 53278480
    assert printed["episodes to optimal (affective)"] == 27.35


def test_table_v_sum_is_the_mean_times_the_runs() -> None:
    (_, std, complete_std), (_, aff, complete_aff) = (
        simulate_unit((AFFECTIVE.standard, 0), TINY),
        simulate_unit((AFFECTIVE, 0), TINY),
    )
    assert complete_std and complete_aff
    std_frame, aff_frame = pd.DataFrame.from_dict(std, orient="index"), pd.DataFrame.from_dict(aff, orient="index")
    total = candidate_statistics(std_frame, aff_frame, Reading(table_v="sum"))
    mean = candidate_statistics(std_frame, aff_frame, Reading(table_v="mean"))
    v_mean = STATISTICS.index("V mean affective")
    assert total[v_mean] == pytest.approx(TINY.seeds * mean[v_mean])
    assert total[:6] == pytest.approx(mean[:6])  # Table IV does not depend on Table V's reading


def test_pre_screen_factor_uses_the_closer_step_unit() -> None:
    summary = pd.DataFrame({"n": [20.0, 20.0], "decisions": [20 * 50.0, 20 * 70.0], "cells": [20 * 600.0, 20 * 600.0]})
    observed = printed_numbers()  # affective 56.28, epsilon-greedy 67.02
    assert steps_ratio(summary, observed, standard=False) == pytest.approx(60 / 56.28)
    assert steps_ratio(summary, observed, standard=True) == pytest.approx(67.02 / 60)
    frozen = summary.assign(decisions=20 * 20000.0, cells=20 * 20000.0)
    assert steps_ratio(frozen, observed, standard=True) == pytest.approx(20000 / 67.02)
    assert REJECT_FACTOR < 20000 / 67.02


def test_pre_screen_stops_a_frozen_replication_early() -> None:
    protocol = Protocol(epsilons=(0.1, 0.2, 0.9), seeds=2, episodes=5)
    frozen = Simulation("epsilon-greedy", 1.0, 0.8)  # first cell ~ a few hundred steps per episode: above 1 step
    _, cells, complete = simulate_unit((frozen, 0), protocol, stop_above=1.0)
    assert not complete and list(cells) == [0.1]  # stopped after the first epsilon cell
    _, full, complete = simulate_unit((frozen, 0), protocol)
    assert complete and list(full) == [0.1, 0.2, 0.9] and full[0.1] == cells[0.1]


def test_scoring_prefers_the_sample_that_holds_the_value() -> None:
    rng = np.random.default_rng(0)
    sample = np.exp(rng.normal(3.0, 0.1, size=(200, len(STATISTICS))))
    sample[:, [4, 5, 10, 11]] = rng.normal(0.0, 0.2, size=(200, 4))
    near, far = sample.mean(axis=0), sample.mean(axis=0) * 3
    for diagonal in (False, True):
        assert log_likelihood(sample, near, diagonal) > log_likelihood(sample, far, diagonal) + 10
    probabilities = posterior([log_likelihood(sample, near), log_likelihood(sample, far), -math.inf])
    assert probabilities.sum() == pytest.approx(1.0) and probabilities[0] > 0.99 and probabilities[2] == 0


def test_log_likelihood_differences_come_with_their_monte_carlo_error() -> None:
    """Fewer replications, a larger Monte Carlo error; the ranking prints differences to the best with that error."""
    from sb3_affect.study.forensics.section import _differences

    rng = np.random.default_rng(1)
    sample = np.exp(rng.normal(3.0, 0.1, size=(400, len(STATISTICS))))
    observed = sample.mean(axis=0) * 1.05
    few, many = monte_carlo_error(sample[:30], observed), monte_carlo_error(sample, observed)
    assert 0 < many < few
    never = sample.copy()
    never[:, 0] = np.nan  # a printed statistic this candidate never produces: log-likelihood -inf, no error
    assert math.isnan(monte_carlo_error(never, observed))
    table = pd.DataFrame({"loglik": [-10.0, -14.0, -math.inf], "loglik_mc_error": [3.0, 4.0, math.nan]})
    assert _differences(table, "loglik", "loglik_mc_error") == ["— (the best)", "-4.0 ± 5.0", "-inf"]


def _normal(mean: float, sd: float, reps: int, seed: int) -> np.ndarray:
    """A synthetic sample of every printed statistic: ``reps`` replications around ``mean`` (positive, log-scale safe)."""
    return np.random.default_rng(seed).normal(mean, sd, size=(reps, len(STATISTICS)))


def test_a_wide_screen_interval_that_covers_a_number_does_not_count_as_reached() -> None:
    """Synthetic samples whose answer is known: only a leader's full replications can reach a printed number."""
    target = np.full(len(STATISTICS), 67.02)
    wide_screen = np.array([[50.0] * len(STATISTICS), [85.0] * len(STATISTICS)])  # 2 replications straddling 67.02
    far_leader = _normal(56.0, 0.5, 30, 1)  # 30 replications, tight, far from the target
    near_leader = _normal(67.0, 0.5, 30, 2)  # 30 replications around the target
    few_leader = np.array([[50.0] * len(STATISTICS), [85.0] * len(STATISTICS)])  # a "leader" with 2 replications
    assert reach_findings([far_leader], [wide_screen], target) == [NOT_RULED_OUT] * len(STATISTICS)
    assert reach_findings([few_leader], [], target) == [NOT_RULED_OUT] * len(STATISTICS)  # too few to count
    assert reach_findings([far_leader, near_leader], [wide_screen], target) == [REACHED] * len(STATISTICS)
    far_screen = np.array([[40.0] * len(STATISTICS), [41.0] * len(STATISTICS)])
    assert reach_findings([far_leader], [far_screen], target) == [NOT_REACHED] * len(STATISTICS)
    partly = target.copy()
    partly[0], partly[1] = 56.1, math.nan  # one statistic the far leader does reach, one the paper does not print
    found = reach_findings([far_leader], [wide_screen], partly)
    assert found[0] == REACHED and found[1] == "not printed" and set(found[2:]) == {NOT_RULED_OUT}
    # the analysis' interval table: the screen's coverage is counted apart and never makes a number reached
    leaders = pd.DataFrame({"candidate": ["far"]})
    table, unreached = _interval_table(leaders, {"far": far_leader}, {"wide": wide_screen}, target)
    assert list(table["finding"]) == [NOT_RULED_OUT] * len(STATISTICS) and unreached == list(STATISTICS)
    assert (table["leaders reaching"] == 0).all() and (table["screened covering"] == 1).all()
    text = "\n".join(findings_lines(table, {"reps": 30, "screen_reps": 2}))
    assert "Reached (inside a leading candidate's 95% predictive interval from 30 replications): none." in text
    assert "not ruled out at screen size" in text and "**IV mean ε-greedy** (67.020; 1 screened candidates cover it)" in text
    few = "\n".join(findings_lines(table, {"reps": MIN_REACH_REPS - 1, "screen_reps": 2}))
    assert f"fewer than the {MIN_REACH_REPS} a printed number needs" in few


def test_bad_candidate_options_are_named() -> None:
    with pytest.raises(ValueError, match="comparison='both'"):
        Simulation("affective", 1.0, 0.8, None, "both", "episode", "cells")
    with pytest.raises(ValueError, match="alpha=0"):
        Simulation("epsilon-greedy", 0.0)
    with pytest.raises(ValueError, match="table_v='total'"):
        Reading(table_v="total")


def test_cli_parses_forensics() -> None:
    args = build_parser().parse_args(["forensics", "--out", "x", "--alphas", "0.5,1", "--reps", "10"])
    assert args.alphas == (0.5, 1.0) and args.reps == 10 and args.command == "forensics"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["forensics", "--out", "x", "--gammas", "high"])


def test_the_shipped_sweep_file_is_the_main_jobs_forensics() -> None:
    """experiments/forensics.yaml: the main job's sizes, the default candidate space and the paper's protocol, so the
    forensics run from it is the one run before with those sizes."""
    study = load_sweep_file("forensics").forensics  # by name: the file shipped with the package
    assert study is not None and (study.screen_reps, study.leaders, study.reps) == (2, 4, 30)
    assert study.space() == CandidateSpace.default() and study.paper_protocol() == Protocol()


def test_a_replications_a_sweeps_or_an_old_forensics_folder_is_refused(tmp_path: Path) -> None:
    (tmp_path / "tiny.yaml").write_text(TINY_STUDY)
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "replicate.json").write_text("{}")  # `sb3-affect run forensics --out runs`, forgetting /forensics
    refused = rf"holds a replication \(replicate.json\), which a sweep run into it would mix with; .*--out {tmp_path}/runs/"
    with pytest.raises(StoreError, match=refused):
        run_study(tmp_path / "tiny.yaml", tmp_path / "runs", workers=1, progress=False)
    assert not (tmp_path / "runs" / "sweep.json").exists()
    run_sweep(ROOT / "experiments" / "smoke.yaml", tmp_path / "smoke", workers=1, progress=False, overrides=["episodes=2"])
    with pytest.raises(StoreError, match=r"holds a sweep \(sweep.json\), which the replication forensics run into it"):
        run_study(tmp_path / "tiny.yaml", tmp_path / "smoke", workers=1, progress=False)
    old = tmp_path / "old"  # the layout before the forensics' replications went into the store
    (old / "summaries").mkdir(parents=True)
    (old / "forensics.json").write_text("{}")
    earlier = rf"^{old} holds the replication forensics of an earlier layout \(forensics.json, summaries/\), which is no "
    with pytest.raises(StoreError, match=earlier):
        run_study(tmp_path / "tiny.yaml", old, workers=1, progress=False)
    assert main(["status", str(old)]) == 2
    with pytest.raises(SweepError, match="the forensics runs in stages: pass stages="):
        run_sweep(tmp_path / "tiny.yaml", tmp_path / "bare", workers=1, progress=False)


def test_the_forensics_command_names_a_bad_size(tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match=r"^sb3-affect forensics: error: --reps=2: fewer than screen_reps \(3\); give "):
        main(["forensics", "--out", str(tmp_path / "f"), "--reps", "2"])
    bad_alpha = r"^sb3-affect forensics: error: --alphas=\[0.0, 1.0\]: 0.0 is not a learning rate; each is in \(0, 1\]$"
    with pytest.raises(SystemExit, match=bad_alpha):
        main(["forensics", "--out", str(tmp_path / "f"), "--alphas", "0,1"])
    assert not (tmp_path / "f").exists()


@pytest.mark.slow
def test_self_check_recovers_the_candidate_that_printed_the_numbers(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Numbers 'printed' by one replication of a known candidate: the analysis ranks that candidate first (a study of
    a smaller grid than a file states: 2 readings of Table II, 8 candidates)."""
    space = CandidateSpace(
        readings=(("literal", "episode", "cells"), ("valence", "episode", "cells")),
        alphas=(1.0,),
        gammas=(0.8,),
        optimal=("walked", "greedy"),
        steps=("decisions",),
        table_v=("sum", "mean"),
    )
    monkeypatch.setattr(ForensicsSpec, "space", lambda study: space)
    (tmp_path / "tiny.yaml").write_text(TINY_STUDY.replace("leaders: 1\n  reps: 2", "leaders: 2\n  reps: 12").replace(
        "seeds: 2, episodes: 10", "seeds: 4, episodes: 25"))  # fmt: skip
    study = load_sweep_file(tmp_path / "tiny.yaml", build=False).forensics
    assert study is not None and study.reps == 12
    protocol = study.paper_protocol()
    wanted = Reading("greedy", "decisions", "mean")
    truth = next(c for c in space.candidates() if c.reading == wanted and c.affective == AFFECTIVE)
    held_out = 99  # a replication the analysis never sees
    std, aff = (pd.DataFrame.from_dict(simulate_unit((sim, held_out), protocol)[1], orient="index")
                for sim in (truth.standard, truth.affective))  # fmt: skip
    printed = candidate_statistics(std, aff, truth.reading)
    result = run_study(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=False, printed=printed)
    assert len(result.screen) == 8 and len(result.leaders) == 8
    assert result.leaders.candidate.iloc[0] == truth.name
    assert result.leaders.posterior.iloc[0] > 0.5
    assert result.unreached == []  # a candidate's own replication lies within the candidates' reach
    section = forensics_section(tmp_path / "f")
    assert "| 1 | literal | episode | cells |" in section.markdown and section.figures[0][0].exists()
    # the replication report shows the section when its folder holds forensics results
    smoke = tmp_path / "smoke"
    run_sweep(ROOT / "experiments" / "smoke.yaml", smoke, workers=1, progress=False)
    shutil.copytree(tmp_path / "f", smoke / "forensics")
    text = _pages(build_report(smoke))  # the report alone never imports the forensics: no section
    assert "## Replication forensics" not in text and "Replication forensics: not run" in text
    text = _pages(build_report(smoke, extra_sections=[report_section(smoke / "forensics")]))  # passed in from above
    assert "## Replication forensics" in text and "figures/forensics_statistics.png" in text
    assert "Replication forensics: included" in text
    assert (smoke / "figures" / "forensics_statistics.png").exists()
    # resumable: everything is stored, nothing is simulated again; another protocol into the folder is refused
    again = run_study(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=False, printed=printed)
    assert again.simulated == 0 and again.reused == result.simulated
    with pytest.raises(StoreError, match="already holds the results of a different sweep"):
        run_study(tmp_path / "tiny.yaml", tmp_path / "f", ["forensics.protocol.seeds=5"], workers=1, progress=False)


def test_the_sensitivity_row_gives_each_printed_number_beside_the_leaders_mean(tmp_path: Path) -> None:
    from sb3_affect.study.forensics.section import leader_sensitivity_lines
    from sb3_affect.study.forensics.statistics import STATISTICS

    sample = pd.DataFrame({s: [1.0 + i, 3.0 + i] for i, s in enumerate(STATISTICS)})  # mean: 2 + i
    sample.to_csv(tmp_path / "sample_top1.csv", index=False)
    leaders = pd.DataFrame({"candidate": ["a"], "alpha": [0.5], "gamma": [0.9]})
    intervals = pd.DataFrame({"printed": [4.0 + 2 * i for i in range(len(STATISTICS))]}, index=list(STATISTICS))
    lines = leader_sensitivity_lines(tmp_path, leaders, intervals)
    assert "alpha 0.5, gamma 0.9; 2 replications" in lines[0]
    body = "\n".join(lines)
    assert f"| {STATISTICS[0]} | 4.00 | 2.00 | 0.50 |" in body and f"| {STATISTICS[-1]} | 28.00 | 14.00 | 0.50 |" in body
    r = next(i for i, s in enumerate(STATISTICS) if "Pearson r" in s)  # a correlation: its difference, not a ratio
    assert f"| {STATISTICS[r]} | {4 + 2 * r:.2f} | {2 + r:.2f} | {-(2 + r):.2f} |" in body
    assert leader_sensitivity_lines(tmp_path / "none", leaders, intervals) == []


TINY_STUDY = """\
name: tiny-forensics
forensics:
  screen_reps: 2
  leaders: 1
  reps: 2
  alphas: [1.0]
  gammas: [0.8]
  protocol: {epsilons: [0.2, 0.6], seeds: 2, episodes: 10}
"""


def _replications(root: Path) -> dict[tuple[str, str, int], tuple[dict[str, list[float]], bool]]:
    """A forensics folder's stored replications, as plain lists (comparable with ==)."""
    stored = ResultsStore(root).summaries()
    return {key: ({k: v.tolist() for k, v in rows.items()}, done) for key, (rows, done) in stored.items()}


@pytest.mark.parametrize("backend", ["local", pytest.param("ray", marks=pytest.mark.ray)])
def test_units_on_the_launchers_executor_store_what_one_process_stores(
    tmp_path: Path, backend: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """
    The same replications stored in this process' launcher with one worker and on the launcher's executor (2 forked
    workers, or Ray tasks); a forensics sweep file runs there with ``sb3-affect run`` and resumes; status reads it.
    """
    if backend == "ray":
        pytest.importorskip("ray")
    (tmp_path / "tiny.yaml").write_text(TINY_STUDY)
    run_study(tmp_path / "tiny.yaml", tmp_path / "one", workers=1, progress=False)
    out = tmp_path / "study"
    command = ["run", str(tmp_path / "tiny.yaml"), "--out", str(out), "--workers", "2", "--backend", backend, "--no-progress"]
    printed = []
    for _ in range(2):
        capsys.readouterr()
        assert main(command) == 0
        printed.append(capsys.readouterr().out.splitlines())
    stored = _replications(out)
    assert stored == _replications(tmp_path / "one") and any(stage == PRESCREEN for _, stage, _ in stored)
    simulated, reused = (int(n) for n in re.findall(r"(\d+) replications simulated now, (\d+) already done", printed[0][0])[0])
    assert simulated == len(stored) > 0 and reused == 0
    assert printed[1][0].startswith(f"tiny-forensics: 0 replications simulated now, {len(stored)} already done")
    assert printed[1][1:] == printed[0][1:] and printed[0][1].startswith("best candidate: affective_a1_g0.8_")
    run = json.loads((out / "run.json").read_text())
    assert (run["screen_reps"], run["leaders"], run["reps"]) == (2, 1, 2) and (out / "forensics.md").exists()
    assert main(["status", str(out)]) == 0
    status = capsys.readouterr().out  # the runs its stages planned, all done (not every run its cells could hold)
    assert status.startswith(f"sweep 'tiny-forensics' in {out}: {len(stored)}/{len(stored)} runs done, 0 failed\n")
    assert "stages" not in status and f"report: {out / 'forensics.md'}" in status


def test_a_failed_or_damaged_replication_is_run_again_and_the_numbers_hold(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A batch that raises is recorded in failed/ (the others kept, the run stops with one line) and retried by the next
    run; a chunk that does not read back is set aside in damaged/ and simulated again; the scores are the same."""
    (tmp_path / "tiny.yaml").write_text(TINY_STUDY)
    clean = run_study(tmp_path / "tiny.yaml", tmp_path / "clean", workers=1, progress=False)
    execute = ForensicsBatch.execute

    def fail_the_affective(batch: ForensicsBatch) -> dict[str, object]:
        if batch.base["simulation"]["agent"] == "affective" and batch.base["labels"]["stage"] != PRESCREEN:
            raise RuntimeError("a worker's bad day")
        return execute(batch)

    monkeypatch.setattr(ForensicsBatch, "execute", fail_the_affective)
    out = tmp_path / "f"
    with pytest.raises(StoreError, match=rf"replications failed \(the others are kept; tracebacks in {out / 'failed'}\)"):
        run_study(tmp_path / "tiny.yaml", out, workers=2, progress=False)
    failed = sorted(p.name for p in (out / "failed").glob("*.json"))
    assert failed and all(name.startswith("affective_") and "stagereplications" in name for name in failed)
    assert main(["status", str(out)]) == 0
    status = capsys.readouterr().out
    assert f" runs done, {len(failed)} failed\n" in status
    assert f"tracebacks are in {out / 'failed'}; the next run retries" in status
    assert "the runs of its next stage are planned once these are done" in status
    monkeypatch.setattr(ForensicsBatch, "execute", execute)
    resumed = run_study(tmp_path / "tiny.yaml", out, workers=2, progress=False)
    assert not list((out / "failed").glob("*.json")) and resumed.reused > 0
    pd.testing.assert_frame_equal(resumed.leaders, clean.leaders)
    chunk = sorted((out / "chunks").glob("*.parquet"))[0]
    chunk.write_bytes(chunk.read_bytes()[:100])  # a chunk cut short (a full disk, a copy)
    capsys.readouterr()
    again = run_study(tmp_path / "tiny.yaml", out, workers=2, progress=False)
    assert again.simulated >= 1 and len(list((out / "damaged").iterdir())) == 1
    assert f"{chunk} is not a readable chunk" in capsys.readouterr().err
    pd.testing.assert_frame_equal(again.leaders, clean.leaders)
    pd.testing.assert_frame_equal(again.screen, clean.screen)


def _pages(report: Path) -> str:
    """report.md and every appendix page it links to, in order (a link to a missing page fails here)."""
    main = report.read_text()
    linked = re.findall(r"^- \[[^\]]+\]\(([\w-]+\.md)\)$", main, re.M)
    return "\n".join([main, *((report.parent / name).read_text() for name in linked)])


def test_a_staged_run_counts_the_runs_its_stages_ask_for(tmp_path: Path) -> None:
    """
    The forensics' cells could hold every replication of every simulation; its stages run a share of them. The run's
    total (and its progress bar's) is what the stages planned: the runs done, then each wave's; a rerun does none.
    """
    from sb3_affect.study.forensics.stages import plan_stages

    (tmp_path / "tiny.yaml").write_text(TINY_STUDY)
    cells = load_sweep_file(tmp_path / "tiny.yaml", build=False).cells()
    first = run_sweep(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=False, stages=plan_stages)
    stored = len(ResultsStore(tmp_path / "f").done_ids())
    assert first.failed == 0 and first.total == first.finished == stored < sum(len(cell.seeds) for cell in cells)
    again = run_sweep(tmp_path / "tiny.yaml", tmp_path / "f", workers=1, progress=True, stages=plan_stages)
    assert (again.total, again.skipped, again.finished) == (stored, stored, 0)
