"""How one decision of the affective agent moves (the Concepts page: ``python docs/figures/decision_moves.py`` writes
docs/_static/decision_moves.png)."""

from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.patches import Rectangle

cases = [
    ("joy: random direction, 2 cells", (2, 2), [(2, 3), (2, 4)]),
    ("anger: greedy, 2 cells", (2, 2), [(3, 2), (4, 2)]),
    ("sadness or fear: greedy, 1 cell", (2, 2), [(3, 2)]),
    ("sadness or fear: greedy, 0 cells (wait)", (2, 2), []),
]
fig, axes = plt.subplots(1, 4, figsize=(12, 3.4))
for ax, (title, start, path) in zip(axes, cases):
    for r in range(5):
        for c in range(5):
            ax.add_patch(Rectangle((c, -r), 1, 1, fill=False, color="0.8"))
    ax.add_patch(Rectangle((4, -4), 1, 1, color="tab:red", alpha=0.35))
    ax.text(4.5, -3.5, "prey", ha="center", va="center", fontsize=8)
    ax.plot(start[1] + 0.5, -start[0] + 0.5, "o", color="tab:blue", ms=10)
    here = start
    for i, cell in enumerate(path, 1):
        ax.annotate("", xy=(cell[1] + 0.5, -cell[0] + 0.5), xytext=(here[1] + 0.5, -here[0] + 0.5),
                    arrowprops=dict(arrowstyle="-|>", color="tab:blue", lw=2))
        ax.text((cell[1] + here[1]) / 2 + 0.5, -(cell[0] + here[0]) / 2 + 0.75, f"update {i}", fontsize=7,
                ha="center", color="tab:blue")
        here = cell
    if not path:
        ax.text(start[1] + 0.5, -start[0] + 0.05, "no move, no update", ha="center", fontsize=7, color="tab:blue")
    ax.set_xlim(0, 5)
    ax.set_ylim(-4, 1)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=9)
fig.suptitle("One decision of the affective agent (greedy = towards the prey here)", fontsize=10)
fig.tight_layout()
out = Path(__file__).resolve().parents[1] / "_static" / "decision_moves.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
