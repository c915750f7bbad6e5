"""The report section of the forensics: tables and one figure, from the CSV files ``analysis.analyse`` wrote."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from sb3_affect.core.settings import AffectQSettings
from sb3_affect.study.forensics.scoring import MIN_REACH_REPS, NOT_REACHED, NOT_RULED_OUT, REACHED, transform
from sb3_affect.study.forensics.statistics import LOG_SCALE, STATISTICS, candidate_statistics, cell_summary
from sb3_affect.study.launcher.forensics_candidates import Reading
from sb3_affect.study.launcher.regular_files import open_regular, read_json
from sb3_affect.study.launcher.store import write_atomic
from sb3_affect.study.report.reading.run_tables import load_results
from sb3_affect.study.report.reading.study_tables import AFFECT_DEFAULT, COMMON
from sb3_affect.study.report.rendering.document import fmt, md_table

FACTORS = ("comparison", "act", "units", "tie_break", "multi_cell", "alpha", "gamma", "optimal", "step", "table_v")

#: The largest ``run.json`` read (the analysis' sizes and findings: a few kB).
MAX_RUN_BYTES = 2**20


class ForensicsSection(NamedTuple):
    """
    A ready-made report section: ``text, images = forensics_section(...)`` like the report's other sections.

    :param markdown: the section's Markdown (heading, text, tables), without the figures
    :param figures: (PNG path, caption) pairs to show after it
    """

    markdown: str
    figures: list[tuple[Path, str]]


def _csv(path: Path, **kwargs: Any) -> pd.DataFrame:
    """A CSV table the analysis wrote (a regular file only: ``regular_files``)."""
    with open_regular(path) as handle:
        return pd.read_csv(handle, **kwargs)


def has_results(folder: str | Path) -> bool:
    """Whether ``folder`` holds a finished forensics analysis."""
    return (Path(folder) / "leaders.csv").exists() and (Path(folder) / "intervals.csv").exists()


def _short(row: pd.Series) -> str:
    return (
        f"{row.comparison}/{row.act}/{row.units}, ties {row.tie_break}, 2 cells {row.multi_cell}, "
        f"alpha {fmt(float(row.alpha))}, gamma {fmt(float(row.gamma))} (x{fmt(float(row.steps_ratio), 0)})"
    )


def _loglik(value: float) -> str:
    return "-inf (never produces a printed value)" if value == -math.inf else f"{value:,.1f}"


def _differences(table: pd.DataFrame, column: str, error: str) -> list[str]:
    """Each row's ``column`` minus the best row's, with the Monte Carlo error of the difference (when recorded)."""
    values = table[column].to_numpy(float)
    finite = values[np.isfinite(values)]
    if not len(finite):
        return ["" for _ in values]
    best = int(np.nanargmax(np.where(np.isfinite(values), values, -np.inf)))
    errors = table[error].to_numpy(float) if error in table.columns else np.full(len(values), np.nan)
    out = []
    for i, value in enumerate(values):
        if not math.isfinite(value):
            out.append("-inf")
            continue
        if i == best:
            out.append("— (the best)")
            continue
        spread = math.sqrt(errors[i] ** 2 + errors[best] ** 2)
        out.append(f"{value - values[best]:,.1f}" + (f" ± {spread:,.1f}" if math.isfinite(spread) else ""))
    return out


def largest_separation(table: pd.DataFrame, column: str = "loglik", error: str = "loglik_mc_error") -> float:
    """The largest |difference from the best| over its Monte Carlo error among ``table``'s rows (NaN: no errors)."""
    values = table[column].to_numpy(float)
    errors = table[error].to_numpy(float) if error in table.columns else np.full(len(values), np.nan)
    if not np.isfinite(values).any():
        return math.nan
    best = int(np.nanargmax(np.where(np.isfinite(values), values, -np.inf)))
    ratios = [abs(v - values[best]) / math.hypot(e, errors[best]) for i, (v, e) in enumerate(zip(values, errors))
              if i != best and math.isfinite(v) and math.hypot(e, errors[best]) > 0]  # fmt: skip
    return max(ratios, default=math.nan)


