"""The ``sb3-affect`` command as a newcomer meets it: clear errors on wrong arguments, help that says what it does."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

import sb3_affect
from sb3_affect.study import replicate, studies
from sb3_affect.study.cli import main
from sb3_affect.study.launcher import ResultsStore, SweepError, load_sweep, run_sweep
from sb3_affect.study.launcher.store import SWEEP_SCHEMA
from sb3_affect.study.launcher.sweep_file import load_sweep_file

ROOT = Path(__file__).resolve().parents[2]

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"

TINY = """\
name: {name}
env: {{id: sb3_affect/GridPursuit-v0, kwargs: {{size: 5, goal: [2, 2]}}}}
episodes: 4
seeds: 2
agents:
  - name: epsilon-greedy
    algo: QLearning
    grid: {{epsilon: [0.1, 0.5]}}
    kwargs: {{exploration_rate: $epsilon}}
  - name: affective
    algo: AffectQ
    grid: {{epsilon: [0.1, 0.5]}}
"""


def tiny(folder: Path, name: str = "tiny") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.yaml"
    path.write_text(TINY.format(name=name))
    return path


def error(capsys: pytest.CaptureFixture[str], argv: list[str], code: int = 2) -> str:
    capsys.readouterr()
    assert main(argv) == code
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return captured.err


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"sb3-affect {sb3_affect.__version__}"


def test_report_on_missing_empty_or_yaml_is_a_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such folder" in error(capsys, ["report", str(tmp_path / "nope")])
    (tmp_path / "empty").mkdir()
    assert "the folder is empty" in error(capsys, ["report", str(tmp_path / "empty")])
    message = error(capsys, ["report", str(EXPERIMENTS / "smoke.yaml")])
    assert "is a file, not a results folder" in message and "sb3-affect run" in message
    (tmp_path / "started" / "runs").mkdir(parents=True)  # a sweep interrupted before its first run finished
    assert "no report can be built" in error(capsys, ["report", str(tmp_path / "started")])
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("not results")
    assert "holds no results" in error(capsys, ["report", str(tmp_path / "other")])


def test_status_of_missing_folder_and_of_a_replicate_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert "no such folder" in error(capsys, ["status", str(tmp_path / "nope")])
    assert "no sweep has been run here" in error(capsys, ["status", str(tmp_path)])
    # The layout `replicate` writes: one sweep per sub-folder.
    for part in ("paper", "dqn"):
        run_sweep(tiny(tmp_path / "files", part), tmp_path / "runs" / part, workers=1, progress=False)
    forensics = load_sweep_file("forensics", build=False)  # its folder, before its first replication: claimed, empty
    resolved = {"schema": SWEEP_SCHEMA, "name": forensics.name, "sweep": forensics.model_dump(mode="json")}
    ResultsStore(tmp_path / "runs" / "forensics").prepare(resolved)
    capsys.readouterr()
    assert main(["status", str(tmp_path / "runs")]) == 0
    out = capsys.readouterr().out
    assert f"{tmp_path / 'runs'}: 3 studies" in out
    assert "sweep 'paper'" in out and "sweep 'dqn'" in out and out.count("8/8 runs done") == 2
    assert re.search(rf"sweep '{forensics.name}' in {tmp_path / 'runs' / 'forensics'}: 0/[1-9]\d* runs done, 0 failed", out)


def test_run_out_is_a_file_and_workers_below_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep, file = tiny(tmp_path), tmp_path / "a-file"
    file.write_text("")
    message = error(capsys, ["run", str(sweep), "--out", str(file), "--no-progress"])
    assert "this is a file; give a results folder" in message and "File exists" not in message
    assert "this is a file" in error(capsys, ["replicate", "--out", str(file)])
    for command in (["run", str(sweep), "--out", str(tmp_path / "out")], ["replicate"]):
        with pytest.raises(SystemExit) as exit_info:
            main([*command, "--workers", "0"])
        assert exit_info.value.code == 2
        assert "--workers: 0 is not allowed" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_set_typo_is_blamed_on_the_set_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    message = error(capsys, ["run", str(EXPERIMENTS / "smoke.yaml"), "--out", str(tmp_path / "o"), "--set", "seed=3"])
    assert "--set 'seed=3'" in message and "did you mean 'seeds'" in message and "invalid sweep file" not in message
    message = error(capsys, ["run", str(EXPERIMENTS / "smoke.yaml"), "--out", str(tmp_path / "o"), "--set", "seeds=0"])
    assert "invalid --set value" in message and "[from --set seeds=0]" in message
    message = error(capsys, ["run", str(tiny(tmp_path)), "--out", str(tmp_path / "o"), "--set", "agents.0.kwarg.gamma=1"])
    assert "'kwarg' is not a key of agents[0]; did you mean 'kwargs'?" in message
    assert "no agent 'dqn'" in error(capsys, ["run", str(tiny(tmp_path)), "--out", str(tmp_path / "o"),
                                             "--set", "agents.dqn.kwargs.gamma=1"])
    # the forensics study file: its own keys, and no SB3 logs
    message = error(capsys, ["run", "forensics", "--out", str(tmp_path / "o"), "--set", "seeds=3"])
    assert "'seeds' is not a key of the forensics (a sweep with forensics) (allowed: name, forensics)" in message
    message = error(capsys, ["run", "forensics", "--out", str(tmp_path / "o"), "--logs", "csv"])
    no_logs = "--logs csv: the forensics study runs on the compiled engine and writes no SB3 logs"
    assert message.strip() == f"sb3-affect: error: {no_logs}"
    assert not (tmp_path / "o").exists()


def test_nested_set_of_a_labelled_kwarg_points_to_the_grid(tmp_path: Path) -> None:
    path = tiny(tmp_path)
    with pytest.raises(SweepError, match=r"takes its value from the grid label 'epsilon'") as info:
        load_sweep(path, ["agents.0.kwargs.exploration_rate=0.3"], build=False)
    suggestion = str(info.value).split("e.g. --set ")[1].split()[0]
    assert suggestion == "agents.epsilon-greedy.grid.epsilon=[0.3]"
    configs = load_sweep(path, [suggestion], build=False).run_configs()
    greedy = [c for c in configs if c["agent"] == "epsilon-greedy"]
    assert {c["labels"]["epsilon"] for c in greedy} == {0.3}
    assert {c["algo_kwargs"]["exploration_rate"] for c in greedy} == {0.3}
    # A kwarg no label binds is overridden as such (by index or by agent name).
    configs = load_sweep(path, ["agents.affective.kwargs.gamma=0.9"], build=False).run_configs()
    assert {c["algo_kwargs"].get("gamma") for c in configs if c["agent"] == "affective"} == {0.9}


def test_help_describes_every_argument(capsys: pytest.CaptureFixture[str]) -> None:
    helps = {}
    for command in ("status", "report", "replicate", "run"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        helps[command] = capsys.readouterr().out
    assert "a results folder (the --out of `run` or `replicate`)" in helps["status"]
    assert "a results folder (the --out of `run` or `replicate`)" in helps["report"]
    assert "report.html" in helps["report"]
    text = " ".join(helps["replicate"].split())
    for name, description in (*studies.PARTS, *studies.TUNED_PARTS):
        assert f"experiments/{name}.yaml: {studies.part_description(name, description)}" in helps["replicate"]
    assert "open it in a browser" in helps["replicate"] and "results folder (default: runs)" in helps["replicate"]
    # one source for each fact: the run counts are read from the experiment files, the wall time from MINUTES
    files = {name: ROOT / "experiments" / f"{name}.yaml" for name in ("paper", "dqn")}
    runs = {name: len(load_sweep(path, build=False).run_configs()) for name, path in files.items()}
    assert f"the paper's protocol ({runs['paper']} runs)" in helps["replicate"]
    assert f"equal seeds and budget ({runs['dqn']} runs)" in helps["replicate"]
    assert studies.MINUTES[1:] in text
    for page in ("README.md", "docs/getting_started.md"):
        assert f"{studies.MINUTES} on 2 idle cores" in (ROOT / page).read_text(), page
    assert "min" not in (ROOT / "Makefile").read_text().split("replicate: venv")[1].split("\n\n")[0]
    assert "parallel runs, >= 1" in helps["run"]
    # the forensics is a part like the others, its sizes read from its sweep file; every part runs local or on Ray
    assert "experiments/forensics.yaml: replication forensics: 2 screen, 4 leaders x 30 replications" in helps["replicate"]
    assert "--backend {local,ray}" in helps["replicate"] and "--ray-address" in helps["replicate"]


@pytest.mark.slow
def test_replicate_says_where_the_report_is(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    files = tmp_path / "files"
    tiny(files, "paper")
    for name, _ in studies.TUNED_PARTS:  # the shipped tuning and tasks beyond the paper, at toy size (below)
        shutil.copy(ROOT / "experiments" / f"{name}.yaml", files / f"{name}.yaml")
    monkeypatch.setattr(replicate, "EXPERIMENTS", files)
    monkeypatch.setattr(replicate, "PARTS", (("paper", "a tiny paper protocol"),))
    for name, value in (("LARGE_SEEDS", 1), ("ABLATION_SEEDS", 1), ("BEYOND_SEEDS", 1), ("ENGINE_EPISODES", 5)):
        monkeypatch.setattr(replicate, name, value)  # the studies at toy size
    assert main(["replicate", "--out", str(tmp_path / "runs"), "--workers", "2", "--no-forensics"]) == 0
    out = capsys.readouterr().out
    html = tmp_path / "runs" / "report.html"
    assert html.exists() and f"Open {html} in a browser" in out.splitlines()[-1]
    assert json.loads((tmp_path / "runs" / "paper" / "sweep.json").read_text())["name"] == "paper"


@pytest.mark.slow
def test_resumed_replicate_keeps_the_times_of_its_runs_and_refuses_a_sweep(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    files = tmp_path / "files"
    tiny(files, "paper")
    for name in (*studies.SIZED, *(name for name, _ in studies.TUNED_PARTS)):  # the shipped studies, at toy size
        shutil.copy(ROOT / "experiments" / f"{name}.yaml", files / f"{name}.yaml")
    monkeypatch.setattr(replicate, "EXPERIMENTS", files)
    studied = tuple(part for part in replicate.PARTS if part[0] in studies.SIZED)
    monkeypatch.setattr(replicate, "PARTS", (("paper", "a tiny paper protocol"), *studied))
    for name, value in (("LARGE_SEEDS", 1), ("ABLATION_SEEDS", 1), ("BEYOND_SEEDS", 1), ("ENGINE_EPISODES", 5)):
        monkeypatch.setattr(replicate, name, value)
    runs = tmp_path / "runs"
    assert main(["replicate", "--out", str(runs), "--workers", "2", "--no-forensics"]) == 0
    first = json.loads((runs / "replicate.json").read_text())["timings"]
    parts = ("large (", "ablation (", "speed_one (", "long (", "ε tuned per task", "static grid, moving and")
    assert first["paper (a tiny paper protocol)"] > 0 and len(first) == 1 + len(parts)
    assert all(sum(key.startswith(part) for key in first) == 1 for part in parts), sorted(first)
    assert main(["replicate", "--out", str(runs), "--workers", "2", "--no-forensics"]) == 0  # a resume: nothing to do
    assert json.loads((runs / "replicate.json").read_text())["timings"] == first
    # A newcomer's `run experiments/smoke.yaml --out runs` (forgetting /smoke) is refused: the folder is a replication.
    err = error(capsys, ["run", str(tiny(files, "smoke")), "--out", str(runs), "--no-progress"])
    assert "holds a replication" in err and f"--out {runs / 'smoke'}" in err
    assert not (runs / "sweep.json").exists() and not (runs / "chunks").exists()


def test_replicate_into_a_folder_holding_a_sweep_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The reverse of a sweep into a replication: the sweep's runs would be reported as the replication's."""
    runs = tmp_path / "runs"
    assert run_sweep(tiny(tmp_path / "files", "smoke"), runs, workers=1, progress=False).finished > 0
    before = sorted(p.relative_to(runs) for p in runs.rglob("*"))
    err = error(capsys, ["replicate", "--out", str(runs), "--workers", "1", "--no-forensics"])
    assert err.count("\n") == 1 and f"{runs} holds a sweep (sweep.json), which a replication run into it would mix with" in err
    assert f"--out {runs / 'replication'}" in err
    assert sorted(p.relative_to(runs) for p in runs.rglob("*")) == before and not (runs / "replicate.json").exists()
