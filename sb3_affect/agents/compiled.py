"""
``learn`` on the compiled engine (``sb3_affect.kernel``): when the kernel applies, and how a model's state goes into
it and comes back (``sb3_affect.agents.compiled_state``). This is the agents' side of the kernel: the kernel itself knows
settings objects and transition tables only; the SB3 objects (callbacks, the Monitor, the logger) are handled here.

The kernel runs in chunks of whole episodes; between chunks this module does what the Python loop does at an episode
end that the kernel can not (the episode log, one block of columns per chunk; SB3's episode buffer, the Monitor's
statistics, the logger, the progress bar, episode-level callbacks). At the end of ``learn`` every piece of state is
written back into the model (Q-table, random generator, appraisal, UCB counts, the episode in progress) and into the
env and its wrappers, so learning can go on with either engine.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    ConvertCallback,
    ProgressBarCallback,
    StopTrainingOnMaxEpisodes,
)
from stable_baselines3.common.monitor import Monitor

from sb3_affect.agents.compiled_moving import MovingKernelRun
from sb3_affect.agents.compiled_run import RunArrays
from sb3_affect.agents.compiled_state import KernelRun
from sb3_affect.agents.reference_loop import episode_end_info, step_locals
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.core.episode_log import COLUMN
from sb3_affect.core.settings import TabularSettings
from sb3_affect.kernel import agent_settings
from sb3_affect.kernel.agent_settings import KernelAgent, kernel_agent
from sb3_affect.kernel.grid_inputs import env_reason, unwrap
from sb3_affect.kernel.moving_batch import moving_reason

__all__ = ["batch_reason", "callback_reason", "compiled_plan", "compiled_reason", "learn_compiled", "model_env_reason"]
_CHUNK_EPISODES = 16384
_PROGRESS_DECISIONS = 500_000


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


def model_env_reason(env: Any) -> str | None:
    """
    Why the kernel can not step a model's ``env`` (None: it can): ``kernel.grid_inputs.env_reason`` with SB3's Monitor
    allowed, or a MovingPursuit the moving-prey kernel steps (``kernel.moving_batch.moving_reason``).
    """
    from sb3_affect.envs import MovingPursuitEnv

    if type(unwrap(env)[0]) is MovingPursuitEnv:
        return moving_reason(env)
    return grid_env_reason(env)


def grid_env_reason(env: Any) -> str | None:
    """Why the grid kernel (``kernel.grid_loop``) can not step a model's ``env`` (None: it can)."""
    reason = env_reason(env, (Monitor,))
    if reason is None and any(isinstance(w, Monitor) and w.info_keywords for w in unwrap(env)[1]):
        return "the Monitor records info_keywords, which the kernel does not produce"
    return reason


def compiled_agent(model: Any) -> tuple[TabularSettings, KernelAgent] | str:
    """The model's settings and the agent the kernel runs, or why the kernel can not run it."""
    settings = model.compiled_settings()
    if isinstance(settings, str):
        return settings
    agent = kernel_agent(settings)
    return agent if isinstance(agent, str) else (settings, agent)


def compiled_plan(model: Any, env: Any, callback: BaseCallback | None) -> tuple[TabularSettings, KernelAgent] | str:
    """What ``model.learn`` runs on the kernel with this env and these callbacks (``compiled_agent``), or why it can not."""
    found = compiled_agent(model)
    if isinstance(found, str):
        return found
    return model_env_reason(env) or callback_reason(callback) or found


def compiled_reason(model: Any, env: Any, callback: BaseCallback | None) -> str | None:
    """Why ``model.learn`` can not run on the kernel with this env and these callbacks (None: it can)."""
    plan = compiled_plan(model, env, callback)
    return plan if isinstance(plan, str) else None


def batch_reason(model: Any, episodes: int) -> str | None:
    """Why ``simulate`` can not run ``model``'s agent as one batch on the kernel (None: it can)."""
    reason = compiled_reason(model, model.single_env(), None) or grid_env_reason(model.single_env())
    if reason is not None:
        return reason
    if model.compiled_settings().episode_parameters(0, 1) is None:
        return "a schedule depends on the training progress, which only the Python side evaluates (one episode at a time)"
    return None