def step_unit_lines(top: pd.DataFrame) -> list[str]:
    """
    The leading candidates that differ only in the step unit, pair by pair: decisions minus cells on the full
    likelihood and on the reachable statistics, each with the Monte Carlo error of the difference (the two
    candidates' errors combined), and how many pairs each unit wins and by two errors.
    """
    if "step" not in top.columns:
        return []
    others = [c for c in FACTORS if c in top.columns and c != "step"]
    ranked = top.reset_index(drop=True)
    scores = [("full likelihood", "loglik", "loglik_mc_error"),
              ("reachable statistics", "loglik_reachable", "loglik_reachable_mc_error")]  # fmt: skip
    scores = [score for score in scores if score[1] in ranked.columns]
    pairs: list[tuple[int, int]] = []
    for _, group in ranked.groupby(others, sort=False, dropna=False):
        units = {str(step): int(i) for i, step in zip(group.index.to_numpy(), group.step.to_numpy())}
        if {"decisions", "cells"} <= set(units):
            pairs.append((units["decisions"], units["cells"]))
    if not pairs:
        return []

    def diff(a: int, b: int, value: str, error: str) -> tuple[float, float]:
        errors = ranked[error] if error in ranked.columns else pd.Series(math.nan, index=ranked.index)
        return float(ranked[value].iloc[a] - ranked[value].iloc[b]), math.hypot(float(errors.iloc[a]), float(errors.iloc[b]))

    pairs.sort(key=min)
    texts = []
    for a, b in pairs:
        found = [diff(a, b, value, error) for _, value, error in scores]
        texts.append(f"ranks {a + 1} (decisions) and {b + 1} (cells): "
                     + ", ".join(f"{name} {d:+,.1f} ± {e:,.1f}" for (name, _, _), (d, e) in zip(scores, found)))  # fmt: skip
    tallies = []
    for name, value, error in scores:
        found = [diff(a, b, value, error) for a, b in pairs]
        wins = sum(d > 0 for d, _ in found)
        separated = [d for d, e in found if abs(d) > 2 * e]
        favour = [f"{sum(d > 0 for d in separated)} favour decisions", f"{sum(d < 0 for d in separated)} favour cells"]
        tallies.append(f"on the {name} decisions score higher in {wins} of {len(pairs)} pairs ({len(separated)} of the "
                       f"{len(pairs)} differences reach two Monte Carlo errors"
                       + (f": {', '.join(favour)}" if separated else "") + ")")  # fmt: skip
    return [
        f"The forensics does not decide the step unit: {len(pairs)} pairs of leading candidates differ only in it "
        "(decisions minus cells, log-likelihood ± the Monte Carlo error of the difference): " + "; ".join(texts)
        + ". " + "; ".join(tallies)[0].upper() + "; ".join(tallies)[1:] + ". The verdict counts steps as decisions "
        "(the paper's unit of time) and gives each claim's verdict in cells beside it.",
        "",
    ]


def verdict_setting() -> dict[str, Any]:
    """The verdict's own implementation (the report's agents and their settings' defaults) in the screen's terms."""

    defaults = AffectQSettings()
    return {
        **AFFECT_DEFAULT,
        "tie_break": defaults.tie_break,
        "multi_cell": defaults.multi_cell,
        "alpha": float(COMMON["learning_rate"]),
        "gamma": float(COMMON["gamma"]),
        "step": "decisions",  # the verdict counts a step as a decision
    }


def leader_sensitivity_lines(folder: Path, leaders: pd.DataFrame, intervals: pd.DataFrame) -> list[str]:
    """
    The sensitivity row of the verdict's sizes: each printed statistic beside its mean over the leading candidate's
    full replications (``sample_top1.csv``), that is, under the best-fitting setting instead of the verdict's own.
    """
    path = Path(folder) / "sample_top1.csv"
    if not path.exists() or leaders.empty:
        return []
    sample = _csv(path)
    leader = leaders.iloc[0]
    setting = ", ".join(f"{c} {leader[c]}" for c in ("alpha", "gamma") if c in leaders.columns)
    rows = pd.DataFrame(index=pd.Index(STATISTICS, name="statistic"))
    rows["printed"] = intervals["printed"].reindex(rows.index)
    rows[f"leader's mean ({len(sample)} replications)"] = [
        float(np.nanmean(sample[s])) if s in sample.columns and np.isfinite(sample[s]).any() else math.nan
        for s in STATISTICS
    ]
    correlation = rows.index.str.contains("Pearson r")  # a correlation's ratio means nothing: its difference

    def against(values: pd.Series | np.ndarray) -> np.ndarray:
        values, printed = np.asarray(values, float), rows["printed"].to_numpy(float)
        return np.where(correlation, values - printed, values / printed)

    rows["leader / printed (r: minus)"] = against(rows.iloc[:, 1])
    own = protocol_statistics(Path(folder).parent / "paper")
    if own is not None:
        rows["the verdict's setting, the protocol's runs (walked, sum)"] = own
        rows["verdict's / printed (r: minus)"] = against(own)
    return [
        f"*Sensitivity of the sizes to the setting: each printed statistic beside its mean under the leading candidate "
        f"({setting}; {len(sample)} replications of the paper's protocol), and under the verdict's own setting (alpha "
        "1.0, gamma 0.8) on the paper protocol's own runs, one replication*",
        "",
        md_table(rows, 2),
        "",
    ]


