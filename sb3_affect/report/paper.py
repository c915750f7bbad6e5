"""The paper's own numbers (docs/definitions.md, "The paper's numbers"), to set ours beside."""

from __future__ import annotations

import math

nan = math.nan

#: Table IV: mean steps per episode, t-test over the 9 epsilons (epsilon-greedy = Variable 1, proposed = Variable 2).
TABLE_IV: dict[str, tuple[float, float]] = {
    "Mean": (67.02, 56.28),
    "Variance": (1626.05, 9.80),
    "Observations": (9, 9),
    "Pearson Correlation": (0.36, nan),
    "Hypothesized Mean Difference": (0, nan),
    "df": (8, nan),
    "t Stat": (0.82, nan),
    "P(T<=t) two-tail": (0.44, nan),
}

#: Table V: total steps before the optimal path is found.
TABLE_V: dict[str, tuple[float, float]] = {
    "Mean": (110190.20, 99357.56),
    "Variance": (76689863, 53278480),
    "Observations": (9, 9),
    "Pearson Correlation": (-0.0623, nan),
    "Hypothesized Mean Difference": (0, nan),
    "df": (8, nan),
    "t Stat": (2.77, nan),
    "P(T<=t) one-tail": (0.01, nan),
}

EPISODES_TO_OPTIMAL = 27.35  # affective agent
STEPS_PER_EPISODE_AFFECTIVE = 56.28
EQUIVALENT_EPSILON_EARLY = 0.3
EQUIVALENT_EPSILON_LATE = 0.1
