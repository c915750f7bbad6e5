"""
Where SB3's own ``DQN.learn`` or ``PPO.learn`` spends its CPU time on Farama's MiniGrid and on the compiled one
(``minigrid_vec_env``), in pairs of runs alternating the two (Farama's first): the settings and the env of
``bench_many_seeds.py``'s sb3 rows (MiniGrid-Empty-8x8, the 7x7x3 view flattened, 4 envs, one torch thread; the
kernels loaded before, so that no run pays numba's start-up in the process).

Each run's CPU seconds (``time.process_time``) are split, through SB3's public hooks only, into the env's
``step_wait`` and ``reset`` (a ``VecEnvWrapper`` around the env), ``train`` (a callback's time from each
``on_rollout_end`` to the next ``on_rollout_start`` or the end of ``learn``) and the rest, SB3's own work while
collecting (the policy's forward passes, the buffer, the callbacks, its bookkeeping of the infos). The last line of
a pair is its ratio (Farama's CPU seconds over the compiled env's) and the ratio it would reach if the compiled
env's step cost nothing: Farama's run over the compiled run without its env.

    python benchmarks/bench_learn_parts.py [--algo DQN|PPO] [--steps 20000] [--envs 4] [--pairs 2] [--smoke]
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from bench_many_seeds import ENV_ID, EPSILON, PPO_SETTINGS, SETTINGS

#: The parts of a run, in the order printed.
PARTS = ("env step_wait + reset", "train", "SB3's collecting work", "learn")


def run_parts(algo: str, compiled: bool, steps: int, n_envs: int) -> dict[str, float]:
    """One ``algo.learn(steps)`` on a fresh model and env: CPU seconds of each of ``PARTS``."""
    import torch as th
    from stable_baselines3 import DQN, PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
    from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

    from sb3_affect.engine.seed_envs import seed_vec_env

    th.set_num_threads(1)
    spent = {part: 0.0 for part in PARTS}

    class TimedEnv(VecEnvWrapper):
        def __init__(self, venv: VecEnv) -> None:
            super().__init__(venv)

        def reset(self) -> VecEnvObs:
            start = time.process_time()
            obs = self.venv.reset()
            spent["env step_wait + reset"] += time.process_time() - start
            return obs

        def step_wait(self) -> VecEnvStepReturn:
            start = time.process_time()
            result = self.venv.step_wait()
            spent["env step_wait + reset"] += time.process_time() - start
            return result

    class TimedTrain(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.ended: float | None = None

        def _on_rollout_start(self) -> None:
            if self.ended is not None:
                spent["train"] += time.process_time() - self.ended
            self.ended = None

        def _on_rollout_end(self) -> None:
            self.ended = time.process_time()

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:
            self._on_rollout_start()

    env = TimedEnv(seed_vec_env(ENV_ID, n_envs, 0, "view", compiled))
    settings: dict[str, Any] = PPO_SETTINGS if algo == "PPO" else {**SETTINGS, **EPSILON}
    model = (PPO if algo == "PPO" else DQN)("MlpPolicy", env, seed=0, device="cpu", **settings)
    start = time.process_time()
    model.learn(steps, callback=TimedTrain())
    spent["learn"] = time.process_time() - start
    spent["SB3's collecting work"] = spent["learn"] - spent["train"] - spent["env step_wait + reset"]
    return spent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", default="PPO", choices=["DQN", "PPO"])
    parser.add_argument("--steps", type=int, default=20_000, help="env steps of each learn (all envs')")
    parser.add_argument("--envs", type=int, default=4)
    parser.add_argument("--pairs", type=int, default=2)
    parser.add_argument("--smoke", action="store_true", help="one pair of tiny runs: checks the script runs")
    args = parser.parse_args(argv)
    steps, pairs = (1200, 1) if args.smoke else (args.steps, args.pairs)
    from sb3_affect.kernel import warm_up

    warm_up(tabular=False, minigrid=True)
    runs: dict[bool, list[dict[str, float]]] = {False: [], True: []}
    for _ in range(pairs):
        for compiled in (False, True):
            runs[compiled].append(run_parts(args.algo, compiled, steps, args.envs))
    print(f"SB3 {args.algo}.learn({steps:,}), {ENV_ID}, obs=view, {args.envs} envs, 1 torch thread: CPU s of each run")
    for part in PARTS:
        farama = " ".join(f"{run[part]:6.2f}" for run in runs[False])
        compiled_ = " ".join(f"{run[part]:6.2f}" for run in runs[True])
        print(f"  {part:<24} Farama's {farama}   compiled {compiled_}")
    for index, (farama_run, compiled_run) in enumerate(zip(runs[False], runs[True])):
        env = compiled_run["env step_wait + reset"]
        print(f"pair {index}: compiled / Farama's {farama_run['learn'] / compiled_run['learn']:.2f}x; the compiled env "
              f"{env / compiled_run['learn']:.1%} of its run; with a step that cost nothing "
              f"{farama_run['learn'] / (compiled_run['learn'] - env):.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