def protocol_statistics(paper: Path) -> np.ndarray | None:
    """
    The printed statistics (``STATISTICS``) of the paper protocol's own runs (the results folder ``paper``: the
    verdict's setting), read as the verdict reads them (steps as decisions, the walked optimal path, Table V as the
    sum over the runs); None when the folder holds no such runs.
    """
    if not (paper / "runs").is_dir():
        return None
    columns = ("episode", "decisions", "cells", "optimal", "greedy_optimal")
    episodes = load_results(paper, columns).episodes
    if episodes.empty or "epsilon" not in episodes.columns:
        return None
    summaries = {}
    for agent in ("epsilon-greedy", "affective"):
        rows = episodes[episodes.agent == agent].rename(columns={"run_id": "seed"})
        if rows.empty:
            return None
        cells = {eps: cell_summary(rows[rows.epsilon == eps]) for eps in sorted(rows.epsilon.astype(float).unique())}
        summaries[agent] = pd.DataFrame(cells).T
    return candidate_statistics(summaries["epsilon-greedy"], summaries["affective"], Reading("walked", "decisions", "sum"))


def verdict_setting_lines(screen: pd.DataFrame) -> list[str]:
    """Where the verdict's own setting ranks in the screen, per definition of "optimal path found"."""
    setting = verdict_setting()
    if not set(setting) <= set(screen.columns):
        return []
    ranked = screen.reset_index(drop=True)
    mine = np.ones(len(ranked), bool)
    for column, value in setting.items():
        mine &= (ranked[column] == value).to_numpy() if isinstance(value, str) else np.isclose(ranked[column], value)
    rows = ranked[mine]
    if not len(rows):
        return []
    leader = screen.iloc[0]
    places = "; ".join(
        f"{position + 1} ({row.optimal} optimal path, Table V as the {row.table_v})"
        for position, (_, row) in zip(np.flatnonzero(mine), rows.iterrows())
        if "optimal" in rows.columns and "table_v" in rows.columns
    )
    return [
        f"The verdict's own setting ({', '.join(f'{k} {v}' for k, v in setting.items())}) ranks {places} of "
        f"{len(screen)} in the screen; the screen's leader uses alpha {fmt(float(leader.alpha))}, gamma "
        f"{fmt(float(leader.gamma))}. The interval table below gives the printed numbers under the leaders' settings "
        "beside the paper's: the verdict's sizes are those of its own setting, not of the best-fitting one.",
        "",
    ]


def _sci(value: float) -> str:
    """One notation in a table: 3 decimals below 1,000, whole numbers with separators from 1,000 on."""
    return fmt(value, 3)


