"""
The launcher on the local backend, end to end with the real agents: results store, resume, lock, and faults.

Faults are injected by ``Faulty``, a real ``QLearning`` that misbehaves on request (raise, ``os._exit``, SIGKILL
itself, or pause) when the environment variable ``SB3_AFFECT_TEST_FAULTS=1`` is set; the sweep file does not change
between the faulty run and the resume, so the resume is a true resume of the same sweep.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from sb3_affect import QLearning
from sb3_affect.study.cli import main
from sb3_affect.study.launcher import ResultsStore, StoreError, run_sweep
from sb3_affect.study.launcher.chunks import chunk_records

EXPERIMENTS = Path(__file__).resolve().parents[3] / "experiments"
TESTS = Path(__file__).resolve().parent
FAULTS = "SB3_AFFECT_TEST_FAULTS"
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


class Faulty(QLearning):
    """``QLearning`` that fails on request: ``fault`` in none|raise|exit|kill, ``pause`` seconds before learning."""

    def __init__(self, policy: Any, env: Any, fault: str = "none", pause: float = 0.0, **kwargs: Any) -> None:
        self.fault = fault
        self.pause = pause
        super().__init__(policy, env, **kwargs)

    def learn(self, *args: Any, **kwargs: Any) -> Any:
        if os.environ.get(FAULTS) == "1":
            if self.fault == "raise":
                raise RuntimeError("injected failure")
            if self.fault == "exit":
                os._exit(3)
            if self.fault == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(self.pause)
        return super().learn(*args, **kwargs)



def _terminal_sigint() -> None:
    """The child reacts to SIGINT as under a terminal, even where this test runs with SIGINT ignored (a `&` job)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)

def unlocked(out: Path) -> bool:
    """No launcher holds ``out``'s lock (the lock file stays; its owner record is gone)."""
    from sb3_affect.study.launcher.folder_lock import is_locked

    return not is_locked(out) and not (out / ".lock.owner").exists()


def hold_lock(out: Path) -> subprocess.Popen[str]:
    """A real process holding ``out``'s lock until killed (returns once it holds it)."""
    code = (
        "import sys, time; from pathlib import Path; from sb3_affect.study.launcher.folder_lock import hold\n"
        "with hold(Path(sys.argv[1])):\n    print('held', flush=True); time.sleep(120)\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(out)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def sweep_file(tmp_path: Path, faults: list[str], seeds: int = 2, pause: float = 0.0, name: str = "faults") -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(
        f"""\
name: {name}
env: {{id: sb3_affect/GridPursuit-v0, kwargs: {{size: 6, goal: [3, 3]}}}}
episodes: 15
seeds: {seeds}
agents:
  - name: q
    algo: test_experiments_local:Faulty
    grid: {{fault: {json.dumps(faults)}}}
    kwargs: {{fault: $fault, pause: {pause}, exploration_rate: 0.3}}
  - name: affective
    algo: AffectQ
"""
    )
    return path


def contents(out: Path) -> dict[str, Any]:
    """
    Run id -> (config, episodes, decisions) of every finished run, chunks and JSON files alike: what must be identical
    between sweeps (timings excluded). No run is stored twice.
    """
    found = {}
    for data in ResultsStore(out).load_runs():
        assert data["status"] == "ok" and data["run_id"] not in found
        found[data["run_id"]] = {k: data[k] for k in ("config", "episodes")} | {"decisions": data["timings"]["decisions"]}
    return found


def no_partial_files(out: Path) -> None:
    leftovers = [p for p in out.rglob("*") if p.name.startswith(".tmp-")]
    assert leftovers == []
    for path in (out / "runs").glob("[!.]*.json"):
        json.loads(path.read_text())  # whole files only
    for path in (out / "chunks").glob("[!.]*.parquet"):
        chunk_records(path)  # whole files only


