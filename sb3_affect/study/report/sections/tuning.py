"""
The tuning's subsection of the section beyond the paper: the rounds of ε tuned on each task beyond the paper read
back from ``DIR/tuning/round<k>/`` with the planning rule that ran them (``sb3_affect.study.launcher.epsilon_tuning``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.study.launcher.epsilon_tuning import MAX_EXTENSIONS, Tuning, eps_text, round_values, tune, tuning_grid
from sb3_affect.study.report.reading.study_tables import episode_cap, study
from sb3_affect.study.report.rendering.document import fmt


def load_tuning(folder: Path) -> tuple[dict[tuple[str, str], Tuning], dict[str, Any]] | None:
    """
    The tuning in ``folder`` (``round0``, ``round1``, ...: results folders of the launcher, the grid first, then the
    extensions), recomputed round by round with ``tune``; None when it holds no finished tuning.

    :return: the tuning of each (task, agent), and the record: ``rounds``, ``seeds``, ``episodes``, ``grid``, ``sweep``
        (its name, from which the seeds derive), ``cap`` (decisions an episode counts at most), ``seeds by key`` (the
        seeds of each (task, agent))
    """

    first = study(Path(folder), "round0")
    if first is None:
        return None
    table, meta = first
    label, grid = tuning_grid(meta["sweep"])
    if label != "epsilon":
        raise ValueError(f"{Path(folder) / 'round0'}: the tuning sweeps epsilon, not {label!r}")
    tables = [table]

    def read_round(k: int, values: dict[tuple[str, str], list[float]]) -> pd.DataFrame:
        if k:
            found = study(Path(folder), f"round{k}")
            if found is None:
                raise LookupError(f"round{k}")
            tables.append(found[0])
        held = round_values(tables[k])
        if held != values:
            raise ValueError(
                f"{Path(folder) / f'round{k}'} holds {held}, not the values the tuning runs there ({values}); "
                "rerun `sb3-affect replicate` into a new folder"
            )
        return tables[k]

    try:
        choices, rounds = tune(read_round, list(round_values(table)), grid)
    except LookupError:
        return None  # a round the tuning needs is not run yet
    runs = pd.concat(tables, ignore_index=True)
    record = {
        "rounds": rounds,
        "seeds": meta["seeds"],
        "episodes": meta["episodes"],
        "grid": grid,
        "sweep": meta["sweep"]["name"],
        "cap": episode_cap(meta["sweep"]),
        "seeds by key": {key: set(g.seed) for key, g in runs.groupby(["task", "agent"], sort=False)},
    }
    return choices, record


def shared_seeds(seeds: Mapping[tuple[str, str], set[int]], evaluation: pd.DataFrame) -> int:
    """How many tuning seeds (``seeds`` per (task, agent)) the evaluation's runs of the same (task, agent) also use."""
    used = {key: set(g.seed) for key, g in evaluation.groupby(["task", "agent"], sort=False)}
    return sum(len(seeds[key] & used.get(key, set())) for key in seeds)


def tuning_section(ctx: Any, evaluation: pd.DataFrame) -> dict[tuple[str, str], Tuning] | None:
    """
    The tuning's subsection of the section beyond the paper (None, and nothing added, when the folder has none).

    :param evaluation: the per-run table of the evaluation (the tasks beyond the paper), whose seeds the tuning's must
        not be
    """

    found = load_tuning(Path(ctx.root) / "tuning")
    if found is None:
        return None
    choices, record = found
    shared = shared_seeds(record["seeds by key"], evaluation)
    evaluation_seeds = int(evaluation.replicate.max()) + 1
    disjoint = (
        f"disjoint from the {evaluation_seeds:,} evaluation seeds: checked"
        if not shared
        else f"but {shared:,} of them are also evaluation seeds of the same task and agent"
    )
    ctx.doc.h("ε tuned on each task", 3)
    ctx.doc.p(
        "ε-greedy and the speed-matched ε-greedy get their ε tuned on each task before the evaluation: grid "
        f"{', '.join(eps_text(v) for v in record['grid'])} (log-spaced), {record['seeds']:,} tuning seeds per value (sweep "
        f"`{record['sweep']}`, the same seeds for every value, {disjoint}), {record['episodes']} episodes per run. "
        "Criterion: mean decisions per episode, lower is "
        f"better; each episode counts at most {record['cap']:,} decisions, so a truncated episode contributes a lower bound "
        "of its length and a value with truncated episodes has a restricted mean (a lower bound of the uncapped mean); "
        "the truncated episodes are counted. When the best value is at an edge of the values run, one value one grid "
        f"step further out is run (at most {MAX_EXTENSIONS} times, ε within [1e-4, 1]); a best value still at an edge "
        "is reported as not interior. The chosen ε is run at the evaluation seeds in the table above."
    )
    rows = {}
    for (task, agent), t in choices.items():
        at_best = dict(zip(t.curve.columns, t.curve.loc[t.best].to_numpy(dtype=float)))
        rows[f"{task} / {agent}"] = {
            "values run": ", ".join(eps_text(v) for v in t.curve.index),
            "chosen ε": eps_text(t.best),
            "interior": t.note,
            "values indistinguishable from it (paired 95% CI of the difference holds 0)": ", ".join(
                eps_text(v) for v in t.within_noise
            )
            or "none",
            "decisions per episode at the chosen ε [95% CI]": f"{fmt(at_best['mean'], 1)} "
            f"[{fmt(at_best['mean'] - 1.96 * at_best['se'], 1)}, {fmt(at_best['mean'] + 1.96 * at_best['se'], 1)}]",
            "truncated episodes at the chosen ε (tuning runs)": int(at_best["truncated"]),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "task / agent"
    ctx.table("tuning_choice", table, "ε tuned per task: the chosen value and whether it lies inside the values run")
    curves = {}
    for (task, agent), t in choices.items():
        short = "ε-greedy" if agent.startswith("epsilon") else "speed ε-greedy"
        curves[f"{task}: {short}"] = {
            eps_text(float(str(e))): f"{fmt(row['mean'], 1)}"
            + (f" ({int(row['truncated']):,} trunc.)" if row["truncated"] else "")
            + (" *" if e == t.best else "")
            for e, row in t.curve.iterrows()
        }
    wide = pd.DataFrame(curves)
    wide = wide.loc[sorted(wide.index, key=float)].fillna("")
    wide.index.name = "ε"
    ctx.table(
        "tuning_curves",
        wide.T,
        "Tuning curves: mean decisions per episode per ε on the tuning seeds (truncated episodes in brackets; * the "
        "chosen value; blank: not run)",
    )
    static = next(iter(choices))[0]  # the first task: the paper's static grid
    kept = []
    for (task, agent), t in choices.items():
        if task != static or 0.01 not in t.curve.index:
            continue
        same = t.best == 0.01 or 0.01 in t.within_noise
        worse = float(t.curve["vs best"].to_numpy()[list(t.curve.index).index(0.01)])
        kept.append(
            f"{agent}: best {eps_text(t.best)}, and 0.01 is "
            + ("indistinguishable from it" if same else f"worse by {fmt(worse, 2)} decisions")
        )
    if kept:
        ctx.doc.p(
            "On the static task the launcher's fair baselines and the verdict's speed-matched ε-greedy keep ε 0.01 (an "
            "older tuning on that task alone); on the tuning seeds here: " + "; ".join(kept) + " per episode."
        )
    return choices
