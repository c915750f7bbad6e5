"""
A second emotion model: Broekens, Jacobs and Jonker (2015), "A reinforcement learning model of joy, distress, hope
and fear" (Connection Science 27(3)), as an SB3 callback that observes any algorithm with a value estimate.

What follows the paper's abstract: joy and distress are the positive and negative parts of the temporal-difference
error of a step, ``delta = r + gamma * V(s') - V(s)``; hope and fear the positive and negative parts of the
anticipated value ``V(s')`` of the state reached. Everything else is this package's choice, made so the model can
watch any SB3 run:

* ``V(s') = 0`` when ``s'`` ends the episode at a terminal state; after a truncation (a time limit) ``V(s')`` is the
  value of the last observation (``terminal_observation``), as SB3's algorithms bootstrap it.
* ``V(s)`` is the value recorded when ``s`` was reached (before the step's learning update), ``V(s')`` the value
  after it.
* Where ``V`` comes from: ``max_a Q(s, a)`` for the package's tabular agents and DQN (QR-DQN: the mean of its
  quantiles); the value head for PPO, A2C, TRPO, MaskablePPO and RecurrentPPO (with its LSTM states); ``Q(s, pi(s))``
  for SAC, TD3, TQC and CrossQ (the deterministic action; the minimum over SAC's and TD3's twin critics, as their
  targets take it; the mean of TQC's quantiles); or a ``value_fn`` you give.
* A step is what the algorithm calls its callbacks for: one env step of each env of the VecEnv for SB3's
  algorithms, one decision for the package's tabular agents. A decision that moves ``k`` cells is discounted per cell
  as the agent's own updates are (``delta = r_1 + gamma r_2 + ... + gamma^k V(s_k) - V(s)``), or once for
  ``multi_cell="jump"``, whose single update sums the rewards; a wait (0 cells) makes no transition and no update,
  so it fires no emotion and is not counted as a step.
* Logged: the means per step of each emotion over an episode, then their means over the last episodes (the
  algorithm's stats window, as SB3 logs ``rollout/ep_rew_mean``).

What a step costs: no forward pass where the algorithm already has the values, one batched pass otherwise. An
on-policy algorithm (PPO, A2C, TRPO, MaskablePPO, RecurrentPPO) values each observation before it acts on it and the
last one of a rollout before it learns: the callback settles a step when the algorithm has valued the state it
reached, one step later (the episode log is complete at the end of ``learn``). On a ``Discrete`` observation space of at
most ``VALUE_TABLE_STATES`` states, SB3's and sb3-contrib's other algorithms value each state once per update (their
``train`` counts the updates): the states met, one at a time, where the pass is made in numpy; all states at once by
torch. Such a step keeps only its lists; its values and emotions are worked out with the other steps of the rollout in
one burst before the algorithm learns, or at the end of an episode (the values, their order and what is logged when
are those of settling each step at once). Otherwise every step is one batched pass over the
VecEnv's observations; a ``value_fn`` is called once per env and step. The pass of a DQN with SB3's default MLP
Q-network is made in numpy on the network's own parameters (``sb3_affect.agents.numpy_values``): on a small network a
torch pass costs more than the step it values.

The paper's experiments are not reproduced: the package has no stored source for their learner or any further
scaling, so only the definitions above are used.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from sb3_affect.agents.callbacks import WindowMeans, check_step_locals, flat_array, logger_file_folder
from sb3_affect.agents.numpy_values import NumpyQValues, q_values_fn
from sb3_affect.agents.sb3_fields import ModelFields, policy_actions
from sb3_affect.core.positions import Position, PositionSpec, check_position, make_position
from sb3_affect.core.registry import EMOTION_MODELS

if TYPE_CHECKING:
    import pandas as pd

#: Columns of ``BroekensCallback.episode_log`` (its emotions and columns as the registry names them: ``EMOTION_MODELS``).
BROEKENS_COLUMNS: tuple[str, ...] = ("episode", "steps", "reward", *EMOTION_MODELS["broekens"].columns, "env")
BROEKENS_EMOTIONS: tuple[str, ...] = EMOTION_MODELS["broekens"].emotions

ValueFn = Callable[[Any, Any], float]


#: How a model's values are read (``value_kind``).
VALUE_KINDS = ("tabular", "q_net", "quantile_net", "value_head", "recurrent", "critic")
#: A ``Discrete`` observation space of at most this many states is valued in all its states at once (one batched pass
#: per update of the algorithm) instead of once per step.
VALUE_TABLE_STATES = 256


def value_kind(model: Any) -> str:
    """Which of ``VALUE_KINDS`` gives the state value of ``model``; a TypeError naming the fix when none does."""
    policy = getattr(model, "policy", None)
    # the package's tabular agents, known by their base class's name: a user's DQN run never imports them
    if any(cls.__name__ == "TabularQAlgorithm" and cls.__module__.startswith("sb3_affect.") for cls in type(model).__mro__):
        return "tabular"
    if hasattr(model, "q_net"):
        return "q_net"
    if hasattr(model, "quantile_net"):
        return "quantile_net"
    if hasattr(policy, "predict_values"):
        return "recurrent" if hasattr(policy, "lstm_actor") else "value_head"
    if hasattr(model, "critic") and hasattr(model, "actor"):
        return "critic"
    raise TypeError(
        f"BroekensCallback needs a value-based algorithm (a tabular agent, DQN, QR-DQN, an actor-critic such as PPO or "
        f"A2C, or SAC, TD3, TQC, CrossQ); {type(model).__name__} has no Q-table, Q-network, value head or critic: pass "
        "value_fn=lambda model, obs: V(obs)"
    )


def _model_values(model: Any, kind: str, obs: Any, lstm: Any = None, starts: Any = None) -> np.ndarray:
    """The values of a batch of observations (``obs``: a VecEnv's batch, or a dict of batches)."""
    if kind == "tabular":
        q = getattr(model, "loop_table", None)
        table = q if q is not None else model.q_table.tolist()
        cells = np.asarray(obs).reshape(-1) - int(model.observation_space.start)
        return np.array([max(table[int(cell)]) for cell in cells], dtype=float)
    policy = model.policy
    training = policy.training
    if training:  # batch norm (CrossQ) and dropout: evaluate, never update (SB3 collects in evaluation mode already)
        policy.set_training_mode(False)
    try:
        with th.no_grad():
            tensor, _ = policy.obs_to_tensor(obs)
            if kind == "q_net":
                values = model.q_net(tensor).max(dim=1).values
            elif kind == "quantile_net":
                values = model.quantile_net(tensor).mean(dim=1).max(dim=1).values
            elif kind == "value_head":
                values = policy.predict_values(tensor)
            elif kind == "recurrent":
                values = policy.predict_values(tensor, lstm, starts)
            else:  # "critic": Q(s, pi(s)) with the deterministic action
                actions = policy_actions(policy, tensor)
                out = model.critic(tensor, actions)
                if isinstance(out, (tuple, list)):  # twin critics (SAC, TD3, CrossQ): the minimum, as their targets
                    values = th.cat([q.reshape(len(q), -1) for q in out], dim=1).min(dim=1).values
                else:  # TQC: (batch, critics, quantiles)
                    values = out.reshape(len(out), -1).mean(dim=1)
    finally:
        if training:
            policy.set_training_mode(True)
    return _as_floats(values)


def _as_floats(values: Any) -> np.ndarray:
    """Values (one per env, a tensor or an array) as a float64 array."""
    if isinstance(values, th.Tensor):
        values = values.cpu().numpy()
    return np.asarray(values, dtype=float).reshape(-1)


def _versioned_updates(model: Any) -> bool:
    """Whether ``model``'s parameters change only in a ``train`` of SB3 or sb3-contrib, which counts its updates."""
    train = getattr(type(model), "train", None)
    return getattr(train, "__module__", "").startswith(("stable_baselines3.", "sb3_contrib."))


def _batch_of_one(obs: Any) -> Any:
    """One env's (unbatched) observation as a batch of one."""
    if isinstance(obs, dict):
        return {key: np.asarray(value)[None] for key, value in obs.items()}
    return np.asarray(obs)[None]


def _row(obs: Any, index: int) -> Any:
    """Env ``index``'s observation of a VecEnv batch, as a batch of one."""
    if isinstance(obs, dict):
        return {key: np.asarray(value)[index : index + 1] for key, value in obs.items()}
    return np.asarray(obs)[index : index + 1]


class _Step(NamedTuple):
    """What one step of the VecEnv gave, kept until the values of the observations it reached are known."""

    dones: list[bool]
    rewards: list[float]
    cut: dict[int, float | None]  # truncated env -> V of its episode's last observation (None: no such observation)
    new_obs: Any
    done_array: np.ndarray | None
    cell_rewards: list[float] | None
    cells: list[int] | None  # each env's cell after the step (``position=``), None without a position


class BroekensCallback(BaseCallback):
    """
    Observe joy, distress, hope and fear (Broekens, Jacobs & Jonker 2015; see the module docstring for what follows
    the paper and what is this package's choice) of any SB3 algorithm with a value estimate, on a VecEnv of any size
    and any observation space the algorithm takes. Logs ``<prefix>joy|distress|hope|fear`` (means over the stats
    window) through the model's logger and keeps ``episode_log`` (one row per episode and env, ``BROEKENS_COLUMNS``):
    the mean intensity of each emotion per step, and ``goal_joy``, the joy of the step that ended the episode at a
    terminal state (NaN when it was cut off). When the logger writes files, the rows are also appended to
    ``broekens_episodes.csv`` in its folder.

    :param value_fn: ``value_fn(model, obs) -> V(obs)`` for an observation batch of one; default by algorithm
    :param gamma: discount of the TD error; default the model's ``gamma``
    :param prefix: prefix of the logger keys
    :param episode_log_path: a CSV file to append the episode rows to (default: see above)
    :param position: where each step is felt, for ``cell_log`` (the mean emotions per cell the step was taken in):
        ``"discrete"``, ``"multidiscrete"``, ``"minigrid"``, ``"minigrid-dir"``, a callable
        ``position(observation, info) -> cell`` or a ``Position`` (``sb3_affect.core.positions``); None: no cell log
    :param verbose: verbosity level
    """

    def __init__(
        self,
        value_fn: ValueFn | None = None,
        gamma: float | None = None,
        prefix: str = "affect/broekens/",
        episode_log_path: str | Path | None = None,
        position: PositionSpec = None,
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        self.position = check_position(position)
        if gamma is not None and not 0.0 <= float(gamma) <= 1.0:
            raise ValueError(f"gamma={gamma!r} must be in [0, 1]")
        if value_fn is not None and not callable(value_fn):
            raise TypeError(f"value_fn must be a callable value_fn(model, obs) -> float, got {value_fn!r}")
        self.value_fn = value_fn
        self.gamma = gamma
        self.prefix = prefix
        self._keys = tuple(prefix + name for name in BROEKENS_EMOTIONS)
        self.episode_log_path = episode_log_path
        self.rows: list[list[Any]] = []
        self._kind = "user"
        self._gamma = 1.0
        # per env: V of its current state, the emotions' sums, steps and reward of its episode in progress
        self._v: list[float] = [0.0]
        self._sums: list[list[float]] = [[0.0] * 4]
        self._steps: list[int] = [0]
        self._reward: list[float] = [0.0]
        self._window = WindowMeans(len(BROEKENS_EMOTIONS))
        self._csv_path: Path | None = None
        self._position: Position | None = None
        self._cells: list[int] = []
        self._cell_sums: dict[int, np.ndarray] = {}  # cell -> [steps, joy, distress, hope, fear] summed
        # where the values come from (see the module docstring): the algorithm's own (on-policy), a table of all states
        self._settle_later = False
        self._pending: _Step | None = None
        # steps to settle before the algorithm learns: (dones, rewards, states, cells) of each
        self._queue: list[tuple[list[bool], list[float], list[int], list[int] | None]] = []
        self._seen_values: Any = None
        self._table_states = self._table_start = 0
        self._table: dict[int, float] | None = None  # state -> V, since the update ``_table_version``
        self._table_version: int | None = None
        self._mirror: NumpyQValues | None = None
        self._row_mirror: NumpyQValues | None = None  # the mirror, when not stale at the table's update

    def _init_callback(self) -> None:
        model = self.model
        self._kind = "user" if self.value_fn is not None else value_kind(model)
        self._gamma = float(self.gamma if self.gamma is not None else getattr(model, "gamma", 1.0))
        self._settle_later = self._kind in ("value_head", "recurrent") and isinstance(model, OnPolicyAlgorithm)
        space = model.observation_space
        tabled = self._kind in ("q_net", "quantile_net", "value_head", "critic") and _versioned_updates(model)
        small = isinstance(space, spaces.Discrete) and int(space.n) <= VALUE_TABLE_STATES
        self._table_states = int(space.n) if tabled and small else 0  # type: ignore[attr-defined]
        self._table_start = int(space.start) if self._table_states else 0  # type: ignore[attr-defined]
        self._table = None
        self._mirror = q_values_fn(model) if self._kind == "q_net" else None

    # -- values ------------------------------------------------------------------------------------------------
    def _values(self, obs: Any, dones: np.ndarray | None = None) -> np.ndarray | list[float]:
        """``V`` of each env's observation in a VecEnv batch (``dones``: which envs start a new episode with it)."""
        if self._table_states:  # first: the common case of a small Discrete space (never with a value_fn)
            return self._table_values(flat_array(obs).tolist())
        if self._kind == "user":
            assert self.value_fn is not None
            n = len(next(iter(obs.values()))) if isinstance(obs, dict) else len(np.asarray(obs))
            return np.array([float(self.value_fn(self.model, _row(obs, i))) for i in range(n)])
        lstm = starts = None
        if self._kind == "recurrent":
            lstm, starts = self._recurrent_inputs(dones)
        return self._net_values(obs, lstm, starts)

    def _net_values(self, obs: Any, lstm: Any = None, starts: Any = None) -> np.ndarray:
        """The model's values of a batch: in numpy where ``numpy_values`` mirrors its network, else by torch."""
        mirror = self._mirror
        if mirror is not None and not mirror.stale():
            return mirror(obs).max(axis=1).astype(float)
        return _model_values(self.model, self._kind, obs, lstm, starts)

    def _table_values(self, states: list[int]) -> list[float]:
        """
        ``V`` of ``states`` of a small Discrete space, each valued once per update of the algorithm: in numpy (the
        mirror of the network) only the states asked for, whose one-row passes cost little; by torch every state at
        once, whose one pass costs about what a pass of one state does.
        """
        version = ModelFields(self.model).n_updates
        if self._table is None or version != self._table_version:
            self._table, self._table_version = {}, version
            mirror = self._mirror
            self._row_mirror = None if mirror is None or mirror.stale() else mirror  # checked once per update
            if self._row_mirror is None:
                start = self._table_start
                self._table = dict(enumerate(self._net_values(np.arange(start, start + self._table_states)).tolist(), start))
        table = self._table
        if len(states) == 1:  # one env: the common case, without building lists
            value = table.get(states[0])
            if value is None:
                row_mirror = self._row_mirror
                if row_mirror is not None:
                    value = row_mirror.state_value(states[0])
                else:
                    value = float(self._net_values(np.asarray(states))[0])
                table[states[0]] = value
            return [value]
        missing = [state for state in dict.fromkeys(states) if state not in table]
        if missing:
            table.update(zip(missing, self._net_values(np.asarray(missing)).tolist()))
        return [table[state] for state in states]

    def _recurrent_inputs(self, dones: np.ndarray | None, index: int | None = None) -> tuple[Any, th.Tensor]:
        """RecurrentPPO's value-LSTM states for the next observation (``index``: one env's, for its last observation)."""
        states = self.locals.get("lstm_states") if self.locals else None
        if states is None:  # training start: the states the next rollout begins with
            fields = ModelFields(self.model)
            states, dones = fields.last_lstm_states, np.asarray(fields.last_episode_starts)
        h, c = states.vf
        device = self.model.device
        if index is not None:  # a truncated episode's last observation continues its episode
            one = (h[:, index : index + 1, :].contiguous(), c[:, index : index + 1, :].contiguous())
            return one, th.zeros(1, device=device)
        assert dones is not None
        return (h, c), th.as_tensor(np.asarray(dones, dtype=np.float32), device=device)

    def _terminal_value(self, terminal_obs: Any, index: int) -> float:
        """``V`` of the last observation of a truncated episode of env ``index``."""
        batch = _batch_of_one(terminal_obs)
        if self._table_states:
            return float(self._values(batch)[0])
        if self._kind == "user":
            assert self.value_fn is not None
            return float(self.value_fn(self.model, batch))
        lstm = starts = None
        if self._kind == "recurrent":
            lstm, starts = self._recurrent_inputs(None, index)
        return float(self._net_values(batch, lstm, starts)[0])

    # -- SB3 hooks ---------------------------------------------------------------------------------------------
    def update_locals(self, locals_: dict[str, Any]) -> None:
        """The algorithm's variables of this step, read where they are (SB3's copies them into ``locals`` each step)."""
        self.locals = locals_

    def _on_training_start(self) -> None:
        fields = ModelFields(self.model)
        last_obs = fields.last_obs
        if last_obs is None:
            raise RuntimeError("BroekensCallback: the algorithm has no current observation at training start")
        n = self.training_env.num_envs
        self._v = [float(v) for v in self._values(last_obs)]
        self._sums = [[0.0] * 4 for _ in range(n)]
        self._steps = [0] * n
        self._reward = [0.0] * n
        self._window = self._window.resized(fields.stats_window_size)
        self._csv_path = self._episode_csv()
        self._pending = None
        self._queue = []
        if self.position is not None:
            self._position = make_position(self.position, self.model.observation_space)
            assert self._position is not None
            self._position.bind(self.training_env, self.model.observation_space)
            self._cells = self._position.cells(self.training_env, last_obs, self._reset_infos(n))

    def _reset_infos(self, n: int) -> list[dict[str, Any]]:
        infos = getattr(self.training_env, "reset_infos", None)
        return list(infos) if infos else [{} for _ in range(n)]

    def _on_step(self) -> bool:
        check_step_locals(self)
        locals_ = self.locals
        if self._table_states and not self._settle_later:  # the step's lists now, the rest before the algorithm learns
            done_list = flat_array(locals_["dones"], bool).tolist()
            new_obs = locals_["new_obs"]
            cells = None if self._position is None else self._position.cells(self.training_env, new_obs, locals_["infos"])
            self._queue.append((done_list, flat_array(locals_["rewards"]).tolist(), flat_array(new_obs).tolist(), cells))
            if True in done_list:
                self._settle_queue(locals_["infos"])
            return True
        dones = flat_array(locals_["dones"], bool)
        new_obs = locals_["new_obs"]
        cell_rewards = locals_.get("cell_rewards")  # the package's tabular agents: this decision's cells
        if cell_rewards is not None and len(cell_rewards) == 0:  # a wait: no transition, no update, no emotion
            if dones[0]:  # the decision cap fell on a wait: the episode ends all the same
                self._close_episode(0, math.nan)
                self._v[0] = float(self._values(new_obs, dones)[0])
            return True
        infos = locals_["infos"]
        done_list = dones.tolist()
        cut = self._cut(done_list, infos)
        rewards = flat_array(locals_["rewards"]).tolist()
        cells = None if self._position is None else self._position.cells(self.training_env, new_obs, infos)
        step = _Step(done_list, rewards, cut, new_obs, dones, cell_rewards, cells)
        if not self._settle_later:
            self._settle(step, self._values(new_obs, dones))
            return True
        values = locals_.get("values")  # the algorithm's values of the states the previous step reached
        if values is None:  # an algorithm that does not show them: value each step here from now on
            self._settle_pending()
            self._settle_later = False
            self._settle(step, self._values(new_obs, dones))
            return True
        if self._pending is not None:
            self._settle(self._pending, _as_floats(values))
        self._pending, self._seen_values = step, values
        return True

    def _cut(self, done_list: list[bool], infos: Any) -> dict[int, float | None]:
        """Truncated envs -> V of their last observation, valued now (RecurrentPPO's: with this step's LSTM states)."""
        cut: dict[int, float | None] = {}
        if True in done_list:
            for i, done in enumerate(done_list):
                info = infos[i]
                if done and info.get("TimeLimit.truncated", False):
                    terminal = info.get("terminal_observation")
                    cut[i] = None if terminal is None else self._terminal_value(terminal, i)
        return cut

    def _settle_queue(self, infos: Any = None) -> None:
        """
        Settle the steps of a small Discrete space queued since the algorithm last learnt (``_on_step`` keeps only their
        lists), in order; ``infos``: the last step's, when it ended an episode (an episode's end settles at its own
        step, so what is logged and when is unchanged). Their states are valued here, in the order and with the
        parameters each step would have valued them with at its own step (the algorithm has not learnt since), but in
        one burst, where the code is already warm, instead of a little between two env steps.
        """
        queue, self._queue = self._queue, []
        steps, values = [], []
        for index, (done_list, rewards, states, cells) in enumerate(queue):
            cut = self._cut(done_list, infos) if index == len(queue) - 1 and infos is not None else {}
            steps.append(_Step(done_list, rewards, cut, states, None, None, cells))
            values.append(self._table_values(states))
        for step, new_values in zip(steps, values):
            self._settle(step, new_values)

    def _settle_pending(self) -> None:
        """Settle the last step: with the values the algorithm gave its rollout's last observations, else its own."""
        step = self._pending
        if step is None:
            return
        values = self.locals.get("values") if self.locals else None
        fresh = values is not None and values is not self._seen_values
        self._settle(step, _as_floats(values) if fresh else self._values(step.new_obs, step.done_array))
        self._pending = None

    def _settle(self, step: _Step, new_values: np.ndarray | list[float]) -> None:
        """The emotions of one step of each env, with ``new_values``, ``V`` of the observations it reached."""
        values = new_values if isinstance(new_values, list) else new_values.tolist()
        rewards, cut, v, sums, gamma = step.rewards, step.cut, self._v, self._sums, self._gamma
        for i, done in enumerate(step.dones):
            truncated = done and i in cut
            if done and not truncated:
                reached = 0.0  # a terminal state anticipates nothing
            else:
                terminal = cut.get(i) if truncated else None
                reached = values[i] if terminal is None else terminal
            if step.cell_rewards is None:  # one env step: r + gamma V(s')
                delta = rewards[i] + gamma * reached - v[i]
            else:
                delta = self._return(reached, step.cell_rewards) - v[i]
            joy = delta if delta > 0.0 else 0.0
            row = sums[i]
            row[0] += joy
            row[1] += 0.0 if delta > 0.0 else -delta
            row[2 if reached > 0.0 else 3] += abs(reached)
            if step.cells is not None:  # the step's emotions, felt in the cell it was taken in
                felt = (joy, 0.0 if delta > 0.0 else -delta, max(reached, 0.0), max(-reached, 0.0))
                cell_sums = self._cell_sums.setdefault(self._cells[i], np.zeros(5))
                cell_sums[0] += 1
                cell_sums[1:] += felt
                self._cells[i] = step.cells[i]
            self._steps[i] += 1
            self._reward[i] += rewards[i]
            if done:
                self._close_episode(i, joy if not truncated else math.nan)
                v[i] = values[i]  # the first state of the next episode
            else:
                v[i] = reached

    def _return(self, reached: float, cell_rewards: list[float]) -> float:
        """What a decision of the package's agents earned, discounted as the learner discounts it."""
        gamma = self._gamma
        if len(cell_rewards) == 1 or getattr(self.model, "multi_cell", None) == "jump":
            return float(sum(cell_rewards)) + gamma * reached
        discounted = sum(r * gamma**j for j, r in enumerate(cell_rewards))  # one Eq. 1 update per cell
        return discounted + gamma ** len(cell_rewards) * reached

    def _on_rollout_end(self) -> None:
        self._settle_queue()  # before the algorithm learns from the rollout
        self._settle_pending()
        self._window.record(self.logger, self._keys, again=False)

    def _on_training_end(self) -> None:
        self._settle_queue()
        self._settle_pending()
        self._window.record(self.logger, self._keys)

    def _close_episode(self, index: int, goal_joy: float) -> None:
        steps = self._steps[index]
        means = [total / steps for total in self._sums[index]] if steps else [math.nan] * 4
        row = [len(self.rows) + 1, steps, self._reward[index], *means, goal_joy, index]
        self.rows.append(row)
        self._window.append(means)
        self._window.record(self.logger, self._keys)
        if self._csv_path is not None:
            new = not self._csv_path.exists()
            self._csv_path.parent.mkdir(parents=True, exist_ok=True)
            with self._csv_path.open("a", newline="") as handle:
                writer = csv.writer(handle)
                if new:
                    writer.writerow(BROEKENS_COLUMNS)
                writer.writerow(row)
        self._sums[index] = [0.0] * 4
        self._steps[index] = 0
        self._reward[index] = 0.0

    def _episode_csv(self) -> Path | None:
        if self.episode_log_path is not None:
            return Path(self.episode_log_path)
        folder = logger_file_folder(self.logger)
        return None if folder is None else folder / "broekens_episodes.csv"

    @property
    def cell_log(self) -> pd.DataFrame:
        """With ``position=``: one row per cell steps were taken in (``cell``, ``steps`` and the mean emotions)."""
        import pandas as pd

        rows = [[cell, int(sums[0]), *(sums[1:] / sums[0]).tolist()] for cell, sums in sorted(self._cell_sums.items())]
        return pd.DataFrame(rows, columns=["cell", "steps", *BROEKENS_EMOTIONS])

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per finished episode, columns ``BROEKENS_COLUMNS``."""
        import pandas as pd

        frame = pd.DataFrame(self.rows, columns=list(BROEKENS_COLUMNS))
        for name in ("episode", "steps", "env"):
            frame[name] = frame[name].astype("int64")
        return frame
