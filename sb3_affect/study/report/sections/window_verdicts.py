"""
Fig. 5 against Fig. 6, and how their verdicts move with the windows read as "early" and "late".

With only joy and anger possible (Table II as printed), an episode's joy share is its equivalent ε: Fig. 6's "about
0.3 early" then says joy holds about 30% of early decisions, so joy can not be "dominant early" (Fig. 5) in the
same per-episode sense. Both statements can hold only when sadness or fear take part of the early decisions, or when
"dominant" means something other than the larger share.
"""

from __future__ import annotations

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, ReportContext
from sb3_affect.study.report.reading.episode_scan import paper_scan
from sb3_affect.study.report.reading.run_tables import EARLY_WINDOWS, LATE_WINDOWS
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts.course_claims import judge_fig5, judge_fig6
from sb3_affect.study.report.verdicts.inference import holm, mean_ci


def window_verdicts(aff: pd.DataFrame) -> pd.DataFrame:
    """One row per (early, late) window pair: the Fig. 5 and Fig. 6 verdicts and the shares behind them."""
    rows = {}
    for lo, hi in EARLY_WINDOWS:
        for late_lo, late_hi in LATE_WINDOWS:
            first, last = f"{lo}_{hi}", f"{late_lo}_{late_hi}"
            row: dict[str, object] = {
                "joy share early (= equivalent ε)": mean_ci(aff[f"joy_{first}"].to_numpy(float)).text(),
                "equivalent ε late": mean_ci(aff[f"eqeps_{last}"].to_numpy(float)).text(),
            }
            for name, judgement in (
                ("Fig. 5 (per-episode)", judge_fig5(aff, weighted=False, early=first, late=last)),
                ("Fig. 5 (decision-weighted per run)", judge_fig5(aff, weighted=True, early=first, late=last)),
                ("Fig. 6", judge_fig6(aff, first, last)),
            ):
                holm(judgement.tests)
                row[name] = claims.verdict_word(judgement.decide(judgement) if judgement.decide else "")
            rows[f"{lo}-{hi} / {late_lo}-{late_hi}"] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "early / late episodes"
    return table


#: The verdict rows whose claims read an early and a late window, by their column of ``window_verdicts``.
WINDOW_CLAIMS = {"fig5:mean": "Fig. 5 (per-episode)", "fig5:weighted": "Fig. 5 (decision-weighted per run)", "fig6": "Fig. 6"}


def window_table(ctx: ReportContext) -> pd.DataFrame | None:
    """``window_verdicts`` of the paper sweep's affective runs (computed once per report), or None when runs are short."""
    if "window verdicts" not in ctx.cache:

        found = paper_scan(ctx)  # the affective runs' window features, from the report's one pass over the episodes
        enough = found.last_episode.get(AFFECTIVE, 0) >= max(w[1] for w in LATE_WINDOWS)
        ctx.cache["window verdicts"] = window_verdicts(found.windows) if enough else None
    table: pd.DataFrame | None = ctx.cache["window verdicts"]
    return table


def window_qualifiers(table: pd.DataFrame | None) -> dict[str, str]:
    """Per claim of ``WINDOW_CLAIMS`` whose verdict changes with the windows: ``window-sensitive`` and how."""
    if table is None:
        return {}
    out = {}
    for key, column in WINDOW_CLAIMS.items():
        counts = table[column].value_counts()
        if len(counts) > 1:
            default = "1-10 / 181-200"
            shown = ", ".join(f"{word!s} under {n}" for word, n in counts.items())
            own = f"; the verdict's pair {default}: {table.at[default, column]!s}" if default in table.index else ""
            out[key] = f"window-sensitive ({shown} of the {len(table)} early / late window pairs, paper sweep{own})"
    return out


def windows_section(ctx: ReportContext) -> None:
    if ctx.verdict_refusal():
        return

    table = window_table(ctx)
    if table is None:
        return
    found = paper_scan(ctx)
    aff = found.windows
    ctx.doc.h("Fig. 5 against Fig. 6, and the windows", 3)
    ctx.doc.p(
        "With only joy and anger possible, an episode's joy share is its equivalent ε. So Fig. 6's \"about 0.3\" early "
        "and Fig. 5's \"joy dominant early\" can not both hold per episode: a joy share of 0.3 leaves anger 0.7. Both "
        "can hold only if sadness or fear took part of the early decisions (impossible under Table II as printed) or "
        "if Fig. 5 weighs decisions rather than episodes (long random walks hold most decisions). The table shows how "
        f"the verdicts move with the windows read as \"early\" and \"late\" (paper sweep, {len(aff)} affective runs)."
    )
    ctx.table("fig5_fig6_windows", table, "Fig. 5 and Fig. 6 verdicts for each choice of windows", 3)
    found.windows = aff.iloc[:0]  # no other section reads them: their memory is let go before the later sections
