"""MovingPursuit: the pursuit grid with a prey that moves (the paper's Sec. VI future work)."""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_affect.envs.grid_pursuit import MOVES, PREY_MODES, _as_cell, build_transitions, check_size, distances_to
from sb3_affect.envs.maze import load_maze


class MovingPursuitEnv(gym.Env[Any, Any]):
    """
    A hunter (the agent) pursues a prey that random-walks or evades, on a square grid (optionally a maze).

    ## Dynamics
    Each step the hunter moves one cell (``Discrete(4)``: up, down, left, right; a move off the grid or into a wall
    leaves it in place). If it enters the prey's cell the prey is captured: reward ``goal_reward``, the episode
    terminates. Otherwise, with probability ``prey_speed``, the prey moves one cell:

    - ``prey="random"``: in one of the four directions, uniformly (a move into a wall or the grid's edge leaves it
      in place);
    - ``prey="evade"``: to the neighbouring cell (or staying) that is farthest from the hunter by shortest-path
      distance, ties at random;
    - ``prey="static"``: never (GridPursuit's task, with the joint observation).

    The prey never moves onto the hunter (it stays instead), so a capture is always the hunter's move. A prey as
    fast as the hunter (``prey_speed=1``) that evades can not be caught on an open grid by one hunter (a grid's cop
    number is 2), so evading prey should be slower; the default is a random walk at half the hunter's speed.

    ## Observation space
    ``Discrete(n * n)`` with ``n = size * size`` cells: ``hunter_cell * n + prey_cell`` (cells as ``row * size + col``),
    so tabular agents see a Markov state. The hunter-x-prey table is n times larger than GridPursuit's (50,625 states on
    15 x 15), so learning takes more episodes.

    ## What "optimal" means here
    ``capture_distance`` is the shortest-path distance from the hunter's start to the prey's start: the fewest cells
    that capture the prey from that start if it stood still. An episode is an *optimal capture* when the hunter
    captures the prey within ``capture_distance`` cells (``optimal_capture(cells, captured)``): it closed in as
    directly as the static optimum allows. A prey that flees can make that impossible in a given episode, one that
    wanders towards the hunter makes it easier, so it is a property of an episode, not a policy guarantee. The env
    deliberately does **not** expose GridPursuit's geometry attributes (``transitions``, ``distances``,
    ``shortest_path_length``): they assume a fixed goal. So the generic episode log has NaN in ``optimal`` and
    ``greedy_optimal`` for this env, and "steps before the optimal path" is computed from ``cells`` and
    ``truncated`` with ``optimal_capture`` (``sb3_affect.study.report.sections.beyond`` does).

    ## The affective appraisal's known map
    The appraiser's known map is over observations, i.e. hunter-x-prey pairs: its edges are the joint transitions
    the agent has experienced (the hunter's move followed by the prey's), and its goals are the capture
    observations (hunter and prey in the same cell). The known remaining distance of a state is therefore the fewest
    cells to a capture along transitions seen so far, an optimistic (best-case prey) estimate; ``act`` keeps its
    previous value in states from which no capture is known, which early on is most of them.

    ## Arguments

    :param size: grid side (int >= 2); ignored when ``maze`` is given
    :param start: the hunter's first cell (row, col)
    :param prey_start: the prey's first cell (row, col)
    :param obstacles: cells neither can enter
    :param maze: a shipped maze name or a text map file (``S`` hunter start, ``G`` prey start); replaces size, start,
        prey_start and obstacles
    :param prey: ``"random"``, ``"evade"`` or ``"static"``
    :param prey_speed: probability that the prey moves after each hunter move, in [0, 1]
    :param goal_reward: reward of a capture (> 0)
    :param step_reward: reward of every other move
    :param render_mode: ``None`` or ``"ansi"``
    """

    metadata = {"render_modes": ["ansi"], "render_fps": 8}

    def __init__(
        self,
        size: int = 15,
        start: Sequence[int] = (0, 0),
        prey_start: Sequence[int] = (6, 6),
        obstacles: Iterable[Sequence[int]] = (),
        maze: str | os.PathLike[str] | None = None,
        prey: str = "random",
        prey_speed: float = 0.5,
        goal_reward: float = 100.0,
        step_reward: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        if maze is not None:
            parsed = load_maze(maze)
            size, start, prey_start, obstacles = parsed.size, parsed.start, parsed.goal, parsed.obstacles
        self.size = check_size(size)
        self.start = _as_cell("start", start, self.size)
        self.prey_start = _as_cell("prey_start", prey_start, self.size)
        if self.start == self.prey_start:
            raise ValueError(f"start={self.start} equals prey_start: the prey would be caught before the episode begins")
        if isinstance(obstacles, (str, bytes)):
            raise TypeError(f"obstacles must be a list of (row, col) pairs, got {obstacles!r}")
        self.obstacles = tuple(sorted({_as_cell(f"obstacles[{i}]", o, self.size) for i, o in enumerate(obstacles)}))
        for name, cell in (("start", self.start), ("prey_start", self.prey_start)):
            if cell in self.obstacles:
                raise ValueError(f"{name}={cell} is on an obstacle")
        if prey not in PREY_MODES:
            raise ValueError(f"prey={prey!r} is not supported; choose one of {', '.join(map(repr, PREY_MODES))}")
        if isinstance(prey_speed, bool) or not isinstance(prey_speed, (int, float)) or not 0.0 <= prey_speed <= 1.0:
            raise ValueError(f"prey_speed={prey_speed!r} must be a probability in [0, 1]")
        if not np.isfinite(goal_reward) or goal_reward <= 0:
            raise ValueError(f"goal_reward={goal_reward!r} must be a finite number > 0")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not supported; use None or 'ansi'")
        self.prey = prey
        self.prey_speed = float(prey_speed) if prey != "static" else 0.0
        self.goal_reward = float(goal_reward)
        self.step_reward = float(step_reward)
        self.render_mode = render_mode

        self.n_cells = self.size * self.size
        blocked = [r * self.size + c for r, c in self.obstacles]
        self.cell_transitions = build_transitions(self.size, blocked)
        self.hunter_start_cell = self.start[0] * self.size + self.start[1]
        self.prey_start_cell = self.prey_start[0] * self.size + self.prey_start[1]
        distance = distances_to(self.prey_start_cell, self.cell_transitions)[self.hunter_start_cell]
        if distance == float("inf"):
            raise ValueError(f"prey_start={self.prey_start} is unreachable from start={self.start}: the obstacles wall it off")
        self.capture_distance = int(distance)
        self._pair_distances: list[list[float]] | None = None
        self.observation_space = spaces.Discrete(self.n_cells * self.n_cells)
        self.action_space = spaces.Discrete(len(MOVES))
        self.initial_state = self.hunter_start_cell * self.n_cells + self.prey_start_cell
        self.hunter = self.hunter_start_cell
        self.prey_cell = self.prey_start_cell

    # -- helpers ---------------------------------------------------------------------------------------------
    def encode(self, hunter_cell: int, prey_cell: int) -> int:
        """The observation of a hunter cell and a prey cell."""
        return hunter_cell * self.n_cells + prey_cell

    def decode(self, observation: int) -> tuple[tuple[int, int], tuple[int, int]]:
        """``((hunter row, col), (prey row, col))`` of an observation."""
        hunter, prey = divmod(int(observation), self.n_cells)
        return divmod(hunter, self.size), divmod(prey, self.size)

    def optimal_capture(self, cells: int, captured: bool) -> bool:
        """An episode that captured the prey within ``capture_distance`` cells (see the class docstring)."""
        return bool(captured) and int(cells) <= self.capture_distance

    def transition_table(self) -> str:
        """Why this env has no transition table (``sb3_affect.envs.transition_table``) for the compiled engine."""
        return (
            "MovingPursuit's prey moves at random, so its moves are no fixed transition table: the grid kernel can "
            "not step it (its own kernel, sb3_affect.kernel.moving_loop, does)"
        )

    def _distances(self) -> list[list[float]]:
        if self._pair_distances is None:
            self._pair_distances = [distances_to(c, self.cell_transitions) for c in range(self.n_cells)]
        return self._pair_distances

    def _move_prey(self) -> None:
        rng = self.np_random
        if self.prey_speed <= 0.0 or rng.random() >= self.prey_speed:
            return
        options = self.cell_transitions[self.prey_cell]
        if self.prey == "random":
            target = options[int(rng.integers(len(options)))]
        else:
            far = self._distances()[self.hunter]
            candidates = [self.prey_cell, *options]
            best = max(far[c] for c in candidates if c != self.hunter)
            ties = sorted({c for c in candidates if c != self.hunter and far[c] == best})
            target = ties[int(rng.integers(len(ties)))]
        if target != self.hunter:
            self.prey_cell = target

    # -- gymnasium API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.hunter = self.hunter_start_cell
        self.prey_cell = self.prey_start_cell
        return self.initial_state, {"cell": self.start, "prey": self.prey_start}

    def step(self, action: Any) -> tuple[int, SupportsFloat, bool, bool, dict[str, Any]]:
        before = self.hunter
        self.hunter = self.cell_transitions[before][int(action)]
        captured = self.hunter == self.prey_cell
        if not captured:
            self._move_prey()
        info = {
            "cell": divmod(self.hunter, self.size),
            "prey": divmod(self.prey_cell, self.size),
            "moved": self.hunter != before,
        }
        reward = self.goal_reward if captured else self.step_reward
        return self.hunter * self.n_cells + self.prey_cell, reward, captured, False, info

    def render(self) -> str | None:
        if self.render_mode != "ansi":
            return None
        blocked = set(self.obstacles)
        lines = []
        for r in range(self.size):
            row = []
            for c in range(self.size):
                s = r * self.size + c
                row.append("H" if s == self.hunter else "P" if s == self.prey_cell else "#" if (r, c) in blocked else ".")
            lines.append(" ".join(row))
        return "\n".join(lines) + "\n"
