"""
Speed benchmark: decisions per second of the SB3-interface learn loops on both engines (the Python loop and the
compiled kernel) against a bare pure-Python loop, the kernel alone on the same decisions and SB3's DQN, ``simulate``
of the paper protocol on the kernel, the kernel's cold and warm start, and the wall time of the paper protocol through
the launcher; with ``--all``, also the other speed figures of the studies (below).

    python benchmarks/bench.py                 # full run (a few minutes), table on stdout, CSV in benchmarks/results.csv
    python benchmarks/bench.py --all           # every figure: also the studies' kernels and the report of a folder
    python benchmarks/bench.py --large         # also the paper protocol with 10,000 seeds per cell through simulate
    python benchmarks/bench.py --smoke         # seconds: tiny sizes, no protocol (what the test suite runs)
    python benchmarks/bench.py --observers     # only the emotion callbacks' cost beside SB3's DQN and PPO (minutes)

Every figure is the median of repeated runs in this one process. The learn loops are measured in paired rounds (the
bare loop, then each learn loop, each compiled one followed by the kernel alone on its decisions); a ratio is the
median of the rounds' ratios, and every round is printed with the machine's load. "Kernel alone" is the kernel's
batch call (``simulate``'s, ``kernel.grid_batch.run_batch``) for the same seed and the episodes the compiled ``learn``
finished; only the call is timed (its inputs, seed key and output rows are made before it): compiled ``learn`` /
kernel alone is what ``learn`` adds to the decisions themselves.

The observers' cost (in the full run, or alone with ``--observers``; ``--observer-setup TEXT``: only the setups whose
name holds TEXT): ``learn`` of SB3's DQN on FrozenLake-v1 (16 states) and on the 15 x 15 grid (225 states, the README's
example) with no callback, with ``EmotionCallback``, with ``BroekensCallback`` (and with both, on the grid), of PPO on
CartPole-v1 without and with ``BroekensCallback``, and of PPO on MiniGrid-Empty-8x8 (4 envs, ``FlatObsWrapper``,
``position="minigrid"``) without, with ``EmotionCallback`` and with both callbacks, torch on one thread, in rounds
that alternate the runs (their order rotating), each run's
steps per second of wall time and of the process's CPU time (a shared machine's other processes slow the first, not
the second); a figure is the median over rounds of its rate relative to the bare algorithm's in the same round
(target: at least 0.95). Each run with a callback also gives the share of its CPU time spent in the callback's hooks,
taken within the run and so steadier on a busy machine (target: at most 0.05).

``--studies`` adds the hunter-team and moving-prey kernels against their Python references (paired rounds) and, with
``--study-seeds N``, their studies at N seeds, from ``benchmarks/bench_studies.py`` where that benchmark exists;
``--report-folder DIR`` (or ``--report-seeds N``) adds ``sb3-affect report`` and ``status`` of a results folder
(``benchmarks/bench_report.py``: wall time and peak memory in a fresh process). ``--minigrid`` adds ``AffectDQN``
against ``DQN`` on MiniGrid-Empty-8x8 with 4 envs and the tabular agents on ``TabularMiniGrid`` against a bare loop
(``benchmarks/bench_minigrid.py``; needs the ``[minigrid]`` extra). ``--all`` is ``--studies --minigrid
--study-seeds 1000 --report-seeds 10000``.
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import os
import platform
import random
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import gymnasium as gym
import numpy as np

import sb3_affect
from sb3_affect import AffectQ, QLearning

ENV_ID = "sb3_affect/GridPursuit-v0"


def bare_loop(env: gym.Env, steps: int, epsilon: float = 0.1, alpha: float = 1.0, gamma: float = 0.8, seed: int = 0) -> int:
    """The floor: epsilon-greedy tabular Q-learning in plain Python (lists, ``random``, ``env.step``)."""
    rng = random.Random(seed)
    n_actions = int(env.action_space.n)  # type: ignore[attr-defined]
    q = [[0.0] * n_actions for _ in range(int(env.observation_space.n))]  # type: ignore[attr-defined]
    s = int(env.reset(seed=seed)[0])
    for _ in range(steps):
        row = q[s]
        if rng.random() < epsilon:
            a = rng.randrange(n_actions)
        else:
            best = max(row)
            a = row.index(best) if row.count(best) == 1 else rng.choice([i for i, v in enumerate(row) if v == best])
        obs, r, terminated, truncated, _ = env.step(a)
        s2 = int(obs)
        target = r if terminated else r + gamma * max(q[s2])
        row[a] += alpha * (target - row[a])
        s = s2
        if terminated or truncated:
            s = int(env.reset()[0])
    return steps


def bare_loop_rate(steps: int) -> float:
    """Decisions per second of ``bare_loop`` (the env built outside the timed part, as ``learn_rate``'s model is)."""
    env = gym.make(ENV_ID)
    start = time.perf_counter()
    bare_loop(env, steps)
    return steps / (time.perf_counter() - start)


def timed(fn: Callable[[], int], repeats: int) -> float:
    """Median units per second of ``fn`` (which returns the units it did) over ``repeats`` runs."""
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        units = fn()
        rates.append(units / (time.perf_counter() - start))
    return statistics.median(rates)


def learn_rate(cls: type, steps: int, **kwargs: object) -> Callable[[], float]:
    """``cls("Grid", env).learn(steps)``; the timed part is ``learn`` (building the model is a fixed cost of ~ms)."""

    def run() -> float:
        model = cls("Grid", gym.make(ENV_ID), seed=0, **kwargs)
        start = time.perf_counter()
        model.learn(steps)
        return model.num_timesteps / (time.perf_counter() - start)

    return run


def kernel_alone(algo: str, steps: int, **kwargs: object) -> Callable[[], float]:
    """
    The kernel alone on ``learn_rate``'s decisions: the one kernel call ``simulate`` makes (``kernel.grid_batch.run_batch``)
    for seed 0 and the episodes a compiled ``learn(steps)`` finishes (checked to be the same episodes). Only the call
    is timed: its inputs, its seed key and its output rows are made before it.
    """
    from sb3_affect.kernel import state_layout
    from sb3_affect.kernel.grid_batch import batch_columns, run_batch
    from sb3_affect.kernel.grid_inputs import settings_inputs
    from sb3_affect.kernel.mt19937 import seed_keys

    model = getattr(sb3_affect, algo)("Grid", gym.make(ENV_ID), seed=0, **kwargs)
    model.learn(steps)
    log = model.episode_log
    episodes = len(log)
    inputs = settings_inputs(algo, kwargs, ENV_ID, None, episodes)
    assert inputs is not None, f"{algo} {kwargs} does not run on the kernel"
    if episodes:
        assert (batch_columns(inputs, [0], episodes)["decisions"] == log["decisions"].to_numpy()).all()
    keys, lengths = seed_keys([0])

    def run() -> float:
        out_i = np.empty((episodes, state_layout.N_OUT_I), dtype=np.int64)  # as learn's: rows the kernel writes in full
        out_f = np.empty((episodes, 2))
        start = time.perf_counter()
        run_batch(inputs, keys, lengths, episodes, out_i, out_f)
        seconds = time.perf_counter() - start
        return int(out_i[:, state_layout.O_DECISIONS].sum()) / seconds

    return run


def load() -> float:
    """The 1-minute load average (other processes on the machine)."""
    return os.getloadavg()[0]


def median_rate(fn: Callable[[], float], repeats: int) -> float:
    return statistics.median(fn() for _ in range(repeats))


EPSILONS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)