def forensics_section(folder: str | Path, figures_dir: str | Path | None = None) -> ForensicsSection:
    """
    The section "Replication forensics" from a ``sb3-affect forensics`` folder.

    :param folder: the folder ``analysis.analyse`` wrote
    :param figures_dir: where to write the figure (default: ``folder/figures``)
    :return: its Markdown and its figure
    """
    folder = Path(folder)
    if not has_results(folder):
        raise FileNotFoundError(f"{folder} holds no forensics results (run `sb3-affect forensics --out {folder}`)")
    figures_dir = Path(figures_dir or folder / "figures")
    figures_dir.mkdir(parents=True, exist_ok=True)
    run = read_json(folder / "run.json", MAX_RUN_BYTES)
    leaders = _csv(folder / "leaders.csv")
    screen = _csv(folder / "screen.csv")
    table = _csv(folder / "intervals.csv", index_col=0)
    lines = [
        "## Replication forensics: which implementation could have printed the paper's numbers?",
        "",
        f"Candidate space: {run['candidates']} candidates ({run['affective_simulations']} affective simulations x "
        f"{run['candidates'] // max(run['affective_simulations'], 1)} ways of reading the logs; "
        f"{run['standard_simulations']} epsilon-greedy simulations shared between them). Each simulation replicates "
        f"the paper's whole protocol with fresh seeds: {run['screen_reps']} replications in the screen, {run['reps']} "
        f"for the {run['leaders']} leading affective simulations. Score: Gaussian synthetic log-likelihood of the "
        f"{len(STATISTICS)} printed statistics (log scale for means, variances and episodes); candidates compared by "
        "their log-likelihood differences with Monte Carlo errors (docs/forensics.md). "
        f"Wall time of the last run: {fmt(float(run['seconds']), 0)} s.",
        "",
    ]
    top = leaders.head(8)
    ranking = top[[c for c in FACTORS if c in top.columns]].copy()
    ranking["log-likelihood"] = top.loglik.map(_loglik)
    ranking["minus the best's [± Monte Carlo error]"] = _differences(top, "loglik", "loglik_mc_error")
    if "loglik_reachable" in top.columns:
        ranking["the same, reachable statistics only"] = _differences(top, "loglik_reachable", "loglik_reachable_mc_error")
    ranking.index = pd.Index(range(1, len(ranking) + 1), name="rank")
    lines += [
        "*Leading candidates, best first (full replications): each log-likelihood minus the best candidate's, with the "
        "Monte Carlo error of the difference (bootstrap over the replications); a difference within about two errors "
        "does not separate two candidates. The last column scores only the printed numbers a leading candidate "
        "reaches (below), ranked against its own best*",
        "",
        md_table(ranking, 2),
        "",
    ]
    largest = largest_separation(top)
    if math.isfinite(largest):
        lines += [
            f"Among these {len(top)} leaders the largest difference from the best in the full likelihood is "
            f"{largest:.1f} Monte Carlo errors: "
            + ("none reaches two there, so the full likelihood does not separate them (the reachable statistics: the "
               "step-unit pairs below)." if largest < 2 else "some reach two."),
            "",
        ]
    lines += step_unit_lines(top)
    lines += verdict_setting_lines(screen)
    lines += leader_sensitivity_lines(folder, leaders, table)
    best_screen = screen.head(8)
    screened = best_screen[[c for c in FACTORS if c in best_screen.columns]].copy()
    screened["screen log-likelihood"] = best_screen.screen_loglik.map(_loglik)
    screened.index = pd.Index(range(1, len(screened) + 1), name="rank")
    rejected = screen[screen.screen_loglik == -math.inf]
    if "steps_ratio" in screen.columns and len(rejected):
        sims = rejected.drop_duplicates(subset=[c for c in FACTORS[:7] if c in rejected.columns])
        lines += [
            f"Pre-screen: {len(sims)} affective simulations ({len(rejected)} candidates) were dropped after one "
            "replication because their own or their ε-greedy partner's mean steps per episode missed the printed "
            "Table IV mean by more than a factor 10 in both step units (the factor in brackets; a lower bound where the "
            "replication was stopped as soon as the factor was certain): "
            + "; ".join(_short(row) for _, row in sims.head(12).iterrows())
            + ("; ..." if len(sims) > 12 else "")
            + ".",
            "",
        ]
    lines += [f"*Screen: the best 8 of {len(screen)} candidates (diagonal likelihood, few replications)*", ""]
    lines += [md_table(screened, 2), ""]
    shown = table.copy()
    for column in shown.columns:
        if "reaching" not in column and "covering" not in column and column != "finding":
            shown[column] = shown[column].map(_sci)
    lines += [
        f"*Each printed number against the simulated 95% interval of the best three candidates; 'leaders reaching': how "
        f"many leader candidates' 95% Student-t predictive intervals from their {run['reps']} replications hold it; "
        f"'screened covering': how many screened candidates' predictive intervals from {run['screen_reps']} "
        "replications hold it (so wide that covering is no evidence); 'finding': what that shows*",
        "",
        md_table(shown, 3),
        "",
    ]
    lines += findings_lines(table, run)
    figure = _figure(folder, table, figures_dir / "forensics_statistics.png")
    caption = (
        "Forensics: each printed statistic (black line) against the simulated replications of the best candidates "
        "(histograms; log scale for means, variances and episodes)"
    )
    return ForensicsSection("\n".join(lines), [(figure, caption)] if figure else [])