def children(pid: int) -> list[int]:
    """Direct child processes of ``pid`` (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def running(pid: int) -> bool:
    """``pid`` exists and is not a zombie."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def wait_until(condition: Any, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def launcher(sweep: Path, out: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    env.pop(FAULTS, None)
    command = [sys.executable, "-m", "sb3_affect", "run", str(sweep), "--out", str(out), "--workers", "2", "--no-progress"]
    pipe = subprocess.PIPE
    return subprocess.Popen(command, env=env, stdout=pipe, stderr=pipe, text=True, start_new_session=True,
        preexec_fn=_terminal_sigint,
    )


def test_smoke_sweep_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "smoke"
    assert main(["run", str(EXPERIMENTS / "smoke.yaml"), "--out", str(out), "--workers", "2", "--set", "episodes=10"]) == 0
    runs = contents(out)
    assert len(runs) == 8 and len(list((out / "chunks").glob("*.parquet"))) >= 4  # tabular runs go in batches
    assert list((out / "runs").glob("*.json")) == []
    from sb3_affect import EPISODE_COLUMNS

    for run in runs.values():
        assert list(run["episodes"]) == sorted(EPISODE_COLUMNS)
        assert run["episodes"]["episode"] == list(range(1, 11))
        assert all(isinstance(v, int) for v in run["episodes"]["decisions"])
    one = next(r for r in ResultsStore(out).load_runs() if r["config"]["agent"] == "affective")
    assert one["timings"]["wall_seconds"] > 0 and "stable_baselines3" in one["versions"]
    assert any(v > 0 for v in one["episodes"]["joy"])
    assert json.loads((out / "sweep.json").read_text())["name"] == "smoke"
    assert unlocked(out)
    no_partial_files(out)
    # Rerunning skips everything; `status` counts the runs.
    summary = run_sweep(EXPERIMENTS / "smoke.yaml", out, workers=2, overrides=["episodes=10"], progress=False)
    assert (summary.total, summary.skipped, summary.finished, summary.failed) == (8, 8, 0, 0)
    capsys.readouterr()
    assert main(["status", str(out)]) == 0
    assert "8/8 runs done" in capsys.readouterr().out
    # The same seed gives the same records in another process (byte-identical config + episodes); per-run SB3 csv
    # logs when asked, which runs each run on its own (one JSON file each): batches equal per-run execution.
    again = tmp_path / "again"
    assert main(["run", str(EXPERIMENTS / "smoke.yaml"), "--out", str(again), "--workers", "1", "--set", "episodes=10",
                 "--logs", "csv", "--no-progress"]) == 0
    assert len(list((again / "runs").glob("*.json"))) == 8 and list((again / "chunks").glob("*.parquet")) == []
    assert contents(again) == runs
    logs = sorted((again / "logs").glob("*/progress.csv"))
    assert [p.parent.name for p in logs] == sorted(runs)
    assert "rollout/ep_len_mean" in logs[0].read_text()
    # Asking for logs (or not) on a resume is the same sweep: logs do not change results.
    summary = run_sweep(EXPERIMENTS / "smoke.yaml", out, overrides=["episodes=10", "logs=[csv]"], progress=False)
    assert summary.skipped == 8


def test_run_that_raises_is_recorded_and_retried(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep, out = sweep_file(tmp_path, ["none", "raise"]), tmp_path / "out"
    monkeypatch.setenv(FAULTS, "1")
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (6, 4, 2)
    failed = sorted((out / "failed").glob("[!.]*.json"))
    assert len(failed) == 2
    record = json.loads(failed[0].read_text())
    assert record["status"] == "failed" and record["config"]["labels"]["fault"] == "raise"
    assert "Traceback" in record["error"] and "RuntimeError: injected failure" in record["error"]
    monkeypatch.delenv(FAULTS)
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished, summary.failed) == (4, 2, 0)
    assert len(contents(out)) == 6 and list((out / "failed").glob("[!.]*.json")) == []


