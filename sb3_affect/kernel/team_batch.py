"""
What the team kernel (``kernel.team_loop``) is fed, and what comes out: a team run of the package's own agents on
HunterPursuit from the members' settings (or freshly built models) and the env, without building a model, and the
run's record columns (the team's log, each hunter's log and its emotion models' observers'), as the launcher stores them.

A run starts as a new ``HunterTeam`` does: each hunter's Q-table at its ``q_init``, ``random.Random(member_seed(seed,
i))``, an empty appraisal; the env's NumPy generator as ``reset(seed=seed)`` leaves it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from sb3_affect.core.team_seeds import member_seed
from sb3_affect.envs.grid_pursuit import MOVES, PREY_MODES
from sb3_affect.kernel import state_layout, team_loop
from sb3_affect.kernel.agent_settings import AFFECT, BehaviourRows, kernel_agent, settings_class
from sb3_affect.kernel.decision import ObsAppraisal
from sb3_affect.kernel.mt19937 import STATE_SIZE, TW_SIZE, seed_key, seed_state
from sb3_affect.kernel.pcg64 import seeded_state
from sb3_affect.kernel.team_emotions import TeamEmotions, first_class_functions, team_emotions

#: The most bytes the known maps of a team's hunters may take (larger observation spaces run on the Python team).
MAX_KNOWN_BYTES = 1 << 30
N_ACTIONS = len(MOVES)


class TeamInputs(NamedTuple):
    """Everything ``run_team`` needs besides the seed: the env and every hunter as the kernel runs them."""

    env: team_loop.TeamEnv
    config: team_loop.Config
    hunters: Any  # team_loop.Hunters
    behaviour: BehaviourRows  # one row per hunter first
    alpha: np.ndarray  # [hunter, episode]
    p: np.ndarray  # [hunter, episode]
    n_states: int
    succ_width: int
    pred_width: int
    emotions: TeamEmotions  # the registry's emotion models, each hunter observed by all


class TeamRun(NamedTuple):
    """A team run's rows and the state it left behind."""

    out_i: np.ndarray
    out_f: np.ndarray
    team_i: np.ndarray
    team_f: np.ndarray
    q: np.ndarray
    mt: np.ndarray
    pcg: np.ndarray
    dist: np.ndarray

    @property
    def decisions(self) -> int:
        """Decisions of all hunters (each hunter takes one per round)."""
        return int(self.out_i[:, :, state_layout.O_DECISIONS].sum())


def team_inputs(agents: Sequence[Any], env: Any, episodes: int) -> TeamInputs | str:
    """
    The kernel inputs of fresh team runs of ``agents`` (one settings object per hunter, ``sb3_affect.core.settings``) on
    ``env`` (a ``HunterPursuitEnv``), or the reason the kernel can not run them.
    """
    from sb3_affect.envs.hunter_pursuit import HunterPursuitEnv

    if type(env) is not HunterPursuitEnv:
        return f"the env {type(env).__name__} is not HunterPursuit"
    if len(agents) != len(env.possible_agents):
        return f"{len(agents)} agents for {len(env.possible_agents)} hunters"
    emotions = team_emotions()  # (a run records every model the registry lists)
    if isinstance(emotions, str):
        return emotions
    specs = []
    schedules = []
    for agent in agents:
        spec = kernel_agent(agent)
        if isinstance(spec, str):
            return spec
        schedule = agent.episode_parameters(0, episodes)
        if schedule is None:
            return "a schedule depends on the training progress, which only the Python side evaluates"
        specs.append(spec)
        schedules.append(schedule)
    n = len(agents)
    n_cells = env.n_cells
    digits = (n if env.observation == "all" else 1) + (env.prey != "static")
    n_states = n_cells**digits
    affect = any(spec.kind == AFFECT for spec in specs)
    width = 5**digits if affect else 1  # a hunter's own cell, each other hunter's and the prey's: staying or a move
    if 2 * n * n_states * width * 4 > MAX_KNOWN_BYTES:
        return f"the hunters' known maps over {n_states:,} observations would need more than {MAX_KNOWN_BYTES >> 30} GB"
    config = team_loop.Config(
        n_cells=int(n_cells),
        prey_start=int(env.prey_start_cell),
        prey=PREY_MODES.index(env.prey),
        surround=env.capture == "surround",
        obs_all=env.observation == "all",
        max_cycles=int(env.max_cycles or 0),
        capture_distance=int(env.capture_distance),
        geometry=env.prey == "static" and env.capture == "enter" and env.observation == "self",
        goal_reward=float(env.goal_reward),
        step_reward=float(env.step_reward),
        prey_speed=float(env.prey_speed),
    )
    speeds_width = max(spec.behaviour.speeds.shape[1] for spec in specs)
    behaviour = BehaviourRows(
        np.array([spec.behaviour.random for spec in specs], dtype=np.int64),
        np.zeros((n, 4, speeds_width), dtype=np.int64),
        np.array([spec.behaviour.n for spec in specs], dtype=np.int64),
    )
    for m, spec in enumerate(specs):
        behaviour.speeds[m, :, : spec.behaviour.speeds.shape[1]] = spec.behaviour.speeds
    cell_trans = np.asarray(env.cell_transitions, dtype=np.int64)
    far = np.array([env.distances_to(h) for h in range(n_cells)]) if env.prey == "evade" else np.zeros((1, 1))
    team_env = team_loop.TeamEnv(
        cell_trans,
        far,
        np.asarray(env.distances_to(env.prey_start_cell), dtype=np.float64),
        np.asarray(env.hunter_start_cells, dtype=np.int64),
    )
    return TeamInputs(
        team_env,
        config,
        team_loop.Hunters(*(np.array(field) for field in zip(*(spec.settings for spec in specs)))),
        behaviour,
        np.array([a for a, _ in schedules]),
        np.array([p for _, p in schedules]),
        n_states,
        width,
        width,
        emotions,
    )


