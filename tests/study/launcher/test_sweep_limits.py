"""
Sweep files that would run code, exhaust the machine or fail later for ever: each is refused at once with an error
naming the key. Sizes are checked from the numbers, so the checks take no time and no memory (run in a child process
under a memory limit and a timeout, so that a regression can not take the machine down).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from sb3_affect.core.registry import resolve_class
from sb3_affect.study.launcher import SweepError, load_sweep

HEAD = "name: s\nepisodes: 5\nseeds: 2\nenv: {id: sb3_affect/GridPursuit-v0, kwargs: {size: 5, goal: [2, 2]}}\n"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def refused_quickly(path: Path, seconds: float = 30, memory_gb: int = 3) -> str:
    """The error of ``load_sweep(path)`` in a child process limited in memory and time."""
    code = textwrap.dedent(
        f"""
        import resource
        resource.setrlimit(resource.RLIMIT_AS, ({memory_gb} * 2**30, {memory_gb} * 2**30))
        from sb3_affect.study.launcher import SweepError, load_sweep
        try:
            load_sweep({str(path)!r})
        except SweepError as error:
            print(error)
        else:
            print("ACCEPTED")
        """
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=seconds, check=False)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-1500:]
    assert "ACCEPTED" not in done.stdout
    return done.stdout


# -- code ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("algo", ["subprocess:Popen", "collections:OrderedDict", "builtins:object"])
def test_an_algo_path_must_name_an_sb3_algorithm(tmp_path: Path, algo: str) -> None:
    path = write(tmp_path, HEAD + f"agents:\n  - name: a\n    algo: '{algo}'\n")
    with pytest.raises(SweepError, match=r"agents\[0\] \(a\)\.algo: .*not a Stable-Baselines3 algorithm"):
        load_sweep(path)
    with pytest.raises(ValueError, match="BaseAlgorithm"):
        resolve_class(algo)


# -- resource bombs ------------------------------------------------------------------------------------------------
def test_a_billion_seeds_is_refused_from_the_number(tmp_path: Path) -> None:
    text = HEAD.replace("seeds: 2", "seeds: 1000000000") + "agents: [{name: a, algo: QLearning}]\n"
    error = refused_quickly(write(tmp_path, text))
    assert "seeds" in error and "1000000" in error.replace(",", "")


def test_a_huge_grid_is_refused_from_its_lengths(tmp_path: Path) -> None:
    values = "[" + ", ".join(str(i / 1000) for i in range(100)) + "]"
    grid = ", ".join(f"g{i}: {values}" for i in range(5))
    error = refused_quickly(write(tmp_path, HEAD + f"agents:\n  - name: a\n    algo: QLearning\n    grid: {{{grid}}}\n"))
    assert "grid" in error and "100 x 100 x 100" in error


def test_too_many_runs_over_the_agents_is_refused(tmp_path: Path) -> None:
    values = "[" + ", ".join(str(i) for i in range(1000)) + "]"
    agents = "".join(f"  - {{name: a{i}, algo: QLearning, grid: {{g: {values}}}}}\n" for i in range(5))
    error = refused_quickly(write(tmp_path, HEAD.replace("seeds: 2", "seeds: 1000") + "agents:\n" + agents))
    assert "5,000,000 runs" in error


def test_an_alias_bomb_in_kwargs_names_the_kwargs_key(tmp_path: Path) -> None:
    text = HEAD + (
        "agents:\n  - name: a\n    algo: QLearning\n    kwargs:\n"
        "      policy_kwargs:\n"
        "        l0: &l0 [x, x, x, x, x, x, x, x, x, x]\n"
        "        l1: &l1 [*l0, *l0, *l0, *l0, *l0, *l0, *l0, *l0, *l0, *l0]\n"
        "        l2: &l2 [*l1, *l1, *l1, *l1, *l1, *l1, *l1, *l1, *l1, *l1]\n"
        "        l3: &l3 [*l2, *l2, *l2, *l2, *l2, *l2, *l2, *l2, *l2, *l2]\n"
        "        l4: &l4 [*l3, *l3, *l3, *l3, *l3, *l3, *l3, *l3, *l3, *l3]\n"
        "        l5: &l5 [*l4, *l4, *l4, *l4, *l4, *l4, *l4, *l4, *l4, *l4]\n"
        "        l6: &l6 [*l5, *l5, *l5, *l5, *l5, *l5, *l5, *l5, *l5, *l5]\n"
        "        l7: &l7 [*l6, *l6, *l6, *l6, *l6, *l6, *l6, *l6, *l6, *l6]\n"
        "        l8: [*l7, *l7, *l7, *l7, *l7, *l7, *l7, *l7, *l7, *l7]\n"
    )
    error = refused_quickly(write(tmp_path, text))
    assert "agents[0].kwargs.policy_kwargs" in error and "expands to more than 100,000 values" in error


def test_a_recursive_alias_is_refused(tmp_path: Path) -> None:
    text = HEAD + "agents:\n  - name: a\n    algo: QLearning\n    kwargs: {policy_kwargs: &r {net: [*r]}}\n"
    error = refused_quickly(write(tmp_path, text))
    assert "agents[0].kwargs.policy_kwargs" in error


def test_a_huge_grid_env_is_refused_before_it_is_built(tmp_path: Path) -> None:
    text = HEAD.replace("size: 5, goal: [2, 2]", "size: 100000, goal: [2, 2]") + "agents: [{name: a, algo: QLearning}]\n"
    error = refused_quickly(write(tmp_path, text), memory_gb=4)
    assert "size=100000 is too large" in error


# -- values that would fail later, for ever ------------------------------------------------------------------------
@pytest.mark.parametrize(
    "change, words",
    [
        ("seeds: [1180591620717411303424]", "seeds"),  # 2**70
        ("seeds: [7, -7]", "seeds"),
        ("seeds: [4294967296]", "seeds"),
        ("episodes: 1000000000000", "episodes"),
    ],
)
def test_values_that_fail_later_are_refused_now(tmp_path: Path, change: str, words: str) -> None:
    key = change.split(":")[0]
    lines = [change if line.startswith(f"{key}:") else line for line in HEAD.splitlines()]
    path = write(tmp_path, "\n".join(lines) + "\nagents: [{name: a, algo: QLearning}]\n")
    with pytest.raises(SweepError, match=words) as error:
        load_sweep(path, build=False)
    assert "Traceback" not in str(error.value)


def test_a_duplicate_key_is_an_error_naming_it_and_its_lines(tmp_path: Path) -> None:
    path = write(tmp_path, HEAD + "episodes: 7\nagents: [{name: a, algo: QLearning}]\n")
    with pytest.raises(SweepError, match=r"line 5, column 1: duplicate key 'episodes' \(first given at line 2\)"):
        load_sweep(path, build=False)
    nested = write(tmp_path, HEAD + "agents: [{name: a, algo: QLearning, kwargs: {gamma: 0.5, gamma: 0.9}}]\n")
    with pytest.raises(SweepError, match="duplicate key 'gamma'"):
        load_sweep(nested, build=False)


def test_a_kwarg_typo_gets_did_you_mean_once(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        HEAD
        + "agents:\n  - name: a\n    algo: QLearning\n    grid: {e: [0.1, 0.2, 0.3]}\n"
        + "    kwargs: {exploration_rate: $e, gama: 0.9}\n",
    )
    with pytest.raises(SweepError) as error:
        load_sweep(path)
    text = str(error.value)
    assert text.count("gama") == 1 and "did you mean 'gamma'?" in text
