"""
The Ray backend on a real two-node Ray cluster on this host, started the way a user starts one (``ray start --head``,
then ``ray start --address`` for the second node), and driven through the ``sb3-affect`` CLI with ``--ray-address``.

Ray rewrites 127.0.0.1 to the machine's address for a cluster (its servers then listen on every interface), so the
nodes and the drivers run inside a network namespace of their own that has only the loopback interface: nothing
they open is reachable from outside. That needs root and ``ip netns`` (iproute2); the module is skipped, with the
reason, where either is missing.

The second node runs from a virtual environment that has Ray and sb3-affect's dependencies but not sb3-affect (its
site-packages links every entry of this venv's except sb3-affect's), so its runs only work because the driver ships
the code. A driver with another numpy is refused. The cluster uses token authentication (``RAY_AUTH_MODE=token``,
``RAY_AUTH_TOKEN``). Every process a test starts runs in a session of its own and is stopped by pid; the last test
stops the cluster mid-sweep (the tests of this module run in file order).
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from sb3_affect.study.launcher import run_sweep

pytestmark = [
    pytest.mark.ray,
    pytest.mark.slow,
    pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="the optional ray extra is not installed"),
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="network namespaces are Linux only"),
]

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "experiments" / "smoke.yaml"
PAPER = ROOT / "experiments" / "paper.yaml"
PORT = 6379
ADDRESS = f"127.0.0.1:{PORT}"
RAY_MAIN = "from ray.scripts.scripts import main; main()"


def contents(out: Path) -> dict[str, Any]:
    """Run id -> (config, episodes) of every finished run, batches (chunks) and runs on their own (JSON) alike."""
    from sb3_affect.study.launcher import ResultsStore

    return {r["run_id"]: {"config": r["config"], "episodes": r["episodes"]} for r in ResultsStore(out).load_runs()}


def count_runs(out: Path) -> int:
    from sb3_affect.study.launcher import ResultsStore

    return len(ResultsStore(out).done_ids()) if (out / "runs").exists() else 0


def alive(pid: int) -> bool:
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def session_members(session: int) -> list[int]:
    """Live processes of a session (each process a test starts leads a session of its own)."""
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


def stop_session(proc: subprocess.Popen[Any], grace: float = 10.0) -> None:
    """Stop a process and everything in its session (also what it starts meanwhile): SIGTERM, then SIGKILL, by pid."""
    for how, seconds in ((signal.SIGTERM, grace), (signal.SIGKILL, 10.0)):
        deadline = time.monotonic() + seconds
        while (members := session_members(proc.pid)) and time.monotonic() < deadline:
            for pid in members:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, how)
            time.sleep(0.3)
    if proc.poll() is None:
        proc.kill()
    proc.wait()


def namespace_pids(namespace: str) -> list[int]:
    found = subprocess.run(["ip", "netns", "pids", namespace], capture_output=True, text=True).stdout.split()
    return [int(pid) for pid in found if alive(int(pid))]


def node_venv(path: Path, drop: tuple[str, ...] = (), keep_ours: bool = False) -> Path:
    """
    A venv whose site-packages links every entry of this interpreter's site-packages except sb3-affect (its package,
    dist-info and editable finder; kept if ``keep_ours``) and ``drop``: Ray and sb3-affect's dependencies, nothing
    downloaded.
    """
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(path)], check=True)
    version = f"python{sys.version_info.major}.{sys.version_info.minor}"
    site = path / "lib" / version / "site-packages"
    ours = Path(sysconfig.get_paths()["purelib"])
    for entry in ours.iterdir():
        name = entry.name.lower()
        if ("sb3_affect" in name and not keep_ours) or name.startswith(drop):
            continue
        (site / entry.name).symlink_to(entry)
    return path / "bin" / "python"


@dataclass
class Cluster:
    """A Ray cluster in the network namespace ``namespace``; ``env`` connects a driver to it."""

    namespace: str
    temp: Path
    env: dict[str, str]
    nodes: list[subprocess.Popen[Any]] = field(default_factory=list)

    def start_node(self, python: Path | str, *args: str, name: str) -> subprocess.Popen[Any]:
        log = self.temp / f"{name}.log"
        command = ["ip", "netns", "exec", self.namespace, str(python), "-c", RAY_MAIN, "start", "--block", "--num-cpus=1"]
        command += ["--disable-usage-stats", f"--temp-dir={self.temp / 'ray'}", *args]
        with log.open("w") as handle:
            proc = subprocess.Popen(
                command, env=self.env, cwd=self.temp, stdout=handle, stderr=subprocess.STDOUT, start_new_session=True
            )
        self.nodes.append(proc)
        deadline = time.monotonic() + 120
        while "Ray runtime started" not in log.read_text():
            if proc.poll() is not None or time.monotonic() > deadline:
                stop_session(proc)
                pytest.fail(f"the Ray node {name} did not start:\n{log.read_text()[-3000:]}")
            time.sleep(0.3)
        return proc

    def run(
        self, *args: str, env: dict[str, str] | None = None, python: Path | None = None, timeout: float = 300
    ) -> subprocess.CompletedProcess[str]:
        """``sb3-affect ARGS`` inside the namespace, as its own session, stopped by pid whatever happens."""
        command = ["ip", "netns", "exec", self.namespace, str(python or sys.executable), "-m", "sb3_affect", *args]
        proc = subprocess.Popen(
            command,
            env=env or self.env,
            cwd=ROOT,  # from the checkout, as a user would: its sb3_affect/ (without envs/) must not shadow the shipped code
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        try:
            out, err = proc.communicate(timeout=timeout)
        finally:
            stop_session(proc, grace=5)
        return subprocess.CompletedProcess(command, proc.returncode, out, err)

    def run_background(self, *args: str) -> subprocess.Popen[str]:
        command = ["ip", "netns", "exec", self.namespace, sys.executable, "-m", "sb3_affect", *args]
        return subprocess.Popen(
            command,
            env=self.env,
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )


@pytest.fixture(scope="module")
def cluster() -> Iterator[Cluster]:
    if os.geteuid() != 0 or shutil.which("ip") is None:
        pytest.skip("needs root and iproute2 (`ip netns`) to run the cluster in a loopback-only network namespace")
    namespace = f"sb3a-{os.getpid()}"
    made = subprocess.run(["ip", "netns", "add", namespace], capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"network namespaces are unavailable here: {made.stderr.strip()}")
    temp = Path(tempfile.mkdtemp(prefix="sb3r-"))  # short: Ray's socket paths live below it
    env = {k: v for k, v in os.environ.items() if not k.startswith(("RAY_", "PYTHONPATH"))}
    env.update(RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(16))
    result = Cluster(namespace, temp, env)
    try:
        subprocess.run(["ip", "netns", "exec", namespace, "ip", "link", "set", "lo", "up"], check=True)
        links = subprocess.run(["ip", "netns", "exec", namespace, "ip", "-o", "link"], capture_output=True, text=True)
        assert [line.split(":")[1].strip() for line in links.stdout.splitlines()] == ["lo"]
        result.start_node(sys.executable, "--head", f"--port={PORT}", "--include-dashboard=false", name="head")
        python = node_venv(temp / "venv-node")
        missing = subprocess.run([str(python), "-c", "import sb3_affect"], capture_output=True, text=True, cwd=temp)
        assert "No module named 'sb3_affect'" in missing.stderr
        result.start_node(python, f"--address={ADDRESS}", name="node2")
        yield result
    finally:
        for proc in result.nodes:
            stop_session(proc)
        left = namespace_pids(namespace)
        deadline = time.monotonic() + 10
        while (remaining := namespace_pids(namespace)) and time.monotonic() < deadline:
            for pid in remaining:  # only processes of our namespace; none should be left
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            time.sleep(0.3)
        subprocess.run(["ip", "netns", "delete", namespace], check=False)
        shutil.rmtree(temp, ignore_errors=True)
        assert left == [], f"processes left in the test's network namespace: {left}"


def test_two_node_sweep_ships_the_code_and_matches_the_local_backend(cluster: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "cluster"
    args = ["run", str(SMOKE), "--out", str(out), "--backend", "ray", "--ray-address", ADDRESS, "--no-progress"]
    done = cluster.run(*args, "--set", "episodes=12", "--logs", "csv")
    assert done.returncode == 0, done.stderr
    assert "8 finished now, 0 failed" in done.stdout
    run_sweep(SMOKE, tmp_path / "local", workers=2, overrides=["episodes=12"], progress=False)
    assert contents(out) == contents(tmp_path / "local")
    records = [json.loads(p.read_text()) for p in (out / "runs").glob("[!.]*.json")]
    assert len({r["timings"]["ray_node"] for r in records}) == 2, "the runs did not spread over both nodes"
    assert {r["timings"]["host"] for r in records} == {socket.gethostname()}
    assert {r["versions"]["sb3_affect"] for r in records} == {records[0]["versions"]["sb3_affect"]}
    # the logs come back with the results and the driver writes them under DIR/logs, wherever the runs ran
    logs = sorted(p.parent.name for p in (out / "logs").glob("*/progress.csv"))
    assert logs == sorted(r["run_id"] for r in records)
    assert all("time/total_timesteps" in (out / "logs" / name / "progress.csv").read_text() for name in logs)
    assert not list(cluster.temp.rglob("progress.csv"))


WRONG_ADDRESSES = """
import json, os, sys
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.ray_errors import RayClusterError
messages = {}
for case, address, token in json.loads(sys.argv[1]):
    os.environ["RAY_AUTH_TOKEN"] = token
    try:
        run_sweep(sys.argv[2], sys.argv[3], backend="ray", ray_address=address, ray_timeout=5, progress=False)
    except RayClusterError as error:
        messages[case] = str(error)
