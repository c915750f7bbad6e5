"""
The optional parts of the package and the extra that installs each one.

``pip install sb3-affect`` installs the plugin: the agents, the callbacks, the envs and the compiled engine. The study
tools on top of it need more libraries, installed by name (``pip install "sb3-affect[report]"``, or ``[all]``). A
study module calls ``require_extra`` before it imports them, so that a missing library gives one line naming the extra
to install instead of a traceback from deep inside the study.
"""

from __future__ import annotations

import importlib.util
import sys
import warnings

#: Extra name -> the modules it installs that the package imports (checked by ``require_extra``).
EXTRAS: dict[str, tuple[str, ...]] = {
    "experiments": ("yaml", "pydantic", "pyarrow"),
    "report": ("yaml", "pydantic", "pyarrow", "matplotlib", "scipy", "markdown", "rliable", "lifelines",
               "statsmodels", "adastop"),
    "hunters": ("pettingzoo",),
    "ray": ("ray",),
    "zoo": ("rl_zoo3", "huggingface_sb3"),
}


class MissingExtraError(ImportError):
    """A part of the package whose extra is not installed; the message is one line naming the extra."""


def missing_modules(extra: str) -> list[str]:
    """The modules of ``extra`` that can not be found (empty when the extra is installed)."""
    if extra not in EXTRAS:
        raise ValueError(f"extra={extra!r} is not an extra of sb3-affect; known: {', '.join(sorted(EXTRAS))}")
    return [name for name in EXTRAS[extra] if not _importable(name)]


def _importable(name: str) -> bool:
    """Whether the top-level module ``name`` can be found (without importing it)."""
    if name in sys.modules:
        return sys.modules[name] is not None  # None: a blocked import (Python's convention)
    return importlib.util.find_spec(name) is not None


def require_extra(extra: str, part: str) -> None:
    """
    Raise ``MissingExtraError`` when a module of ``extra`` is missing: ``part`` (what the user reached for, e.g.
    "the report") needs it, and the message says what to install.
    """
    missing = missing_modules(extra)
    if missing:
        raise MissingExtraError(
            f"{part} needs the {extra!r} extra (missing: {', '.join(missing)}): pip install \"sb3-affect[{extra}]\""
        )


def numba_problem() -> str | None:
    """Why numba (the compiled engine) can not be imported here, or ``None`` when it can."""
    try:
        import numba  # noqa: F401
    except ImportError as error:  # not installed, or a build that does not load on this platform
        return f"numba can not be imported ({error})"
    return None


_NUMBA_WARNED = False


def numba_usable(engine: str) -> bool:
    """
    Whether a tabular agent's ``engine`` can use the compiled kernel here: numba imports. ``engine="auto"`` without it
    runs the Python loop (one warning per process); ``engine="compiled"`` raises an error naming what is missing.
    """
    global _NUMBA_WARNED
    problem = numba_problem()
    if problem is None:
        return True
    if engine == "compiled":
        raise ModuleNotFoundError(f"engine='compiled' needs numba: {problem}; pip install numba, or use engine='python'")
    if not _NUMBA_WARNED:
        _NUMBA_WARNED = True
        warnings.warn(f"{problem}: engine='auto' runs the Python loop (same results, slower)", RuntimeWarning, stacklevel=3)
    return False


__all__ = ["EXTRAS", "MissingExtraError", "missing_modules", "numba_problem", "numba_usable", "require_extra"]
