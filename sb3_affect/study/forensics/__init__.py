"""Replication forensics: which candidate implementation could have produced the paper's printed numbers.

The names below are imported on first use (PEP 562), so that importing one module of this package (the launcher's
``forensics.stages``) does not import the analysis (SciPy, the report's statistics).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from sb3_affect.study.forensics.analysis import ForensicsResult, analyse
    from sb3_affect.study.forensics.statistics import STATISTICS, printed_numbers
    from sb3_affect.study.forensics.study_run import run_study
    from sb3_affect.study.launcher.forensics_candidates import Candidate, CandidateSpace, Protocol, Reading, Simulation

_LAZY: dict[str, str] = {
    "ForensicsResult": "sb3_affect.study.forensics.analysis",
    "analyse": "sb3_affect.study.forensics.analysis",
    "run_study": "sb3_affect.study.forensics.study_run",
    "Candidate": "sb3_affect.study.launcher.forensics_candidates",
    "CandidateSpace": "sb3_affect.study.launcher.forensics_candidates",
    "Protocol": "sb3_affect.study.launcher.forensics_candidates",
    "Reading": "sb3_affect.study.launcher.forensics_candidates",
    "Simulation": "sb3_affect.study.launcher.forensics_candidates",
    "STATISTICS": "sb3_affect.study.forensics.statistics",
    "printed_numbers": "sb3_affect.study.forensics.statistics",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'sb3_affect.study.forensics' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "STATISTICS",
    "Candidate",
    "CandidateSpace",
    "ForensicsResult",
    "Protocol",
    "Reading",
    "Simulation",
    "analyse",
    "printed_numbers",
    "run_study",
]
