"""
The deep study's runs (``study: deep``, ``sb3_affect.study.launcher.deep_schema``): for each task and agent, one *cell*,
all its seeds trained together by the engine's lockstep trainer (``sb3_affect.engine.lockstep``, what ``train_many``
runs), each seed's greedy policy evaluated every ``eval_every`` env steps on ``eval_episodes`` evaluation envs of its
own (seeded apart from every training env), one episode per env.

A cell writes ``OUT/cells/<task>__<agent>.json`` when it is done (a finished cell is not run again); ``OUT/deep_study.json``
holds the validated study, and a folder holding another study's is refused. Per seed and evaluation it records the greedy
policy's success rate and mean return, and over the env steps since the previous evaluation: the share of random
decisions (ε for SB3's DQN, the share of random decisions of an ``ActionRepeat`` agent, both after ``learning_starts``),
the share of env steps in each emotion (``AffectDQN``), and the training episodes ended and reached the goal; per seed,
the env step of its first training episode that reached the goal (None: never, a censored run).

A cell whose agent ``replays`` another waits for that agent's cell on the same task and takes its random share, averaged
over seeds, part by part as its ε (``ReplayedEpsilonDQN``). Cells run in ``workers`` processes (one torch thread
each), or in this process when ``workers`` is 1 (one torch thread while they run: the stacked networks are small
and more threads only wait on each other, most of all on a busy machine).
"""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import time
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import sb3_affect
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.core.registry import resolve_class
from sb3_affect.study.launcher.deep_schema import TUNED, DeepAgent, DeepStudy

#: The evaluation envs of seed s are seeded ``EVAL_SEED_OFFSET + s * eval_episodes + i``: apart from every training env
#: (seeded ``s + i`` for ``i < n_envs``) for seeds below the offset.
EVAL_SEED_OFFSET = 1_000_000
#: The file naming the study a folder holds.
STUDY_FILE = "deep_study.json"
#: The folder of the finished cells.
CELLS = "cells"


def cell_path(out: Path, task: str, agent: str) -> Path:
    return out / CELLS / f"{task}__{agent}.json"


@dataclass
class DeepSummary:
    """What ``run_deep_study`` did: cells trained now and found done, wall seconds, the folder."""

    name: str
    trained: int
    reused: int
    seconds: float
    out_dir: Path

    @property
    def total(self) -> int:
        return self.trained + self.reused


def vec_env(study: DeepStudy, env_id: str, n_envs: int, seed: int) -> Any:
    """One seed's VecEnv of ``n_envs`` envs: the compiled MiniGrid, or Farama's with ``FlatObsWrapper`` (``study.env``)."""
    if study.env == "compiled":
        make = getattr(sb3_affect, "minigrid_vec_env", None)
        if make is None:
            raise ValueError("env='compiled': this install has no sb3_affect.minigrid_vec_env; give env: farama")
        return make(env_id, n_envs, seed=seed, obs=study.obs)
    from sb3_affect.engine.seed_envs import seed_vec_env  # (torch: the deep study's engine)

    return seed_vec_env(env_id, n_envs, seed, study.obs)


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


def replayed_epsilons(source: dict[str, Any]) -> list[float]:
    """A finished cell's random share, averaged over its seeds, per part of training (a part without decisions: 1)."""
    shares = np.asarray(source["random_share"], dtype=float)  # (seeds, parts); None read as NaN
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a part without decisions in any seed
        mean = np.nanmean(shares, axis=0)
    return [1.0 if math.isnan(value) else float(value) for value in mean]


