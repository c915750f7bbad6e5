"""MazePursuit: GridPursuit on a text map (see ``sb3_affect.envs.maze``)."""

from __future__ import annotations

import os

from sb3_affect.envs.grid_pursuit import GridPursuitEnv
from sb3_affect.envs.maze import load_maze


class MazePursuitEnv(GridPursuitEnv):
    """
    ``GridPursuitEnv`` whose size, start, goal and obstacles come from a text map: a shipped maze by name (``open``,
    ``wall``, ``rooms``, ``zigzag``) or a user's file. Same spaces, rewards, dynamics and geometry attributes
    (``transitions``, ``distances``, ``start_state``, ``shortest_path_length``) as GridPursuit, so the episode log's
    ``optimal`` and ``greedy_optimal`` columns keep their meaning (a shortest path around the walls).

    :param maze: a shipped maze name or the path of a text map
    :param goal_reward: reward on entering the goal (> 0)
    :param step_reward: reward of every other move
    :param render_mode: ``None``, ``"ansi"`` or ``"rgb_array"``
    """

    def __init__(
        self,
        maze: str | os.PathLike[str] = "open",
        goal_reward: float = 100.0,
        step_reward: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        self.maze = load_maze(maze)
        super().__init__(
            size=self.maze.size,
            start=self.maze.start,
            goal=self.maze.goal,
            obstacles=self.maze.obstacles,
            goal_reward=goal_reward,
            step_reward=step_reward,
            render_mode=render_mode,
        )
