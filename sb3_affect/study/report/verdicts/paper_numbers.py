"""
The paper's own numbers and sentences, copied verbatim from Badoy & Teknomo, "Q-Learning with Basic Emotions"
(HNICEM 2014, arXiv 1609.01468), each with where it is printed, to set ours beside (docs/definitions.md, "The
paper's numbers").

Numbers are kept exactly as printed (as strings too, so "0.00" and "110190.20" keep their digits).
"""

from __future__ import annotations

import math

nan = math.nan

#: Table IV ("T-test comparison for average number of steps per episode", Sec. V), as printed:
#: (epsilon-greedy selection, proposed); "" where the paper leaves the cell empty.
TABLE_IV_PRINTED: dict[str, tuple[str, str]] = {
    "Mean": ("67.02", "56.28"),
    "Variance": ("1626.05", "9.80"),
    "Observations": ("9", "9"),
    "Pearson Correlation": ("0.36", ""),
    "Hypothesized Mean Difference": ("0.00", ""),
    "df": ("8", ""),
    "t Stat": ("0.82", ""),
    "P(T<=t) one-tail": ("0.22", ""),
    "t Critical one-tail": ("1.86", ""),
    "P(T<=t) two-tail": ("0.44", ""),
    "t Critical two-tail": ("2.31", ""),
}

#: Table V ("T-test comparison for total number of steps before optimal path is found", Sec. V), as printed.
TABLE_V_PRINTED: dict[str, tuple[str, str]] = {
    "Mean": ("110190.20", "99357.56"),
    "Variance": ("76689863", "53278480"),
    "Observations": ("9", "9"),
    "Pearson Correlation": ("-0.0623", ""),
    "Hypothesized Mean Difference": ("0", ""),
    "df": ("8", ""),
    "t Stat": ("2.77", ""),
    "P(T<=t) one-tail": ("0.01", ""),
    "t Critical one-tail": ("1.86", ""),
    "P(T<=t) two-tail": ("0.02", ""),
    "t Critical two-tail": ("2.31", ""),
}


def _numbers(printed: dict[str, tuple[str, str]]) -> dict[str, tuple[float, float]]:
    return {row: (float(a) if a else nan, float(b) if b else nan) for row, (a, b) in printed.items()}


#: The same tables as numbers (epsilon-greedy = Variable 1, proposed = Variable 2).
TABLE_IV: dict[str, tuple[float, float]] = _numbers(TABLE_IV_PRINTED)
TABLE_V: dict[str, tuple[float, float]] = _numbers(TABLE_V_PRINTED)

EPISODES_TO_OPTIMAL = 27.35  # Sec. V, text beside Fig. 6
STEPS_PER_EPISODE_AFFECTIVE = 56.28  # Table IV
EQUIVALENT_EPSILON_EARLY = 0.3  # Sec. V, Fig. 6 text: "starting high reaching about 0.3"
EQUIVALENT_EPSILON_LATE = 0.1  # "decreasing to 0.1 near the end"
#: The paper's protocol (Sec. IV): "20 simulations with 200 episodes each, for each value of epsilon".
SEEDS_PER_CELL = 20
EPSILONS: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)

#: The paper's sentences the verdict judges, verbatim, with where they are printed.
QUOTES: dict[str, tuple[str, str]] = {
    "table_iv": (
        "Table IV doesn't show significant difference between the two agents in terms of number of steps per episode",
        "Sec. V, text above Table IV; Table IV",
    ),
    "fig3": (
        "Fig. 3 shows that for epsilon below 0.5, the standard agent has lower step count per episode, and above 0.6, "
        "the proposed agent performs better.",
        "Sec. V, text above Table IV (Fig. 3)",
    ),
    "table_v": (
        "T-test shows that in finding the optimal path, the proposed affective agent performs better.",
        "Sec. V, text above Table V; Table V",
    ),
    "fig4": (
        "This is evident in Fig. 4 which shows the proposed agent has lesser number of steps except when ε = 0.7.",
        "Sec. V, text above Table V (Fig. 4)",
    ),
    "episodes_to_optimal": (
        "for the proposed affective agent, the average number of episodes required to find the optimal path is 27.35.",
        "Sec. V, text beside Fig. 6",
    ),
    "fig5": (
        "joy being the dominant emotion in the earlier episodes, which would be superseded by anger in the latter "
        "episodes. Fig. 5 shows you this behavior.",
        "Sec. V, text beside Fig. 5",
    ),
    "fig6": (
        "The figure shows a varying ε throughout the simulation, starting high reaching about 0.3 and decreasing to "
        "0.1 near the end.",
        "Sec. V, text beside Fig. 6",
    ),
    "long_run": (
        "in the long run, the total number of steps of the affective agent will be lower than that of the standard "
        "Q-learning agent.",
        "Sec. VI (Conclusion)",
    ),
    "printed_iv": (
        "Mean: 67.02 (epsilon-greedy selection), 56.28 (proposed)",
        "Table IV, row Mean",
    ),
    "printed_v": (
        "Mean: 110190.20 (epsilon-greedy selection), 99357.56 (proposed)",
        "Table V, row Mean",
    ),
    "four_emotions": (
        "we propose using four basic emotions: joy, sadness, fear, and anger to influence a Q-learning agent.",
        "Abstract; Table II",
    ),
}