# -- one cell ------------------------------------------------------------------------------------------------------------
def _trainer_class() -> type:
    """The lockstep trainer with the study's recording and evaluation (imported here: torch only where cells run)."""
    from sb3_affect.agents.action_repeat import ActionRepeat  # (torch: off the tabular sweep path)
    from sb3_affect.engine.lockstep import Lockstep  # (torch: the deep study's engine)
    from sb3_affect.engine.seed_envs import SeedEnvs  # (torch: the deep study's engine)

    class Evaluating(Lockstep):
        """``Lockstep`` that records each seed's exploration and evaluates its greedy policy every ``eval_every`` steps."""

        def setup_study(self, eval_envs: list[Any], eval_seeds: list[int], eval_every: int) -> None:
            self.eval_envs, self.eval_seeds, self.eval_every = SeedEnvs(eval_envs), eval_seeds, eval_every
            self.next_eval = eval_every
            n = self.n_seeds
            self.rows: dict[str, list[list[float]]] = {key: [] for key in (
                "success", "return", "random_share", "train_episodes", "train_successes")}  # fmt: skip
            self.emotion_rows: dict[str, list[list[float]]] = {name: [] for name in EMOTION_NAMES}
            self.first_success: list[int | None] = [None] * n
            self._reset_interval()
            self._seen = np.zeros((n, 2), dtype=np.int64)

        def _reset_interval(self) -> None:
            n = self.n_seeds
            self.random = np.zeros((n, 2))  # (random decisions or summed ε, decisions or steps)
            self.emotions = np.zeros((n, len(EMOTION_NAMES)))
            self.episodes = np.zeros((n, 2))  # (ended, reached the goal)

        def _store(self, buffer_actions: np.ndarray, new_obs: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
                   infos: list[list[dict[str, Any]]]) -> None:
            for s, e in zip(*np.nonzero(dones)):
                goal = not infos[s][e].get("TimeLimit.truncated", False)
                self.episodes[s] += (1, goal)
                if goal and self.first_success[s] is None:
                    self.first_success[s] = int(self.models[s].num_timesteps)
            for s, model in enumerate(self.models):
                for emotion in getattr(model, "_emotions", None) or ():
                    self.emotions[s, int(emotion)] += 1
            super()._store(buffer_actions, new_obs, rewards, dones, infos)

        def _after_step(self, dones: np.ndarray, log_interval: int) -> None:
            first = self.models[0]
            if first.num_timesteps > first.learning_starts:
                for s, model in enumerate(self.models):
                    if isinstance(model, ActionRepeat):  # its counts since its last log
                        self.random[s] += (model._random_decisions, model._decisions) - self._seen[s]
                    else:
                        self.random[s] += (model.exploration_rate, 1)
            super()._after_step(dones, log_interval)
            self._seen = np.array([(m._random_decisions, m._decisions) if isinstance(m, ActionRepeat) else (0, 0)
                                   for m in self.models])
            if first.num_timesteps >= self.next_eval:
                self.next_eval += self.eval_every
                self._record()

        def _record(self) -> None:
            success, returns = self.evaluate()
            rows = self.rows
            rows["success"].append(success.tolist())
            rows["return"].append(returns.tolist())
            with np.errstate(invalid="ignore", divide="ignore"):
                rows["random_share"].append((self.random[:, 0] / self.random[:, 1]).tolist())
                steps = self.emotions.sum(axis=1, keepdims=True)
                shares = np.where(steps > 0, self.emotions / np.maximum(steps, 1), np.nan)
            for index, name in enumerate(EMOTION_NAMES):
                self.emotion_rows[name].append(shares[:, index].tolist())
            rows["train_episodes"].append(self.episodes[:, 0].tolist())
            rows["train_successes"].append(self.episodes[:, 1].tolist())
            self._reset_interval()

        def evaluate(self) -> tuple[np.ndarray, np.ndarray]:
            """Each seed's greedy policy for one episode on each of its evaluation envs: (success rate, mean return)."""
            envs = self.eval_envs
            for env, seed in zip(envs.envs, self.eval_seeds):
                env.seed(seed)
            obs = np.stack([np.asarray(env.reset()) for env in envs.envs])
            finished = np.zeros(obs.shape[:2], dtype=bool)
            reached = np.zeros(obs.shape[:2], dtype=bool)
            returns = np.zeros(obs.shape[:2])
            while not finished.all():
                obs, rewards, dones, infos = envs.step(self.stack.greedy(obs))
                live = ~finished
                returns[live] += rewards[live]
                for s, e in zip(*np.nonzero(dones & live)):
                    finished[s, e] = True
                    reached[s, e] = not infos[s][e].get("TimeLimit.truncated", False)
            return reached.mean(axis=1), returns.mean(axis=1)

    return Evaluating


def build_cell(study: DeepStudy, task: str, agent: DeepAgent, epsilons: Sequence[float] | None = None) -> Any:
    """The lockstep trainer of one cell, ready to ``learn(budget)``: a model per seed, its evaluation envs set up."""
    from sb3_affect.study.launcher.count_bonus import CountBonus  # (torch: SB3's VecEnv wrapper)

    spec = study.tasks[task]
    cls = resolve_class(agent.algo)
    kwargs = agent_kwargs(study, task, agent, epsilons)
    scale = bonus_scale(study, task, agent)
    models = []
    for seed in study.seeds:
        env = vec_env(study, spec.id, study.n_envs, seed)
        models.append(cls("MlpPolicy", CountBonus(env, scale) if scale else env, seed=seed, device="cpu", **kwargs))
    n_eval = study.eval_episodes
    eval_seeds = [EVAL_SEED_OFFSET + seed * n_eval for seed in study.seeds]
    trainer = _trainer_class()(models, study.seeds)
    trainer.setup_study([vec_env(study, spec.id, n_eval, seed) for seed in eval_seeds], eval_seeds, study.eval_every)
    return trainer


