"""
The deep study on the Ray backend (a real local Ray instance, the fixture of test_experiments_ray): one task per batch
of seeds, the cells the local backend's forked workers give, and no fall-back to local when Ray is not there.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("minigrid")

from test_deep_study_run import TOY, chunks, toy
from test_experiments_ray import ray_instance  # noqa: F401  (the module's Ray instance)

from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.ray_errors import RayClusterError
from sb3_affect.study.launcher.store import ResultsStore

pytestmark = [
    pytest.mark.ray,
    pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="the optional ray extra is not installed"),
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the fixture reads /proc and ss"),
]


def cells(out: Path) -> dict[Any, Any]:
    """Every cell's record without its CPU seconds."""
    found = ResultsStore(out).evaluations()
    for record in found.values():
        record.pop("seconds")
    return found


def test_ray_runs_one_task_per_batch_and_gives_the_local_backends_cells(ray_instance: Any, tmp_path: Path) -> None:  # noqa: F811
    study = toy(tmp_path, seeds=[0, 1, 2], seeds_per_batch=2, agents=TOY["agents"][:3])  # type: ignore[index]
    local = run_sweep(study, tmp_path / "local", workers=2, progress=False)
    remote = run_sweep(study, tmp_path / "ray", workers=2, backend="ray", progress=False)
    assert (local.finished, local.failed) == (remote.finished, remote.failed) == (9, 0)
    assert len(chunks(tmp_path / "ray")) == 6  # per cell: one task of two seeds, one of one
    found = cells(tmp_path / "ray")
    assert found == cells(tmp_path / "local") and len(found) == 3
    assert all(cell["seeds"] == [0, 1, 2] for cell in found.values())  # its runs in seed order


def test_no_ray_cluster_is_an_error_not_a_local_run(tmp_path: Path) -> None:
    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    with pytest.raises(RayClusterError, match=r"no Ray cluster at 127\.0\.0\.1:9"):
        run_sweep(study, tmp_path / "out", backend="ray", ray_address="127.0.0.1:9", ray_timeout=2, progress=False)
    assert not chunks(tmp_path / "out")