def simulate_protocol(seeds: int, batch: int = 1000) -> tuple[float, int]:
    """Seconds and decisions of the paper protocol (9 epsilon-greedy + 9 affective cells x seeds x 200 episodes)."""
    from sb3_affect.engine.simulation import simulate

    start, decisions = time.perf_counter(), 0
    for cell, epsilon in enumerate(EPSILONS):
        for first in range(0, seeds, batch):
            seed_list = range(first, min(seeds, first + batch))
            rows = simulate("QLearning", {"exploration_rate": epsilon}, ENV_ID, None, seed_list, 200)
            decisions += int(rows["decisions"].sum())
            affective = range(10**6 * (cell + 1) + first, 10**6 * (cell + 1) + seed_list.stop)
            decisions += int(simulate("AffectQ", {}, ENV_ID, None, affective, 200)["decisions"].sum())
    return time.perf_counter() - start, decisions


def kernel_start_seconds(cache_dir: str) -> float:
    """Wall time of a fresh process that imports the package and runs one tiny simulate of each agent kind."""
    code = (
        "from sb3_affect.engine.simulation import simulate\n"
        "for algo in ('QLearning', 'AffectQ', 'Boltzmann', 'UCBQLearning'):\n"
        "    simulate(algo, {}, 'sb3_affect/GridPursuit-v0', None, [0], 1)\n"
    )
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True, env={**os.environ, "NUMBA_CACHE_DIR": cache_dir})
    return time.perf_counter() - start


