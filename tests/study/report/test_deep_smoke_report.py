"""
The deep study's report section on a real folder: experiments/deep_smoke.yaml, cut to one task, two seeds and 2,000 env
steps, run by the launcher (train_many on Farama's MiniGrid), then read by the section.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
import yaml

pytest.importorskip("minigrid")

from rliable import metrics as rmetrics
from test_deep_study_report import section

from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.report.sections import deep_minigrid as deep

SMOKE = Path(__file__).resolve().parents[3] / "experiments" / "deep_smoke.yaml"


def test_the_section_of_a_smoke_folder_has_curves_profile_iqm_censoring_power_and_a_sentence(tmp_path: Path) -> None:
    data = yaml.safe_load(SMOKE.read_text())
    data.update(seeds=[0, 1], evaluation={**data["evaluation"], "every": 1000},
                tasks={"Empty-8x8": {**data["tasks"]["Empty-8x8"], "total_timesteps": 2000}},
                agents=data["agents"][:3])  # DQN, AffectDQN and the control replaying its random share
    (tmp_path / "small.yaml").write_text(yaml.safe_dump(data))
    study = load_sweep_file(tmp_path / "small.yaml", build=False)
    assert study.kind == "deep"
    run_sweep(tmp_path / "small.yaml", tmp_path / "deep_smoke", workers=1, progress=False)
    text, ctx = section(tmp_path, tmp_path / "out")
    assert "## Deep agents on MiniGrid, greedy policies (smoke size): deep_smoke/" in text
    assert deep.power_sentence(2) in text  # the power calculation, printed
    assert "On Empty-8x8, by the greedy success AUC per run (the rule: " in text  # the sentence computed by the rule
    for figure in ("success", "return", "random", "emotions"):  # learning curves, random share, emotion profile
        assert (ctx.out / "figures" / f"deep_smoke_{figure}.png").is_file()
    iqm = pd.read_csv(ctx.out / "tables" / "deep_smoke_iqm.csv")
    assert list(iqm.agent) == [agent.name for agent in study.agents] and (iqm.runs == 2).all()
    scores = deep.run_scores(deep.load_deep(tmp_path / "deep_smoke"))
    for agent, shown in zip(iqm.agent, iqm["success AUC"]):  # rliable's IQM of the runs' success AUCs
        runs = scores[scores.agent == agent].auc_success.to_numpy()
        assert shown == pytest.approx(float(rmetrics.aggregate_iqm(runs[:, None])))
    first = pd.read_csv(ctx.out / "tables" / "deep_smoke_first_success.csv")
    assert ((first.reached + first.censored) == first.runs).all()  # a run that never succeeds is censored, not dropped
    steps = scores.first_success.to_numpy()
    assert ((steps > 0) & (steps <= 2000)).all() and (steps[~scores.reached.to_numpy()] == 2000).all()