def team_settings_inputs(
    members: Sequence[tuple[str | type, Mapping[str, Any]]], env_id: str, env_kwargs: Mapping[str, Any], episodes: int
) -> TeamInputs | None:
    """
    The kernel inputs of fresh team runs of ``members`` (``(algo, kwargs)`` per hunter) on
    ``make_parallel(env_id, **env_kwargs)``, from the agents' settings (no model, no torch); None where the kernel
    can not run them (an agent that is not the package's own, an argument that is not a setting, a progress schedule).
    Bad kwargs raise the constructor's error.
    """
    from sb3_affect.envs import make_parallel

    settings = []
    for algo, kwargs in members:
        settings_cls = settings_class(algo, kwargs)
        if settings_cls is None:
            return None
        settings.append(settings_cls(**kwargs))
    inputs = team_inputs(settings, make_parallel(env_id, **dict(env_kwargs)), episodes)
    return None if isinstance(inputs, str) else inputs


def run_team(inputs: TeamInputs, seed: int, episodes: int) -> TeamRun:
    """One fresh team run of ``episodes`` episodes with the run seed ``seed`` (``team_loop.team_loop``)."""
    n = len(inputs.hunters.q_init)
    n_states = inputs.n_states
    q = np.empty((n, n_states, N_ACTIONS))
    mt = np.zeros((n, STATE_SIZE), dtype=np.int64)
    for m in range(n):
        q[m] = inputs.hunters.q_init[m]
        key = np.asarray(seed_key(member_seed(seed, m)), dtype=np.int64)
        seed_state(mt[m], key, len(key))
    state = team_loop.TeamState(
        q,
        mt,
        np.empty((n, TW_SIZE), dtype=np.int64),
        np.zeros((n, n_states, N_ACTIONS), dtype=np.int64),
        np.zeros((n, n_states), dtype=np.int64),
        np.zeros((n, team_loop.N_TEAM_IST), dtype=np.int64),
        np.zeros((n, team_loop.S_OBSERVER + inputs.emotions.n_state)),
        seeded_state(seed),
        np.zeros(n, dtype=np.int64),
    )
    appraisal = ObsAppraisal(
        np.full((n, n_states), math.inf),
        np.zeros((n, n_states, inputs.succ_width), dtype=np.int32),
        np.zeros((n, n_states), dtype=np.int64),
        np.zeros((n, n_states, inputs.pred_width), dtype=np.int32),
        np.zeros((n, n_states), dtype=np.int64),
        np.zeros((n, n_states), dtype=np.bool_),
        np.zeros((n, episodes + 1)),
    )
    rows = team_loop.TeamEpisodes(
        inputs.alpha,
        inputs.p,
        np.zeros((n, episodes, state_layout.N_OUT_I), dtype=np.int64),
        np.zeros((n, episodes, team_loop.F_OBSERVER + inputs.emotions.n_out)),
        np.zeros((episodes, team_loop.N_TEAM_I), dtype=np.int64),
        np.zeros(episodes),
    )
    work = team_loop.TeamWork(
        np.empty(N_ACTIONS),
        np.empty(n_states + 1, dtype=np.int64),
        np.zeros((n, n_states), dtype=np.int64),
        np.empty(n_states * N_ACTIONS + 1, dtype=np.int64),
        np.empty(5, dtype=np.int64),
    )
    with first_class_functions():
        team_loop.team_loop(
            inputs.env, inputs.config, inputs.hunters, inputs.behaviour, state, appraisal, rows, work,
            inputs.emotions.observers, episodes,
        )  # fmt: skip
    return TeamRun(rows.rows_i, rows.rows_f, rows.team_i, rows.team_f, q, mt, state.pcg, appraisal.dist)


