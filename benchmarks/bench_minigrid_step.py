"""
The compiled MiniGrid's step beside minigrid's (``bench.py --minigrid`` adds these rows; alone it writes
``results_minigrid_step.csv``):

* env steps per second of ``VecEnv.step`` on ``make_vec_env(env_id, n, seed=0, wrapper_class=FlatObsWrapper)``
  (Farama's env in a DummyVecEnv) and on ``sb3_affect.minigrid_vec_env(env_id, n, seed=0)``, the same random actions
  (the same episodes: the two are equal step for step), for n = 4, 16 and 128 envs on Empty-8x8 (walls seen through)
  and DoorKey-8x8 (occlusion); and ``step_arrays`` (the step without info dicts, for a trainer), in paired rounds
  (Farama's, then the compiled step, then ``step_arrays``); a ratio is the median of the rounds' ratios. Target: the
  compiled step at least 200 x minigrid's.

    python benchmarks/bench_minigrid_step.py [--smoke] [--repeats N] [--csv PATH]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

TASKS = ("MiniGrid-Empty-8x8-v0", "MiniGrid-DoorKey-8x8-v0")
ENV_COUNTS = (4, 16, 128)


def farama_rate(env_id: str, n: int, env_steps: int) -> Callable[[], float]:
    from minigrid.wrappers import FlatObsWrapper
    from stable_baselines3.common.env_util import make_vec_env

    def run() -> float:
        venv = make_vec_env(env_id, n, seed=0, wrapper_class=FlatObsWrapper)
        return stepped(venv, venv.step, n, max(1, env_steps // n))

    return run


def compiled_rate(env_id: str, n: int, env_steps: int, raw: bool) -> Callable[[], float]:
    from sb3_affect import minigrid_vec_env

    def run() -> float:
        venv = minigrid_vec_env(env_id, n, seed=0)
        return stepped(venv, venv.step_arrays if raw else venv.step, n, max(1, env_steps // n))

    return run


def stepped(venv: object, step: Callable[[np.ndarray], object], n: int, calls: int) -> float:
    """Env steps per second of ``calls`` calls of ``step`` with random actions (drawn before the clock starts)."""
    actions = np.random.default_rng(0).integers(0, 7, size=(calls, n))
    venv.reset()  # type: ignore[attr-defined]
    step(actions[0])  # the first call loads the kernel
    start = time.perf_counter()
    for row in actions:
        step(row)
    return calls * n / (time.perf_counter() - start)


def step_rows(repeats: int, smoke: bool = False) -> list[tuple[str, float, str]]:
    """The rows: (measure, value, note)."""
    farama_steps, compiled_steps = (200, 2000) if smoke else (2000, 200_000)
    rows: list[tuple[str, float, str]] = []
    for env_id in TASKS:
        for n in ENV_COUNTS:
            measures = {
                "farama": farama_rate(env_id, n, farama_steps),
                "step": compiled_rate(env_id, n, compiled_steps, raw=False),
                "arrays": compiled_rate(env_id, n, compiled_steps, raw=True),
            }
            rounds = [{key: fn() for key, fn in measures.items()} for _ in range(repeats)]
            rate = {key: statistics.median(r[key] for r in rounds) for key in measures}
            ratio = {key: statistics.median(r[key] / r["farama"] for r in rounds) for key in ("step", "arrays")}
            what = f"{env_id}, {n} envs (env steps/s)"
            print(f"{what}: minigrid {rate['farama']:,.0f}, compiled step {ratio['step']:.0f} x, step_arrays "
                  f"{ratio['arrays']:.0f} x", flush=True)
            rows.append((f"minigrid VecEnv.step, FlatObsWrapper, {what}", rate["farama"], "reference"))
            rows.append((f"minigrid_vec_env step, {what}", rate["step"], f"{ratio['step']:.0f} x minigrid (target >= 200)"))
            rows.append((f"minigrid_vec_env step_arrays, {what}", rate["arrays"], f"{ratio['arrays']:.0f} x minigrid"))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--smoke", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--csv", type=Path, default=Path(__file__).with_name("results_minigrid_step.csv"))
    args = parser.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench import write_rows  # type: ignore[import-not-found]

    repeats = 1 if args.smoke else args.repeats
    return write_rows(step_rows(repeats, args.smoke), args.csv, repeats, f"median of {repeats} paired round(s)")


if __name__ == "__main__":
    sys.exit(main())
