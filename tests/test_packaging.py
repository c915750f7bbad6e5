"""The wheel ships every package of the source tree: each folder with an ``__init__.py`` is in pyproject's list."""

from __future__ import annotations

from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def source_packages(root: Path) -> set[str]:
    """The dotted names of the folders under ``root/sb3_affect`` that hold an ``__init__.py``."""
    return {".".join(init.parent.relative_to(root).parts) for init in (root / "sb3_affect").rglob("__init__.py")}


def test_every_package_of_the_source_tree_is_in_the_wheel() -> None:
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    missing = source_packages(ROOT) - listed
    assert not missing, f"packages not in pyproject.toml's [tool.setuptools] packages: {sorted(missing)}"


def test_a_new_folder_is_seen(tmp_path: Path) -> None:
    (tmp_path / "sb3_affect" / "study" / "new_room").mkdir(parents=True)
    (tmp_path / "sb3_affect" / "__init__.py").write_text("")
    (tmp_path / "sb3_affect" / "study" / "new_room" / "__init__.py").write_text("")
    assert source_packages(tmp_path) == {"sb3_affect", "sb3_affect.study.new_room"}
