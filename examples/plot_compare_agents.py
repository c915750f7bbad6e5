"""
AffectQ beside epsilon-greedy Q-learning
=========================================

Both agents of the paper, a few seeds each, on the same task: mean decisions per episode (the paper's "steps").
``QLearning`` is the standard agent (``exploration_rate`` is epsilon); ``AffectQ`` has no epsilon.
"""

import os

import matplotlib.pyplot as plt
import pandas as pd
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, QLearning

SMOKE = bool(os.environ.get("SB3_AFFECT_SMOKE"))
EPISODES, SEEDS = (20, 2) if SMOKE else (200, 5)
ENV = "sb3_affect/GridPursuit-v0"


def decisions(make_model) -> pd.Series:
    """Mean decisions per episode over the seeds."""
    runs = []
    for seed in range(SEEDS):
        model = make_model(seed).learn(10**8, callback=StopTrainingOnMaxEpisodes(EPISODES))
        runs.append(model.episode_log.set_index("episode").decisions)
    return pd.concat(runs, axis=1).mean(axis=1)


curves = {
    "epsilon-greedy, epsilon 0.1": decisions(lambda seed: QLearning("Grid", ENV, exploration_rate=0.1, seed=seed)),
    "epsilon-greedy, epsilon 0.5": decisions(lambda seed: QLearning("Grid", ENV, exploration_rate=0.5, seed=seed)),
    "affective (AffectQ)": decisions(lambda seed: AffectQ("Grid", ENV, seed=seed)),
}
for name, curve in curves.items():
    print(f"{name:28s} mean decisions per episode {curve.mean():8.1f}")

# %%
# A rolling mean over 10 episodes; log scale, since the first episodes take thousands of decisions.
fig, ax = plt.subplots(figsize=(7, 4))
for name, curve in curves.items():
    ax.plot(curve.index, curve.rolling(10, min_periods=1).mean(), label=name)
ax.set_yscale("log")
ax.set_xlabel("episode")
ax.set_ylabel(f"decisions per episode (mean of {SEEDS} seeds)")
ax.legend()
fig.tight_layout()
plt.show()
