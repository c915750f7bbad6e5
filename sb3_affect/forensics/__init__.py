"""Replication forensics: which candidate implementation could have produced the paper's printed numbers."""

from sb3_affect.forensics.analysis import ForensicsResult, run_forensics
from sb3_affect.forensics.candidates import Candidate, CandidateSpace, Protocol, Reading, Simulation
from sb3_affect.forensics.statistics import STATISTICS, printed_numbers

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