def test_dead_worker_is_recorded_and_others_finish(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep, out = sweep_file(tmp_path, ["none", "exit", "kill"]), tmp_path / "out"
    monkeypatch.setenv(FAULTS, "1")
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (8, 4, 4)
    errors = {json.loads(p.read_text())["config"]["labels"]["fault"]: json.loads(p.read_text())["error"]
              for p in (out / "failed").glob("[!.]*.json")}
    assert "died" in errors["exit"] and "exit code 3" in errors["exit"]
    assert "killed by SIGKILL" in errors["kill"]
    monkeypatch.delenv(FAULTS)
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished, summary.failed) == (4, 4, 0)
    assert len(contents(out)) == 8


def test_different_sweep_into_same_dir_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=1), tmp_path / "out"
    run_sweep(sweep, out, workers=1, progress=False)
    before = contents(out)
    with pytest.raises(StoreError, match="different sweep"):
        run_sweep(sweep, out, workers=1, overrides=["seeds=2"], progress=False)
    other = sweep_file(tmp_path, ["none"], seeds=1, name="other")
    assert main(["run", str(other), "--out", str(out), "--no-progress"]) == 2
    assert "different sweep" in capsys.readouterr().err
    assert contents(out) == before
    assert unlocked(out)


def test_stale_lock_of_dead_launcher_is_taken_over(tmp_path: Path) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=1), tmp_path / "out"
    dead = subprocess.Popen(["true"])
    dead.wait()
    out.mkdir()
    (out / ".lock").write_text(str(dead.pid))  # the pid file of an earlier version, or an empty one: no lock held
    (out / ".lock.owner").write_text(str(dead.pid))
    summary = run_sweep(sweep, out, workers=1, progress=False)
    assert summary.finished == 2
    assert unlocked(out)


@linux_only
def test_lock_of_a_reused_pid_is_stale(tmp_path: Path) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=1), tmp_path / "out"
    out.mkdir()
    (out / ".lock").write_text(f"{os.getpid()} 1")  # our pid is alive, but it is not the launcher that started at tick 1
    assert run_sweep(sweep, out, workers=1, progress=False).finished == 2


def test_live_lock_is_refused(tmp_path: Path) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=1), tmp_path / "out"
    out.mkdir()
    holder = hold_lock(out)
    try:
        with pytest.raises(StoreError, match=f"in use by another launcher \\(pid {holder.pid}\\)"):
            run_sweep(sweep, out, workers=1, progress=False)
        assert (out / ".lock.owner").read_text().split()[0] == str(holder.pid)
        assert not (out / "runs").exists()
    finally:
        holder.kill()
        holder.wait()
    assert run_sweep(sweep, out, workers=1, progress=False).finished == 2  # the kernel released the dead holder's lock


def test_full_disk_gives_clear_error_and_loses_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=4), tmp_path / "out"
    real_fsync, writes = os.fsync, []

    def fsync(fd: int) -> None:  # the lock's owner record, sweep.json (and its 2 copies) and 3 runs fit, then the disk is full
        writes.append(fd)
        if len(writes) > 7:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    with pytest.raises(StoreError, match="disk is full"):
        run_sweep(sweep, out, workers=2, progress=False)
    monkeypatch.setattr(os, "fsync", real_fsync)
    kept = contents(out)
    assert len(kept) == 3
    no_partial_files(out)
    assert unlocked(out)
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished) == (3, 5)
    assert {k: v for k, v in contents(out).items() if k in kept} == kept


