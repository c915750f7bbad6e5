"""
What counts as *reaching the goal* when an episode terminates.

The appraisal (``EmotionCallback``, and through it ``AffectQ``) learns where the goal is: a cell the agent entered
when an episode ended at the goal becomes a goal of its known map, and ``act`` measures the known distance to it.
An episode can also terminate elsewhere: FrozenLake's holes end an episode with reward 0. A *goal test* decides,
for a terminating transition, whether it reached the goal. It is called only when ``terminated`` is true (a
truncation, by a time limit or the safety cap, is never the goal), with the transition's reward and info.

The default, ``positive_terminal_reward``, reads:

1. the env's own verdict when its info carries SB3's ``is_success`` key;
2. otherwise, a termination with a reward > 0 is the goal, any other termination is not.

The package's envs (GridPursuit, MazePursuit, MovingPursuit) terminate only at the goal, with a reward > 0, so for
them every termination is the goal. On Gymnasium's toy-text envs the default gives: FrozenLake, the goal (reward 1)
yes, a hole (reward 0) no; Taxi, a correct drop-off (+20) yes. CliffWalking ends only at its goal, with the same
reward as every step (-1), so the default never sees a goal there: pass ``every_termination`` (or your own test) as
``EmotionCallback(goal=...)``, and ``AffectQ(..., emotion_callback=EmotionCallback(goal=every_termination))``.

A termination can also be a failure with a positive reward: CartPole pays +1 every step, the one where the pole falls
included, so the default takes the fall for the goal and the appraisal would map its way to it. ``EmotionCallback``
warns once when the default counts a termination whose reward has the sign of the rewards before it (a reward for
surviving, not for arriving); tell it what the goal is, e.g. ``goal=lambda reward, info: False`` on an env without
one (every termination a failure), or ``goal=lambda reward, info: info.get("x") == ...`` (passing ``goal=`` silences
the warning).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

#: ``goal(reward, info) -> bool`` for a transition that terminated the episode.
GoalTest = Callable[[float, dict[str, Any]], bool]


def positive_terminal_reward(reward: float, info: dict[str, Any]) -> bool:
    """The default goal test: ``info["is_success"]`` when the env says it, else ``reward > 0``."""
    success = info.get("is_success")
    if success is not None:
        return bool(success)
    return reward > 0


def every_termination(reward: float, info: dict[str, Any]) -> bool:
    """Every termination is the goal (envs that end only at their goal, whatever its reward, e.g. CliffWalking)."""
    return True


__all__ = ["GoalTest", "every_termination", "positive_terminal_reward"]
