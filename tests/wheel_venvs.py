"""
The package as a user installs it, for the tests that run it away from the checkout (``test_wheel.py``,
``test_docs_code_blocks.py``): the sdist built from a copy of the source tree, the wheel built from that sdist (as pip
builds one from a source archive), and fresh virtual environments in a temporary folder, with no checkout on their path.

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
import tarfile
import zipfile
from importlib import metadata
from pathlib import Path

from packaging.markers import default_environment
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]
#: What the sdist is built from: the files of the source tree a build reads (no build folders, caches or results).
SOURCE_TREE = ("pyproject.toml", "MANIFEST.in", "README.md", "sb3_affect", "envs", "experiments", "examples")
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", ".pytest_cache", ".hypothesis")


def build_sdist(out: Path) -> Path:
    """The sdist, built from a copy of the source tree in ``out`` (so that builds of several test workers do not share
    the checkout's ``build/`` and egg-info folders)."""
    tree = out / "tree"
    tree.mkdir(parents=True)
    for name in SOURCE_TREE:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, tree / name, ignore=IGNORED)
        elif source.exists():
            shutil.copy2(source, tree / name)
    built = subprocess.run([sys.executable, "-m", "build", "--sdist", "--no-isolation", "--outdir", str(out), str(tree)],
                           capture_output=True, text=True)
    assert built.returncode == 0, built.stderr[-3000:]
    return next(out.glob("sb3_affect-*.tar.gz"))


def build_wheel(out: Path, sdist: Path | None = None) -> Path:
    """The wheel built from ``sdist`` (default: a new ``build_sdist``), as pip builds one from a source archive."""
    sdist = sdist or build_sdist(out / "sdist")
    with tarfile.open(sdist) as archive:
        archive.extractall(out / "unpacked", filter="data")
    (source,) = (out / "unpacked").iterdir()
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w",
                            str(out), str(source)], capture_output=True, text=True)
    assert built.returncode == 0, built.stderr[-3000:]
    return next(out.glob("sb3_affect-*.whl"))


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


def _install(wheel: Path, site: Path) -> None:
    """Install a pure-Python wheel: its files go to site-packages as they are (the tests run the CLI as a module)."""
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(site)


def _copy_compiled_code(site: Path) -> None:
    """
    Copy numba's cache of the checkout's compiled functions (the kernels, compiled or loaded here first, and what else
    this session compiled) into the install's ``__pycache__`` folders, with the kernel's digest of its sources and the
    source files' modification times (numba's index checks them), so the install loads them as it would after
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
        # numba's index checks each source file's size and modification time: the wheel's files got the time of their
        # extraction, so they take the checkout's (the same content) and the install finds the cached code valid
        for source in cache.parent.glob("*.py"):
            installed = target.parent / source.name
            if installed.exists():
                os.utime(installed, ns=(source.stat().st_atime_ns, source.stat().st_mtime_ns))


def core_venv(wheel: Path, path: Path, compiled: bool = False) -> Path:
    """A venv at ``path`` with the wheel and the core requirements only; ``compiled``: with the kernels' numba cache."""
    python, site = _venv(path)
    core_requirements = [Requirement(r).name for r in metadata.requires("sb3-affect") or [] if "extra ==" not in r]
    _link_distributions(_closure(core_requirements), site)
    _install(wheel, site)
    if compiled:
        _copy_compiled_code(site)
    return python


def full_venv(wheel: Path, path: Path) -> Path:
    """A venv at ``path`` with the wheel beside every library of the test environment, and the kernels' numba cache."""
    python, site = _venv(path)
    # every library of this environment, not sb3_affect: its site-packages folders (a .pth file of theirs that adds
    # another folder is not read there, so each is named; an editable install's finder is not installed by them)
    folders = dict.fromkeys([sysconfig.get_paths()["purelib"], *(p for p in sys.path if p.endswith("site-packages"))])
    (site / "test-environment.pth").write_text("".join(f"{folder}\n" for folder in folders))
    _install(wheel, site)
    _copy_compiled_code(site)
    return python


def run(python: Path, args: list[str], cwd: Path, timeout: float = 600,
        env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``python ARGS`` in ``cwd``, with this process's environment less its ``PYTHON*`` variables, plus ``env``."""
    environment = {key: value for key, value in os.environ.items() if not key.startswith("PYTHON")}
    return subprocess.run([str(python), *args], cwd=cwd, env={**environment, **(env or {})}, capture_output=True,
                          text=True, timeout=timeout)
