"""Shared fixtures."""

from __future__ import annotations

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
