"""Every appraisal of one episode of a real AffectQ run (the Concepts page: ``python docs/figures/appraised_episode.py``
writes docs/_static/appraised_episode.png)."""

from pathlib import Path

import matplotlib.pyplot as plt
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, EmotionCallback, table_ii

seen = []
def recording_rule(appraisal):
    emotion = table_ii(appraisal)
    seen.append((appraisal, emotion))
    return emotion

model = AffectQ("Grid", "sb3_affect/GridPursuit-v0", seed=2, emotion_callback=EmotionCallback(emotion_rule=recording_rule))
model.learn(10**8, callback=StopTrainingOnMaxEpisodes(3))
seen.clear()
model.learn(10**8, callback=StopTrainingOnMaxEpisodes(1), reset_num_timesteps=False)
points = [(a, e) for a, e in seen if a is not None]
x = range(1, len(points) + 1)
fig, ax = plt.subplots(figsize=(8, 3.6))
ax.plot(x, [a.norm for a, _ in points], label="norm", color="black")
ax.plot(x, [a.exp1 for a, _ in points], label="exp1", ls="--")
ax.plot(x, [a.act for a, _ in points], label="act")
colours = {"JOY": "gold", "ANGER": "tab:red", "SADNESS": "tab:blue", "FEAR": "tab:purple"}
for i, (_, e) in enumerate(points, 1):
    ax.axvspan(i - 0.5, i + 0.5, color=colours[e.name], alpha=0.25, lw=0)
for name, colour in colours.items():
    ax.fill_between([], [], color=colour, alpha=0.25, label=name.lower())
ax.set_xlabel("decision in episode 4")
ax.set_ylabel("cells")
ax.legend(ncols=3, fontsize=8)
fig.tight_layout()
out = Path(__file__).resolve().parents[1] / "_static" / "appraised_episode.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
