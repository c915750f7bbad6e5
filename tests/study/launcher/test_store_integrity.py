"""
The results store counts only what it can read back: damaged, foreign and copied files are named by ``status``,
refused by ``report`` with their path, and set aside by the next run, which redoes their runs; the folder's sweep
survives the deletion of ``sweep.json``. Real sweeps into real folders (the faulty agent of the launcher tests).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from test_experiments_local import contents, sweep_file

from sb3_affect.study.cli import main
from sb3_affect.study.launcher import ResultsStore, StoreError, SweepError, load_sweep, run_sweep


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, dict[str, Any]]:
    """A finished sweep: 4 runs of the faulty agent (one JSON file each) and 4 AffectQ runs (chunks)."""
    tmp = tmp_path_factory.mktemp("reference")
    sweep, out = sweep_file(tmp, ["none"], seeds=4), tmp / "out"
    assert run_sweep(sweep, out, workers=2, progress=False).finished == 8
    return sweep, out, contents(out)


@pytest.fixture
def folder(reference: tuple[Path, Path, dict[str, Any]], tmp_path: Path) -> tuple[Path, Path, dict[str, Any]]:
    sweep, out, runs = reference
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    return sweep, copy, runs


def status(out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    capsys.readouterr()
    assert main(["status", str(out)]) == 0
    return capsys.readouterr().out


def test_damaged_run_files_are_not_done_and_are_redone(
    folder: tuple[Path, Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    sweep, out, runs = folder
    files = sorted((out / "runs").glob("[!.]*.json"))
    assert len(files) == 4
    damages = [b"\x00garbage\xff", files[1].read_bytes()[: len(files[1].read_bytes()) // 2], b"", b"{}"]
    for path, data in zip(files, damages):
        path.write_bytes(data)
    shown = status(out, capsys)
    assert "4/8 runs done" in shown
    for path in files:
        assert f"not counted: {path}" in shown
    with pytest.raises(StoreError, match=str(files[0]).replace(".", r"\.")):
        ResultsStore(out).results()
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(files[0]) in err and "Traceback" not in err
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished) == (4, 4)
    assert sorted(p.name for p in (out / "damaged").iterdir()) == sorted(f"runs-{p.name}" for p in files)
    assert (out / "damaged" / f"runs-{files[3].name}").read_bytes() == b"{}"  # kept, not deleted
    assert contents(out) == runs
    assert "8/8 runs done" in status(out, capsys)


def test_truncated_and_unreadable_chunks_are_named_set_aside_and_redone(
    folder: tuple[Path, Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    sweep, out, runs = folder
    chunks = sorted((out / "chunks").glob("*.parquet"))
    assert len(chunks) >= 2
    truncated, unreadable = chunks[0], chunks[1]
    truncated.write_bytes(truncated.read_bytes()[:-100])
    unreadable.unlink()
    unreadable.mkdir()  # a name that can not be read as a file (chmod 000 does not stop root)
    shown = status(out, capsys)
    assert f"not counted: {truncated}" in shown and f"not counted: {unreadable}" in shown
    assert "Traceback" not in shown
    with pytest.raises(StoreError, match="rerun the sweep"):
        ResultsStore(out).runs_frame()
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert summary.failed == 0 and summary.finished > 0
    assert (out / "damaged" / f"chunks-{truncated.name}").exists()
    assert contents(out) == runs


def test_chunk_damaged_past_its_footer_gives_one_line_naming_it(folder: tuple[Path, Path, dict[str, Any]]) -> None:
    _, out, _ = folder
    chunk = sorted((out / "chunks").glob("*.parquet"))[0]
    data = bytearray(chunk.read_bytes())
    data[4:200] = b"\x00" * 196  # the first data pages, the footer intact
    chunk.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=f"{chunk.name}.*damaged data") as error:
        ResultsStore(out).results()
    assert "\n" not in str(error.value)


def test_deleting_sweep_json_does_not_let_another_sweep_in(
    folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep, out, runs = folder
    (out / "sweep.json").unlink()
    other = sweep_file(tmp_path, ["none"], seeds=1, name="other")
    with pytest.raises(StoreError, match="different sweep"):
        run_sweep(other, out, workers=1, progress=False)
    assert "8/8 runs done" in status(out, capsys)  # status reads the copy
    for copy in (out / "chunks" / ".sweep", out / "runs" / ".sweep"):
        copy.unlink()
    with pytest.raises(StoreError, match="different sweep"):  # every record gone: its files name other runs
        run_sweep(other, out, workers=1, progress=False)
    summary = run_sweep(sweep, out, workers=2, progress=False)  # its own sweep resumes, and records itself again
    assert (summary.skipped, summary.finished) == (8, 0)
    assert (out / "sweep.json").exists() and contents(out) == runs


def test_copied_and_foreign_chunks_are_not_counted(
    folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep, out, runs = folder
    chunk = sorted((out / "chunks").glob("*.parquet"))[0]
    shutil.copy(chunk, out / "chunks" / f"zz-copy-{chunk.name}")
    other_sweep = sweep_file(tmp_path, ["none"], seeds=3, name="other")
    other = tmp_path / "other"
    run_sweep(other_sweep, other, workers=1, progress=False)
    foreign = sorted((other / "chunks").glob("*.parquet"))[0]
    shutil.copy(foreign, out / "chunks" / foreign.name)
    shutil.copy(next((other / "runs").glob("[!.]*.json")), out / "runs")
    shown = status(out, capsys)
    assert "8/8 runs done" in shown, shown
    assert f"zz-copy-{chunk.name} holds batch {chunk.stem!r}, not the batch of its file name (a copy?)" in shown
    assert "another sweep" in shown
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished) == (8, 0)
    assert len(list((out / "damaged").iterdir())) == 3
    assert contents(out) == runs


def test_hidden_and_overlong_agent_names_are_refused(tmp_path: Path) -> None:
    for name in (".hidden", "a" * 300):
        path = tmp_path / "s.yaml"
        path.write_text(f"name: s\nepisodes: 2\nseeds: 1\nagents:\n  - name: '{name}'\n    algo: QLearning\n")
        with pytest.raises(SweepError, match=r"agents\[0\] \(.*\)\.name: String should match pattern") as error:
            load_sweep(path, build=False)
        assert len(str(error.value).splitlines()) <= 3


def test_saved_sweep_is_read_without_importing(folder: tuple[Path, Path, dict[str, Any]], capsys: pytest.CaptureFixture[str],
                                               tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``status`` and ``report`` import nothing a folder's sweep.json names."""
    _, out, _ = folder
    (tmp_path / "pwnmod.py").write_text("import pathlib\npathlib.Path(__file__).with_name('PWNED').write_text('x')\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("sweep.json", "chunks/.sweep", "runs/.sweep"):
        saved = json.loads((out / name).read_text())
        saved["sweep"]["agents"][0]["algo"] = "pwnmod:Evil"
        saved["sweep"]["env"]["id"] = "pwnmod:Env-v0"
        (out / name).write_text(json.dumps(saved))
    status(out, capsys)
    main(["report", str(out)])
    assert not (tmp_path / "PWNED").exists()


def _read_only(folder: Path) -> Any:
    """Make ``folder`` read-only for real: chmod for a normal user, a read-only bind mount for root (None: can not)."""
    import os
    import subprocess

    if os.geteuid() != 0:
        folder.chmod(0o555)
        return lambda: folder.chmod(0o755)
    if subprocess.run(["mount", "--bind", str(folder), str(folder)], capture_output=True).returncode != 0:
        return None
    if subprocess.run(["mount", "-o", "remount,ro,bind", str(folder)], capture_output=True).returncode != 0:
        subprocess.run(["umount", str(folder)], check=False)
        return None
    return lambda: subprocess.run(["umount", str(folder)], check=False)


def test_report_of_a_read_only_folder_names_it_and_writes_elsewhere(
    folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, out, _ = folder
    undo = _read_only(out)
    if undo is None:
        pytest.skip("can not make a folder read-only here")
    try:
        capsys.readouterr()
        assert main(["report", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(out) in err and "--out" in err and "Traceback" not in err
        elsewhere = tmp_path / "report"
        assert main(["report", str(out), "--out", str(elsewhere)]) == 0
        assert (elsewhere / "report.html").exists()
    finally:
        undo()


def test_a_sweep_into_a_replication_folder_is_refused(folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path) -> None:
    sweep, out, _ = folder
    replication = tmp_path / "runs"
    replication.mkdir()
    shutil.copytree(out, replication / "paper")
    with pytest.raises(StoreError, match=f"holds a replication .*paper/.*--out {replication / 'faults'}"):
        run_sweep(sweep, replication, workers=1, progress=False)
    assert not (replication / "sweep.json").exists()


UNSORTED_GRID = """\
name: unsorted
env: {id: sb3_affect/GridPursuit-v0, kwargs: {size: 5, goal: [2, 2]}}
episodes: 6
seeds: 2
agents:
  - name: q
    algo: QLearning
    grid: {epsilon: [0.1, 0.9], alpha: [1.0, 0.5]}
    kwargs: {exploration_rate: $epsilon, learning_rate: $alpha}
"""


def _legacy_run_id(config: dict[str, Any]) -> str:
    """The run id as folders were named before: the prefix's labels in the grid's order (not sorted)."""
    import hashlib
    import re

    digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
    labels = "-".join(f"{k}{v}" for k, v in config["labels"].items() if k != "replicate")
    prefix = re.sub(r"[^A-Za-z0-9_.+-]+", "_", f"{config['agent']}-{labels}-s{config['seed']}".replace("--", "-"))
    return f"{prefix}-{digest}"


@pytest.mark.parametrize("legacy", [False, True], ids=["new", "written-before"])
def test_a_grid_not_in_alphabetical_order_is_counted_read_and_resumed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, legacy: bool
) -> None:
    sweep, out = tmp_path / "unsorted.yaml", tmp_path / "out"
    sweep.write_text(UNSORTED_GRID)
    with monkeypatch.context() as patch:
        if legacy:
            patch.setattr("sb3_affect.study.launcher.run_ids.run_id", _legacy_run_id)
        assert run_sweep(sweep, out, workers=1, progress=False).finished == 8
    if legacy:  # the files hold ids in the grid's order (epsilon first), as such folders do
        meta = json.loads(__import__("pyarrow.parquet").parquet.read_metadata(next((out / "chunks").glob("*.parquet")))
                          .metadata[b"sb3_affect"])
        assert meta["runs"][0][0].startswith("q-epsilon")
    shown = status(out, capsys)
    assert "8/8 runs done" in shown and "not counted" not in shown, shown
    runs, episodes = ResultsStore(out).results()
    assert len(runs) == 8 and len(episodes) == 8 * 6 and runs.run_id.str.startswith("q-alpha").all()
    summary = run_sweep(sweep, out, workers=1, progress=False)
    assert (summary.skipped, summary.finished) == (8, 0) and not (out / "damaged").exists()


def test_report_imports_no_env_module_a_folder_names(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep run on a ``module:Env`` id (Gymnasium imports the module): ``report`` on its folder imports nothing."""
    import sys

    (tmp_path / "evilmod.py").write_text("import pathlib\npathlib.Path(__file__).with_name('PWNED').touch()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    sweep, out = tmp_path / "evil.yaml", tmp_path / "out"
    sweep.write_text(
        "name: evil\nenv: {id: 'evilmod:sb3_affect/GridPursuit-v0', kwargs: {size: 5, goal: [2, 2]}}\nepisodes: 6\n"
        "seeds: 2\nagents:\n  - name: q\n    algo: QLearning\n"
    )
    assert run_sweep(sweep, out, workers=1, progress=False).finished == 2
    (tmp_path / "PWNED").unlink(missing_ok=True)
    monkeypatch.delitem(sys.modules, "evilmod", raising=False)
    capsys.readouterr()
    assert main(["report", str(out)]) == 0, capsys.readouterr().err
    assert not (tmp_path / "PWNED").exists() and "evilmod" not in sys.modules


def test_report_never_writes_through_a_symbolic_link(
    folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A link at a file's name is replaced (its target untouched); a link in place of ``tables/`` is refused."""
    _, out, _ = folder
    precious, elsewhere = tmp_path / "precious", tmp_path / "elsewhere"
    precious.write_text("keep me")
    elsewhere.mkdir()
    (out / "report.md").symlink_to(precious)
    (out / "tables").mkdir()
    (out / "tables" / "agents.csv").symlink_to(precious)
    capsys.readouterr()
    assert main(["report", str(out)]) == 0, capsys.readouterr().err
    assert precious.read_text() == "keep me"
    assert not (out / "report.md").is_symlink() and (out / "report.md").read_text().startswith("#")
    assert not any(p.is_symlink() or p.name.startswith(".tmp-") for p in (out / "tables").iterdir())
    shutil.rmtree(out / "tables")
    (out / "tables").symlink_to(elsewhere)
    capsys.readouterr()
    assert main(["report", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{out / 'tables'} is a symbolic link" in err, err
    assert list(elsewhere.iterdir()) == [] and precious.read_text() == "keep me"


def test_a_folder_path_that_is_not_utf8_is_refused_up_front(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """pyarrow can not open such a path: the sweep is refused before anything runs (it would be rerun forever)."""
    import os

    out = Path(os.fsdecode(bytes(tmp_path) + b"/x\xffy"))
    sweep = tmp_path / "smoke.yaml"
    sweep.write_text(UNSORTED_GRID)
    capsys.readouterr()
    assert main(["run", str(sweep), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "must be valid UTF-8" in err and r"x\udcffy" in err, err
    assert not os.path.exists(out)


def _rewrite_chunk(path: Path, target: Path, edit_meta: Any = None, run: Any = None, rows: int | None = None) -> None:
    """
    Write ``path``'s chunk to ``target`` with its footer (``edit_meta(meta)``) or its ``run`` column changed, or its
    first ``rows`` rows only.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"sb3_affect"])
    if edit_meta is not None:
        edit_meta(meta)
    if run is not None:
        table = table.set_column(table.schema.get_field_index("run"), "run", pa.array(run, pa.int32()))
    if rows is not None:
        table = table.slice(0, rows)
    pq.write_table(table.replace_schema_metadata({b"sb3_affect": json.dumps(meta).encode()}), target)


def _affective_chunk(out: Path) -> Path:
    return next(p for p in sorted((out / "chunks").glob("*.parquet")) if "affective" in p.name)


def test_a_hand_edited_chunk_is_not_counted(
    folder: tuple[Path, Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    """A run listed twice, runs whose labels were swapped, a modified copy named to sort first: none counts."""
    sweep, out, runs = folder
    chunk = _affective_chunk(out)
    original = chunk.read_bytes()

    def twice(meta: dict[str, Any]) -> None:
        meta["runs"].append(list(meta["runs"][0]))

    def relabel(meta: dict[str, Any]) -> None:
        meta["base"]["labels"]["epsilon"] = 0.5

    for edit, why in ((twice, "twice"), (relabel, "but its labels and seed give run")):
        _rewrite_chunk(chunk, chunk, edit)
        shown = status(out, capsys)
        assert f"not counted: {chunk}" in shown and why in shown, shown
        with pytest.raises(StoreError, match=why):
            ResultsStore(out).results()
        chunk.write_bytes(original)
    copy = out / "chunks" / "aaa-copy.parquet"
    _rewrite_chunk(chunk, copy, lambda meta: meta["timings"].update(wall_seconds=99.0))
    shown = status(out, capsys)
    assert "8/8 runs done" in shown and f"not counted: {copy}" in shown and f"not counted: {chunk}" not in shown
    summary = run_sweep(sweep, out, workers=1, progress=False)
    assert (summary.skipped, summary.finished) == (8, 0)
    assert chunk.read_bytes() == original and (out / "damaged" / "chunks-aaa-copy.parquet").exists()
    assert contents(out) == runs


def test_a_run_column_outside_the_chunks_runs_is_one_error_not_an_allocation(
    folder: tuple[Path, Path, dict[str, Any]],
) -> None:
    import pyarrow.parquet as pq

    _, out, _ = folder
    chunk = _affective_chunk(out)
    original = chunk.read_bytes()
    run = pq.read_table(chunk).column("run").to_numpy().copy()
    run[-1] = 2**31 - 1
    _rewrite_chunk(chunk, chunk, run=run)
    wrong = rf"{chunk.name}: its run column holds run 2147483647, not one of the \d+ runs"
    with pytest.raises(ValueError, match=wrong) as error:
        ResultsStore(out).results()
    assert "\n" not in str(error.value)
    chunk.write_bytes(original)
    _rewrite_chunk(chunk, chunk, rows=pq.read_metadata(chunk).num_rows - 1)  # the last run's last episode cut off
    with pytest.raises(ValueError, match=r"holds 14 episodes of a run, its config says episodes=15"):
        ResultsStore(out).results()


def test_fifos_and_huge_files_are_not_read(folder: tuple[Path, Path, dict[str, Any]], tmp_path: Path) -> None:
    """A FIFO (a reader would block on it) and a 20 GB sparse run file are named, never read (commands run apart: a
    blocked read must not stop the test run)."""
    import os
    import subprocess
    import sys

    sweep, out, runs = folder
    os.mkfifo(out / "chunks" / "zz.parquet")
    os.mkfifo(out / "runs" / "zz.json")
    (out / "sweep.json").unlink()
    os.mkfifo(out / "sweep.json")  # the copies name the sweep
    huge = out / "runs" / "zy.json"
    huge.touch()
    os.truncate(huge, 20 * 2**30)

    def command(*argv: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "sb3_affect", *argv], capture_output=True, text=True, timeout=900)

    shown = command("status", str(out))
    assert shown.returncode == 0 and "8/8 runs done" in shown.stdout, shown
    assert f"not counted: {out / 'chunks' / 'zz.parquet'} is not a regular file" in shown.stdout
    assert f"not counted: {huge} is 21,474,836,480 bytes, more than the" in shown.stdout
    refused = command("report", str(out))
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "zy.json is 21,474,836,480 bytes" in refused.stderr
    summary = run_sweep(sweep, out, workers=1, progress=False)
    assert (summary.skipped, summary.finished) == (8, 0)
    assert sorted(p.name for p in (out / "damaged").iterdir()) == ["chunks-zz.parquet", "runs-zy.json", "runs-zz.json"]
    assert contents(out) == runs


def test_report_of_a_folder_in_use_or_incomplete_says_so(
    folder: tuple[Path, Path, dict[str, Any]], capsys: pytest.CaptureFixture[str]
) -> None:
    """A launcher still writing: refused; runs missing: the report says how many it covers; checksums: what it read."""
    _, out, _ = folder
    with ResultsStore(out).lock():
        capsys.readouterr()
        assert main(["report", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{out} is in use by a launcher (pid " in err, err
    _affective_chunk(out).unlink()
    (out / "chunks" / ".tmp-zz.parquet").write_bytes(b"half a chunk")  # what a launcher writes before its rename
    assert main(["report", str(out)]) == 0, capsys.readouterr().err
    report = (out / "report.md").read_text()
    counted = ResultsStore(out).checked_files()
    runs = len(counted.run_files) + sum(len(meta["runs"]) for meta in counted.chunk_files.values())
    assert f"Incomplete: {out} holds {runs:,} of the 8 runs of sweep 'faults'" in report and runs < 8
    listed = sorted(line.split("  ", 1)[1] for line in (out / "checksums.sha256").read_text().splitlines())
    assert listed == sorted(p.relative_to(out).as_posix() for p in [*counted.run_files, *counted.chunk_files])
