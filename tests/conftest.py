"""Shared fixtures."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import pytest

import sb3_affect  # noqa: F401  (registers the envs)


@pytest.fixture
def grid_env() -> gym.Env:
    return gym.make("sb3_affect/GridPursuit-v0")


@pytest.fixture(autouse=True, scope="session")
def _sb3_logdir(tmp_path_factory: pytest.TempPathFactory) -> object:
    """SB3's algorithms make a folder for their default logger (/tmp/SB3-<date> unless SB3_LOGDIR says where) on every
    ``learn``, even one that writes nothing: keep those inside pytest's temporary directory."""
    import os

    before = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if before is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = before


#: Gymnasium's own time limit. Importing rl_zoo3 replaces it for the whole process (``rl_zoo3.gym_patches``), and the
#: compiled engine does not step an env wrapped in rl_zoo3's (the Python loop runs instead).
TIME_LIMIT = gym.wrappers.TimeLimit
TIME_LIMIT_MODULES = (gym.wrappers, gym.wrappers.common, gym.envs.registration)


@pytest.fixture(autouse=True)
def _gymnasium_time_limit() -> object:
    """Gymnasium's time limit back after each test: a test that ran the zoo does not change the envs of the tests run
    after it in the same process (whatever order they run in: pytest-xdist gives each worker its own)."""
    yield
    for module in TIME_LIMIT_MODULES:
        module.TimeLimit = TIME_LIMIT  # type: ignore[attr-defined]


@pytest.fixture
def zoo(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> Callable[[list[str], Path], str]:
    """``python -m sb3_affect.integrations.zoo ARGS`` in ``cwd``, in this process (the zoo's modules run as ``__main__``)."""
    import matplotlib
    import rl_zoo3.gym_patches

    from sb3_affect.integrations.zoo import main as zoo_main

    matplotlib.use("Agg")
    for module in TIME_LIMIT_MODULES:  # rl_zoo3's time limit, as its users have it (conftest puts Gymnasium's back)
        module.TimeLimit = rl_zoo3.gym_patches.PatchedTimeLimit

    def run(args: list[str], cwd: Path) -> str:
        monkeypatch.chdir(cwd)
        capsys.readouterr()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            zoo_main(args)
        return capsys.readouterr().out

    return run
