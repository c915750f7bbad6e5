"""
The appraisal of one env of a VecEnv, step by step: what ``EmotionCallback`` runs for each env in observer mode, and
so the appraisal of the deep affective agents (``AffectDQN``, ``AffectQRDQN``). Plain Python with no SB3 in it, so a
trainer of its own can run the same appraisal: per env, ``begin(cell)`` at an episode's start, ``feel(rule, counted)``
before each decision, ``step(...)`` after each env step and ``close(...)`` at the episode's end.

**One unit: moves.** A move is an env step that tries to take the agent to a neighbouring cell of the map: on a grid
whose observation is the cell (``position=None``, ``"discrete"``, ``"multidiscrete"``) and with a callable, every env
step (a bump into a wall included: the agent spent the move, as the tabular agents count it); under
``position="minigrid"`` MiniGrid's ``forward`` only, and under ``"minigrid-dir"`` ``forward`` and the two turns (the
direction is part of the cell there); picking up, dropping, toggling and ``done`` (a wait) are not moves
(``Position.is_move``). With ``units="cells"`` the elapsed part of ``act``, ``exp1`` and ``norm`` (the power trend of
the past episodes' lengths) count moves, and the known map's distance to the goal (``act``'s remaining part) counts
them too: its edges are the moves that changed the cell, so the shortest known path is the fewest moves known to reach
the goal. (Before, ``"minigrid"`` counted turns in elapsed and norm but not in the distance.) With
``units="decisions"`` ``norm`` and elapsed count decisions, as ``Appraiser`` documents.

**``act`` before the goal is known.** Until an episode reaches the goal the map has no distance to it, so ``act`` is
unknown (infinite). Table II then gives joy under the literal reading (``act >= norm``), so the agent explores at
random until its first goal, and fear or anger (both greedy in Table III) under the valence reading. That is a choice
of this implementation (the paper does not say what act is before a goal is known), not a finding. Where the current
cell has no known path, ``act`` keeps the value of the last cell that had one *in this episode* (``last_act`` is reset
at each episode's start: a new episode may start elsewhere, e.g. on DoorKey).
"""

from __future__ import annotations

from sb3_affect.core.appraisal import INF, Appraiser
from sb3_affect.core.emotions import Emotion, EmotionRule


def observe_step(appraiser: Appraiser, s: int, s2: int, reached_goal: bool, move: bool) -> None:
    """
    One env step from cell ``s`` to ``s2`` (``reached_goal``: it ended the episode at the goal, ``s2`` is a goal;
    ``move``: the step was a move, which counts in elapsed).
    """
    if reached_goal:
        appraiser.known.add_goal(s2)
    if s != s2:
        appraiser.known.add(s, s2)
    appraiser.elapsed_cells += move


class LaneAppraisal:
    """The appraisal, emotion counts and episode in progress of one env (see the module docstring)."""

    def __init__(self, appraiser: Appraiser) -> None:
        self.appraiser = appraiser
        self.emotion = Emotion.JOY
        self.deciding = False  # the env's current decision has not been counted in ``decisions`` yet
        self.counts = [0, 0, 0, 0]
        self.state = 0
        self.decisions = self.steps = self.random_moves = self.waits = 0
        self.reward = 0.0

    def begin(self, cell: int) -> None:
        """An episode starts in ``cell``."""
        appraiser = self.appraiser
        appraiser.start_episode()
        appraiser.last_act = INF
        self.counts = [0, 0, 0, 0]
        self.state = cell
        self.decisions = self.steps = self.random_moves = self.waits = 0
        self.reward = 0.0

    def feel(self, rule: EmotionRule, counted: bool = True) -> Emotion:
        """
        Appraise the env's next decision and feel its emotion; ``counted``: it enters the emotion profile (False for
        SB3's warm-up, whose actions are SB3's uniformly random ones, not the emotions').
        """
        appraiser = self.appraiser
        emotion = rule(appraiser.appraise(self.state))
        appraiser.elapsed_decisions += 1
        if counted:
            self.counts[emotion] += 1
        self.emotion = emotion
        self.deciding = True
        return emotion

    def step(self, s2: int, reward: float, reached_goal: bool, mapped: bool = True, move: bool = True) -> None:
        """
        One env step of the episode in progress, from ``self.state`` to cell ``s2`` (at an episode's end, its last cell);
        ``mapped``: the cells are real (a position hook), so a goal reached enters the map; ``move``: it was a move.
        """
        observe_step(self.appraiser, self.state, s2, reached_goal and mapped, move)
        self.decisions += self.deciding
        self.deciding = False
        self.steps += 1
        self.reward += reward
        self.state = s2

    def note_decision(self, random_direction: bool, wait: bool) -> None:
        """The decision the env has just taken drew its direction at random / was a wait (an agent that says so)."""
        self.random_moves += random_direction
        self.waits += wait

    def close(self, reached_goal: bool) -> tuple[list[int], float]:
        """The episode ended: feed the norm's regression; returns (emotion counts, the norm used)."""
        appraiser = self.appraiser
        norm = appraiser.norm
        appraiser.end_episode(reached_goal)
        return list(self.counts), norm

    def shares(self) -> list[float] | None:
        """Each emotion's share of the episode's counted decisions (None when none was counted)."""
        total = sum(self.counts)
        return [c / total for c in self.counts] if total else None
