"""
Hostile files and folders against the study: every file it reads from a folder is a regular file inside it or one
line naming it (FIFOs and links to devices are never opened, so nothing blocks); the forensics give one line for a bad
chunk of replications, a read-only folder or a full disk, lock their folder and are never mixed with a sweep or a
replication; a
sweep whose wrappers, position or env can not work, or an override that would relabel runs, is refused before it runs.
"""

from __future__ import annotations

import errno
import os
import re
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
import yaml

from sb3_affect.study.cli import main
from sb3_affect.study.forensics import run_study
from sb3_affect.study.forensics.section import forensics_section
from sb3_affect.study.launcher import ResultsStore, SweepError, folder_lock, load_sweep, run_sweep
from sb3_affect.study.launcher.batches import batchable
from sb3_affect.study.launcher.regular_files import UnreadableFile, read_bytes
from sb3_affect.study.launcher.store import StoreError, claim_kind
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.replicate import _Record
from sb3_affect.study.report.rendering.document import Document
from sb3_affect.study.report.sections.reproducibility import replicate_runs, run_tables, sha256

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "experiments" / "smoke.yaml"
#: The smallest forensics of the default candidate space: one alpha and gamma, a tiny protocol.
TINY = """\
name: tiny-forensics
forensics:
  screen_reps: 2
  leaders: 1
  reps: 3
  alphas: [1.0]
  gammas: [0.8]
  protocol: {epsilons: [0.2, 0.6], seeds: 2, episodes: 10}
"""


@pytest.fixture(autouse=True)
def never_blocks() -> Iterator[None]:
    """A read that blocks (a FIFO opened) fails the test instead of hanging the test run."""

    def blocked(signum: int, frame: Any) -> None:
        raise AssertionError("a read blocked: a FIFO or a device was opened")

    previous = signal.signal(signal.SIGALRM, blocked)
    signal.alarm(300)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _one_line(error: BaseException, path: Path) -> None:
    text = str(error)
    assert "\n" not in text and str(path) in text and "Traceback" not in text, text


