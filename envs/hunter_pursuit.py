"""HunterPursuit: several hunters pursue one prey, a PettingZoo ``ParallelEnv`` (Kuremoto et al.'s pursuit problem)."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

try:
    from pettingzoo import ParallelEnv
except ImportError as error:  # one line naming the extra (the envs import nothing of the package but the envs)
    raise ImportError(
        f"the multi-agent pursuit env (HunterPursuit) needs the 'hunters' extra ({error}): pip install \"sb3-affect[hunters]\""
    ) from None

from sb3_affect.envs.grid_pursuit import MOVES, PREY_MODES, _as_cell, build_transitions, check_size, distances_to
from sb3_affect.envs.maze import load_maze

#: The action that leaves a hunter where it is (0-3 are ``MOVES``: up, down, left, right).
STAY = len(MOVES)
CAPTURE_MODES = ("enter", "surround")
OBSERVATION_MODES = ("self", "all")
#: Kuremoto et al.'s layout: a 17 x 17 grid, the prey at (9, 9), two hunters from (2, 2) and (14, 14).
KUREMOTO_STARTS: tuple[tuple[int, int], ...] = ((2, 2), (14, 14))


class HunterPursuitEnv(ParallelEnv):
    """
    Several hunters (agents ``hunter_0``, ``hunter_1``, ...) pursue one prey on a square grid, all moving at once.

    The defaults are Kuremoto et al.'s pursuit problem: a 17 x 17 grid, a prey that does not move at (9, 9), two
    hunters starting at (2, 2) and (14, 14) (cells are ``(row, col)`` from 0, as in the package's other envs).

    ## Actions
    ``Discrete(5)`` per hunter: 0 up, 1 down, 2 left, 3 right (one cell; off the grid or into an obstacle stays
    put), 4 stay. Hunters may share a cell.

    ## One step
    All hunters move at once. With ``capture="enter"`` a hunter that enters the prey's cell captures it. Otherwise,
    with probability ``prey_speed``, the prey moves one cell (``prey="random"``: one of the four directions uniformly;
    ``"evade"``: to the neighbouring cell, or staying, farthest from its nearest hunter by shortest-path distance,
    ties at random; ``"static"``: never). The prey never moves onto a hunter.

    ## Capture (``capture``)

    - ``"enter"`` (default): a hunter entering the prey's cell. The capturers (every hunter that entered it in
      that step) receive ``goal_reward``; the others ``step_reward``.
    - ``"surround"``: hunters can not enter the prey's cell (a move into it stays put, like a wall); the prey is
      captured when every hunter stands on a different cell orthogonally next to it (checked after the hunters
      move and again after the prey moves). Every hunter receives ``goal_reward``. Needs at most as many hunters as
      the prey's start has free neighbours.

    A capture ends the episode for every hunter (``terminations`` all True; ``infos[h]["capturer"]`` says who was
    rewarded for it). ``max_cycles`` (default: none) truncates an episode after that many steps.

    ## Observations (``observation``)
    Cells are ``row * size + col`` and ``n = size * size``. Each hunter observes one integer:

    - ``"self"`` (default): its own cell, ``Discrete(n)``; with a moving prey also the prey's cell,
      ``own * n + prey``, ``Discrete(n ** 2)``.
    - ``"all"``: its own cell, then the other hunters' cells in agent order (and the prey's when it moves), as
      digits in base ``n``, ``Discrete(n ** hunters)`` (``n ** (hunters + 1)`` with a moving prey). Large:
      289 ** 3 = 24 million states for two hunters and a moving prey on 17 x 17.

    A static prey's cell is a constant, so it is left out of the observation.

    ## Optimal capture
    ``capture_distance`` is the fewest one-cell moves in which the team could capture the prey at its start: with
    ``enter`` the shortest-path distance from the nearest hunter's start (10 on Kuremoto's layout, from (14, 14));
    with ``surround`` the smallest, over assignments of the hunters to different free neighbours of the prey, of the
    largest distance a hunter walks. An episode is an *optimal capture* (``optimal_capture``) when, with ``enter``, a
    hunter rewarded for the capture made at most ``capture_distance`` moves in the episode (for a static prey: the
    nearest hunter walked a shortest path), with ``surround`` when no hunter made more than ``capture_distance``
    moves. It counts each hunter's own moves, not env steps: a learner that sometimes moves two cells in one
    decision (AffectQ, ``sb3_affect.agents.hunter_team``) spreads a decision over two env steps without slowing its teammates.

    :param size: grid side (int >= 2); ignored when ``maze`` is given
    :param starts: each hunter's first cell (row, col); their number is the number of hunters (default Kuremoto's
        two; with a maze, one hunter at its ``S``)
    :param prey_start: the prey's first cell (row, col)
    :param obstacles: cells nobody can enter
    :param maze: a shipped maze name or a text map file (``G`` the prey's start, ``S`` the default hunter start);
        replaces size, prey_start and obstacles
    :param prey: ``"static"``, ``"random"`` or ``"evade"``
    :param prey_speed: probability that a moving prey moves after each step, in [0, 1]
    :param capture: ``"enter"`` or ``"surround"`` (above)
    :param observation: ``"self"`` or ``"all"`` (above)
    :param goal_reward: reward of a capture (> 0)
    :param step_reward: reward of every other step
    :param max_cycles: truncate an episode after this many steps (None: never)
    :param render_mode: ``None`` or ``"ansi"``
    """

    metadata: dict[str, Any] = {"name": "hunter_pursuit_v0", "render_modes": ["ansi"], "is_parallelizable": True}

    def __init__(
        self,
        size: int = 17,
        starts: Sequence[Sequence[int]] | None = None,
        prey_start: Sequence[int] = (9, 9),
        obstacles: Iterable[Sequence[int]] = (),
        maze: str | os.PathLike[str] | None = None,
        prey: str = "static",
        prey_speed: float = 0.5,
        capture: str = "enter",
        observation: str = "self",
        goal_reward: float = 100.0,
        step_reward: float = 0.0,
        max_cycles: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        if maze is not None:
            parsed = load_maze(maze)
            size, prey_start, obstacles = parsed.size, parsed.goal, parsed.obstacles
            starts = starts if starts is not None else (parsed.start,)
        if starts is None:
            starts = KUREMOTO_STARTS
        self.size = check_size(size)
        if isinstance(starts, (str, bytes)) or not isinstance(starts, Sequence) or len(starts) < 1:
            raise ValueError(f"starts must be a non-empty list of (row, col) cells, one per hunter, got {starts!r}")
        self.starts = tuple(_as_cell(f"starts[{i}]", s, self.size) for i, s in enumerate(starts))
        self.prey_start = _as_cell("prey_start", prey_start, self.size)
        if isinstance(obstacles, (str, bytes)):
            raise TypeError(f"obstacles must be a list of (row, col) pairs, got {obstacles!r}")
        self.obstacles = tuple(sorted({_as_cell(f"obstacles[{i}]", o, self.size) for i, o in enumerate(obstacles)}))
        for i, cell in enumerate(self.starts):
            if cell == self.prey_start:
                raise ValueError(f"starts[{i}]={cell} equals prey_start: the prey would be caught before the episode begins")
            if cell in self.obstacles:
                raise ValueError(f"starts[{i}]={cell} is on an obstacle")
        if self.prey_start in self.obstacles:
            raise ValueError(f"prey_start={self.prey_start} is on an obstacle")
        for name, value, allowed in (
            ("prey", prey, PREY_MODES),
            ("capture", capture, CAPTURE_MODES),
            ("observation", observation, OBSERVATION_MODES),
        ):
            if value not in allowed:
                raise ValueError(f"{name}={value!r} is not supported; choose one of {', '.join(map(repr, allowed))}")
        if isinstance(prey_speed, bool) or not isinstance(prey_speed, (int, float)) or not 0.0 <= prey_speed <= 1.0:
            raise ValueError(f"prey_speed={prey_speed!r} must be a probability in [0, 1]")
        for reward_name, reward in (("goal_reward", goal_reward), ("step_reward", step_reward)):
            if isinstance(reward, bool) or not isinstance(reward, (int, float)) or not np.isfinite(reward):
                raise ValueError(f"{reward_name}={reward!r} must be a finite number")
        if goal_reward <= 0:
            raise ValueError(f"goal_reward={goal_reward!r} must be > 0 (a capture must be worth it)")
        if max_cycles is not None and (isinstance(max_cycles, bool) or not isinstance(max_cycles, int) or max_cycles < 1):
            raise ValueError(f"max_cycles={max_cycles!r} must be None or an integer >= 1")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not supported; use None or 'ansi'")
        self.prey = prey
        self.prey_speed = float(prey_speed) if prey != "static" else 0.0
        self.capture = capture
        self.observation = observation
        self.goal_reward = float(goal_reward)
        self.step_reward = float(step_reward)
        self.max_cycles = max_cycles
        self.render_mode = render_mode

        self.n_cells = self.size * self.size
        self._pair_distances: dict[int, list[float]] = {}
        self.cell_transitions = build_transitions(self.size, [r * self.size + c for r, c in self.obstacles])
        self.hunter_start_cells = tuple(r * self.size + c for r, c in self.starts)
        self.prey_start_cell = self.prey_start[0] * self.size + self.prey_start[1]
        self.possible_agents = [f"hunter_{i}" for i in range(len(self.starts))]
        self.agents: list[str] = []
        self.capture_distance = self._capture_distance()
        digits = (len(self.starts) if observation == "all" else 1) + (self.prey != "static")
        self._observation_spaces = {a: spaces.Discrete(self.n_cells**digits) for a in self.possible_agents}
        self._action_spaces = {a: spaces.Discrete(len(MOVES) + 1) for a in self.possible_agents}
        self.hunters = list(self.hunter_start_cells)
        self.prey_cell = self.prey_start_cell
        self.steps = 0
        self.np_random, _ = seeding.np_random(None)

    # -- geometry ------------------------------------------------------------------------------------------------
    def distances_to(self, cell: int) -> list[float]:
        """Shortest one-cell-move distances from every cell to ``cell`` (cached)."""
        if cell not in self._pair_distances:
            self._pair_distances[cell] = distances_to(cell, self.cell_transitions)
        return self._pair_distances[cell]

    def _free_neighbours(self, cell: int) -> list[int]:
        return sorted({t for t in self.cell_transitions[cell] if t != cell})

    def _capture_distance(self) -> int:
        if self.capture == "enter":
            far = self.distances_to(self.prey_start_cell)
            best = min(far[c] for c in self.hunter_start_cells)
        else:
            neighbours = self._free_neighbours(self.prey_start_cell)
            if len(neighbours) < len(self.starts):
                raise ValueError(
                    f"capture='surround' needs every hunter on a different free neighbour of the prey, but prey_start="
                    f"{self.prey_start} has {len(neighbours)} free neighbours for {len(self.starts)} hunters"
                )
            tables = {c: self.distances_to(c) for c in neighbours}
            best = min(
                max(tables[c][h] for c, h in zip(cells, self.hunter_start_cells))
                for cells in itertools.permutations(neighbours, len(self.starts))
            )
        if best == float("inf"):
            raise ValueError(f"the prey at {self.prey_start} can not be captured from starts={list(self.starts)}: walled off")
        return int(best)

    def optimal_capture(self, moves: Sequence[int], capturers: Sequence[int]) -> bool:
        """
        Whether an episode was an optimal capture (see the class docstring).

        :param moves: each hunter's one-cell moves in the episode (bumps into walls count), in agent order
        :param capturers: indices of the hunters rewarded for the capture (empty: no capture)
        """
        if not capturers:
            return False
        if self.capture == "enter":
            return min(int(moves[i]) for i in capturers) <= self.capture_distance
        return max(int(m) for m in moves) <= self.capture_distance

    def encode(self, agent_index: int) -> int:
        """The observation of hunter ``agent_index`` in the current state."""
        n = self.n_cells
        cells = [self.hunters[agent_index]]
        if self.observation == "all":
            cells += [c for i, c in enumerate(self.hunters) if i != agent_index]
        if self.prey != "static":
            cells.append(self.prey_cell)
        value = 0
        for c in cells:
            value = value * n + c
        return value

    # -- PettingZoo API ------------------------------------------------------------------------------------------
    def observation_space(self, agent: str) -> spaces.Space:
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_spaces[agent]

    def _observations(self) -> dict[str, int]:
        return {a: self.encode(i) for i, a in enumerate(self.possible_agents)}

    def _info(self, i: int, moved: bool = False, captured: bool = False, capturer: bool = False) -> dict[str, Any]:
        return {
            "cell": divmod(self.hunters[i], self.size),
            "prey": divmod(self.prey_cell, self.size),
            "moved": moved,
            "captured": captured,
            "capturer": capturer,
        }

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        if seed is not None:
            self.np_random, _ = seeding.np_random(seed)
        self.agents = list(self.possible_agents)
        self.hunters = list(self.hunter_start_cells)
        self.prey_cell = self.prey_start_cell
        self.steps = 0
        return self._observations(), {a: self._info(i) for i, a in enumerate(self.possible_agents)}

    def _surrounded(self) -> bool:
        neighbours = set(self._free_neighbours(self.prey_cell))
        return len(set(self.hunters)) == len(self.hunters) and all(h in neighbours for h in self.hunters)

    def _move_prey(self) -> None:
        if self.prey_speed <= 0.0 or self.np_random.random() >= self.prey_speed:
            return
        rng = self.np_random
        options = self.cell_transitions[self.prey_cell]
        occupied = set(self.hunters)
        if self.prey == "random":
            target = options[int(rng.integers(len(options)))]
        else:
            tables = [self.distances_to(h) for h in occupied]
            candidates = sorted({self.prey_cell, *options} - occupied)
            if not candidates:
                return
            score = {c: min(t[c] for t in tables) for c in candidates}
            best = max(score.values())
            ties = [c for c in candidates if score[c] == best]
            target = ties[int(rng.integers(len(ties)))]
        if target not in occupied:
            self.prey_cell = target

    def step(
        self, actions: dict[str, Any]
    ) -> tuple[dict[str, Any], dict[str, float], dict[str, bool], dict[str, bool], dict[str, dict[str, Any]]]:
        if not self.agents:
            raise RuntimeError("step() after the episode ended: call reset() first")
        moved = []
        for i, agent in enumerate(self.possible_agents):
            if agent not in actions:
                raise KeyError(f"no action for {agent}: a step needs one action per hunter ({', '.join(self.agents)})")
            action = int(actions[agent])
            if not 0 <= action <= STAY:
                raise ValueError(f"actions[{agent!r}]={action} is not in Discrete({STAY + 1})")
            before = self.hunters[i]
            target = before if action == STAY else self.cell_transitions[before][action]
            if self.capture == "surround" and target == self.prey_cell:
                target = before
            self.hunters[i] = target
            moved.append(target != before)
        self.steps += 1
        if self.capture == "enter":
            capturers = [h == self.prey_cell for h in self.hunters]
            captured = any(capturers)
        else:
            captured = self._surrounded()
        if not captured:
            self._move_prey()
            if self.capture == "surround":
                captured = self._surrounded()
        if self.capture == "surround":
            capturers = [captured] * len(self.hunters)
        truncated = not captured and self.max_cycles is not None and self.steps >= self.max_cycles
        observations = self._observations()
        rewards = {a: self.goal_reward if capturers[i] else self.step_reward for i, a in enumerate(self.possible_agents)}
        terminations = dict.fromkeys(self.possible_agents, captured)
        truncations = dict.fromkeys(self.possible_agents, truncated)
        infos = {a: self._info(i, moved[i], captured, capturers[i]) for i, a in enumerate(self.possible_agents)}
        if captured or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def render(self) -> str | None:
        if self.render_mode != "ansi":
            return None
        blocked = set(self.obstacles)
        lines = []
        for r in range(self.size):
            row = []
            for c in range(self.size):
                s = r * self.size + c
                mark = "P" if s == self.prey_cell else "#" if (r, c) in blocked else "."
                for i, h in enumerate(self.hunters):
                    if h == s:
                        mark = str(i) if len(self.hunters) <= 10 else "H"
                row.append(mark)
            lines.append(" ".join(row))
        return "\n".join(lines) + "\n"

    def close(self) -> None:
        pass


def parallel_env(**kwargs: Any) -> HunterPursuitEnv:
    """PettingZoo-style constructor: ``parallel_env()`` is Kuremoto's layout; keywords as ``HunterPursuitEnv``."""
    return HunterPursuitEnv(**kwargs)
