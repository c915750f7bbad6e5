"""
Train AffectQ and watch its emotions
====================================

The paper's affective agent on the paper's task (15 x 15 grid, start (0, 0), prey at (6, 6)) for 200 episodes.
Each decision it appraises its progress, feels one emotion and the emotion sets the direction and the speed.
``model.episode_log`` has one row per episode: decisions, cells moved, whether the path was optimal, and how many
decisions were made in each emotion.
"""

import os

import gymnasium as gym
import matplotlib.pyplot as plt
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers sb3_affect/GridPursuit-v0)
from sb3_affect import AffectQ

EPISODES = 20 if os.environ.get("SB3_AFFECT_SMOKE") else 200

env = gym.make("sb3_affect/GridPursuit-v0")
model = AffectQ("Grid", env, seed=0)
model.learn(total_timesteps=10**8, callback=StopTrainingOnMaxEpisodes(EPISODES))
log = model.episode_log
print(log[["episode", "decisions", "cells", "optimal", "joy", "anger"]].tail())
first = log.index[log.optimal].min() if log.optimal.any() else None
print("first optimal episode:", None if first is None else int(log.episode[first]))

# %%
# Decisions per episode fall as the Q-table fills in. Below, the share of each episode's decisions made in each
# emotion (a rolling mean over 10 episodes, as in the paper's Fig. 5); the share of *joy* (random direction) is the
# agent's "equivalent epsilon" (the paper's Fig. 6).
fractions = log[["joy", "sadness", "fear", "anger"]].div(log.decisions, axis=0).rolling(10, min_periods=1).mean()
fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
top.plot(log.episode, log.decisions, label="decisions")
top.plot(log.episode, log.cells, label="cells moved", alpha=0.7)
top.axhline(12, color="grey", ls=":", label="shortest path (12 cells)")
top.set_yscale("log")
top.set_ylabel("per episode")
top.legend()
for emotion in fractions:
    bottom.plot(log.episode, fractions[emotion], label=emotion)
bottom.set_xlabel("episode")
bottom.set_ylabel("fraction of decisions\n(10-episode mean)")
bottom.legend(ncols=4)
fig.suptitle("AffectQ, one run")
fig.tight_layout()
plt.show()