def _stop_remaining(leaves: list[BaseCallback]) -> int | None:
    # (a tabular agent has one env: its budget of episodes is ``max_episodes``)
    stops = [leaf for leaf in leaves if isinstance(leaf, StopTrainingOnMaxEpisodes)]
    remaining = [leaf.max_episodes - leaf.n_episodes for leaf in stops]
    return min(remaining) if remaining else None


def learn_compiled(
    model: Any,
    env: Any,
    q: np.ndarray,
    total_timesteps: int,
    callback: BaseCallback,
    log_interval: int | None,
    plan: tuple[TabularSettings, KernelAgent],
) -> None:
    """
    ``reference_loop.run_loop`` on the kernel (see the module docstring), on the model's run methods as the Python
    loop (``resume_episode`` to ``keep_episode``), with its table ``q`` and the ``compiled_plan`` of the call.
    """
    episode = model.resume_episode(total_timesteps)
    settings, agent = plan
    run_class = MovingKernelRun if moving_reason(env) is None else KernelRun
    run: RunArrays = run_class(model, env, q, episode, settings, agent)
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
                to_dump = log_interval - model.episode_num % log_interval
                if model.logger.output_formats:  # every dump is written: stop at each
                    max_episodes = min(max_episodes, to_dump)
                elif max_episodes > to_dump:  # nothing is written: end the chunk on a dump, which leaves the logger
                    max_episodes = to_dump + (max_episodes - to_dump) // log_interval * log_interval  # as all would
            if bars:
                limit_t = min(limit_t, model.num_timesteps + _PROGRESS_DECISIONS)
            parameters = settings.episode_parameters(model.run_episodes, max_episodes)
            if parameters is None:
                max_episodes = 1
                alpha, p = np.empty(1), np.empty(1)
            else:
                alpha, p = parameters
            alpha[0] = model.alpha
            p[0] = model.episode_exploration()
            before = model.num_timesteps
            finished, _ = run.step(alpha, p, limit_t, max_episodes)
            model.num_timesteps = run.timesteps
            if finished:
                block = run.block(finished)  # the episode log's columns of the finished episodes
                model.close_episodes(block)
                run.monitor_episodes(block["cells"], block["truncated"])
                _record(model, run, log_interval)
                model.advance_schedules(total_timesteps)
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


def _record(model: Any, run: RunArrays, log_interval: int | None) -> None:
    """The logger keys of an episode end (only the last episode before a dump matters: records overwrite)."""
    logger = model.logger  # recorded whenever a logger exists, as SB3 does (per chunk of episodes, never per decision)
    row = model.last_episode_row()
    if run.agent.kind == agent_settings.AFFECT:
        counts = [row[COLUMN[name]] for name in EMOTION_NAMES]
        total = sum(counts)
        for name, count in zip(EMOTION_NAMES, counts):
            logger.record(f"affect/{name}", count / total)
        norm = row[COLUMN["norm"]]
        logger.record("affect/norm", norm if norm == norm else 0.0)
    model.log_episode_end(row[COLUMN["random_moves"]], row[COLUMN["decisions"]], log_interval)


def _call_back(
    model: Any,
    run: RunArrays,
    callback: BaseCallback,
    leaves: list[BaseCallback],
    finished: int,
    decisions: int,
    total_timesteps: int,
) -> bool:
    """Call the episode-level callbacks with the locals of the last decision of the chunk (an episode end)."""
    obs_start, act_start = run.obs_start, run.act_start
    info = run.last_info()
    if finished:
        if run.last_monitor_info is not None:
            info["episode"] = run.last_monitor_info
        info = episode_end_info(info, run.last_s2 + obs_start, run.last_terminated)
    cb_locals: dict[str, Any] = {"self": model, "total_timesteps": total_timesteps, "callback": callback}
    step_locals(cb_locals, run.state + obs_start, run.last_reward, bool(finished), info, run.last_action + act_start)
    callback.update_locals(cb_locals)
    go_on = True
    for leaf in leaves:
        leaf.n_calls += decisions - 1
        if isinstance(leaf, StopTrainingOnMaxEpisodes) and finished > 1:
            leaf.n_episodes += finished - 1
        go_on = leaf.on_step() and go_on
    return go_on