def dqn_rate(steps: int) -> Callable[[], int]:
    import torch as th
    from stable_baselines3 import DQN

    th.set_num_threads(1)

    def run() -> int:
        model = DQN("MlpPolicy", gym.make(ENV_ID), learning_starts=100, seed=0)
        model.learn(steps)
        return int(model.num_timesteps)

    return run


class ObserverSetup(NamedTuple):
    """One observers' setup: the algorithm, its env and keywords, its steps per run (full run, smoke run; the smoke run
    also shortens PPO's rollouts), the observers timed (``+`` joins callbacks attached together), the envs of its
    VecEnv, a MiniGrid observation wrapper and the callbacks' keywords (``position``)."""

    algo: str
    env_id: str
    kwargs: dict[str, object]
    sizes: tuple[int, int]
    observers: tuple[str, ...]
    n_envs: int = 1
    wrapper: str | None = None
    callback_kwargs: dict[str, object] = {}


#: The observers' setups: FrozenLake's 16 states, the README's own example (the 15 x 15 grid, 225 states), PPO on
#: CartPole and PPO on MiniGrid with the cell read from the env (``position="minigrid"``).
OBSERVER_SETUPS: dict[str, ObserverSetup] = {
    "DQN on FrozenLake-v1": ObserverSetup("DQN", "FrozenLake-v1", {"learning_starts": 100}, (4000, 300),
                                          ("EmotionCallback", "BroekensCallback")),
    "DQN on sb3_affect/GridPursuit-v0 (225 states)": ObserverSetup(
        "DQN", ENV_ID, {}, (4000, 300), ("EmotionCallback", "BroekensCallback", "EmotionCallback+BroekensCallback")),
    "PPO on CartPole-v1": ObserverSetup("PPO", "CartPole-v1", {}, (4096, 256), ("BroekensCallback",)),
    "PPO on MiniGrid-Empty-8x8-v0, 4 envs, position=minigrid": ObserverSetup(
        "PPO", "MiniGrid-Empty-8x8-v0", {}, (8192, 512), ("EmotionCallback", "EmotionCallback+BroekensCallback"),
        n_envs=4, wrapper="FlatObsWrapper", callback_kwargs={"position": "minigrid"}),
}


#: The hooks SB3 calls on a callback during ``learn``: the time spent in them is the callback's share.
HOOKS = ("init_callback", "on_training_start", "on_rollout_start", "update_locals", "on_step", "on_rollout_end",
         "on_training_end")


def timed_hooks(callback: object, spent: list[float]) -> None:
    """Wrap ``callback``'s hooks so that the thread CPU time spent in them adds up in ``spent[0]``."""
    for name in HOOKS:
        method = getattr(callback, name)

        def hook(*args: object, _method: Callable[..., object] = method) -> object:
            start = time.thread_time()
            try:
                return _method(*args)
            finally:
                spent[0] += time.thread_time() - start

        setattr(callback, name, hook)


