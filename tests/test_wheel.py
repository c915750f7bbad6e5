"""
The built wheel (from the sdist), installed away from the checkout, in the two venvs of ``wheel_venvs``: **core** (the
core requirements only, so no extra's library can be imported) and **full** (every library of the test environment).
"""

from __future__ import annotations

import re
import subprocess
import tarfile
from pathlib import Path

import pytest
from wheel_venvs import ROOT, build_sdist, build_wheel, core_venv, full_venv, run


@pytest.fixture(scope="module")
def sdist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_sdist(tmp_path_factory.mktemp("sdist"))


@pytest.fixture(scope="module")
def wheel(sdist: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_wheel(tmp_path_factory.mktemp("dist"), sdist)


def test_the_sdist_ships_the_examples_the_docs_point_to(sdist: Path) -> None:
    tracked = subprocess.run(["git", "ls-files", "examples"], cwd=ROOT, capture_output=True, text=True).stdout.split()
    examples = tracked or [str(p.relative_to(ROOT)) for p in (ROOT / "examples").glob("*.*")]  # a checkout without git
    with tarfile.open(sdist) as archive:
        shipped = {name.split("/", 1)[1] for name in archive.getnames() if "/" in name}
    assert examples and set(examples) <= shipped, sorted(set(examples) - shipped)
    assert not [name for name in shipped if "__pycache__" in name or name.endswith(".pyc")]


@pytest.fixture(scope="module")
def core(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return core_venv(wheel, tmp_path_factory.mktemp("core") / "venv")


@pytest.fixture(scope="module")
def full(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return full_venv(wheel, tmp_path_factory.mktemp("full") / "venv")


CORE_SCRIPT = """
import sys, gymnasium as gym, numpy as np, sb3_affect
from stable_baselines3 import DQN
from sb3_affect import AffectQ, BroekensCallback, EmotionCallback, QLearning
from sb3_affect.core.extras import EXTRAS, missing_modules
assert "site-packages" in sb3_affect.__file__, sb3_affect.__file__
for cls in (QLearning, AffectQ):
    # the Python loop: the compiled engine's first compilation in a new install takes 20-40 s (tested elsewhere)
    model = cls("Grid", gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 3)), seed=0, engine="python").learn(400)
    model.save(f"{cls.__name__}.zip")
    loaded = cls.load(f"{cls.__name__}.zip")
    assert (loaded.q_table == model.q_table).all()
    action, _ = loaded.predict(np.array([0]), deterministic=True)
    print(cls.__name__, "ok", int(action[0]))
# SB3's progress bar (tqdm and rich come with the plugin)
QLearning("Grid", gym.make("FrozenLake-v1"), seed=0, engine="python").learn(200, progress_bar=True)
print("progress bar ok")
emotions, broekens = EmotionCallback(), BroekensCallback()
DQN("MlpPolicy", "FrozenLake-v1", learning_starts=10, seed=0).learn(300, callback=[emotions, broekens])
print("callbacks", len(emotions.episode_log), len(broekens.episode_log))
extras = sorted({m for extra in ("experiments", "report", "hunters", "ray", "zoo") for m in EXTRAS[extra]})
missing = {m for extra in ("experiments", "report", "hunters", "ray", "zoo") for m in missing_modules(extra)}
print("installed", sorted(set(extras) - missing))
print("imported", sorted(m for m in sys.modules if m.split(".")[0] in extras or m.startswith(("sb3_affect.study.launcher",
      "sb3_affect.study.report", "sb3_affect.study.forensics"))))
"""


def test_core_wheel_learns_saves_loads_predicts_and_observes_dqn(core: Path, tmp_path: Path) -> None:
    result = run(core, ["-c", CORE_SCRIPT], tmp_path)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "QLearning ok" in out and "AffectQ ok" in out and "progress bar ok" in out
    emotions, broekens = map(int, re.search(r"callbacks (\d+) (\d+)", out).groups())  # type: ignore[union-attr]
    assert emotions > 0 and broekens > 0
    assert "installed []" in out and "imported []" in out, out


def test_core_wheel_names_the_extra_a_study_command_needs(core: Path, tmp_path: Path) -> None:
    for argv, extra in ((["run", "paper", "--out", "out"], "experiments"), (["replicate", "--out", "out"], "report")):
        result = run(core, ["-m", "sb3_affect", *argv], tmp_path)
        assert result.returncode == 2, result.stderr
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and f'pip install "sb3-affect[{extra}]"' in lines[0], result.stderr
    zoo = ["-m", "sb3_affect.integrations.zoo", "train", "--algo", "affectq", "--env", "FrozenLake-v1"]
    result = run(core, zoo, tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == ("python -m sb3_affect.integrations.zoo: error: the rl-zoo3 recipe needs the 'zoo' "
                                     'extra (missing: rl_zoo3, huggingface_sb3): pip install "sb3-affect[zoo]"')


def test_wheel_runs_shipped_sweeps_by_name_and_by_their_source_path(full: Path, tmp_path: Path) -> None:
    result = run(full, ["-m", "sb3_affect", "run", "smoke", "--out", "by_name", "--workers", "1", "--no-progress",
                        "--set", "episodes=5", "--set", "seeds=1"], tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "by_name" / "sweep.json").exists()
    # by its source path: the shipped file is found and read (the override it is given is then refused)
    result = run(full, ["-m", "sb3_affect", "run", "experiments/smoke.yaml", "--out", "by_path", "--set", "seeds=0"],
                 tmp_path)
    assert result.returncode == 2 and "seeds" in result.stderr and "can not read" not in result.stderr, result.stderr
    assert "sb3_affect/sweeps/smoke.yaml" in result.stderr
    result = run(full, ["-m", "sb3_affect", "run", "nosuch", "--out", "x"], tmp_path)
    assert result.returncode == 2 and "give a YAML path or a shipped sweep: ablation, " in result.stderr


REPLICATE = """
import sys
import sb3_affect.study.replicate as replicate
assert "site-packages" in replicate.__file__
replicate.PARTS = (("paper", "the paper's protocol, at toy size"), *(p for p in replicate.PARTS if p[0] == "forensics"))
replicate.LARGE_SEEDS = replicate.ABLATION_SEEDS = replicate.BEYOND_SEEDS = 1
replicate.ENGINE_EPISODES = 5
# the grid of one alpha and one gamma, its one leader replicated twice
replicate.OVERRIDES = {"forensics": ["forensics.alphas=[1.0]", "forensics.gammas=[0.8]", "forensics.leaders=1",
                                     "forensics.reps=2"]}
from sb3_affect.study.launcher import sweep_file
load = sweep_file.load_sweep
toy = ("seeds=1", "episodes=5")  # the tabular sweeps at toy size (the forensics file has its own sizes, above)
sweep_file.load_sweep = lambda path, overrides=(), **kw: load(
    path, [*overrides, *(() if str(path).endswith("forensics.yaml") else toy)], **kw)
import sb3_affect.study.launcher.launcher as launcher
launcher.load_sweep = sweep_file.load_sweep
from sb3_affect.study.cli import main
sys.exit(main(["replicate", "--out", "runs", "--workers", "1"]))
"""


def test_wheel_replicates_from_an_empty_folder(full: Path, tmp_path: Path) -> None:
    """``sb3-affect replicate`` from the wheel, at toy size: the shipped paper sweep, the studies, the forensics, the
    report."""
    result = run(full, ["-c", REPLICATE], tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "runs" / "report.html").exists() and (tmp_path / "runs" / "paper" / "sweep.json").exists()
    assert (tmp_path / "runs" / "forensics" / "forensics.md").exists()  # the shipped experiments/forensics.yaml
