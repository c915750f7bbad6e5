"""
HunterPursuit's own pieces in numba (``envs.hunter_pursuit.HunterPursuitEnv`` is the reference): a hunter's observation
(``encode``), the surround test (``surrounded``) and the prey's move after a step (``team_prey``: a random walk, or
the evading prey's candidate farthest from its nearest hunter, ties sorted and drawn with the env's generator).
"""

from __future__ import annotations

import math

import numpy as np

from sb3_affect.kernel.choice import insert_tie
from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.pcg64 import integers, random01
from sb3_affect.kernel.state_layout import PREY_RANDOM


@kernel_inline
def encode(hunters: np.ndarray, prey: int, i: int, n_cells: int, obs_all: bool, prey_moves: bool) -> int:
    """``HunterPursuitEnv.encode(i)``: hunter ``i``'s cell, the others' (``"all"``), the prey's (moving prey)."""
    value = hunters[i]
    if obs_all:
        for j in range(hunters.shape[0]):
            if j != i:
                value = value * n_cells + hunters[j]
    if prey_moves:
        value = value * n_cells + prey
    return value


@kernel_inline
def surrounded(hunters: np.ndarray, prey: int, cell_trans: np.ndarray) -> bool:
    """``HunterPursuitEnv._surrounded``: every hunter on a different free neighbour of the prey."""
    n = hunters.shape[0]
    for i in range(n):
        h = hunters[i]
        for j in range(i):
            if hunters[j] == h:
                return False
        if h == prey:
            return False
        neighbour = False
        for a in range(cell_trans.shape[1]):
            if cell_trans[prey, a] == h:
                neighbour = True
        if not neighbour:
            return False
    return True


@kernel_jit
def team_prey(
    pcg: np.ndarray,
    cell_trans: np.ndarray,
    far: np.ndarray,
    prey_kind: int,
    speed: float,
    hunters: np.ndarray,
    prey: int,
    ties: np.ndarray,
) -> int:
    """``HunterPursuitEnv._move_prey``: the prey's cell after its chance to move (``ties``: work space, 5 entries)."""
    if speed <= 0.0 or random01(pcg) >= speed:
        return prey
    n_moves = cell_trans.shape[1]
    if prey_kind == PREY_RANDOM:
        target = cell_trans[prey, integers(pcg, n_moves)]
    else:
        # the candidates (staying or a move, not a hunter's cell) farthest from their nearest hunter; sorted ties
        best = -math.inf
        count = 0
        for j in range(n_moves + 1):
            c = prey if j == 0 else cell_trans[prey, j - 1]
            occupied = False
            d = math.inf
            for i in range(hunters.shape[0]):
                h = hunters[i]
                occupied |= h == c
                d = min(d, far[h, c])
            if occupied:
                continue
            if d > best:
                best = d
                count = 0
            if d == best:
                count = insert_tie(ties, count, c)
        if count == 0:
            return prey
        target = ties[integers(pcg, count)]
    for i in range(hunters.shape[0]):
        if hunters[i] == target:
            return prey
    return target
