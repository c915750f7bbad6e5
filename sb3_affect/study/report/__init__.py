"""The replication report: the paper's tables and figures from our runs, beside the paper's own numbers."""

from sb3_affect.core.extras import require_extra

require_extra("report", "the report")

from sb3_affect.study.report.build import build_report
from sb3_affect.study.report.estimation.bootstrap import (
    bootstrap_ci,
    bootstrap_improvement,
    iqm,
    paired_ttest_table,
    probability_of_improvement,
)

__all__ = ["bootstrap_ci", "bootstrap_improvement", "build_report", "iqm", "paired_ttest_table", "probability_of_improvement"]
