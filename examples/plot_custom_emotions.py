"""
Your own emotion rule and behaviour table
=========================================

``AffectQ`` looks each decision's emotion up in a behaviour table (Table III by default). Both halves can be
replaced: the emotion rule (``EmotionCallback(emotion_rule=...)``, any function from an appraisal to an
``Emotion``) and the behaviour table (``behaviour_table={Emotion.JOY: Behaviour(...), ...}``).

Here a "calm" agent: it feels fear (slow, greedy) whenever the episode runs longer than its norm, and otherwise
Table II decides; and its joy moves one cell at a time.
"""

import os

import matplotlib.pyplot as plt
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import TABLE_III, AffectQ, Appraisal, Behaviour, Emotion, EmotionCallback, table_ii

EPISODES = 20 if os.environ.get("SB3_AFFECT_SMOKE") else 150


def calm_rule(appraisal: Appraisal | None) -> Emotion:
    """Fear once the episode has run past its norm; otherwise Table II as the paper reads it."""
    if appraisal is not None and appraisal.exp1 > appraisal.norm:
        return Emotion.FEAR
    return table_ii(appraisal)


calm_table = {**TABLE_III, Emotion.JOY: Behaviour(random_direction=True, speeds=(1,))}
agents = {
    "paper (Table II, Table III)": AffectQ("Grid", "sb3_affect/GridPursuit-v0", seed=1),
    "calm rule, joy at speed 1": AffectQ(
        "Grid",
        "sb3_affect/GridPursuit-v0",
        seed=1,
        emotion_callback=EmotionCallback(emotion_rule=calm_rule),
        behaviour_table=calm_table,
    ),
}
fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), sharey=True)
for ax, (name, model) in zip(axes, agents.items()):
    log = model.learn(10**8, callback=StopTrainingOnMaxEpisodes(EPISODES)).episode_log
    shares = log[["joy", "sadness", "fear", "anger"]].sum() / log.decisions.sum()
    print(f"{name:28s}", " ".join(f"{k} {v:.2f}" for k, v in shares.items()))
    ax.bar(shares.index, shares.values)
    ax.set_title(name)
axes[0].set_ylabel("fraction of all decisions")
fig.tight_layout()
plt.show()
