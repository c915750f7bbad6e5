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
    assert "repeats runs" in shown and "another sweep" in shown
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
