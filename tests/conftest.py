"""Shared fixtures."""

from __future__ import annotations

import gymnasium as gym
import pytest

import sb3_affect  # noqa: F401  (registers the envs)


@pytest.fixture
def grid_env() -> gym.Env:
    return gym.make("sb3_affect/GridPursuit-v0")
