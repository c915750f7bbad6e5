"""
The studies beyond the single static task on their kernels: hunter teams (``kernel.team_loop``) and moving prey
(``kernel.moving_loop``), each against its Python reference in paired rounds, then the report's studies at full size.

    python benchmarks/bench_studies.py                 # paired rounds, then the studies at 1,000 seeds
    python benchmarks/bench_studies.py --seeds 100     # the studies with fewer seeds
    python benchmarks/bench_studies.py --skip-studies  # paired rounds only

Paired rounds: one run on the Python side and the same run (same seed) on the kernel, alternately first, each round
timed side by side, so that the machine's load (other processes) weighs on both alike; every round's ratio is printed,
not only the best. The studies: ``experiments/hunters.yaml`` and ``hunters_moving.yaml`` through the launcher (2
workers, seeds overridden), and the moving-prey and maze tasks of ``sb3-affect replicate`` (``experiments/beyond.yaml``
with the file's ε, through the launcher). The 1-minute load average is printed with every figure. Results:
``benchmarks/results_studies.csv``.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
TEAM = [("AffectQ", {}), ("QLearning", {"exploration_rate": 0.1})]
MOVING = ("sb3_affect/MovingPursuit-v0", {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "random"})


def load() -> float:
    return os.getloadavg()[0]


def team_pair(seeds: list[int], episodes: int) -> tuple[Callable[[], int], Callable[[], int]]:
    """The Python team and the team kernel on Kuremoto's layout (static prey), one run per seed: their decisions."""
    from sb3_affect.agents.broekens import BroekensCallback
    from sb3_affect.agents.hunter_team import HunterTeam
    from sb3_affect.envs import HUNTER_PURSUIT_ID, make_parallel
    from sb3_affect.kernel.team_batch import run_team, team_columns, team_settings_inputs

    def python() -> int:
        total = 0
        for seed in seeds:
            team = HunterTeam(make_parallel(HUNTER_PURSUIT_ID), TEAM, seed=seed)
            team.learn(episodes, callbacks={agent: BroekensCallback() for agent in team.models})
            total += sum(m.num_timesteps for m in team.models.values())
        return total

    def compiled() -> int:
        total = 0
        for seed in seeds:
            inputs = team_settings_inputs(TEAM, HUNTER_PURSUIT_ID, {}, episodes)
            assert inputs is not None
            run = run_team(inputs, seed, episodes)
            team_columns(inputs, run)
            total += run.decisions
        return total

    return python, compiled


def moving_pair(seeds: list[int], episodes: int) -> tuple[Callable[[], int], Callable[[], int]]:
    """AffectQ against a random-walking prey (7 x 7): ``simulate`` on the Python loop and on the moving-prey kernel."""
    from sb3_affect.engine.simulation import simulate

    def run(engine: str) -> int:
        return int(simulate("AffectQ", {}, MOVING[0], MOVING[1], seeds, episodes, engine=engine)["decisions"].sum())

    return (lambda: run("python")), (lambda: run("compiled"))


def paired(name: str, pair: tuple[Callable[[], int], Callable[[], int]], rounds: int) -> list[dict[str, Any]]:
    python, compiled = pair
    assert python() == compiled()  # (and compiles the kernel outside the timed rounds)
    rows = []
    for r in range(rounds):
        times = {}
        for side in (("python", "compiled") if r % 2 == 0 else ("compiled", "python")):
            start = time.perf_counter()
            decisions = (python if side == "python" else compiled)()
            times[side] = time.perf_counter() - start
        ratio = times["python"] / times["compiled"]
        rows.append({"measure": name, "round": r, "python_s": times["python"], "compiled_s": times["compiled"],
                     "ratio": ratio, "decisions": decisions, "load": load()})  # fmt: skip
        print(f"{name} round {r}: python {times['python']:.3f} s, compiled {times['compiled']:.4f} s, "
              f"ratio {ratio:.0f}x, {decisions:,} decisions, load {load():.1f}", flush=True)  # fmt: skip
    ratios = [row["ratio"] for row in rows]
    print(f"{name}: median ratio {statistics.median(ratios):.0f}x (every round above)", flush=True)
    return rows


def studies(seeds: int) -> list[dict[str, Any]]:
    from sb3_affect.study.launcher import run_sweep

    rows = []
    listed = "[" + ", ".join(str(i) for i in range(seeds)) + "]"
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("hunters", "hunters_moving"):
            before = load()
            start = time.perf_counter()
            summary = run_sweep(ROOT / "experiments" / f"{name}.yaml", Path(tmp) / name, workers=2,
                                overrides=[f"seeds={listed}"], progress=False)  # fmt: skip
            wall = time.perf_counter() - start
            rows.append({"measure": f"{name} study, {seeds} seeds, 2 workers", "wall_s": wall, "runs": summary.finished,
                         "load": max(before, load())})  # fmt: skip
            print(f"{name}: {summary.finished} team runs in {wall:.1f} s (2 workers, load {load():.1f})", flush=True)
        before = load()
        start = time.perf_counter()
        summary = run_sweep(ROOT / "experiments" / "beyond.yaml", Path(tmp) / "beyond", workers=2,
                            overrides=[f"seeds={seeds}"], progress=False)  # fmt: skip
        wall = time.perf_counter() - start
        rows.append({"measure": f"beyond study (moving and evading prey, mazes), {seeds} seeds, 2 workers",
                     "wall_s": wall, "runs": summary.finished, "load": max(before, load())})  # fmt: skip
        print(f"beyond: {summary.finished} runs in {wall:.1f} s (2 workers, load {load():.1f})", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=5, help="paired rounds per measure (default 5)")
    parser.add_argument("--pair-seeds", type=int, default=4, help="runs per side in each paired round (default 4)")
    parser.add_argument("--seeds", type=int, default=1000, help="seeds of the studies (default 1000)")
    parser.add_argument("--skip-studies", action="store_true", help="paired rounds only")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results_studies.csv")
    args = parser.parse_args()
    print(f"load average at start: {load():.1f} on {os.cpu_count()} CPUs", flush=True)
    seeds = list(range(args.pair_seeds))
    rows = paired(f"two hunters (AffectQ + QLearning), Kuremoto, {len(seeds)} runs x 200 episodes", team_pair(seeds, 200),
                  args.rounds)  # fmt: skip
    rows += paired(f"AffectQ, random-walking prey 7x7, {len(seeds)} runs x 200 episodes", moving_pair(seeds, 200),
                   args.rounds)  # fmt: skip
    if not args.skip_studies:
        rows += studies(args.seeds)
    fields = ["measure", "round", "python_s", "compiled_s", "ratio", "decisions", "wall_s", "runs", "load"]
    with args.out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fields)
        writer.writeheader()
        writer.writerows(rows)
    print(f"results: {args.out}")


if __name__ == "__main__":
    main()
