"""
``learn`` on the compiled engine: when the kernel applies, and how a model's state goes into it and comes back.

The kernel runs in chunks of whole episodes; between chunks this module does what the Python loop does at an episode
end that the kernel can not (the episode rows, SB3's episode buffer, the Monitor's statistics, the logger, the
progress bar, episode-level callbacks). At the end of ``learn`` every piece of state is written back into the model
(Q-table, random generator, appraisal, UCB counts, the episode in progress) and into the env and its wrappers, so
learning can go on with either engine.
"""

from __future__ import annotations

import gc
import time
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    ConvertCallback,
    ProgressBarCallback,
    StopTrainingOnMaxEpisodes,
)

from sb3_affect.kernel import loop
from sb3_affect.kernel.agents import agent_spec, current_exploration, episode_schedule
from sb3_affect.kernel.inputs import env_reason, unwrap
from sb3_affect.kernel.state import KernelRun

__all__ = ["callback_reason", "compiled_reason", "env_reason", "learn_compiled", "unwrap"]
_CHUNK_EPISODES = 4096
_PROGRESS_DECISIONS = 500_000

_DONE = np.array([True])
_DONE.flags.writeable = False


def callback_leaves(callback: BaseCallback) -> list[BaseCallback]:
    """The callbacks inside ``callback`` (CallbackList flattened; an empty ConvertCallback dropped)."""
    if isinstance(callback, CallbackList):
        return [leaf for child in callback.callbacks for leaf in callback_leaves(child)]
    if isinstance(callback, ConvertCallback) and callback.callback is None:
        return []
    return [callback]


def callback_reason(callback: BaseCallback | None) -> str | None:
    """Why the callbacks need the Python loop (None: the kernel can serve them)."""
    if callback is None:
        return None
    for leaf in callback_leaves(callback):
        if isinstance(leaf, (ProgressBarCallback, StopTrainingOnMaxEpisodes)) or getattr(leaf, "episode_level", False):
            continue
        return (
            f"the callback {type(leaf).__name__} is called after every decision; the kernel calls back only at "
            "episode ends (StopTrainingOnMaxEpisodes, the progress bar, and callbacks with episode_level = True)"
        )
    return None


def compiled_reason(model: Any, env: Any, callback: BaseCallback | None) -> str | None:
    """Why ``model.learn`` can not run on the kernel with this env and these callbacks (None: it can)."""
    spec = agent_spec(model)
    if isinstance(spec, str):
        return spec
    return env_reason(env) or callback_reason(callback)


def _stop_remaining(leaves: list[BaseCallback]) -> int | None:
    remaining = [leaf._total_max_episodes - leaf.n_episodes for leaf in leaves if isinstance(leaf, StopTrainingOnMaxEpisodes)]
    return min(remaining) if remaining else None


def learn_compiled(model: Any, env: Any, total_timesteps: int, callback: BaseCallback, log_interval: int | None) -> None:
    """``sb3_affect.loop.run_loop`` on the kernel (see the module docstring)."""
    if model._episode_state is None:
        model._begin_episode(total_timesteps)
    spec = agent_spec(model)
    assert not isinstance(spec, str)
    run = KernelRun(model, env, spec)
    leaves = callback_leaves(callback)
    bars = [leaf for leaf in leaves if isinstance(leaf, ProgressBarCallback)]
    episodic = [leaf for leaf in leaves if not isinstance(leaf, ProgressBarCallback)]
    one_at_a_time = any(not isinstance(leaf, StopTrainingOnMaxEpisodes) for leaf in episodic)
    calls_before = model.num_timesteps
    try:
        while model.num_timesteps < total_timesteps:
            limit_t = total_timesteps
            max_episodes = 1 if one_at_a_time else _CHUNK_EPISODES
            remaining = _stop_remaining(episodic)
            if remaining is not None:
                if remaining <= 0:  # the Python loop would stop after one decision
                    limit_t = model.num_timesteps + 1
                max_episodes = min(max_episodes, max(remaining, 1))
            if log_interval is not None and log_interval > 0:
                to_dump = log_interval - model._episode_num % log_interval
                if model.logger.output_formats:  # every dump is written: stop at each
                    max_episodes = min(max_episodes, to_dump)
                elif max_episodes > to_dump:  # nothing is written: end the chunk on a dump, which leaves the logger
                    max_episodes = to_dump + (max_episodes - to_dump) // log_interval * log_interval  # as all would
            if bars:
                limit_t = min(limit_t, model.num_timesteps + _PROGRESS_DECISIONS)
            schedule = episode_schedule(model, spec.kind, len(model._episode_rows), max_episodes)
            if schedule is None:
                max_episodes = 1
                alpha, p = np.empty(1), np.empty(1)
            else:
                alpha, p = schedule
            alpha[0] = model._alpha
            p[0] = current_exploration(model, spec.kind)
            before = model.num_timesteps
            finished, _ = run.step(alpha, p, limit_t, max_episodes)
            model.num_timesteps = run.timesteps
            if finished:
                _close_episodes(model, run, finished)
                _record(model, run, log_interval)
                model._update_current_progress_remaining(model.num_timesteps, total_timesteps)
                model._update_schedules()
            for bar in bars:
                bar.pbar.update(model.num_timesteps - before)
            if episodic and (finished or limit_t == before + 1):
                go_on = _call_back(
                    model, run, callback, episodic, finished, model.num_timesteps - calls_before, total_timesteps
                )
                calls_before = model.num_timesteps
                if not go_on:
                    break
    finally:
        for leaf in leaves:
            if not isinstance(leaf, ProgressBarCallback):
                leaf.n_calls += model.num_timesteps - calls_before
        run.write_back()