def run_cell(study: DeepStudy, task: str, agent: DeepAgent, epsilons: Sequence[float] | None = None) -> dict[str, Any]:
    """Train and evaluate every seed of ``agent`` on ``task`` together; the cell's record (see the module docstring)."""
    start = time.perf_counter()
    spec = study.tasks[task]
    trainer = build_cell(study, task, agent, epsilons)
    trainer.learn(spec.budget)
    models, n_eval, scale = trainer.models, study.eval_episodes, bonus_scale(study, task, agent)

    def by_seed(rows: list[list[float]]) -> list[list[float | None]]:
        return [[None if math.isnan(v) else v for v in column] for column in np.asarray(rows, dtype=float).T.tolist()]

    return {
        "task": task, "agent": agent.name, "algo": agent.algo, "env_id": spec.id, "seeds": list(study.seeds),
        "budget": spec.budget, "eval_every": study.eval_every, "eval_episodes": n_eval,
        "eval_steps": [study.eval_every * (k + 1) for k in range(len(trainer.rows["success"]))],
        "count_bonus": scale, "epsilons": None if epsilons is None else list(epsilons),
        **{key: by_seed(rows) for key, rows in trainer.rows.items()},
        "emotions": {name: by_seed(rows) for name, rows in trainer.emotion_rows.items()}
        if hasattr(models[0], "emotion_callback") else None,
        "first_success": trainer.first_success,
        "seconds": time.perf_counter() - start,
    }  # fmt: skip


def _cell_in_worker(study_data: dict[str, Any], task: str, agent_index: int, epsilons: list[float] | None) -> dict[str, Any]:
    import torch  # (torch: off the tabular sweep path)

    torch.set_num_threads(1)
    study = DeepStudy.model_validate(study_data)
    return run_cell(study, task, study.agents[agent_index], epsilons)


# -- the study -----------------------------------------------------------------------------------------------------------
def _write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)


def _claim_folder(study: DeepStudy, out: Path) -> None:
    """Write ``OUT/deep_study.json``, or refuse a folder that holds another study's results (one line)."""
    marker = out / STUDY_FILE
    data = study.model_dump(mode="json")
    if marker.is_file() and not marker.is_symlink():
        if json.loads(marker.read_text()) != data:
            raise ValueError(f"{out} holds the results of another deep study ({marker} differs): give another --out")
        return
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"{out} is not empty and holds no {STUDY_FILE}: give an empty or new folder")
    _write_json(marker, data)


def run_deep_study(
    study: DeepStudy, out: Path, workers: int | None = 1, log: Callable[[str], None] = print
) -> DeepSummary:
    """
    Run every cell of ``study`` not yet in ``out`` (tasks x agents, each cell all seeds), ``workers`` cells at a time.

    :param workers: processes (None: the usable CPUs; 1: in this process)
    :param log: where one line per finished cell goes
    """
    out = Path(out)
    _claim_folder(study, out)
    start = time.perf_counter()
    workers = workers or len(os.sched_getaffinity(0))
    todo = [(task, index) for task in study.tasks for index in range(len(study.agents))]
    done = {(task, agent.name) for task in study.tasks for agent in study.agents if cell_path(out, task, agent.name).is_file()}
    reused = len(done)
    todo = [(task, index) for task, index in todo if (task, study.agents[index].name) not in done]
    trained = 0

    def ready(task: str, index: int) -> bool:
        source = study.agents[index].replays
        return source is None or (task, source) in done

    def epsilons(task: str, index: int) -> list[float] | None:
        source = study.agents[index].replays
        return None if source is None else replayed_epsilons(json.loads(cell_path(out, task, source).read_text()))

    def finish(result: dict[str, Any]) -> None:
        nonlocal trained
        _write_json(cell_path(out, result["task"], result["agent"]), result)
        done.add((result["task"], result["agent"]))
        trained += 1
        final = [row[-1] for row in result["success"] if row]
        log(f"   {result['task']} {result['agent']}: {len(result['seeds'])} seeds, final greedy success "
            f"{np.mean(final) if final else math.nan:.2f}, {result['seconds']:.1f} s")

    if workers == 1:
        import torch  # (torch: off the tabular sweep path)

        threads = torch.get_num_threads()
        torch.set_num_threads(1)  # the stacked networks are small: more threads only wait on each other
        try:
            while todo:
                task, index = next(cell for cell in todo if ready(*cell))
                todo.remove((task, index))
                finish(run_cell(study, task, study.agents[index], epsilons(task, index)))
        finally:
            torch.set_num_threads(threads)
    else:
        data = study.model_dump(mode="json")
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            running: set[Future[dict[str, Any]]] = set()
            while todo or running:
                for cell in [cell for cell in todo if ready(*cell)]:
                    todo.remove(cell)
                    running.add(pool.submit(_cell_in_worker, data, cell[0], cell[1], epsilons(*cell)))
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for future in finished:
                    finish(future.result())
    return DeepSummary(study.name, trained, reused, time.perf_counter() - start, out)