def findings_lines(table: pd.DataFrame, run: dict[str, Any]) -> list[str]:
    """
    What the forensics showed about each printed number, from the interval table's "finding" column (written by
    ``analysis.analyse``): reached only on the leaders' full replications; screen-size coverage is "not ruled out".
    """
    if "finding" not in table.columns:  # a folder from before the findings: nothing is decided from its counts
        return ["This folder predates the findings: rerun `sb3-affect forensics` to decide which numbers are reached.", ""]
    reps, screen_reps = int(run["reps"]), int(run["screen_reps"])
    covering: dict[str, int] = {}
    if "screened covering" in table.columns:
        covering = {str(k): int(v) for k, v in table["screened covering"].items()}

    def named(finding: str, counts: bool = False) -> list[str]:
        rows = table[table["finding"] == finding]
        return [
            f"**{name}** ({_sci(float(row.printed))}"
            + (f"; {covering[str(name)]} screened candidates cover it" if counts and str(name) in covering else "")
            + ")"
            for name, row in rows.iterrows()
        ]

    reached, open_, shut = named(REACHED), named(NOT_RULED_OUT, counts=True), named(NOT_REACHED)
    lines = []
    if reps < MIN_REACH_REPS:
        lines.append(
            f"The leaders have {reps} replications, fewer than the {MIN_REACH_REPS} a printed number needs to count as "
            "reached: at this size no number is shown to be reached."
        )
    lines += [
        f"- Reached (inside a leading candidate's 95% predictive interval from {reps} replications): "
        + (", ".join(reached) or "none")
        + ".",
        f"- Not reached by any leading candidate at {reps} replications, not ruled out at screen size (only intervals "
        f"from {screen_reps} replications cover them; that is no evidence a candidate prints them): "
        + (", ".join(open_) or "none")
        + ".",
        "- Not reached by any candidate, screen included (evidence of a difference the candidate space does not cover): "
        + (", ".join(shut) or "none")
        + ".",
        "",
    ]
    return lines


def _figure(folder: Path, table: pd.DataFrame, path: Path) -> Path | None:
    import matplotlib  # (the report extra: only when figures are drawn)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # (the report extra: only when figures are drawn)

    samples = [_csv(p) for p in sorted(folder.glob("sample_top*.csv"))]
    if not samples:
        return None
    printed = transform(table["printed"].to_numpy(dtype=float))
    fig, axes = plt.subplots(3, 5, figsize=(16, 8.5))
    for index, (name, ax) in enumerate(zip(STATISTICS, axes.flat)):
        for rank, sample in enumerate(samples):
            values = transform(sample.to_numpy(dtype=float))[:, index]
            values = values[np.isfinite(values)]
            if len(values):  # values equal to float precision can not be cut into 20 bins: one
                bins = 20 if np.all(np.diff(np.linspace(values.min(), values.max(), 21)) > 0) else 1
                ax.hist(values, bins=bins, alpha=0.45, label=f"#{rank + 1}", color=f"C{rank}")
        if np.isfinite(printed[index]):
            ax.axvline(printed[index], color="black", lw=2, label="paper")
        ax.set_title(name + (" (log)" if LOG_SCALE[index] else ""), fontsize=9)
        ax.set_xlabel("log of the value" if LOG_SCALE[index] else "value", fontsize=7)
        ax.set_ylabel("replications", fontsize=7)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(STATISTICS) :]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def report_section(folder: str | Path) -> Any:
    """
    The forensics as a report section, for ``build_report(..., extra_sections=[report_section(folder)])``: the layer
    above both (``sb3_affect.study.replicate``, the CLI) wires it, so the report never imports the forensics. None when
    ``folder`` holds no results.
    """
    folder = Path(folder)
    if not has_results(folder):
        return None

    def forensics_report_section(ctx: Any) -> None:
        run = read_json(folder / "run.json", MAX_RUN_BYTES)
        section = forensics_section(folder, ctx.out / "figures")
        ctx.doc.md(section.markdown)
        for figure_path, caption in section.figures:
            ctx.doc.img(figure_path, caption)
        ctx.cache["forensics"] = (
            f"included ({folder}: {run['screen_reps']} screen replications, {run['leaders']} leaders x {run['reps']} "
            f"replications, {float(run['seconds']):.0f} s)"
        )

    return forensics_report_section


def write_standalone(folder: str | Path) -> Path:
    """``folder/forensics.md``: the section with its figure, readable on its own."""
    folder = Path(folder)
    section = forensics_section(folder)
    parts = [section.markdown, ""]
    for path, caption in section.figures:
        parts += [f"![{caption}]({path.relative_to(folder).as_posix()})", "", f"*{caption}*", ""]
    md = folder / "forensics.md"
    write_atomic(md, "\n".join(parts).encode())
    return md