print(json.dumps(messages))
"""


def test_wrong_address_or_token_fails_at_once_with_a_message(cluster: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "x"
    start = time.monotonic()
    no_token = {k: v for k, v in cluster.env.items() if not k.startswith("RAY_AUTH")} | {"HOME": str(tmp_path)}
    args = ["run", str(SMOKE), "--out", str(out), "--backend", "ray", "--ray-address", ADDRESS, "--no-progress"]
    denied = cluster.run(*args, env=no_token)
    assert denied.returncode == 2, denied.stderr
    assert f"could not authenticate with the Ray cluster at {ADDRESS}" in denied.stderr
    assert "RAY_AUTH_MODE=token" in denied.stderr and "Traceback" not in denied.stderr
    token = cluster.env["RAY_AUTH_TOKEN"]
    cases = [("refused", "127.0.0.1:6390", token), ("client port", "127.0.0.1:10001", token), ("token", ADDRESS, "0" * 32)]
    command = ["ip", "netns", "exec", cluster.namespace, sys.executable, "-c", WRONG_ADDRESSES, json.dumps(cases)]
    found = subprocess.run([*command, str(SMOKE), str(out)], env=cluster.env, capture_output=True, text=True, timeout=120)
    assert found.returncode == 0, found.stderr
    messages = json.loads(found.stdout.splitlines()[-1])
    assert "no Ray cluster at 127.0.0.1:6390: connecting to 127.0.0.1:6390 failed (Connection refused)" in messages["refused"]
    assert "127.0.0.1:10001 answers, but it is not a Ray head node's GCS port" in messages["client port"]
    assert f"the Ray cluster at {ADDRESS} rejected this driver's token" in messages["token"]
    assert time.monotonic() - start < 60
    # a port that accepts connections and never answers (here, outside the namespace: it listens on 127.0.0.1 only)
    from sb3_affect.study.launcher.ray_errors import RayClusterError

    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        address = f"127.0.0.1:{silent.getsockname()[1]}"
        start = time.monotonic()
        with pytest.raises(RayClusterError, match=f"no Ray cluster answered at {address} within 3 s"):
            run_sweep(SMOKE, out, backend="ray", ray_address=address, ray_timeout=3, progress=False)
        assert time.monotonic() - start < 20
    assert not list(out.glob("runs/*.json"))


def test_a_driver_with_other_package_versions_is_refused(cluster: Cluster, tmp_path: Path) -> None:
    import numpy

    other = "2.3.5" if numpy.__version__ != "2.3.5" else "2.2.6"
    python = node_venv(tmp_path / "venv-other", drop=("numpy",), keep_ours=True)
    site = next((tmp_path / "venv-other" / "lib").glob("python*/site-packages"))
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(site), f"numpy=={other}"]
    if subprocess.run(pip, capture_output=True, text=True).returncode != 0:
        pytest.skip(f"numpy {other} (a numpy other than the nodes') could not be installed for the driver")
    out = tmp_path / "mixed"
    args = ["run", str(SMOKE), "--out", str(out), "--backend", "ray", "--ray-address", ADDRESS, "--no-progress"]
    refused = cluster.run(*args, python=python)
    assert refused.returncode == 2, refused.stderr
    assert f"the Ray cluster at {ADDRESS} can not run this sweep" in refused.stderr
    assert refused.stderr.count(f"numpy {numpy.__version__} (the driver has {other})") == 2, refused.stderr  # both nodes
    assert "Traceback" not in refused.stderr
    assert not list((out / "runs").glob("*.json"))


def test_a_cluster_stopped_mid_sweep_ends_like_ctrl_c_and_the_rerun_loses_nothing(cluster: Cluster, tmp_path: Path) -> None:
    # 7,200 shorter runs of the paper's protocol: 18 batches of 400 runs, a few tenths of a second each on one worker,
    # so the cluster stops while most of the sweep is still to do, however fast the kernel and the task start-up get.
    total = 7_200
    out, overrides = tmp_path / "cluster", ["seeds=400", "episodes=100"]
    args = ["run", str(PAPER), "--out", str(out), "--backend", "ray", "--ray-address", ADDRESS, "--no-progress"]
    sets = [x for o in overrides for x in ("--set", o)]
    driver = cluster.run_background(*args, "--workers", "1", *sets)  # one batch at a time on the cluster
    try:
        deadline = time.monotonic() + 120
        while count_runs(out) < 3:
            assert driver.poll() is None and time.monotonic() < deadline, "the sweep did not start"
            time.sleep(0.1)
        stopped = time.monotonic()
        for node in cluster.nodes:  # the whole cluster goes away (like `ray stop` on every node)
            stop_session(node)
        out_text, err = driver.communicate(timeout=90)
        took = time.monotonic() - stopped
    finally:
        stop_session(driver, grace=5)
    assert driver.returncode == 130, f"{out_text}\n{err}"
    assert f"the Ray cluster at {ADDRESS} was lost mid-sweep" in err
    assert "finished runs are kept, rerun the same command to resume" in err and "Traceback" not in err
    assert took < 40
    assert not (out / ".lock.owner").exists() and not list(out.rglob(".tmp-*"))  # the lock released (its file stays)
    assert not (out / "failed").exists() or not list((out / "failed").iterdir()), "a lost cluster marked runs failed"
    kept = count_runs(out)
    assert 3 <= kept < total
    resumed = run_sweep(PAPER, out, workers=2, overrides=overrides, progress=False)
    assert (resumed.skipped, resumed.finished, resumed.failed) == (kept, total - kept, 0)
    run_sweep(PAPER, tmp_path / "local", workers=2, overrides=overrides, progress=False)
    assert contents(out) == contents(tmp_path / "local")
