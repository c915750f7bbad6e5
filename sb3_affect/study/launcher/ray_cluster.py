"""
The Ray side of the ``ray`` backend: connect, ship the code, check versions, run tasks, notice a lost cluster.

* Without an address: a private instance on this machine (``address="local"``, so neither ``RAY_ADDRESS`` nor a
  cluster recorded by an earlier ``ray start`` can redirect it), dashboard off, every process on 127.0.0.1 (the
  environment Ray reads when it is imported is set by ``launcher.executor``, which imports this module).
* With an address (``HOST:PORT`` or ``ray://HOST:PORT``): the address is tried first and ``ray.init`` is given
  ``timeout`` seconds (:mod:`sb3_affect.study.launcher.ray_connect`), so a wrong address or a missing token fails with a
  message instead of retrying forever;
  this package's code (``sb3_affect`` with its ``envs`` subpackage, as the driver imports it) is shipped with the
  job as a Ray ``py_modules`` entry, so a worker node needs Python, Ray and sb3-affect's dependencies, not
  sb3-affect; then one zero-CPU task per node reports its host and package versions, and a node whose versions differ
  from the driver's is refused before any run starts (a run that still comes back with other versions, from a node
  that joined later, is recorded as failed).
* A cluster that stops answering mid-sweep ends the sweep with :class:`ClusterLost`, which the CLI reports like Ctrl-C
  (finished runs are kept, rerun to resume; exit 130); results that arrived are stored, nothing is marked failed.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import ray
from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

import sb3_affect
import sb3_affect.envs
from sb3_affect.study.launcher.one_run import execute_run, package_versions
from sb3_affect.study.launcher.ray_connect import (
    handshake,
    init_with_timeout,
    plain_text,
    shutdown_within,
    working_directory,
)
from sb3_affect.study.launcher.ray_errors import ClusterLost, RayClusterError, head_stopped_answering, host_port, reachable
from sb3_affect.study.launcher.regular_files import write_file
from sb3_affect.study.launcher.signals import sigint_ignored

__all__ = ["RaySession", "connect", "execute_task", "plain_text", "write_logs"]

Versions = dict[str, str]


def stage_package(folder: Path) -> Path:
    """
    Copy the ``sb3_affect`` package the driver imports into ``folder/sb3_affect``, with ``envs`` inside it (an editable
    install maps ``sb3_affect.envs`` to the top-level ``envs/`` folder): the exact code the worker nodes will run.
    numba's cache of the compiled functions (``__pycache__/*.nbi``, ``*.nbc``, keyed by the source's content and the
    CPU) goes with it, so a node with the driver's CPU loads the kernels instead of compiling them (minutes) for each
    new package; another CPU compiles its own. Python's bytecode (``*.pyc``) stays behind.
    """
    ignore = shutil.ignore_patterns("*.pyc")
    target = folder / "sb3_affect"
    shutil.copytree(Path(sb3_affect.__file__).parent, target, ignore=ignore)
    envs = Path(sb3_affect.envs.__file__).parent
    if envs != Path(sb3_affect.__file__).parent / "envs":
        shutil.rmtree(target / "envs", ignore_errors=True)
        shutil.copytree(envs, target / "envs", ignore=ignore)
    return target


def _probe() -> Versions:
    """A zero-CPU task run once on every node: the package versions there."""
    return package_versions()


def version_differences(ours: Versions, theirs: Versions) -> list[str]:
    """``"numpy 2.3.5 (the driver has 2.4.1)"`` for each package whose version differs."""
    return [f"{name} {theirs.get(name)} (the driver has {ours[name]})" for name in ours if theirs.get(name) != ours[name]]


def check_nodes(address: str, timeout: float) -> None:
    """Run :func:`_probe` on every alive node; refuse nodes that can not run sb3-affect or have other versions."""
    ours = package_versions()
    probe = ray.remote(num_cpus=0, max_retries=0)(_probe)
    nodes = [n for n in ray.nodes() if n.get("Alive")]
    refs = {
        probe.options(scheduling_strategy=NodeAffinitySchedulingStrategy(n["NodeID"], soft=False)).remote(): n for n in nodes
    }
    ready, missing = ray.wait(list(refs), num_returns=len(refs), timeout=timeout)
    problems = []
    for ref in missing:
        node = refs[ref]
        problems.append(f"node {node['NodeManagerAddress']} ({node['NodeManagerHostname']}) did not answer in {timeout:g} s")
    for ref in ready:
        node = refs[ref]
        where = f"node {node['NodeManagerAddress']} ({node['NodeManagerHostname']})"
        try:
            versions = ray.get(ref)
        except Exception as error:
            cause = plain_text(str(error)).strip().splitlines()
            problems.append(f"{where} can not run sb3-affect: {cause[-1] if cause else type(error).__name__}")
            continue
        differences = version_differences(ours, versions)
        if differences:
            problems.append(f"{where} has " + ", ".join(differences))
    if problems:
        needs = ", ".join(f"{k} {v}" for k, v in ours.items() if k != "sb3_affect")
        raise RayClusterError(
            f"the Ray cluster at {address} can not run this sweep:\n  " + "\n  ".join(problems) + "\nsb3-affect's code is "
            f"shipped with the job; every node needs the driver's versions of: {needs} (and Ray {ray.__version__})"
        )


#: How long a failure that is not the run's own waits before the cluster's loss is ruled out (``RaySession.lost``).
SETTLE_SECONDS = 3.0


class RaySession:
    """
    A connected Ray job for one sweep: :meth:`run` submits tasks, at most ``cap`` at a time, and watches the cluster.

    :param address: the cluster's address, or ``None`` for the private instance
    """

    def __init__(self, address: str | None) -> None:
        self.ray = ray
        self.address = address
        self.gcs: tuple[str, int] | None = None
        if address and not address.startswith("ray://"):
            with contextlib.suppress(Exception):
                self.gcs = host_port(ray.get_runtime_context().gcs_address)

    def lost(self, settle: float = 0.0) -> str | None:
        """
        Why the cluster counts as lost (its GCS refuses connections for 3 s), or ``None``. ``settle``: seconds to wait
        first, for a cluster that is going away to finish doing so (its GCS may still answer while its nodes are gone).
        """
        if self.gcs is None:
            return None
        time.sleep(settle)
        return head_stopped_answering(*self.gcs)

    def run(
        self,
        items: list[Any],
        submit: Callable[[Any], Any],
        on_value: Callable[[Any, Any], None],
        on_error: Callable[[Any, BaseException], None],
        cap: int | None = None,
    ) -> None:
        """
        Submit ``submit(item)`` for each item (at most ``cap`` pending), and hand each outcome to ``on_value`` or
        ``on_error``; raise :class:`ClusterLost` when the cluster stops answering (the pending items are left alone).
        """
        ray = self.ray
        queue = deque(items)
        pending: dict[Any, Any] = {}
        while queue or pending:
            while queue and (cap is None or len(pending) < cap):
                item = queue.popleft()
                pending[submit(item)] = item
            try:
                done, _ = ray.wait(list(pending), num_returns=1, timeout=2.0)
            except Exception as error:  # a ray:// client whose server went away, or a driver cut off from its raylet
                raise ClusterLost.of(self.address, f"{type(error).__name__}: {plain_text(str(error))}") from None
            if not done:
                why = self.lost()
                if why:
                    raise ClusterLost.of(self.address, why)
                continue
            item = pending.pop(done[0])
            try:
                value = ray.get(done[0])
            except Exception as error:  # the task's worker died (after Ray's retry): the run failed, unless all is lost
                # (the run's own exception is the run's failure; a worker, node or object lost may be the cluster going)
                why = self.lost(settle=0.0 if isinstance(error, ray.exceptions.RayTaskError) else SETTLE_SECONDS)
                if why:
                    raise ClusterLost.of(self.address, why) from None
                on_error(item, error)
            else:
                on_value(item, value)


def _private_init(workers: int) -> None:
    # Ctrl-C in a terminal sends SIGINT to the whole process group: the instance's processes inherit "ignore SIGINT"
    # from here, so that only this driver reacts (cancels the tasks and shuts the instance down). address="local": a
    # new instance whatever RAY_ADDRESS or an earlier `ray start` says.
    with sigint_ignored():
        ray.init(address="local", num_cpus=workers, include_dashboard=False, log_to_driver=False, _node_ip_address="127.0.0.1")


@contextlib.contextmanager
def connect(address: str | None, workers: int, timeout: float = 60.0) -> Iterator[RaySession]:
    """
    Connect for one sweep (see the module docstring) and disconnect afterwards (stopping a private instance).

    :param address: ``HOST:PORT`` / ``ray://HOST:PORT`` of a running cluster, or ``None`` for a private instance
    :param workers: CPUs of the private instance
    :param timeout: seconds to wait for a cluster to answer (connection, and the version check of its nodes)
    """
    if address:
        where = host_port(address)
        if where is None:
            raise RayClusterError(f"--ray-address {address!r} is not HOST:PORT or ray://HOST:PORT")
        why = reachable(*where, timeout=min(timeout, 10.0))
        if why is not None:
            raise RayClusterError(
                f"no Ray cluster at {address}: connecting to {where[0]}:{where[1]} failed ({why}); start one with "
                "`ray start --head` or check --ray-address"
            )
        if not address.startswith("ray://"):
            handshake(address, *where, timeout=timeout)
    if ray.is_initialized():  # the caller's own ray.init: use it as it is, leave it running
        yield RaySession(address)
        return
    staging = None
    try:
        if address:
            staging = tempfile.mkdtemp(prefix="sb3-affect-ship-")
            package = stage_package(Path(staging))
            # Ray puts the driver's working directory on every worker's sys.path, before the shipped code: started from
            # a checkout (or a shared filesystem), its sb3_affect/ folder, which lacks envs/, would shadow the package.
            (Path(staging) / "cwd").mkdir()
            with working_directory(Path(staging) / "cwd"):
                init_with_timeout(ray, address, timeout, {"py_modules": [str(package)]})
            check_nodes(address, timeout)
        else:
            _private_init(workers)
        yield RaySession(address)
    finally:
        # Ctrl-C or an error: ``ray.shutdown`` ends this job, and Ray stops the job's tasks with it (and a private
        # instance). No ``ray.cancel(force=True)`` of the pending tasks: racing with tasks that are just finishing, it
        # crashes the driver inside Ray ("Tried to complete task that was not pending", Ray 2.60).
        if ray.is_initialized():
            shutdown_within(ray)
        if staging:
            shutil.rmtree(staging, ignore_errors=True)


def execute_task(config: dict[str, Any], log_dir: str | None, formats: tuple[str, ...]) -> tuple[Any, ...]:
    """
    A Ray task: ``("ok", result, logs)`` or ``("error", traceback)`` (the same failure record as the local backend).

    SB3 logger output goes to a scratch folder on the worker's node and comes back as ``logs`` (relative path ->
    bytes), for the driver to write under ``log_dir``; the result's ``timings`` get the Ray node id.
    """
    scratch = tempfile.mkdtemp(prefix="sb3-affect-logs-") if log_dir is not None else None
    try:
        result = execute_run(config, scratch, formats)
        logs: dict[str, bytes] = {}
        if scratch is not None:
            for path in sorted(Path(scratch).rglob("*")):
                if path.is_file():
                    logs[str(path.relative_to(scratch))] = path.read_bytes()
        with contextlib.suppress(Exception):
            result["timings"]["ray_node"] = ray.get_runtime_context().get_node_id()
        return "ok", result, logs
    except Exception:
        return ("error", traceback.format_exc())
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def write_logs(log_dir: str, logs: dict[str, bytes]) -> None:
    """Write a run's returned logger files under ``log_dir`` (each through a temp file and a rename)."""
    root = Path(log_dir)
    for name, data in logs.items():
        path = root / name
        if root.resolve() not in path.resolve().parents:
            continue  # a worker can only name files below the run's log folder
        path.parent.mkdir(parents=True, exist_ok=True)
        write_file(path, data)