def _hostile(path: Path, kind: str, outside: Path) -> None:
    """Put a hostile entry at ``path``: a FIFO, a link to a device or to a file outside, a folder, an empty file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() or path.is_symlink():
        path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":  # (a link to /dev/zero would be read forever by a reader that follows links)
        path.symlink_to("/dev/null")
    elif kind == "link":
        outside.write_text('{"cells": {"0.2": {}}}')
        path.symlink_to(outside)
    elif kind == "folder":
        path.mkdir()
    elif kind == "empty":
        path.write_bytes(b"")
    else:
        path.write_bytes(b"\x00garbage\xff")


@pytest.mark.parametrize("kind", ["fifo", "device", "link", "folder"])
def test_the_one_rule_reads_regular_files_only(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "folder" / "file.json"
    _hostile(path, kind, tmp_path / "outside.json")
    with pytest.raises(UnreadableFile, match=r"is not a regular file \(a (FIFO|symbolic link|folder)\)") as error:
        read_bytes(path)
    _one_line(error.value, path)
    regular = tmp_path / "regular.json"
    regular.write_text("{}")
    assert read_bytes(regular) == b"{}"
    (tmp_path / "root").mkdir()
    (tmp_path / "root" / "sub").symlink_to(tmp_path)  # a regular file, through a folder that is a link out of root
    with pytest.raises(UnreadableFile, match="lies outside"):
        read_bytes(tmp_path / "root" / "sub" / "regular.json", root=tmp_path / "root")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("files") / "tiny.yaml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def forensics(tmp_path_factory: pytest.TempPathFactory, tiny: Path) -> Path:
    """A finished forensics folder of the smallest grid and protocol."""
    out = tmp_path_factory.mktemp("forensics") / "f"
    run_study(tiny, out, workers=1, progress=False)
    return out


@pytest.fixture
def copy(forensics: Path, tmp_path: Path) -> Path:
    import shutil

    shutil.copytree(forensics, tmp_path / "f")
    return tmp_path / "f"


@pytest.mark.parametrize("kind", ["fifo", "device", "link", "folder", "empty", "garbage"])
def test_a_chunk_of_replications_that_is_not_one_is_one_line_naming_it(
    copy: Path, tmp_path: Path, tiny: Path, kind: str
) -> None:
    path = sorted((copy / "chunks").glob("*.parquet"))[0]
    _hostile(path, kind, Path("/etc/passwd") if kind == "link" else tmp_path / "x")
    with pytest.raises(StoreError) as error:
        ResultsStore(copy).summaries()
    _one_line(error.value, path)
    # the next run sets it aside and simulates its replications again
    assert run_study(tiny, copy, workers=1, progress=False).simulated >= 1
    assert len(list((copy / "damaged").iterdir())) == 1 and len(ResultsStore(copy).summaries()) > 0


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_forensics_records_that_are_not_regular_are_named_never_opened(
    copy: Path, tmp_path: Path, kind: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["status", str(copy)]) == 0
    whole = capsys.readouterr().out
    _hostile(copy / "plan.json", kind, tmp_path / "x")  # status: never blocks, counts every run of the sweep instead
    assert main(["status", str(copy)]) == 0
    shown = capsys.readouterr().out
    done = re.search(r"(\d+)/(\d+) runs done", whole)
    assert done and done[1] == done[2] and f"{done[1]}/" in shown and f"/{done[2]} runs" not in shown
    _hostile(copy / "leaders.csv", kind, tmp_path / "x")
    with pytest.raises(ValueError) as error:
        forensics_section(copy)
    _one_line(error.value, copy / "leaders.csv")


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_replication_records_and_tables_that_are_not_regular_are_named(tmp_path: Path, kind: str) -> None:
    _hostile(tmp_path / "replicate.json", kind, tmp_path / "x")
    with pytest.raises(StoreError) as error:
        _Record(tmp_path)
    _one_line(error.value, tmp_path / "replicate.json")
    with pytest.raises(UnreadableFile):
        replicate_runs(tmp_path)
    table = tmp_path / "study" / "table.csv"
    _hostile(table, kind, tmp_path / "x")
    with pytest.raises(UnreadableFile) as unread:
        run_tables(tmp_path)
    _one_line(unread.value, table)
    with pytest.raises(UnreadableFile):
        sha256(table)
    _hostile(tmp_path / ".lock.owner", kind, tmp_path / "x")
    assert folder_lock.recorded_owner(tmp_path) is None


def test_a_full_disk_or_a_read_only_folder_during_the_analysis_is_one_line(
    copy: Path, tmp_path: Path, tiny: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    before = {p.name: p.read_bytes() for p in copy.iterdir() if p.is_file()}
    for code, said in ((errno.ENOSPC, "the disk is full"), (errno.EROFS, "not writable")):
        def refuse(fd: int, code: int = code) -> None:
            raise OSError(code, os.strerror(code))

        monkeypatch.setattr(os, "fsync", refuse)  # every replication is stored: only the analysis writes
        with pytest.raises(StoreError, match=said) as error:
            run_study(tiny, copy, workers=1, progress=False)
        _one_line(error.value, copy)
        with pytest.raises(StoreError, match=said):  # a new --out on a read-only disk: refused before anything runs
            run_study(tiny, tmp_path / code.__str__(), workers=1, progress=False)
        monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in copy.iterdir() if p.is_file() and p.name in before} == before


def test_duplicated_protocol_epsilons_are_refused_at_validation() -> None:
    with pytest.raises(SweepError, match=r"forensics.protocol.epsilons: 0.1 is given twice"):
        load_sweep_file(ROOT / "experiments" / "forensics.yaml", ["forensics.protocol.epsilons=[0.1, 0.1]"])


def test_forensics_folders_are_locked_and_never_mixed(copy: Path, tmp_path: Path, tiny: Path) -> None:
    with folder_lock.hold(copy), pytest.raises(StoreError, match="in use by another launcher"):
        run_study(tiny, copy, workers=1, progress=False)
    saved = (copy / "sweep.json").read_bytes()
    with pytest.raises(StoreError, match=r"holds the replication forensics \(sweep.json\), which a sweep run into it"):
        run_sweep(SMOKE, copy, workers=1, progress=False, overrides=["episodes=2"])
    assert (copy / "sweep.json").read_bytes() == saved
    with pytest.raises(StoreError, match=r"holds a sweep \(sweep.json\), which a replication run into it would mix with"):
        claim_kind(copy, "replication", "replication")


def _sweep(tmp_path: Path, env: dict[str, Any], algo: str = "QLearning") -> Path:
    data = {"name": "hostile", "env": env, "episodes": 2, "seeds": 1, "agents": [{"name": "a", "algo": algo}]}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_wrapper_the_env_can_not_take_is_refused_before_anything_runs(tmp_path: Path) -> None:
    path = _sweep(tmp_path, {"id": "sb3_affect/GridPursuit-v0", "wrappers": ["PositionBonus"]})
    with pytest.raises(SweepError, match=r"env.kwargs: the env can not be built and stepped: AttributeError: .*agent_pos"):
        load_sweep(path)
    config = load_sweep(path, build=False).cells()[0].base
    assert not batchable(config, logs=False)  # a wrapped env never runs on simulate's bare env
    assert batchable({**config, "env_wrappers": []}, logs=False)


def test_a_position_preset_the_env_can_not_give_is_refused_at_validation(tmp_path: Path) -> None:
    path = _sweep(tmp_path, {"id": "sb3_affect/GridPursuit-v0", "position": "minigrid"})
    with pytest.raises(SweepError, match=r"position='minigrid': the env has no agent_pos"):
        load_sweep(path)


def test_minigrids_fetch_is_refused_up_front_every_time(tmp_path: Path) -> None:
    """Fetch draws its object and its mission at each reset: the check resets with fixed seeds, so it refuses it every time."""
    from sb3_affect.study.launcher.one_run import check_configs

    path = _sweep(tmp_path, {"id": "MiniGrid-Fetch-5x5-N2-v0", "kwargs": {"numObjs": 1}, "wrappers": ["TabularMiniGrid"]})
    config = load_sweep(path, build=False).cells()[0].config(0)
    for _ in range(8):  # a check that built the env once would pass half of the time
        (problem,) = check_configs([config])
        refused = re.search(r"TabularMiniGrid: MiniGrid-Fetch-5x5-N2-v0 gives another mission", problem[1])
        assert problem[0] == "" and refused, problem


@pytest.mark.parametrize(
    "override",
    [
        "agents.0.kwargs={exploration_rate: 0.3}",
        "agents.epsilon-greedy.kwargs={}",
        "agents.0={name: epsilon-greedy, algo: QLearning, grid: {epsilon: [0.1, 0.9]}}",
    ],
)
def test_set_can_not_override_a_kwarg_a_grid_label_drives(override: str) -> None:
    with pytest.raises(SweepError, match=r"kwargs.exploration_rate of agent 'epsilon-greedy' takes its value from the grid"):
        load_sweep(SMOKE, [override], build=False)
    kept = load_sweep(SMOKE, ["agents.0.kwargs={exploration_rate: $epsilon, gamma: 0.5}"], build=False)
    assert [c.base["algo_kwargs"] for c in kept.cells()[:2]] == [
        {"exploration_rate": 0.1, "gamma": 0.5}, {"exploration_rate": 0.9, "gamma": 0.5}
    ]


def test_status_into_a_closed_pipe_ends_quietly(copy: Path, monkeypatch: pytest.MonkeyPatch,
                                               capfd: pytest.CaptureFixture[str]) -> None:
    folder = copy  # a forensics folder
    read, write = os.pipe()
    os.close(read)  # `| head -1` has gone
    with open(write, "w", buffering=1) as pipe:
        monkeypatch.setattr(sys, "stdout", pipe)
        assert main(["status", str(folder)]) == 141
        monkeypatch.undo()
    assert "Traceback" not in capfd.readouterr().err


def test_markdown_tables_escape_what_would_break_them(tmp_path: Path) -> None:
    doc = Document("t")
    doc.table(pd.DataFrame({"agent": ["x|y <b>", "P(T<=t) < 1e-300"], "runs": [3, 4]}))
    rows = [line for line in doc.markdown(tmp_path).splitlines() if line.startswith("|")]
    assert len(rows) == 4 and len({len(re.split(r"(?<!\\)\|", row)) for row in rows}) == 1, rows
    assert "<b" not in "\n".join(rows) and "x\\|y &lt;b>" in rows[2]  # a tag's opening < is escaped
    assert "P(T<=t) < 1e-300" in rows[3]  # a comparison stays as printed


def test_the_forensics_figure_draws_samples_equal_to_float_precision(tmp_path: Path) -> None:
    import numpy as np

    from sb3_affect.study.forensics.section import _figure
    from sb3_affect.study.forensics.statistics import STATISTICS

    values = np.full((3, len(STATISTICS)), 27.35)
    values[1] = np.nextafter(27.35, 30.0)  # a tiny sample's replications can agree to the last bit but one
    pd.DataFrame(values, columns=list(STATISTICS)).to_csv(tmp_path / "sample_top1.csv", index=False)
    table = pd.DataFrame({"printed": np.full(len(STATISTICS), 27.35)}, index=pd.Index(STATISTICS))
    figure = _figure(tmp_path, table, tmp_path / "figure.png")
    assert figure is not None and figure.stat().st_size > 0
