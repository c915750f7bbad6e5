"""
The deep study on the Ray backend (a real local Ray instance, the fixture of test_experiments_ray): one task per batch
of seeds, the cells the local backend's forked workers give, and no fall-back to local when Ray is not there.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("minigrid")

from test_deep_study_run import TOY, toy
from test_experiments_ray import ray_instance  # noqa: F401  (the module's Ray instance)

from sb3_affect.study.launcher.deep_study import CELLS, run_deep_study
from sb3_affect.study.launcher.ray_errors import RayClusterError

pytestmark = [
    pytest.mark.ray,
    pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="the optional ray extra is not installed"),
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the fixture reads /proc and ss"),
]


def cells(out: Path) -> dict[str, Any]:
    """Every cell's record without its CPU seconds."""
    found = {}
    for path in sorted((out / CELLS).glob("*.json")):
        record = json.loads(path.read_text())
        record.pop("seconds")
        found[path.name] = record
    return found


def test_ray_runs_one_task_per_batch_and_gives_the_local_backends_cells(ray_instance: Any, tmp_path: Path) -> None:  # noqa: F811
    study = toy(tmp_path, seeds=[0, 1, 2], seeds_per_batch=2, agents=TOY["agents"][:3])  # type: ignore[index]
    local = run_deep_study(study, tmp_path / "local", workers=2, log=lambda line: None)
    lines: list[str] = []
    remote = run_deep_study(study, tmp_path / "ray", workers=2, backend="ray", log=lines.append)
    assert (local.trained, local.batches) == (remote.trained, remote.batches) == (3, 6)
    assert sum("batch 2/2 (seeds 2)" in line for line in lines) == 3  # seeds 0-1 in one task, seed 2 in another
    found = cells(tmp_path / "ray")
    assert found == cells(tmp_path / "local") and len(found) == 3
    assert all(cell["seeds"] == [0, 1, 2] for cell in found.values())  # merged in seed order


def test_no_ray_cluster_is_an_error_not_a_local_run(tmp_path: Path) -> None:
    study = toy(tmp_path, agents=TOY["agents"][:1])  # type: ignore[index]
    with pytest.raises(RayClusterError, match=r"no Ray cluster at 127\.0\.0\.1:9"):
        run_deep_study(study, tmp_path / "out", backend="ray", ray_address="127.0.0.1:9", ray_timeout=2)
    assert not (tmp_path / "out" / CELLS).exists()
