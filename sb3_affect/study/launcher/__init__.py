"""Experiment sweeps: YAML files, the launcher, the results store, local and Ray backends."""

from sb3_affect.core.extras import require_extra

require_extra("experiments", "the experiment launcher and results store")

from sb3_affect.study.launcher.launcher import SweepSummary, run_sweep
from sb3_affect.study.launcher.one_run import execute_run
from sb3_affect.study.launcher.run_ids import run_id
from sb3_affect.study.launcher.schema import Sweep, SweepError
from sb3_affect.study.launcher.store import ResultsStore, StoreError
from sb3_affect.study.launcher.sweep_file import load_sweep

__all__ = [
    "ResultsStore",
    "StoreError",
    "Sweep",
    "SweepError",
    "SweepSummary",
    "execute_run",
    "load_sweep",
    "run_id",
    "run_sweep",
]
