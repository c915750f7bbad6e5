"""
The core summary of both paper agents, default definitions: 20 seeds x 200 episodes per agent, in-process (no launcher).

    python experiments/core_summary.py [--seeds 20] [--episodes 200]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import pandas as pd
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, QLearning


def run(cls: type, seeds: int, episodes: int, **kwargs: object) -> pd.DataFrame:
    logs = []
    for seed in range(seeds):
        model = cls("Grid", gym.make("sb3_affect/GridPursuit-v0"), seed=seed, **kwargs)
        model.learn(10**9, callback=StopTrainingOnMaxEpisodes(episodes))
        logs.append(model.episode_log.assign(seed=seed))
    return pd.concat(logs, ignore_index=True)


def first_optimal(log: pd.DataFrame) -> str:
    firsts = log[log.optimal].groupby("seed").episode.min()
    never = log.seed.nunique() - len(firsts)
    return f"{firsts.mean():.2f} (runs that never found it: {never})"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--episodes", type=int, default=200)
    args = parser.parse_args()
    agents = {
        "affective": run(AffectQ, args.seeds, args.episodes),
        "epsilon 0.1": run(QLearning, args.seeds, args.episodes, exploration_rate=0.1),
        "epsilon 0.9": run(QLearning, args.seeds, args.episodes, exploration_rate=0.9),
    }
    for name, log in agents.items():
        print(
            f"{name:12s} mean decisions/episode {log.decisions.mean():8.2f}  cells/episode {log.cells.mean():8.2f}  "
            f"first optimal episode {first_optimal(log)}  truncated {int(log.truncated.sum())}"
        )
    log = agents["affective"]
    print("affective: per-episode fractions of decisions (Fig. 5/6), mean over runs and over the episodes of each window")
    fractions = log[["joy", "sadness", "fear", "anger", "random_moves"]].div(log.decisions, axis=0)
    fractions = fractions.rename(columns={"random_moves": "equivalent epsilon"}).assign(episode=log.episode)
    for lo, hi in ((1, 10), (21, 40), (181, 200)):
        window = fractions[(fractions.episode >= lo) & (fractions.episode <= hi)].drop(columns="episode").mean()
        print(f"  episodes {lo:3d}-{hi:3d}: " + "  ".join(f"{k} {v:.3f}" for k, v in window.items()))


if __name__ == "__main__":
    main()
