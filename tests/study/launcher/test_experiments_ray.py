"""
The Ray backend on a real local Ray instance: the same run files as the local backend, every Ray process listening
on 127.0.0.1 only, and nothing left running afterwards. Skipped when the optional ``ray`` extra is not installed.

Ray rewrites ``_node_ip_address="127.0.0.1"`` to the machine's address (and its gRPC servers then listen on all
interfaces) unless ``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``, which Ray reads when it is imported; the launcher sets it
for the local instance it starts, and this test sets it before importing Ray.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.launcher.folder_lock import is_locked

pytestmark = [
    pytest.mark.ray,
    pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="the optional ray extra is not installed"),
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and ss"),
]

SMOKE = Path(__file__).resolve().parents[3] / "experiments" / "smoke.yaml"
TESTS = Path(__file__).resolve().parent
OVERRIDES = ["episodes=12"]



def _terminal_sigint() -> None:
    """The child reacts to SIGINT as under a terminal, even where this test runs with SIGINT ignored (a `&` job)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)

def contents(out: Path) -> dict[str, Any]:
    return {r["run_id"]: {"config": r["config"], "episodes": r["episodes"]} for r in ResultsStore(out).load_runs()}


def alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def descendants(pid: int) -> set[int]:
    """Every live process below ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                parents[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return {p for p in found if alive(p)}


def listeners(pids: set[int]) -> list[str]:
    """``ss -ltnp`` lines of the TCP sockets that ``pids`` listen on."""
    out = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True, check=True).stdout
    return [line for line in out.splitlines() if any(f"pid={pid}," in line for pid in pids)]


def session_members(session: int) -> list[int]:
    """Live processes of a session (the launcher was started in a new session: session id = its pid)."""
    members = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[3]) == session and fields[0] != "Z":
                members.append(int(entry.name))
    return members


def left_in_session(session: int) -> list[int]:
    """The processes of ``session`` still there after up to 15 s (then killed, so that the next test starts clean)."""
    deadline = time.monotonic() + 15
    while session_members(session) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = session_members(session)
    for pid in left:
        os.kill(pid, 9)
    return left


def wait_for_runs(out: Path, proc: subprocess.Popen[str], runs: int) -> None:
    """Until ``runs`` runs of the launcher ``proc`` are stored in ``out`` (a first batch of 100 on a busy machine)."""
    deadline = time.monotonic() + 240
    while not (out / "chunks").exists() or len(ResultsStore(out).done_ids()) < runs:
        assert time.monotonic() < deadline and proc.poll() is None, "the sweep did not start"
        time.sleep(0.1)


@pytest.fixture(scope="module")
def ray_instance() -> Iterator[Any]:
    """One local Ray instance for this module's in-process tests; its workers can import the fault-injecting agent."""
    if shutil.which("ss") is None:
        pytest.skip("needs ss (iproute2) to check the listening addresses")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("RAY_USAGE_STATS_ENABLED", "0")
        patch.setenv("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
        # Ray workers inherit the environment of ray.init: they can import test_experiments_local:Faulty, armed.
        patch.setenv("PYTHONPATH", os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")]))
        patch.setenv("SB3_AFFECT_TEST_FAULTS", "1")
        import ray
        import ray._private.ray_constants as constants

        patch.setattr(constants, "ENABLE_RAY_CLUSTER", False)  # in case Ray was imported before the variable was set
        temp_dir = f"/tmp/ray{os.getpid()}"
        before = descendants(os.getpid())
        ray.init(num_cpus=2, include_dashboard=False, _temp_dir=temp_dir, _node_ip_address="127.0.0.1", log_to_driver=False)
        try:
            yield ray
        finally:
            started = descendants(os.getpid()) - before
            ray.shutdown()
            deadline = time.monotonic() + 20
            while any(alive(pid) for pid in started) and time.monotonic() < deadline:
                time.sleep(0.2)
            left = [pid for pid in started if alive(pid)]
            for pid in left:  # only the processes this module started, by pid
                os.kill(pid, 9)
            shutil.rmtree(temp_dir, ignore_errors=True)
            assert left == [], f"Ray processes still running after ray.shutdown(): {left}"


def test_ray_backend_gives_the_local_run_files_and_listens_on_loopback_only(ray_instance: Any, tmp_path: Path) -> None:
    run_sweep(SMOKE, tmp_path / "local", workers=2, overrides=OVERRIDES, progress=False)
    summary = run_sweep(SMOKE, tmp_path / "ray", workers=2, backend="ray", overrides=OVERRIDES, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (8, 8, 0)
    ours = descendants(os.getpid())
    lines = listeners(ours)
    assert lines, "found no listening Ray process"
    outside = [line for line in lines if not (line.split()[3].startswith(("127.0.0.1:", "[::ffff:127.0.0.1]:", "[::1]:")))]
    assert outside == [], "Ray listens beyond 127.0.0.1:\n" + "\n".join(outside)
    assert contents(tmp_path / "ray") == contents(tmp_path / "local")
    pids = {r["timings"]["pid"] for r in ResultsStore(tmp_path / "ray").load_runs()}
    assert os.getpid() not in pids  # the runs ran in Ray workers, the files were written by the driver


def test_two_hunter_sweep_on_ray_gives_the_local_run_files(ray_instance: Any, tmp_path: Path) -> None:
    hunters = SMOKE.parent / "hunters.yaml"
    overrides = ["episodes=6", "seeds=[0, 1]", "env.kwargs={size: 7, starts: [[0, 0], [6, 6]], prey_start: [3, 3]}"]
    run_sweep(hunters, tmp_path / "local", workers=2, overrides=overrides, progress=False)
    summary = run_sweep(hunters, tmp_path / "ray", workers=2, backend="ray", overrides=overrides, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (8, 8, 0)
    found = contents(tmp_path / "ray")
    assert found == contents(tmp_path / "local")
    assert all(len(run["config"]["team"]) == 2 and "hunter_1/decisions" in run["episodes"] for run in found.values())


def test_ray_backend_records_failed_runs_and_dead_workers(ray_instance: Any, tmp_path: Path) -> None:
    from test_experiments_local import sweep_file

    sweep, out = sweep_file(tmp_path, ["none", "raise", "exit"], seeds=1), tmp_path / "ray"
    summary = run_sweep(sweep, out, workers=2, backend="ray", progress=False)
    assert (summary.total, summary.finished, summary.failed) == (4, 2, 2)
    errors = {}
    for path in (out / "failed").glob("[!.]*.json"):
        record = json.loads(path.read_text())
        errors[record["config"]["labels"]["fault"]] = record["error"]
    assert "RuntimeError: injected failure" in errors["raise"] and "Traceback" in errors["raise"]
    assert "WorkerCrashedError" in errors["exit"] or "died" in errors["exit"], errors["exit"]
    assert len(contents(out)) == 2


def test_cli_ray_backend_starts_and_stops_its_own_instance(tmp_path: Path) -> None:
    # RAY_ADDRESS (a cluster nobody runs) must not redirect the private instance, nor make Ray reject num_cpus
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "RAY_ADDRESS": "127.0.0.1:9"}
    command = [sys.executable, "-m", "sb3_affect", "run", str(SMOKE), "--out", str(tmp_path / "ray"), "--backend", "ray"]
    command += ["--workers", "2", "--no-progress", "--set", OVERRIDES[0]]
    pipe = subprocess.PIPE
    proc = subprocess.Popen(command, env=env, stdout=pipe, stderr=pipe, text=True, start_new_session=True,
        preexec_fn=_terminal_sigint,
    )
    try:
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "8 finished now" in out
    run_sweep(SMOKE, tmp_path / "local", workers=2, overrides=OVERRIDES, progress=False)
    assert contents(tmp_path / "ray") == contents(tmp_path / "local")

    left = left_in_session(proc.pid)
    assert left == [], f"processes of the launcher's Ray instance left running: {left}"


def test_ctrl_c_on_ray_backend_stops_the_instance_and_leaves_no_partial_files(tmp_path: Path) -> None:
    out = tmp_path / "ray"
    paper = SMOKE.parent / "paper.yaml"
    command = [sys.executable, "-m", "sb3_affect", "run", str(paper), "--out", str(out), "--backend", "ray", "--workers", "2"]
    pipe = subprocess.PIPE
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    command += ["--set", "seeds=100"]  # 18 batches of 100 runs: plenty left to stop, on any engine
    proc = subprocess.Popen([*command, "--no-progress"], env=env, stdout=pipe, stderr=pipe, text=True, start_new_session=True,
        preexec_fn=_terminal_sigint,
    )
    try:
        wait_for_runs(out, proc, 5)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: SIGINT to the launcher and every process of its group
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted" in err
    left = left_in_session(proc.pid)
    assert left == [], f"processes of the launcher's Ray instance left running: {left}"
    assert not (out / ".lock.owner").exists()  # the lock released (its file stays)
    assert [p for p in out.rglob(".tmp-*")] == []
    done = ResultsStore(out).load_runs()
    assert 5 <= len(done) < 1800 and all(r["status"] == "ok" for r in done)


@pytest.mark.parametrize("part", ["", "paper"], ids=["run", "replicate"])
def test_a_driver_that_ray_ends_abruptly_is_reported_in_one_line_and_its_name_taken_off_the_lock(
    tmp_path: Path, part: str
) -> None:
    # Ray's core worker ends its driver at once when the raylet it is connected to dies (exit 1, no Python exception):
    # SIGKILL on the driver stands for that here. The command is the driver's parent: it says so in one line, takes the
    # dead driver's name off the lock of the folder it held (a replication's part: OUT/paper) and exits 130, as for a
    # lost cluster; the finished runs are kept.
    out = tmp_path / "ray"
    held = out / part
    paper = SMOKE.parent / "paper.yaml"
    what = ["replicate"] if part else ["run", str(paper), "--set", "seeds=100", "--no-progress"]
    command = [sys.executable, "-m", "sb3_affect", *what, "--out", str(out), "--backend", "ray", "--workers", "2"]
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    pipe = subprocess.PIPE
    proc = subprocess.Popen(command, env=env, stdout=pipe, stderr=pipe, text=True, start_new_session=True,
                            preexec_fn=_terminal_sigint)
    try:
        wait_for_runs(held, proc, 5)
        driver = int((held / ".lock.owner").read_text().split()[0])
        assert driver != proc.pid and driver in descendants(proc.pid)
        os.kill(driver, signal.SIGKILL)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert (f"sb3-affect: the Ray driver (process {driver}) ended with exit code -9 while it held {held}; finished runs "
            "are kept, rerun the same command to resume") in err
    assert "Traceback" not in err
    left = left_in_session(proc.pid)
    assert left == [], f"processes of the dead driver's Ray instance left running: {left}"
    assert not (held / ".lock.owner").exists() and not is_locked(held)
    done = ResultsStore(held).load_runs()
    _, agents, _ = ResultsStore(held).progress()
    assert 5 <= len(done) < sum(runs for runs, _, _ in agents.values())  # stopped mid-sweep, the finished runs kept
    assert all(r["status"] == "ok" for r in done)