def observer_run(setup: ObserverSetup, kwargs: dict[str, object], steps: int,
                 observer: str | None) -> Callable[[], tuple[float, float, float]]:
    """
    ``learn(steps)`` of SB3's ``setup.algo`` on its env with the package's callbacks ``observer`` (None: no callback;
    ``A+B``: both): steps per second of wall and CPU time, and the share of ``learn``'s CPU time spent in the callbacks'
    hooks (both taken in the same run, so the machine's other processes hardly move it).
    """
    import stable_baselines3
    import torch as th
    from stable_baselines3.common.env_util import make_vec_env

    th.set_num_threads(1)
    wrapper_class = None
    if setup.wrapper is not None:
        import minigrid.wrappers

        wrapper_class = getattr(minigrid.wrappers, setup.wrapper)

    def run() -> tuple[float, float, float]:
        env = make_vec_env(setup.env_id, n_envs=setup.n_envs, seed=0, wrapper_class=wrapper_class)
        model = getattr(stable_baselines3, setup.algo)("MlpPolicy", env, seed=0, **kwargs)
        names = [] if observer is None else observer.split("+")
        callbacks = [getattr(sb3_affect, name)(**setup.callback_kwargs) for name in names]
        spent = [0.0]
        for callback in callbacks:
            timed_hooks(callback, spent)
        wall, cpu = time.perf_counter(), time.process_time()
        model.learn(steps, callback=callbacks or None)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        return model.num_timesteps / wall, model.num_timesteps / cpu, spent[0] / cpu

    return run


