"""
Issue 7's report section: every agent ranked on decisions per episode, cells per episode and steps before the
optimal path (bootstrap 95% CIs), on the static task and on moving prey, and the personalities' emotion profiles.

The numbers come from ``sb3_affect.baselines.summary`` (definitions there and in docs/beyond_the_paper.md); this module
only assembles the markdown, so the report build can add it::

    from sb3_affect.report.baselines import baselines_section
    text = baselines_section(["runs/issue7", "runs/issue7-baselines_moving7", "runs/issue7-baselines_moving"])
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from sb3_affect.baselines.summary import emotion_profile, load_runs, markdown, profile_markdown, summarise

INTRO = (
    "The paper's baseline is epsilon-greedy averaged over epsilon 0.1 to 0.9. Here every agent runs on the same seeds "
    "beside tuned baselines (epsilon, temperature and UCB coefficient chosen on separate seeds), a decaying epsilon, "
    "optimistic initial values, and epsilon-greedy moving 1 or 2 cells a decision like the affective agent. Means over "
    "runs with percentile-bootstrap 95% confidence intervals; ranked by decisions per episode. On moving prey, optimal "
    "means a capture within the prey's starting distance (docs/beyond_the_paper.md)."
)


def baselines_section(run_dirs: Sequence[str | Path], title: str = "Beyond the paper: fair baselines and moving prey") -> str:
    """The section as markdown (empty string when none of ``run_dirs`` holds runs)."""
    records = [record for folder in run_dirs if Path(folder).exists() for record in load_runs(folder)]
    if not records:
        return ""
    text = f"## {title}\n\n{INTRO}\n\n{markdown(summarise(records))}"
    profile = emotion_profile(records)
    if len(profile):
        text += "\nPersonalities (a bias on the appraisal's norm: optimistic 0.8, pessimistic 1.25). " + profile_markdown(
            profile
        )
    return text
