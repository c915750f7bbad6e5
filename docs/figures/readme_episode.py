"""Two episodes of one real AffectQ run on the 15 x 15 grid, each one-cell move coloured by the emotion of its decision
(the README's figure: ``python docs/figures/readme_episode.py`` writes docs/_static/affective_episode.png)."""

from pathlib import Path

import matplotlib.pyplot as plt
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import AffectQ, EmotionCallback


class Tracing(EmotionCallback):
    """Records each decision's emotion and each one-cell move, in order: a move belongs to the decision before it."""

    def __init__(self) -> None:
        super().__init__()
        self.decisions: list[str] = []
        self.moves: list[tuple[int, int, str]] = []

    def feel(self, state):
        emotion = super().feel(state)
        self.decisions.append(emotion.name.lower())
        return emotion

    def observe(self, s, s2, terminated):
        self.moves.append((int(s), int(s2), self.decisions[-1]))
        super().observe(s, s2, terminated)


SIZE, EPISODES = 15, 30
COLOURS = {"joy": "gold", "anger": "tab:red", "sadness": "tab:blue", "fear": "tab:purple"}
trace = Tracing()
model = AffectQ("Grid", "sb3_affect/GridPursuit-v0", seed=0, emotion_callback=trace)
episodes = []
for episode in range(1, EPISODES + 1):
    trace.decisions.clear()
    trace.moves.clear()
    model.learn(10**8, callback=StopTrainingOnMaxEpisodes(1), reset_num_timesteps=episode == 1)
    episodes.append((episode, list(trace.decisions), list(trace.moves)))
# the first short episode that felt both joy and anger, and the last episode
mixed = next(e for e in episodes if {"joy", "anger"} <= set(e[1]) and len(e[1]) <= 60)
fig, axes = plt.subplots(1, 2, figsize=(9, 4.6))
for ax, (episode, decisions, moves) in zip(axes, (mixed, episodes[-1])):
    ax.set_xlim(-0.5, SIZE - 0.5)
    ax.set_ylim(SIZE - 0.5, -0.5)
    ax.set_xticks(range(0, SIZE, 2))
    ax.set_yticks(range(0, SIZE, 2))
    ax.grid(True, color="0.92")
    ax.tick_params(labelsize=7)
    for s, s2, emotion in moves:
        (r, c), (r2, c2) = divmod(s, SIZE), divmod(s2, SIZE)
        ax.plot([c, c2], [r, r2], color=COLOURS[emotion], lw=2.2, alpha=0.75, solid_capstyle="round")
    ax.scatter([0], [0], marker="s", s=80, color="black", zorder=3, label="start")
    ax.scatter([6], [6], marker="*", s=200, color="tab:green", zorder=3, label="prey")
    felt = sorted(set(decisions), key=list(COLOURS).index)
    ax.set_title(f"episode {episode}: {len(decisions)} decisions, {len(moves)} cells ({', '.join(felt)})", fontsize=9)
    ax.set_xlabel("column")
    ax.set_ylabel("row")
for name, colour in COLOURS.items():
    axes[-1].plot([], [], color=colour, lw=3, label=name)
axes[-1].legend(loc="lower right", fontsize=8, framealpha=0.9)
fig.suptitle("AffectQ on the 15 x 15 grid: joy walks at random, anger runs greedily 2 cells a decision", fontsize=10)
fig.tight_layout()
out = Path(__file__).resolve().parents[1] / "_static" / "affective_episode.png"
fig.savefig(out, dpi=100)
print(f"wrote {out}")