def observer_rows(repeats: int, smoke: bool, only: str | None = None) -> list[tuple[str, float, str]]:
    """
    Each observer's steps per second relative to its algorithm's alone (wall and CPU time), in alternating rounds
    (``only``: the setups whose name contains it).
    """
    import warnings

    rows: list[tuple[str, float, str]] = []
    for name, setup in OBSERVER_SETUPS.items():
        if only is not None and only not in name:
            continue
        if setup.wrapper is not None and importlib.util.find_spec("minigrid") is None:
            print(f"{name}: skipped (needs the [minigrid] extra)", flush=True)
            continue
        algo, steps, kwargs = setup.algo, setup.sizes[1] if smoke else setup.sizes[0], setup.kwargs
        if smoke and algo == "PPO":
            kwargs = {**kwargs, "n_steps": 128 // setup.n_envs, "batch_size": 64}
        runs = {observer: observer_run(setup, kwargs, steps, observer) for observer in (None, *setup.observers)}
        rounds: list[dict[str | None, tuple[float, float, float]]] = []
        loads: list[float] = []
        for i in range(repeats):
            order = list(runs)
            order = order[i % len(order) :] + order[: i % len(order)]  # rotate: no run always goes first
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # e.g. FrozenLake's "no goal reached yet" in a short run
                measured = {observer: runs[observer]() for observer in order}
            rounds.append(measured)
            loads.append(load())
            cells = " | ".join(f"{obs or algo} {w:,.0f}/s wall, {c:,.0f}/s CPU" + (f", {f:.1%} in it" if obs else "")
                               for obs, (w, c, f) in measured.items())
            print(f"{name}, round {i}: {cells} | load {loads[-1]:.2f}", flush=True)
        alone = [r[None] for r in rounds]
        rows.append((f"{name}, {algo} alone (steps/s, wall)", statistics.median(r[0] for r in alone), f"{steps} steps"))
        rows.append((f"{name}, {algo} alone (steps/s, CPU)", statistics.median(r[1] for r in alone), f"{steps} steps"))
        span = f"median of {repeats} rounds, load {min(loads):.1f}-{max(loads):.1f}"
        for observer in setup.observers:
            shown = observer.replace("+", " with ")
            for column, what in ((0, "wall"), (1, "CPU")):
                ratio = statistics.median(r[observer][column] / r[None][column] for r in rounds)
                rows.append((f"{name}, with {shown} / alone ({what} time)", ratio, f"{span} (target >= 0.95)"))
            share = statistics.median(r[observer][2] for r in rounds)
            rows.append((f"{name}, share of learn's CPU time in {shown}", share, f"{span} (target <= 0.05)"))
    return rows


def protocol_seconds(workers: int) -> float | None:
    """Wall time of experiments/paper.yaml (360 runs) with the launcher, or None if the launcher is not there."""
    try:
        from sb3_affect.study.launcher import run_sweep
    except ImportError:
        return None
    sweep = Path(__file__).resolve().parents[1] / "experiments" / "paper.yaml"
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        run_sweep(sweep, Path(out) / "paper", workers=workers, progress=False)
        return time.perf_counter() - start


def study_rows(repeats: int, seeds: int) -> list[tuple[str, float, str]]:
    """The team and moving-prey kernels against their Python references (``bench_studies``), and their studies."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        import bench_studies  # type: ignore[import-not-found]
    except ImportError:
        print("studies: benchmarks/bench_studies.py is not on this branch (no team or moving-prey kernel yet)")
        return [("team and moving-prey kernels", float("nan"), "no benchmark on this branch")]
    rows = []
    for name, pair in (
        ("two hunters (AffectQ + QLearning), 4 runs x 200 episodes", bench_studies.team_pair(list(range(4)), 200)),
        ("AffectQ, random-walking prey 7x7, 4 runs x 200 episodes", bench_studies.moving_pair(list(range(4)), 200)),
    ):
        measured = bench_studies.paired(name, pair, repeats)
        ratio = statistics.median(row["ratio"] for row in measured)
        rows.append((f"{name}: Python / kernel time", ratio, f"median of {len(measured)} paired rounds"))
    if seeds:
        for study in bench_studies.studies(seeds):
            rows.append((f"{study['measure']} (s)", study["wall_s"], f"{study['runs']} runs, load {study['load']:.1f}"))
    return rows


def report_rows(folders: list[str], seeds: int) -> list[tuple[str, float, str]]:
    """``sb3-affect report`` and ``status`` of results folders: wall seconds and peak MB (``bench_report``)."""
    with tempfile.TemporaryDirectory() as work:
        out = Path(work) / "report.csv"
        command = [sys.executable, str(Path(__file__).with_name("bench_report.py")), "--out", str(out), "--keep", work]
        command += [arg for folder in folders for arg in ("--folder", folder)]
        command += ["--seeds", str(seeds)] if seeds else []
        subprocess.run(command, check=True)
        with out.open() as handle:
            measured = list(csv.DictReader(handle))
    rows = []
    for row in measured:
        name = f"{row['measure']}, {int(row['runs']):,} runs"
        target = " (target <= 30 s, <= 1 GB)" if row["measure"] == "report" else ""
        rows.append((f"{name} (s)", float(row["wall_s"]), f"peak {float(row['peak_mb']):,.0f} MB{target}"))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes, no protocol: checks the script runs")
    parser.add_argument("--large", action="store_true", help="also the paper protocol with 10,000 seeds per cell")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--csv", type=Path, help="default: results.csv here (--observers: results_observers.csv)")
    parser.add_argument(
        "--all", action="store_true", help="every figure: --studies --minigrid --study-seeds 1000 --report-seeds 10000"
    )
    parser.add_argument("--studies", action="store_true", help="the team and moving-prey kernels vs their Python loops")
    parser.add_argument("--study-seeds", type=int, default=0, help="also the studies at this many seeds (with --studies)")
    parser.add_argument("--minigrid", action="store_true", help="AffectDQN vs DQN and the tabular agents on MiniGrid")
    parser.add_argument("--report-folder", action="append", default=[], help="time report and status of this folder")
    parser.add_argument("--report-seeds", type=int, default=0, help="run the paper sweep at N seeds, then time its report")
    parser.add_argument("--observers", action="store_true", help="only the emotion callbacks' cost beside DQN and PPO")
    parser.add_argument("--observer-setup", metavar="TEXT", help="--observers: only the setups whose name holds TEXT")
    args = parser.parse_args(argv)
    if args.all:
        args.studies = args.minigrid = True
        args.study_seeds = args.study_seeds or 1000
        args.report_seeds = args.report_seeds or 10_000
    steps, dqn_steps, repeats = (3000, 300, 1) if args.smoke else (200_000, 5000, args.repeats)
    print(f"load average at start: {load():.2f} on {os.cpu_count()} CPUs", flush=True)
    if args.observers:
        csv_path = args.csv or Path(__file__).with_name("results_observers.csv")
        observed = observer_rows(repeats, args.smoke, args.observer_setup)
        return write_rows(observed, csv_path, repeats, f"{repeats} alternating round(s)")

    rows: list[tuple[str, float, str]] = []
    learn_rate(QLearning, 10)()  # load (or compile) the kernel before timing it
    learn_rate(AffectQ, 10)()
    # Paired rounds: each round measures the bare loop and then the four learn loops, back to back, so a ratio compares
    # figures taken under the same machine conditions (a shared VM's speed drifts by tens of percent over minutes);
    # a figure is the median over rounds, a ratio the median of the rounds' ratios.
    measures = {
        "bare": lambda: bare_loop_rate(steps),
        "q_py": learn_rate(QLearning, steps, exploration_rate=0.1, engine="python"),
        "a_py": learn_rate(AffectQ, steps, engine="python"),
        # each learn loop right before the kernel alone on its decisions
        "q_c": learn_rate(QLearning, steps, exploration_rate=0.1),
        "q_k": kernel_alone("QLearning", steps, exploration_rate=0.1),
        "a_c": learn_rate(AffectQ, steps),
        "a_k": kernel_alone("AffectQ", steps),
        # ten times the decisions: a run of 10-20 ms is at the mercy of other processes on a shared machine
        "q_cL": learn_rate(QLearning, 10 * steps, exploration_rate=0.1),
        "q_kL": kernel_alone("QLearning", 10 * steps, exploration_rate=0.1),
        "a_cL": learn_rate(AffectQ, 10 * steps),
        "a_kL": kernel_alone("AffectQ", 10 * steps),
    }
    rounds = []
    for i in range(repeats):
        r = {key: fn() for key, fn in measures.items()}
        rounds.append(r)
        print(
            f"round {i}: bare {r['bare']:,.0f}/s | compiled learn QLearning {r['q_c'] / r['bare']:.1f} x bare, "
            f"{r['q_k'] / r['q_c']:.2f} x kernel time | AffectQ {r['a_c'] / r['bare']:.1f} x bare, "
            f"{r['a_k'] / r['a_c']:.2f} x kernel time | {10 * steps:,} decisions: QLearning {r['q_cL'] / r['bare']:.1f} x "
            f"bare, {r['q_kL'] / r['q_cL']:.2f} x kernel time, AffectQ {r['a_cL'] / r['bare']:.1f} x bare, "
            f"{r['a_kL'] / r['a_cL']:.2f} x kernel time | Python engine {r['q_py'] / r['bare']:.2f} / "
            f"{r['a_py'] / r['bare']:.2f} x bare | load {load():.2f}",
            flush=True,
        )
    rate = {key: statistics.median(r[key] for r in rounds) for key in measures}
    ratio = {key: statistics.median(r[key] / r["bare"] for r in rounds) for key in measures}
    compiled = ("q_c", "a_c", "q_cL", "a_cL")
    slower = {key: statistics.median(r[key.replace("_c", "_k")] / r[key] for r in rounds) for key in compiled}
    bare, q_py, a_py, q_rate, a_rate = (rate[key] for key in ("bare", "q_py", "a_py", "q_c", "a_c"))
    rows.append(("bare pure-Python loop (decisions/s)", bare, "floor"))
    rows.append(("QLearning.learn, Python engine (decisions/s)", q_py, f"{ratio['q_py']:.2f} x bare (target >= 0.5)"))
    rows.append(("AffectQ.learn, Python engine (decisions/s)", a_py, f"{ratio['a_py']:.2f} x bare (target >= 0.3)"))
    rows.append(("QLearning.learn eps 0.1, compiled (decisions/s)", q_rate, f"{ratio['q_c']:.1f} x bare (target >= 30)"))
    rows.append(("AffectQ.learn, compiled (decisions/s)", a_rate, f"{ratio['a_c']:.1f} x bare (target >= 35)"))
    rows.append(("QLearning eps 0.1, kernel alone (decisions/s)", rate["q_k"], f"{ratio['q_k']:.1f} x bare"))
    rows.append(("AffectQ, kernel alone (decisions/s)", rate["a_k"], f"{ratio['a_k']:.1f} x bare"))
    rows.append(("QLearning: compiled learn time / kernel time", slower["q_c"], f"{slower['q_c']:.2f} (target <= 1.3)"))
    rows.append(("AffectQ: compiled learn time / kernel time", slower["a_c"], f"{slower['a_c']:.2f} (target <= 1.3)"))
    long = f"{10 * steps:,} decisions"
    rows.append((f"QLearning.learn eps 0.1, compiled, {long} (decisions/s)", rate["q_cL"], f"{ratio['q_cL']:.1f} x bare"))
    rows.append((f"AffectQ.learn, compiled, {long} (decisions/s)", rate["a_cL"], f"{ratio['a_cL']:.1f} x bare"))
    for algo, key in (("QLearning", "q_cL"), ("AffectQ", "a_cL")):
        rows.append((f"{algo}: compiled learn time / kernel time, {long}", slower[key], f"{slower[key]:.2f} (target <= 1.3)"))
    d_rate = timed(dqn_rate(dqn_steps), max(1, repeats // 2))
    rows.append(("SB3 DQN.learn (steps/s, 1 torch thread)", d_rate, "reference"))
    rows.append(("QLearning (Python engine) / DQN", q_py / d_rate, "target >= 100"))
    rows.append(("AffectQ (Python engine) / DQN", a_py / d_rate, "target >= 100"))
    rows.append(("QLearning (compiled) / DQN", q_rate / d_rate, ""))
    rows.append(("AffectQ (compiled) / DQN", a_rate / d_rate, ""))
    if not args.smoke:
        sims = [simulate_protocol(20) for _ in range(repeats)]
        seconds = statistics.median(s for s, _ in sims)
        rows.append(("simulate, paper protocol, 360 runs, 1 process (s)", seconds, "kernel; target well under 2 s"))
        rows.append(("simulate, paper protocol (decisions/s)", sims[0][1] / seconds, "both agents, all epsilons"))
        with tempfile.TemporaryDirectory() as cache:
            cold = kernel_start_seconds(cache)
            warm = kernel_start_seconds(cache)
        rows.append(("new process: import + first kernel use, cold cache (s)", cold, "compiles every kernel"))
        rows.append(("new process: import + first kernel use, warm cache (s)", warm, "loads the cached kernels"))
        if args.large:
            seconds, decisions = simulate_protocol(10_000)
            note = f"1 process, {decisions:,} decisions"
            rows.append(("simulate, paper protocol, 10,000 seeds per cell (s)", seconds, note))
        for workers in (1, 2):
            launcher = protocol_seconds(workers)
            if launcher is None:
                rows.append((f"paper protocol, {workers} worker(s) (s)", float("nan"), "launcher not installed"))
            else:
                rows.append((f"paper protocol, {workers} worker(s) (s)", launcher, "sb3-affect run, 360 runs x 200 episodes"))

    rows += observer_rows(repeats, args.smoke)
    if args.studies and not args.smoke:
        rows += study_rows(repeats, args.study_seeds)
    if args.minigrid:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_minigrid import minigrid_rows  # type: ignore[import-not-found]

        rows += minigrid_rows(repeats, args.smoke)
    if (args.report_folder or args.report_seeds) and not args.smoke:
        rows += report_rows(args.report_folder, args.report_seeds)
    sizes = f"median of {repeats} run(s); {steps} decisions per tabular run, {dqn_steps} DQN steps per run"
    return write_rows(rows, args.csv or Path(__file__).with_name("results.csv"), repeats, sizes)


def write_rows(rows: list[tuple[str, float, str]], path: Path, repeats: int, sizes: str) -> int:
    """Print the table (with the machine's load and versions) and write it to the CSV file ``path``."""
    cores = os.cpu_count()
    print(f"load average at the end: {load():.2f}")
    print(f"sb3-affect {sb3_affect.__version__} | Python {platform.python_version()} | {cores} cores | {platform.machine()}")
    print(sizes)
    width = max(len(name) for name, _, _ in rows)
    for name, value, note in rows:
        print(f"{name:<{width}}  {value:>12,.{3 if abs(value) < 10 else 1}f}  {note}")
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["measure", "value", "note", "cores", "repeats"])
        for name, value, note in rows:
            writer.writerow([name, f"{value:.3f}", note, cores, repeats])
    return 0


if __name__ == "__main__":
    sys.exit(main())