@linux_only
@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a small tmpfs needs root")
def test_really_full_disk(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=4), tmp_path / "out"
    out.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=20k", "tmpfs", str(out)], capture_output=True).returncode != 0:
        pytest.skip("can not mount a tmpfs here")
    try:
        assert main(["run", str(sweep), "--out", str(out), "--workers", "2", "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert "the disk is full; finished runs are kept" in err, err
        kept = contents(out)
        assert 0 < len(kept) < 8
        no_partial_files(out)
        assert unlocked(out)
        subprocess.run(["mount", "-o", "remount,size=4m", str(out)], check=True)
        summary = run_sweep(sweep, out, workers=2, progress=False)
        assert (summary.skipped, summary.finished) == (len(kept), 8 - len(kept))
        assert {k: v for k, v in contents(out).items() if k in kept} == kept
    finally:
        subprocess.run(["umount", str(out)], check=False, capture_output=True)


def _read_only(folder: Path) -> Any:
    """Make ``folder`` read-only for real: chmod for a normal user, a read-only tmpfs mount for root."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return lambda: folder.chmod(0o755)
    if subprocess.run(["mount", "-o", "remount,ro,bind", str(folder)], capture_output=True).returncode != 0:
        return None
    return lambda: subprocess.run(["umount", str(folder)], check=False)


@linux_only
def test_read_only_out_folder_gives_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=2), tmp_path / "out"
    out.mkdir()
    if os.geteuid() == 0 and subprocess.run(["mount", "--bind", str(out), str(out)], capture_output=True).returncode != 0:
        pytest.skip("running as root without mount rights: no way to make a folder read-only")
    try:
        run_sweep(sweep, out, workers=2, progress=False)
        next((out / "runs").glob("[!.]*.json")).unlink()  # leave one run to do
        kept = contents(out)
        undo = _read_only(out)
        if undo is None:
            pytest.skip("could not remount read-only")
        try:
            assert main(["run", str(sweep), "--out", str(out), "--workers", "2", "--no-progress"]) == 2
            err = capsys.readouterr().err
            assert str(out) in err and "not writable" in err, err
            assert contents(out) == kept
        finally:
            undo()
    finally:
        if os.geteuid() == 0:
            subprocess.run(["umount", str(out)], check=False, capture_output=True)
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert (summary.skipped, summary.finished) == (3, 1)


@linux_only
def test_sigkill_launcher_then_resume_gives_the_uninterrupted_results(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=4, pause=1.5), tmp_path / "out"
    first = launcher(sweep, out)
    try:
        wait_until(lambda: (out / "runs").exists() and len(list((out / "runs").glob("[!.]*.json"))) >= 2, 60, "2 runs")
        # A second launcher on the same folder is refused while the first holds it.
        assert main(["run", str(sweep), "--out", str(out), "--no-progress"]) == 2
        assert f"in use by another launcher (pid {first.pid})" in capsys.readouterr().err
        workers = [pid for pid in children(first.pid) if running(pid)]
        assert workers, "the launcher has no worker processes"
        os.kill(first.pid, signal.SIGKILL)
        first.wait(timeout=10)
        # Mid-run workers (1.5 s pause) die with their launcher at once instead of finishing as orphans.
        wait_until(lambda: not any(running(pid) for pid in workers), 0.7, "the workers to die with the launcher")
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    done_before = len(contents(out))
    assert 2 <= done_before < 8
    assert (out / ".lock.owner").read_text().split()[0] == str(first.pid)  # its record stays, its lock is gone:
    from sb3_affect.study.launcher.folder_lock import is_locked

    assert not is_locked(out)
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert summary.skipped == done_before and summary.finished == 8 - done_before and summary.failed == 0
    no_partial_files(out)
    reference = tmp_path / "reference"
    run_sweep(sweep, reference, workers=2, progress=False)
    assert contents(out) == contents(reference)
    assert len(contents(out)) == 8


@linux_only
@pytest.mark.parametrize("stop, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_ctrl_c_stops_workers_and_leaves_no_partial_files(tmp_path: Path, stop: int, code: int, word: str) -> None:
    sweep, out = sweep_file(tmp_path, ["none"], seeds=6, pause=1.0), tmp_path / "out"
    proc = launcher(sweep, out)
    try:
        wait_until(lambda: (out / "runs").exists() and len(children(proc.pid)) == 2, 60, "2 workers")
        workers = children(proc.pid)
        if stop == signal.SIGINT:
            os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does: SIGINT to the whole process group
        else:
            os.kill(proc.pid, signal.SIGTERM)  # `kill PID`: the launcher only
        start = time.monotonic()
        _, err = proc.communicate(timeout=15)
        assert time.monotonic() - start < 10
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == code, err
    assert word in err and "rerun the same command to resume" in err
    assert not any(running(pid) for pid in workers), "orphan worker processes"
    assert unlocked(out)
    no_partial_files(out)
    done = len(contents(out))
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert summary.skipped == done and len(contents(out)) == 12


_RACER = """
import json, os, sys, time
from pathlib import Path
from sb3_affect.study.launcher import ResultsStore, StoreError
out, log, go, rounds, stale = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
for r in range(rounds):
    start = go + 0.4 * r
    if stale != "none" and sys.argv[6] == "0":  # the first racer leaves what a dead launcher of the pid-file lock left
        while time.time() < start - 0.12:
            pass
        (out / ".lock").write_text("" if stale == "empty" else stale)
    while time.time() < start:
        pass
    try:
        with ResultsStore(out).lock():
            with log.open("a") as handle:
                handle.write(json.dumps(["in", r, os.getpid(), time.time()]) + "\\n")
            time.sleep(0.08)
            with log.open("a") as handle:
                handle.write(json.dumps(["out", r, os.getpid(), time.time()]) + "\\n")
    except StoreError:
        pass
"""


@pytest.mark.parametrize("stale", ["none", "empty", "dead pid"])
def test_racing_launchers_never_both_hold_the_lock(tmp_path: Path, stale: str) -> None:
    """
    4 real processes race on ``ResultsStore.lock()`` in 25 rounds, all starting each round at the same instant (with
    a stale lock file of the pid-file era before each round, or none): never two holders at once.
    """
    dead = subprocess.Popen(["true"])
    dead.wait()
    out, log, rounds = tmp_path / "out", tmp_path / "log", 25
    out.mkdir()
    mark = {"none": "none", "empty": "empty", "dead pid": str(dead.pid)}[stale]
    go = time.time() + 3.0  # time for the 4 interpreters to start
    racers = [
        subprocess.Popen([sys.executable, "-c", _RACER, str(out), str(log), str(go), str(rounds), mark, str(i)])
        for i in range(4)
    ]
    for racer in racers:
        assert racer.wait(timeout=120) == 0
    events = sorted((json.loads(line) for line in log.read_text().splitlines()), key=lambda e: e[3])
    holders, overlaps = 0, []
    for kind, r, pid, _ in events:
        holders += 1 if kind == "in" else -1
        if holders > 1:
            overlaps.append((r, pid))
    assert overlaps == [], f"two launchers held the lock at once in rounds {sorted({r for r, _ in overlaps})}"
    assert sum(kind == "in" for kind, *_ in events) >= rounds // 2  # the rounds did race for the lock
    assert unlocked(out)


def test_two_sweeps_started_at_once_one_is_refused(tmp_path: Path) -> None:
    """A paper-like and a smoke-like sweep into one folder, started together: one runs, the other is refused."""
    first, second = sweep_file(tmp_path, ["none"], seeds=2, pause=0.5), sweep_file(tmp_path, ["none"], seeds=2, name="other")
    out = tmp_path / "out"
    procs = [launcher(first, out), launcher(second, out)]
    codes = [proc.wait(timeout=120) for proc in procs]
    errs = [proc.stderr.read() if proc.stderr else "" for proc in procs]
    assert sorted(codes) == [0, 2], errs
    assert any("in use by another launcher" in e or "different sweep" in e for e in errs), errs
    runs = contents(out)
    assert len(runs) == 4 and len({r["config"]["sweep"] for r in runs.values()}) == 1