def _plain(values: np.ndarray) -> list[Any]:
    """Python values of a column, NaN as None (the JSON records' convention)."""
    return [None if isinstance(v, float) and v != v else v for v in values.tolist()]


def hunter_columns(inputs: TeamInputs, run: TeamRun, m: int) -> dict[str, list[Any]]:
    """Hunter ``m``'s episode log (``EPISODE_COLUMNS``), as lists of plain values (NaN as None)."""
    ints, floats = run.out_i[m], run.out_f[m]
    episodes = ints.shape[0]
    geometry = inputs.config.geometry
    kind = int(inputs.hunters.kind[m])
    nan = [None] * episodes
    return {
        "episode": list(range(1, episodes + 1)),
        "decisions": ints[:, state_layout.O_DECISIONS].tolist(),
        "cells": ints[:, state_layout.O_CELLS].tolist(),
        "reward": floats[:, state_layout.F_REWARD].tolist(),
        "optimal": ints[:, state_layout.O_OPTIMAL].astype(bool).tolist() if geometry else nan,
        "truncated": ints[:, state_layout.O_TRUNCATED].astype(bool).tolist(),
        "random_moves": ints[:, state_layout.O_RANDOM].astype(np.float64).tolist(),
        "waits": ints[:, state_layout.O_WAITS].tolist(),
        "joy": ints[:, state_layout.O_JOY].tolist(),
        "sadness": ints[:, state_layout.O_SADNESS].tolist(),
        "fear": ints[:, state_layout.O_FEAR].tolist(),
        "anger": ints[:, state_layout.O_ANGER].tolist(),
        "greedy_optimal": ints[:, state_layout.O_GREEDY].astype(bool).tolist() if geometry else nan,
        "norm": _plain(floats[:, state_layout.F_NORM]) if kind == AFFECT else nan,
    }


def team_columns(inputs: TeamInputs, run: TeamRun) -> dict[str, list[Any]]:
    """
    A team run's record columns, as the Python team gives them: the team's (``team_loop.TEAM_COLUMNS``), then per hunter
    ``hunter_<i>/<column>`` (its episode log) and ``hunter_<i>/<model>_<column>`` for each emotion model of the registry
    (``broekens_<joy|distress|hope|fear|goal_joy>``).
    """
    n, episodes = run.out_i.shape[0], run.out_i.shape[1]
    ints = run.out_i
    total = ints.sum(axis=0)
    columns: dict[str, list[Any]] = {
        "episode": list(range(1, episodes + 1)),
        "decisions": run.team_i[:, team_loop.T_ROUNDS].tolist(),
        "cells": run.team_i[:, team_loop.T_STEPS].tolist(),
        "reward": run.team_f.tolist(),
        "optimal": run.team_i[:, team_loop.T_OPTIMAL].astype(bool).tolist(),
        "truncated": run.team_i[:, team_loop.T_TRUNCATED].astype(bool).tolist(),
        "random_moves": total[:, state_layout.O_RANDOM].tolist(),
        "waits": total[:, state_layout.O_WAITS].tolist(),
        "joy": total[:, state_layout.O_JOY].tolist(),
        "sadness": total[:, state_layout.O_SADNESS].tolist(),
        "fear": total[:, state_layout.O_FEAR].tolist(),
        "anger": total[:, state_layout.O_ANGER].tolist(),
        "greedy_optimal": [None] * episodes,
        "norm": [None] * episodes,
        "capturer": run.team_i[:, team_loop.T_CAPTURER].tolist(),
    }
    for m in range(n):
        agent = f"hunter_{m}"
        for name, values in hunter_columns(inputs, run, m).items():
            columns[f"{agent}/{name}"] = values
        for model, where in inputs.emotions.columns.items():
            for name, at in where.items():
                columns[f"{agent}/{model}_{name}"] = _plain(run.out_f[m, :, team_loop.F_OBSERVER + at])
    return columns


def warm_up() -> None:
    """Load (the first time on a machine: compile) the team kernel, on a 3 x 3 grid with two hunters of each family."""
    from sb3_affect.core.settings import AffectQSettings, QLearningSettings
    from sb3_affect.envs.hunter_pursuit import HunterPursuitEnv

    env = HunterPursuitEnv(size=3, starts=[(0, 0), (2, 2)], prey_start=(1, 1))
    inputs = team_inputs([AffectQSettings(), QLearningSettings()], env, 1)
    assert not isinstance(inputs, str), inputs
    run_team(inputs, 0, 1)
