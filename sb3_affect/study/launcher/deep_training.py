"""
One batch of the deep study trained and evaluated (``deep_batches.DeepBatch`` runs it in a worker): its seeds of one
cell trained together by the public trainer ``sb3_affect.train_many`` with one torch thread, and evaluated every
``eval_every`` env steps (``deep_recording``).

A batch's record, per seed and evaluation: the greedy policy's success rate and mean return on its evaluation envs,
and over the env steps since the previous evaluation the share of random decisions, the share of env steps in each
emotion (``AffectDQN``), the training episodes ended and reached the goal; per seed, the env step of its first
training episode that reached the goal (None: never, a censored run).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from typing import Any

import torch as th

import sb3_affect
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.core.registry import resolve_class
from sb3_affect.engine.seed_envs import seed_vec_env
from sb3_affect.study.launcher.count_bonus import CountBonus
from sb3_affect.study.launcher.deep_recording import GreedyEvaluation, TrainingRecorder
from sb3_affect.study.launcher.deep_schema import EVAL_SEED_OFFSET, RECORD_ROWS, TUNED, DeepAgent, DeepStudy

#: ``train_many``'s ``log_interval`` in the study: no run ends this many episodes, so no ``dump_logs`` resets the
#: random-decision counters of an ``ActionRepeat`` agent, which ``deep_recording`` reads.
NO_LOGS = 2**62


def agent_kwargs(study: DeepStudy, task: str, agent: DeepAgent, epsilons: Sequence[float] | None = None) -> dict[str, Any]:
    """The agent's arguments on ``task``: the study's network, the task's tuned learning rate, then the agent's own."""
    spec = study.tasks[task]
    kwargs: dict[str, Any] = dict(study.network)
    if spec.learning_rate is not None:
        kwargs["learning_rate"] = spec.learning_rate
    if agent.epsilon == TUNED:
        kwargs["exploration_fraction"] = spec.exploration_fraction
    if epsilons is not None:
        kwargs["epsilons"] = list(epsilons)
    kwargs.update(agent.kwargs)
    return kwargs


def bonus_scale(study: DeepStudy, task: str, agent: DeepAgent) -> float | None:
    return study.tasks[task].count_bonus if agent.count_bonus == TUNED else agent.count_bonus  # type: ignore[return-value]


#: The replay buffer of the agents ``check_study`` builds (what a transition costs is read from it, then scaled).
PROBE_BUFFER = 100


def check_study(study: DeepStudy, batches_at_once: int) -> None:
    """
    Before a deep study claims its folder: every agent built once, on the first task's env (Farama's, one env, a small
    buffer), so that an argument its algorithm refuses is refused now; and the memory of ``batches_at_once`` batches
    estimated from those models (each seed's replay buffer, its Q-network, target network and Adam's two moments) and
    refused when it exceeds this machine's. A ``ValueError`` of one line naming the agent, or the figure.
    """
    name, spec = next(iter(study.tasks.items()))
    env = seed_vec_env(spec.id, 1, 0, study.obs, False)
    seed_bytes = 0.0
    for index, agent in enumerate(study.agents):
        epsilons = [1.0] * (spec.budget // study.eval_every) if agent.replays is not None else None
        kwargs = {**agent_kwargs(study, name, agent, epsilons), "buffer_size": PROBE_BUFFER}
        try:
            model = resolve_class(agent.algo)("MlpPolicy", env, seed=0, device="cpu", **kwargs)
        except (ValueError, TypeError, KeyError, AssertionError) as error:
            raise ValueError(f"agents[{index}] ({agent.name}) on {name}: {' '.join(str(error).split())}") from None
        buffer = model.replay_buffer
        transition = sum(getattr(buffer, field).nbytes for field in ("observations", "next_observations", "actions",
                                                                      "rewards", "dones")) / PROBE_BUFFER
        parameters = sum(p.numel() for p in model.q_net.parameters())
        buffer_size = int(agent_kwargs(study, name, agent).get("buffer_size", 1_000_000))
        seed_bytes = max(seed_bytes, transition * buffer_size + 16 * parameters)
    size = study.seeds_per_batch or len(study.seeds)
    need = seed_bytes * size * batches_at_once
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have:
        raise ValueError(
            f"the deep study needs about {need / 2**30:.1f} GiB ({size} seeds a batch x {batches_at_once} batches at a "
            f"time x {seed_bytes / 2**20:.1f} MiB a seed: its replay buffer and networks), more than this machine's "
            f"{have / 2**30:.1f} GiB: give fewer seeds_per_batch or workers, or a smaller buffer_size"
        )


def run_batch(study: DeepStudy, task: str, agent: DeepAgent, seeds: Sequence[int],
              epsilons: Sequence[float] | None = None) -> dict[str, Any]:
    """
    Train and evaluate ``seeds`` of ``agent`` on ``task`` through ``train_many``: the batch's record. With one torch
    thread (the stacked networks are small: more threads only wait on each other); the caller's count is restored.
    """
    threads = th.get_num_threads()
    th.set_num_threads(1)
    try:
        return _run_batch(study, task, agent, seeds, epsilons)
    finally:
        th.set_num_threads(threads)


def _run_batch(study: DeepStudy, task: str, agent: DeepAgent, seeds: Sequence[int],
               epsilons: Sequence[float] | None) -> dict[str, Any]:
    start = time.process_time()
    spec, compiled, n_eval = study.tasks[task], study.env == "compiled", study.eval_episodes
    scale = bonus_scale(study, task, agent)
    eval_seeds = [EVAL_SEED_OFFSET + seed * n_eval for seed in seeds]
    evaluate = GreedyEvaluation([seed_vec_env(spec.id, n_eval, s, study.obs, compiled) for s in eval_seeds], eval_seeds)
    recorders = [TrainingRecorder() for _ in seeds]
    rows: dict[str, list[list[float]]] = {key: [] for key in RECORD_ROWS}
    emotion_rows: list[list[list[float]]] = []

    def on_models(models: list[Any]) -> None:
        success, returns = evaluate(models)
        intervals = [recorder.take_interval() for recorder in recorders]
        rows["success"].append(success.tolist())
        rows["return"].append(returns.tolist())
        for key in ("random_share", "train_episodes", "train_successes"):
            rows[key].append([interval[key] for interval in intervals])
        emotion_rows.append([interval["emotions"] for interval in intervals])

    models = sb3_affect.train_many(
        agent.algo, spec.id, list(seeds), study.n_envs, total_timesteps=spec.budget, obs=study.obs, compiled=compiled,
        log_interval=NO_LOGS, every=study.eval_every, on_models=on_models, callbacks=recorders,
        env_wrapper=(lambda env: CountBonus(env, scale)) if scale else None, **agent_kwargs(study, task, agent, epsilons),
    )

    def by_seed(table: list[list[float]]) -> list[list[float | None]]:  # (evaluations, seeds) -> (seeds, evaluations)
        return [[None if math.isnan(v) else v for v in column] for column in zip(*table)]

    affective = hasattr(models[0], "emotion_callback")
    return {
        "task": task, "agent": agent.name, "algo": agent.algo, "env_id": spec.id, "seeds": list(seeds),
        "budget": spec.budget, "eval_every": study.eval_every, "eval_episodes": n_eval,
        "eval_steps": [study.eval_every * (k + 1) for k in range(len(rows["success"]))],
        "count_bonus": scale, "epsilons": None if epsilons is None else list(epsilons),
        **{key: by_seed(table) for key, table in rows.items()},
        "emotions": {name: by_seed([[seed[k] for seed in evaluation] for evaluation in emotion_rows])
                     for k, name in enumerate(EMOTION_NAMES)} if affective else None,
        "first_success": [recorder.first_success for recorder in recorders],
        "seconds": time.process_time() - start,
    }  # fmt: skip
