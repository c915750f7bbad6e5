"""Replication forensics: which candidate implementation could have produced the paper's printed numbers.

The names below are imported on first use (PEP 562), so that importing a module of this package (``sb3-affect status``
reads ``forensics.unit_files``) does not import the analysis (SciPy, the report's statistics).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from sb3_affect.study.forensics.analysis import ForensicsResult, run_forensics
    from sb3_affect.study.forensics.candidates import Candidate, CandidateSpace, Protocol, Reading, Simulation
    from sb3_affect.study.forensics.statistics import STATISTICS, printed_numbers

_LAZY: dict[str, str] = {
    "ForensicsResult": "sb3_affect.study.forensics.analysis",
    "run_forensics": "sb3_affect.study.forensics.analysis",
    "Candidate": "sb3_affect.study.forensics.candidates",
    "CandidateSpace": "sb3_affect.study.forensics.candidates",
    "Protocol": "sb3_affect.study.forensics.candidates",
    "Reading": "sb3_affect.study.forensics.candidates",
    "Simulation": "sb3_affect.study.forensics.candidates",
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
    "printed_numbers",
    "run_forensics",
]
