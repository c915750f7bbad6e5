"""
One batch of the deep study trained and evaluated (``deep_batches.DeepBatch`` runs it in a worker): its seeds of one
cell trained together by the public trainer ``sb3_affect.train_many`` with one torch thread, and evaluated every
``evaluation.every`` env steps (``deep_recording``).

A batch's record, per seed and evaluation (arrays ``(seeds, evaluations)``, NaN where a part had no decision or
emotion): the greedy policy's success rate and mean return on its evaluation envs, and over the env steps since the
previous evaluation the share of random decisions, the share of env steps in each emotion (``AffectDQN``), the
training episodes ended and reached the goal; per seed, the env step of its first training episode that reached the
goal (None: never, a censored run). ``chunks.encode_evaluations`` stores it as one chunk.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import torch as th

import sb3_affect
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.core.registry import resolve_class
from sb3_affect.engine.seed_envs import seed_vec_env
from sb3_affect.study.launcher.chunks import EVALUATION_ROWS
from sb3_affect.study.launcher.count_bonus import CountBonus
from sb3_affect.study.launcher.deep_recording import GreedyEvaluation, TrainingRecorder
from sb3_affect.study.launcher.deep_schema import EVAL_SEED_OFFSET

if TYPE_CHECKING:
    from sb3_affect.study.launcher.schema import Sweep

#: ``train_many``'s ``log_interval`` in the study: no run ends this many episodes, so no ``dump_logs`` resets the
#: random-decision counters of an ``ActionRepeat`` agent, which ``deep_recording`` reads.
NO_LOGS = 2**62


#: The replay buffer of the agents ``check_study`` builds (what a transition costs is read from it, then scaled).
PROBE_BUFFER = 100


def check_study(study: Sweep, batches_at_once: int) -> None:
    """
    Before a deep study claims its folder: every agent built once, on the first task's env (Farama's, one env, a small
    buffer), so that an argument its algorithm refuses is refused now; and the memory of ``batches_at_once`` batches
    estimated from those models (each seed's replay buffer, its Q-network, target network and Adam's two moments) and
    refused when it exceeds this machine's. A ``ValueError`` of one line naming the agent, or the figure.
    """
    assert study.tasks is not None and study.trainer is not None and study.evaluation is not None  # (a deep study)
    name, spec = next(iter(study.tasks.items()))
    env = seed_vec_env(spec.id, 1, 0, study.trainer.obs, False)
    seed_bytes = 0.0
    for index, (agent, cell) in enumerate(zip(study.agents, study.cells())):
        epsilons = [1.0] * ((spec.total_timesteps or 0) // study.evaluation.every) if agent.replays is not None else None
        kwargs = {**cell.base["algo_kwargs"], **({} if epsilons is None else {"epsilons": epsilons}),
                  "buffer_size": PROBE_BUFFER}  # fmt: skip
        try:
            model = resolve_class(agent.algo or "")("MlpPolicy", env, seed=0, device="cpu", **kwargs)
        except (ValueError, TypeError, KeyError, AssertionError) as error:
            raise ValueError(f"agents[{index}] ({agent.name}) on {name}: {' '.join(str(error).split())}") from None
        buffer = model.replay_buffer
        transition = sum(getattr(buffer, field).nbytes for field in ("observations", "next_observations", "actions",
                                                                      "rewards", "dones")) / PROBE_BUFFER
        parameters = sum(p.numel() for p in model.q_net.parameters())
        buffer_size = int(cell.base["algo_kwargs"].get("buffer_size", 1_000_000))
        seed_bytes = max(seed_bytes, transition * buffer_size + 16 * parameters)
    size = study.trainer.seeds_per_batch or len(study.seeds if isinstance(study.seeds, list) else [])
    need = seed_bytes * size * batches_at_once
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > have:
        raise ValueError(
            f"the deep study needs about {need / 2**30:.1f} GiB ({size} seeds a batch x {batches_at_once} batches at a "
            f"time x {seed_bytes / 2**20:.1f} MiB a seed: its replay buffer and networks), more than this machine's "
            f"{have / 2**30:.1f} GiB: give fewer seeds_per_batch or workers, or a smaller buffer_size"
        )


def run_batch(base: dict[str, Any], seeds: Sequence[int], epsilons: Sequence[float] | None = None) -> dict[str, Any]:
    """
    Train and evaluate ``seeds`` of the cell whose base run config is ``base`` (``Sweep.deep_cells``) through
    ``train_many``: the batch's record. With one torch thread (the stacked networks are small: more threads only wait
    on each other); the caller's count is restored.
    """
    threads = th.get_num_threads()
    th.set_num_threads(1)
    try:
        return _run_batch(base, seeds, epsilons)
    finally:
        th.set_num_threads(threads)


def _run_batch(base: dict[str, Any], seeds: Sequence[int], epsilons: Sequence[float] | None) -> dict[str, Any]:
    start = time.process_time()
    env_id, compiled, n_eval, obs = base["env_id"], base["env"] == "compiled", base["eval_episodes"], base["obs"]
    scale = base["count_bonus"]
    eval_seeds = [EVAL_SEED_OFFSET + seed * n_eval for seed in seeds]
    evaluate = GreedyEvaluation([seed_vec_env(env_id, n_eval, s, obs, compiled) for s in eval_seeds], eval_seeds)
    recorders = [TrainingRecorder() for _ in seeds]
    rows: dict[str, list[list[float]]] = {key: [] for key in EVALUATION_ROWS}
    emotion_rows: list[list[list[float]]] = []

    def on_models(models: list[Any]) -> None:
        success, returns = evaluate(models)
        intervals = [recorder.take_interval() for recorder in recorders]
        rows["success"].append(success.tolist())
        rows["return"].append(returns.tolist())
        for key in ("random_share", "train_episodes", "train_successes"):
            rows[key].append([interval[key] for interval in intervals])
        emotion_rows.append([interval["emotions"] for interval in intervals])

    kwargs = {**base["algo_kwargs"], **({} if epsilons is None else {"epsilons": list(epsilons)})}
    models = sb3_affect.train_many(
        base["algo"], env_id, list(seeds), base["n_envs"], total_timesteps=base["budget"], obs=obs, compiled=compiled,
        log_interval=NO_LOGS, every=base["eval_every"], on_models=on_models, callbacks=recorders,
        env_wrapper=(lambda env: CountBonus(env, scale)) if scale else None, **kwargs,
    )
    affective = hasattr(models[0], "emotion_callback")
    return {
        **{key: np.asarray(table, dtype=float).T for key, table in rows.items()},  # (seeds, evaluations) each
        "emotions": {name: np.asarray([[seed[k] for seed in evaluation] for evaluation in emotion_rows], dtype=float).T
                     for k, name in enumerate(EMOTION_NAMES)} if affective else None,
        "first_success": [recorder.first_success for recorder in recorders],
        "seconds": time.process_time() - start,
    }  # fmt: skip
