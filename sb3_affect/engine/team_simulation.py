"""
``simulate_team``: one team run of the package's own agents on HunterPursuit on the team kernel
(``sb3_affect.kernel.team_loop``), from the members' settings, without building a model (no torch): the record
columns a Python team gives (the team's log, each hunter's log and its emotion models' columns).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from sb3_affect.kernel import team_loop
from sb3_affect.kernel.jit import TEAM_COMPILE_CPU_SECONDS, announce_compile
from sb3_affect.kernel.team_batch import run_team, team_columns, team_settings_inputs


class TeamSimulation(NamedTuple):
    """A team run's record columns and the decisions all its hunters took."""

    columns: dict[str, list[Any]]
    decisions: int


def simulate_team(
    members: Sequence[tuple[str | type, Mapping[str, Any]]],
    env_id: str,
    env_kwargs: Mapping[str, Any],
    seed: int,
    episodes: int,
) -> TeamSimulation | None:
    """
    One fresh team run of ``members`` (``(algo, kwargs)`` per hunter) on ``make_parallel(env_id, **env_kwargs)`` with
    the run seed ``seed``, for ``episodes`` episodes, on the team kernel; None where the kernel can not run it (an agent
    or argument the kernel does not know, a member's ``engine="python"``, a schedule of the training progress).
    """
    if any(kwargs.get("engine", "auto") == "python" for _, kwargs in members):
        return None
    inputs = team_settings_inputs(members, env_id, env_kwargs, episodes)
    if inputs is None:
        return None
    announce_compile("the hunter team's loop (simulate_team)", (team_loop.team_loop,), TEAM_COMPILE_CPU_SECONDS)
    run = run_team(inputs, int(seed), episodes)
    return TeamSimulation(team_columns(inputs, run), run.decisions)
