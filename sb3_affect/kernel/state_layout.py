"""
The index tables every world's loop shares (the grid's ``kernel.grid_loop``, moving prey's ``kernel.moving_loop``,
hunter teams' ``kernel.team_loop``): the run's state arrays (``ist``: ints, ``fst``: floats) and an episode's row
(``O_*``: its int columns, ``F_*``: its float columns), and the prey's modes as the kernel codes them. Each world adds
only its own tail after these heads (moving prey: the hunter's and the prey's cells; a team: each hunter's decision
in progress and its observer), numbered from ``N_IST`` and ``N_FST``.
"""

from __future__ import annotations

from sb3_affect.envs.grid_pursuit import PREY_MODES

#: The prey's modes (``PREY_MODES`` of the envs): the kernel's code of a mode is its index there.
PREY_STATIC = PREY_MODES.index("static")
PREY_RANDOM = PREY_MODES.index("random")
PREY_EVADE = PREY_MODES.index("evade")

# ist: the run's int state (a world's own entries follow from N_IST)
(
    I_T,  # the run's decisions (num_timesteps)
    I_STATE,  # the agent's observation
    I_DECISIONS,
    I_CELLS,
    I_RANDOM,
    I_WAITS,
    I_JOY,
    I_SADNESS,
    I_FEAR,
    I_ANGER,
    I_CHANGED,  # the Q-table changed where the last greedy walk read it
    I_GREEDY,  # the greedy walk's last answer (-1: none yet)
    I_TL_ELAPSED,  # env steps the env's TimeLimit counted
    I_NFIT,  # the power fit's values
    I_EL_CELLS,
    I_EL_DECISIONS,
    I_LAST_ACTION,  # I_LAST_*: the last decision of the last finished episode (its callbacks' locals)
    I_LAST_PREV,
    I_LAST_S2,
    I_LAST_TERMINATED,
) = range(20)
N_IST = 20
# fst: the run's float state (a world's own entries follow from N_FST)
S_REWARD, S_NORM, S_LAST_ACT, S_LAST_REWARD, S_FIT0 = range(5)  # S_FIT0..S_FIT0+3: the power fit's running sums
N_FST = S_FIT0 + 4

# an episode's row: its int columns (``rows_i``; a world without a fixed goal leaves O_OPTIMAL and O_GREEDY unset)
(O_DECISIONS, O_CELLS, O_OPTIMAL, O_TRUNCATED, O_RANDOM, O_WAITS, O_JOY, O_SADNESS, O_FEAR, O_ANGER, O_GREEDY) = range(11)
N_OUT_I = 11
# and its float columns (``rows_f``; a team's hunter adds its observer's from N_OUT_F)
F_REWARD, F_NORM = range(2)
N_OUT_F = 2
