"""
The built wheel, installed away from the checkout.

Two venvs are made in a temporary folder (no checkout on their path; every command runs from an empty folder):

* **core**: the wheel and only the packages its core requirements pull in (their installed copies, found through the
  requirements' metadata and linked into the venv), so no extra's library can be imported;
* **full**: the wheel beside every package of the test environment (all extras).

A real fresh install (pip, from the registry) is measured by ``benchmarks/footprint.py``; here the point is what the
installed package can do on its own.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from importlib import metadata
from pathlib import Path

import pytest
from packaging.markers import default_environment
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]


def _closure(names: list[str]) -> set[str]:
    """The installed distributions ``names`` require, transitively (requirements without extras)."""
    seen: set[str] = set()
    stack = list(names)
    environment = default_environment()
    while stack:
        name = re.sub(r"[-_.]+", "-", stack.pop()).lower()
        if name in seen:
            continue
        seen.add(name)
        for text in metadata.requires(name) or []:
            requirement = Requirement(text)
            if requirement.marker is None or requirement.marker.evaluate({**environment, "extra": ""}):
                stack.append(requirement.name)
    return seen


def _link_distributions(names: set[str], site: Path) -> None:
    """Link the top-level files of the installed distributions ``names`` into ``site``."""
    for name in names:
        dist = metadata.distribution(name)
        base = Path(str(dist.locate_file("")))
        tops = {Path(str(f)).parts[0] for f in dist.files or [] if not str(f).startswith("..")}
        for top in tops:
            source, target = base / top, site / top
            if source.exists() and not target.exists() and top != "__pycache__":
                target.symlink_to(source)


def _venv(path: Path) -> tuple[Path, Path]:
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(path)], check=True)
    python = path / "bin" / "python"
    site = Path(subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               check=True, capture_output=True, text=True).stdout.strip())
    return python, site


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("dist")
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", str(out),
                            str(ROOT)], capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    return next(out.glob("sb3_affect-*.whl"))


def _install(wheel: Path, site: Path) -> None:
    """Install a pure-Python wheel: its files go to site-packages as they are (the test runs the CLI as a module)."""
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)


@pytest.fixture(scope="module")
def core(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    python, site = _venv(tmp_path_factory.mktemp("core") / "venv")
    core_requirements = [Requirement(r).name for r in metadata.requires("sb3-affect") or [] if "extra ==" not in r]
    _link_distributions(_closure(core_requirements), site)
    _install(wheel, site)
    return python


def _copy_compiled_code(site: Path) -> None:
    """
    Copy numba's cache of the checkout's compiled functions (the kernels, compiled or loaded here first, and what else
    this session compiled) into the install's ``__pycache__`` folders, with the kernel's digest of its sources. numba
    keys a cached function by its source file's content, not its path, so the install loads them as it would after
    its own first run, instead of compiling every kernel again (minutes) in each of its commands. Compiling on a cold
    cache is ``make venv``'s step (``python -m sb3_affect.kernel``) and the checkout's first import.
    """
    from sb3_affect.kernel import warm_up

    warm_up()
    for cache in (ROOT / "sb3_affect").rglob("__pycache__"):
        target = site / cache.relative_to(ROOT)
        for path in [*cache.glob("*.nbi"), *cache.glob("*.nbc"), *cache.glob("*.sha256")]:
            target.mkdir(exist_ok=True)
            shutil.copy2(path, target / path.name)


@pytest.fixture(scope="module")
def full(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    python, site = _venv(tmp_path_factory.mktemp("full") / "venv")
    (site / "test-environment.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")  # every library, not sb3_affect
    _install(wheel, site)
    _copy_compiled_code(site)
    return python


def run(python: Path, args: list[str], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    env = {key: value for key, value in os.environ.items() if not key.startswith("PYTHON")}
    return subprocess.run([str(python), *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


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
replicate.OVERRIDES = {"forensics": ["leaders=1", "reps=2"]}  # the forensics run, with one leader replicated twice
from sb3_affect.study.launcher import sweep_file
load = sweep_file.load_sweep
sweep_file.load_sweep = lambda path, overrides=(), **kw: load(path, [*overrides, "seeds=1", "episodes=5"], **kw)
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
