"""
Write an experiment file and run it
===================================

What ``sb3-affect run FILE --out DIR`` does, from Python: an experiment file names the env, the episodes, the seeds
and the agents with a grid of labels. ``run_sweep`` validates it, runs every run (resuming what ``DIR`` already
holds) and stores the results in ``DIR``: our own tabular agents run in batches stored as Parquet chunks
(``DIR/chunks/``), other runs as one JSON file each (``DIR/runs/``); ``ResultsStore(DIR)`` reads either. The same file
runs from the shell with::

    sb3-affect run my_sweep.yaml --out runs/my_sweep
    sb3-affect report runs/my_sweep
"""

import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from sb3_affect.study.launcher import ResultsStore, run_sweep

SMOKE = bool(os.environ.get("SB3_AFFECT_SMOKE"))
SWEEP = f"""\
name: my-sweep
env: {{id: sb3_affect/GridPursuit-v0, kwargs: {{size: 9, goal: [4, 4]}}}}
episodes: {20 if SMOKE else 100}
seeds: {2 if SMOKE else 5}
agents:
  - name: epsilon-greedy
    algo: QLearning
    grid: {{epsilon: [0.1, 0.3, 0.9]}}
    kwargs: {{exploration_rate: $epsilon}}
  - name: affective
    algo: AffectQ
    grid: {{comparison: [literal, valence]}}
    kwargs: {{comparison: $comparison}}
"""
folder = Path(tempfile.mkdtemp())
(folder / "my_sweep.yaml").write_text(SWEEP)
summary = run_sweep(folder / "my_sweep.yaml", folder / "out", workers=2, progress=False)
print(f"{summary.total} runs, {summary.finished} finished, {summary.failed} failed, {summary.seconds:.1f} s")
store = ResultsStore(folder / "out")
print(sorted(p.name for p in (folder / "out" / "chunks").glob("*.parquet"))[:3], "...")

# %%
# Each run record holds its config (with the grid labels) and one list per episode-log column.
rows = []
for run in store.load_runs():
    labels = {k: v for k, v in run["config"]["labels"].items() if k != "replicate"}
    name = run["config"]["agent"] + " " + " ".join(f"{k}={v}" for k, v in labels.items())
    decisions = run["episodes"]["decisions"]
    rows.append({"agent": name, "decisions per episode": sum(decisions) / len(decisions)})
table = pd.DataFrame(rows).groupby("agent")["decisions per episode"].agg(["mean", "count"])
print(table)

fig, ax = plt.subplots(figsize=(7, 3.5))
ax.barh(table.index, table["mean"])
ax.set_xlabel("mean decisions per episode")
ax.set_title("my-sweep: one bar per agent and grid point")
fig.tight_layout()
plt.show()