def _close_episodes(model: Any, run: KernelRun, finished: int) -> None:
    """``TabularQAlgorithm._close_episode`` for the kernel's ``finished`` episodes (the logger aside), in bulk."""
    ints, floats = run.out_i[:finished], run.out_f[:finished]
    first = len(model._episode_rows) + 1
    truncated = ints[:, loop.O_TRUNCATED].astype(bool)
    columns = [  # each as Python ints, floats or bools (``tolist``), in the order of ``EPISODE_COLUMNS``' rows
        range(first, first + finished),
        ints[:, loop.O_DECISIONS].tolist(),
        ints[:, loop.O_CELLS].tolist(),
        floats[:, 0].tolist(),
        ints[:, loop.O_OPTIMAL].astype(bool).tolist(),
        truncated.tolist(),
        ints[:, loop.O_RANDOM].tolist(),
        ints[:, loop.O_WAITS].tolist(),
        *(ints[:, column].tolist() for column in range(loop.O_JOY, loop.O_ANGER + 1)),
        ints[:, loop.O_GREEDY].astype(bool).tolist(),
        floats[:, 1].tolist(),
    ]
    enabled = gc.isenabled()
    gc.disable()  # thousands of new row lists at once: no collection passes in between (they hold no cycles)
    try:
        model._episode_rows.extend(map(list, zip(*columns)))
    finally:
        if enabled:
            gc.enable()
    model._truncated_episodes += int(truncated.sum())
    model._episode_num += finished
    buffer = model.ep_info_buffer
    keep = finished if buffer.maxlen is None else min(finished, buffer.maxlen)
    stamp = round(time.time() - model.start_time / 1e9, 6)
    for j in range(finished - keep, finished):
        buffer.append(
            {"r": float(floats[j, 0]), "l": int(ints[j, loop.O_DECISIONS]), "c": int(ints[j, loop.O_CELLS]), "t": stamp}
        )
    run.monitor_episodes(ints[:, loop.O_CELLS], truncated)


def _record(model: Any, run: KernelRun, log_interval: int | None) -> None:
    """The logger keys of an episode end (only the last episode before a dump matters: records overwrite)."""
    logger = model.logger  # recorded whenever a logger exists, as SB3 does (per chunk of episodes, never per decision)
    row = model._episode_rows[-1]
    if run.spec.kind == loop.AFFECT:
        counts = row[8:12]
        total = sum(counts)
        for name, count in zip(("joy", "sadness", "fear", "anger"), counts):
            logger.record(f"affect/{name}", count / total)
        norm = row[13]
        logger.record("affect/norm", norm if norm == norm else 0.0)
    logger.record("affect/equivalent_epsilon", row[6] / row[1])
    if log_interval is not None and model._episode_num % log_interval == 0:
        model.dump_logs()


def _call_back(
    model: Any,
    run: KernelRun,
    callback: BaseCallback,
    leaves: list[BaseCallback],
    finished: int,
    decisions: int,
    total_timesteps: int,
) -> bool:
    """Call the episode-level callbacks with the locals of the last decision of the chunk (an episode end)."""
    obs_start, act_start = run.obs_start, run.act_start
    s2, prev = run.last_s2, run.last_prev
    info: dict[str, Any] = {"cell": divmod(s2, run.size), "moved": s2 != prev}
    if finished:
        if run.last_monitor_info is not None:
            info["episode"] = run.last_monitor_info
        info["terminal_observation"] = s2 + obs_start
        if not run.last_terminated:
            info["TimeLimit.truncated"] = True
    callback.update_locals(
        {
            "self": model,
            "total_timesteps": total_timesteps,
            "callback": callback,
            "new_obs": [run.state + obs_start],
            "rewards": [run.last_reward],
            "dones": _DONE if finished else np.array([False]),
            "infos": [info],
            "actions": [run.last_action + act_start],
        }
    )
    go_on = True
    for leaf in leaves:
        leaf.n_calls += decisions - 1
        if isinstance(leaf, StopTrainingOnMaxEpisodes) and finished > 1:
            leaf.n_episodes += finished - 1
        go_on = leaf.on_step() and go_on
    return go_on
