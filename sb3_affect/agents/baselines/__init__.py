"""
Fair baselines for the affective agent: SB3-style tabular agents on the same loop, env and episode log.

- ``DecayingEpsilonGreedy``: epsilon-greedy with epsilon decaying over episodes (plain-data schedule).
- ``Boltzmann``: softmax exploration with a fixed, scheduled or episode-decaying temperature.
- ``UCBQLearning``: UCB1 count bonus per cell.
- ``OptimisticQLearning``: optimistic initial Q-values, greedy policy.
- ``SpeedEpsilonGreedy``: epsilon-greedy moving 1 or 2 cells per decision, like the affective agent.

In experiment files: ``algo: "sb3_affect.agents.baselines:Boltzmann"`` and so on.
"""

from sb3_affect.agents.baselines.boltzmann import Boltzmann, softmax_action
from sb3_affect.agents.baselines.decaying import DecayingEpsilonGreedy
from sb3_affect.agents.baselines.optimistic import OptimisticQLearning
from sb3_affect.agents.baselines.speed import SpeedEpsilonGreedy
from sb3_affect.agents.baselines.ucb import UCBQLearning

__all__ = [
    "Boltzmann",
    "DecayingEpsilonGreedy",
    "OptimisticQLearning",
    "SpeedEpsilonGreedy",
    "UCBQLearning",
    "softmax_action",
]
