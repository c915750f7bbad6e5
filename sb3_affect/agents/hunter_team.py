"""
Independent learners in one world: a team of the package's own tabular agents hunting together.

Each hunter of a ``HunterPursuitEnv`` (``sb3_affect.envs.hunter_pursuit``) is an ordinary ``QLearning``, ``AffectQ``
or baseline instance, built on a ``HunterView`` (its own Gymnasium window on the shared env), learning from its own
experience only and keeping its own ``episode_log``; teams may mix classes. ``DecisionStepper`` runs each agent's own
decision, update and bookkeeping code, so there is no second implementation of the agents.

## Time: rounds
Every hunter takes exactly one decision per *round*, so each hunter's decision count (``num_timesteps``, the paper's
"steps") is the team's number of rounds. A decision moves its hunter 0, 1 or 2 cells (AffectQ's speeds; QLearning
always 1). A round lasts as many env steps as its longest decision: in env step ``j`` every hunter whose decision has
more than ``j`` cells moves, the others stay (a round of waits takes no env step, as a wait takes no ``env.step``
in ``learn``). A moving prey gets its chance to move after every env step, as after every hunter move in
``MovingPursuit``.

## What each hunter learns from
Its own one-cell moves: each is one Eq. 1 update from the cell it left to its observation after the env step. While it
stands still (waiting, or its decision was shorter than the round) the world may change (others move, the prey
moves): its next decision starts from its observation then. A capture ends the episode for everyone. For the hunter(s)
rewarded for it (``infos[h]["capturer"]``) that made a move in that env step, the episode *terminated* at the goal;
for every other hunter it was *cut off*: its last update bootstraps from the cell it reached (as for a time limit) and
its episode-log row says ``truncated=True``. So a hunter's ``optimal`` column means that *it* captured the prey along
a shortest path, and the team's ``optimal`` is the env's ``optimal_capture`` of the hunters' moves (with ``"enter"``:
a capturer made no more one-cell moves than the nearest hunter's shortest path).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import pandas as pd
from gymnasium import spaces
from stable_baselines3.common.logger import Logger

from sb3_affect.agents.stepping import DecisionStepper
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.core.team_seeds import member_seed
from sb3_affect.envs.grid_pursuit import MOVES
from sb3_affect.envs.hunter_pursuit import STAY, HunterPursuitEnv

#: Columns of ``HunterTeam.episode_log``: the usual episode columns for the team, then who captured.
TEAM_COLUMNS: tuple[str, ...] = (*EPISODE_COLUMNS, "capturer")


class HunterView(gym.Env[Any, Any]):
    """
    One hunter's Gymnasium window on a team env: its observation space and the four moves. ``reset`` returns the
    hunter's current observation (it does not reset the shared env); ``step`` is refused: the team moves everyone.

    When the prey is static, captures are ``"enter"`` and the hunter observes its own cell, the view also exposes the
    geometry of the hunter's own task (``transitions``, ``distances``, ``start_state``, ``shortest_path_length``), so
    the agent's ``optimal``/``greedy_optimal`` columns mean what they mean on GridPursuit, for this hunter.

    :param env: the team env
    :param agent: the hunter's name (``"hunter_0"``, ...)
    """

    def __init__(self, env: HunterPursuitEnv, agent: str) -> None:
        self.agent = agent
        self.index = env.possible_agents.index(agent)
        self.observation_space = env.observation_space(agent)
        self.action_space = spaces.Discrete(len(MOVES))
        self.current = env.encode(self.index)
        if env.prey == "static" and env.capture == "enter" and env.observation == "self":
            self.transitions = env.cell_transitions
            self.distances = env.distances_to(env.prey_start_cell)
            self.start_state = env.hunter_start_cells[self.index]
            self.shortest_path_length = int(self.distances[self.start_state])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        return self.current, {}

    def step(self, action: Any) -> Any:
        raise RuntimeError(f"{self.agent}'s view is moved by its HunterTeam, not stepped directly (e.g. by learn())")


def _same(value: Any) -> Any:
    return value


class HunterTeam:
    """
    Independent tabular learners hunting together in one ``HunterPursuitEnv`` (see the module docstring).

    :param env: the team env (one hunter per member)
    :param members: one ``(algo, kwargs)`` per hunter, in agent order: the class (or its launcher name, e.g.
        ``"AffectQ"``, ``"sb3_affect.agents.baselines:Boltzmann"``) and its constructor arguments
    :param seed: the run's seed: the env's draws and, through ``member_seed``, each hunter's
    """

    def __init__(self, env: HunterPursuitEnv, members: Sequence[tuple[str | type, Mapping[str, Any]]], seed: int = 0) -> None:
        from sb3_affect.core.registry import resolve_class

        if not isinstance(env, HunterPursuitEnv):
            raise TypeError(f"env must be a HunterPursuitEnv, got {type(env).__name__}")
        if len(members) != len(env.possible_agents):
            raise ValueError(
                f"members: {len(members)} given for {len(env.possible_agents)} hunters ({', '.join(env.possible_agents)})"
            )
        self.env = env
        self.seed = int(seed)
        self._seeded = False
        self.models: dict[str, TabularQAlgorithm] = {}
        for i, (agent, (algo, kwargs)) in enumerate(zip(env.possible_agents, members)):
            cls: Any = resolve_class(algo) if isinstance(algo, str) else algo
            if not (isinstance(cls, type) and issubclass(cls, TabularQAlgorithm)):
                raise TypeError(f"members[{i}]: {algo!r} is not a tabular agent of this package (QLearning, AffectQ, ...)")
            model = cls("Grid", HunterView(env, agent), seed=member_seed(self.seed, i), **dict(kwargs))
            model.set_logger(Logger(folder=None, output_formats=[]))
            self.models[agent] = model
        self._rows: list[list[Any]] = []

    def learn(self, episodes: int, callbacks: Mapping[str, Any] | None = None) -> HunterTeam:
        """
        Train every hunter for ``episodes`` team episodes (the env's ``max_cycles``, or the members' smallest
        ``max_episode_decisions`` in rounds, cut an episode short).

        :param episodes: team episodes to run
        :param callbacks: SB3 callback(s) per hunter name, called once per decision of that hunter as in ``learn``
        :return: the team
        """
        if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
            raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
        env, agents = self.env, self.env.possible_agents
        callbacks = dict(callbacks or {})
        unknown = set(callbacks) - set(agents)
        if unknown:
            raise ValueError(f"callbacks for unknown hunters {sorted(unknown)}; the team has {', '.join(agents)}")
        cap = min(m.max_episode_decisions for m in self.models.values())
        first_obs, _ = env.reset(seed=None if self._seeded else self.seed)  # each learn() starts a fresh episode
        self._seeded = True
        steppers = {}
        for agent in agents:
            model = self.models[agent]
            view = model.single_env().unwrapped
            assert isinstance(view, HunterView)
            view.current = first_obs[agent]
            steppers[agent] = DecisionStepper(model, episodes * model.max_episode_decisions, callback=callbacks.get(agent))
        done_episodes = rounds = steps = 0
        team_reward = 0.0
        while done_episodes < episodes:
            decisions = {a: steppers[a].decide() for a in agents}
            length = max(k for _, k, _ in decisions.values())
            captured = truncated = False
            ended: dict[str, bool] = dict.fromkeys(agents, False)
            capturers: list[int] = []
            rows: list[list[Any]] = []
            next_obs: dict[str, Any] = {}
            for j in range(length):
                actions = {a: (action if j < k else STAY) for a, (action, k, _) in decisions.items()}
                obs, rewards, terminations, truncations, infos = env.step(actions)
                steps += 1
                team_reward += sum(rewards.values())
                captured = any(terminations.values())
                truncated = any(truncations.values())
                for i, a in enumerate(agents):
                    if j < decisions[a][1]:
                        ended[a] = captured and bool(infos[a]["capturer"])
                        steppers[a].transition(obs[a], rewards[a], ended[a], truncated, infos[a])
                    else:
                        steppers[a].set_state(obs[a])
                    if captured and infos[a]["capturer"]:
                        capturers.append(i)
                if captured or truncated:
                    break
            rounds += 1
            over = captured or truncated or rounds >= cap
            if over:
                next_obs, _ = env.reset()
            for a in agents:
                first: Any = next_obs.get(a)
                reset = functools.partial(_same, first)
                episode_ended = steppers[a].end_decision(ended[a], over and not ended[a], reset=reset)
                if episode_ended:
                    assert over, "a hunter's episode ends with the team's"
                    rows.append(self.models[a].last_episode_row())
            if over:
                self._close(rows, rounds, steps, team_reward, captured, capturers)
                done_episodes += 1
                rounds = steps = 0
                team_reward = 0.0
            if not all(s.continue_training for s in steppers.values()):
                break
        for stepper in steppers.values():
            stepper.close()
        return self

    def _close(
        self, rows: list[list[Any]], rounds: int, steps: int, reward: float, captured: bool, capturers: list[int]
    ) -> None:
        column = {name: i for i, name in enumerate(EPISODE_COLUMNS)}

        def total(name: str) -> Any:
            values = [r[column[name]] for r in rows]
            return math.nan if any(v != v for v in values) else sum(values)

        self._rows.append(
            [
                len(self._rows) + 1,
                rounds,
                steps,
                reward,
                self.env.optimal_capture([r[column["cells"]] for r in rows], sorted(set(capturers))),
                not captured,
                total("random_moves"),
                total("waits"),
                total("joy"),
                total("sadness"),
                total("fear"),
                total("anger"),
                math.nan,
                math.nan,
                capturers[0] if capturers else -1,
            ]
        )

    @property
    def episode_log(self) -> pd.DataFrame:
        """
        One row per team episode, columns ``TEAM_COLUMNS``: ``decisions`` = rounds (each hunter's decisions),
        ``cells`` = env steps, ``reward`` = all hunters' rewards, ``optimal`` = the env's ``optimal_capture`` of the
        hunters' moves, ``truncated`` = not captured, ``random_moves``/``waits``/emotions summed over the hunters,
        ``greedy_optimal`` and ``norm`` NaN (per hunter only), ``capturer`` = index of the (first) hunter rewarded
        for the capture (-1: none).
        """
        frame = pd.DataFrame(self._rows, columns=list(TEAM_COLUMNS))
        for name in ("episode", "decisions", "cells", "capturer"):
            frame[name] = frame[name].astype("int64")
        for name in ("optimal", "truncated"):
            frame[name] = frame[name].astype(bool)
        return frame

