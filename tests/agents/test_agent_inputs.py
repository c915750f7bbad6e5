"""
The agents' inputs: decision counts, observations, the size of the Q-table, and model files (their declared sizes and
saved values). Each bad input is one clear error, raised before anything is allocated or run.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.serialization import ModelFileError

ENV_ID = "sb3_affect/GridPursuit-v0"


def run_python(code: str, timeout: float = 120) -> str:
    """Run ``code`` in a fresh interpreter (a hang or a blow-up can not take the test run with it); its stdout."""
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=timeout, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


# -- learn's decision count ----------------------------------------------------------------------------------------
def test_learn_with_a_fractional_count_is_refused_not_spun_forever() -> None:
    out = run_python(
        """
        import gymnasium as gym
        import sb3_affect
        from sb3_affect import QLearning
        model = QLearning("Grid", gym.make("sb3_affect/GridPursuit-v0"), seed=0)
        for bad in (2.5, -1, float("nan"), float("inf"), True, "10"):
            try:
                model.learn(bad)
            except (ValueError, TypeError) as error:
                print(type(error).__name__, str(error).count("\\n"), "total_timesteps" in str(error))
        model.learn(1e2)  # an integral float, as SB3 accepts
        print(model.num_timesteps)
        """,
        timeout=60,
    )
    lines = out.split("\n")
    assert lines[:6] == ["ValueError 0 True"] * 4 + ["TypeError 0 True"] * 2
    assert lines[6] == "100"


# -- predict's observations ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("cls", [QLearning, AffectQ])
@pytest.mark.parametrize("bad", [-1, 3.7, 0.99, True, 225, math.nan, [0, 999], np.array([[1], [-2]]), "x", None])
def test_predict_refuses_observations_outside_the_space(cls: type, bad: object) -> None:
    model = cls("Grid", gym.make(ENV_ID), seed=0)
    with pytest.raises(ValueError, match=r"observation .* (outside the observation space|not a whole number|not a state)"):
        model.predict(bad, deterministic=True)
    with pytest.raises(ValueError, match="observation"):
        model.predict(bad, deterministic=False)


def test_predict_accepts_states_of_the_space() -> None:
    model = QLearning("Grid", gym.make(ENV_ID), seed=0, exploration_rate=0.5)
    for good in (0, 224, np.int64(7), 3.0, [0, 224], np.array([1, 2])):
        for deterministic in (True, False):
            model.predict(good, deterministic=deterministic)


# -- the table's size ----------------------------------------------------------------------------------------------
class Big(gym.Env):
    """A chain of ``n`` states (observation space ``Discrete(n)``), ending every 97 steps."""

    def __init__(self, n: int) -> None:
        self.observation_space, self.action_space, self.s = spaces.Discrete(n), spaces.Discrete(4), 0

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[int, dict]:
        super().reset(seed=seed)
        self.s = 0
        return 0, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict]:
        self.s = (self.s + 1 + int(action)) % int(self.observation_space.n)
        return self.s, float(self.s % 97 == 0), self.s % 97 == 0, False, {}


@pytest.mark.parametrize("n", [10**9, 10**20])
def test_an_impossible_table_is_refused_before_allocation(n: int) -> None:
    with pytest.raises((ValueError, OverflowError)) as error:
        QLearning("Grid", Big(n) if n < 2**62 else _big_space_env(n))
    assert "\n" not in str(error.value) and ("GiB" in str(error.value) or "Discrete" in str(error.value))


def _big_space_env(n: int) -> gym.Env:
    env = Big(10)
    env.observation_space = spaces.Discrete(10**9)  # Gymnasium itself refuses 10**20; 10**9 stands for it
    return env


@pytest.mark.parametrize("algo", ["QLearning", "AffectQ"])
def test_learn_on_ten_million_states_holds_the_table_plus_a_bounded_overhead(algo: str) -> None:
    out = run_python(
        f"""
        import resource, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_agent_inputs import Big
        from sb3_affect import {algo}
        model = {algo}("Grid", Big(10**7), seed=0)
        built = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        model.learn(500)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        print(built, peak, model.num_timesteps, float(model.q_table.sum()) != 0.0)
        """,
        timeout=120,
    )
    built, peak, steps, learnt = out.split()
    assert steps == "500" and learnt == "True"
    # The table is 320 MB (and the known map's distances 80 MB); a list per state of it would be gigabytes.
    assert float(peak) - float(built) < 150, out


# -- model files ---------------------------------------------------------------------------------------------------
def rewrite(path: Path, member: str, data: bytes, compression: int = zipfile.ZIP_DEFLATED) -> None:
    """Replace one member of a model file (the others kept as they are)."""
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    members[member] = data
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content, compress_type=compression if name == member else zipfile.ZIP_DEFLATED)


@pytest.fixture
def saved(tmp_path: Path) -> Path:
    model = QLearning("Grid", gym.make(ENV_ID), seed=0)
    model.learn(200)
    path = tmp_path / "model.zip"
    model.save(path)
    return path


@pytest.mark.parametrize("member", ["data", "sb3_affect.json", "policy.pth"])
def test_a_zip_bomb_is_refused_from_its_declared_size(saved: Path, member: str) -> None:
    rewrite(saved, member, b" " * (80 * 2**20))  # 80 MB of blanks: tens of kB compressed
    assert saved.stat().st_size < 2**20
    with pytest.raises(ModelFileError, match=f"the '{member}' entry expands to 83,886,080 bytes") as error:
        QLearning.load(saved)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize("n", [10**9, 10**20])
def test_a_huge_declared_space_is_refused_before_allocation(saved: Path, n: int) -> None:
    with zipfile.ZipFile(saved) as archive:
        twin = json.loads(archive.read("sb3_affect.json"))
    twin["observation_space"]["n"] = n
    rewrite(saved, "sb3_affect.json", json.dumps(twin).encode())
    with pytest.raises(ModelFileError, match="Discrete") as error:
        QLearning.load(saved)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(
    "key, value, words",
    [
        ("gamma", 7, "gamma"),
        ("exploration_rate", -3, "exploration_rate"),
        ("max_episode_decisions", -1, "max_episode_decisions"),
        ("q_init", "x", "q_init"),
        ("predict", "x", "'predict' names a method"),
        ("q_table", 1, "'q_table' names a method"),
    ],
)
def test_saved_values_are_checked_as_the_constructor_checks_them(saved: Path, key: str, value: object, words: str) -> None:
    with zipfile.ZipFile(saved) as archive:
        data = json.loads(archive.read("data"))
    data[key] = value
    rewrite(saved, "data", json.dumps(data).encode())
    with pytest.raises(ModelFileError, match=words) as error:
        QLearning.load(saved)
    assert "\n" not in str(error.value)
