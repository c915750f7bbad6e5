"""
The tasks beyond the paper and the agents run on them through the engine (``beyond_cells``): the paper's static grid,
moving prey (random walk and evading) and two mazes; the affective agent, ε-greedy at the paper's ε 0.1, and
ε-greedy and the speed-matched ε-greedy with ε tuned on each task (``report.tuning``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from sb3_affect.study.report.engine_studies import PAPER_ENV, Cell

#: Tasks beyond the paper run through the engine: (task label, env id, env kwargs).
TASKS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("static grid 15x15 (the paper's task)", PAPER_ENV[0], dict(PAPER_ENV[1])),
    ("moving prey 7x7 (random walk)", "sb3_affect/MovingPursuit-v0",
     {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "random", "prey_speed": 0.5}),
    ("evading prey 7x7", "sb3_affect/MovingPursuit-v0",
     {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "evade", "prey_speed": 0.5}),
    ("maze: wall", "sb3_affect/MazePursuit-v0", {"maze": "wall"}),
    ("maze: rooms", "sb3_affect/MazePursuit-v0", {"maze": "rooms"}),
)  # fmt: skip
#: Agents with fixed settings on every task: (name, algo, kwargs).
BEYOND_AGENTS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("affective", "AffectQ", {}),
    ("epsilon-greedy 0.1", "QLearning", {"exploration_rate": 0.1}),
)
#: Agents whose ε is tuned on each task (``report.tuning``): (name, algo, kwargs without ``exploration_rate``).
TUNED_AGENTS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("epsilon-greedy, tuned ε", "QLearning", {}),
    ("speed-epsilon-greedy, tuned ε", "sb3_affect.agents.baselines:SpeedEpsilonGreedy", {"speeds": [1, 2]}),
)
#: Safety cap of the tasks beyond the paper: an episode of this many decisions is truncated (and counted).
BEYOND_CAP = 2000
#: The sweep name the evaluation seeds derive from (``derive_seed("beyond", agent, {"task": task}, r)``).
SWEEP = "beyond"


def beyond_cells(tuned: Mapping[tuple[str, str], float]) -> list[Cell]:
    """
    Every (task, agent) of the study beyond the paper. Seeds: sweep ``SWEEP``, point ``{"task": task}``, the same per
    agent whatever its ε.

    :param tuned: the ε of each tuned agent on each task, keyed ``(task, agent)`` (``report.tuning.run_tuning``)
    """
    missing = [(task, agent) for task, _, _ in TASKS for agent, _, _ in TUNED_AGENTS if (task, agent) not in tuned]
    if missing:
        raise ValueError(f"no tuned ε for {', '.join(f'{a} on {t}' for t, a in missing)} (run the tuning first)")
    cells = []
    for task, env_id, env_kwargs in TASKS:
        for agent, algo, kwargs in BEYOND_AGENTS:
            cap = {**kwargs, "max_episode_decisions": BEYOND_CAP}
            cells.append(Cell(agent, algo, cap, {"task": task}, SWEEP, {"task": task}, env_id, env_kwargs))
        for agent, algo, kwargs in TUNED_AGENTS:
            eps = float(tuned[(task, agent)])
            cap = {**kwargs, "exploration_rate": eps, "max_episode_decisions": BEYOND_CAP}
            cells.append(Cell(agent, algo, cap, {"task": task, "epsilon": eps}, SWEEP, {"task": task}, env_id, env_kwargs))
    return cells
