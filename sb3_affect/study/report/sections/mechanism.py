"""
Why the affective agent behaves as it does: its episodes are bimodal (short greedy ones, and random walks in joy),
what "equivalent epsilon" then means, and Fig. 5 under both weightings.
"""

from __future__ import annotations

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, ReportContext
from sb3_affect.study.report.reading.episode_scan import paper_scan
from sb3_affect.study.report.reading.run_tables import EMOTIONS, profile, window_mean
from sb3_affect.study.report.reading.settled_window import LONG, SETTLED, settled_numbers, settled_part
from sb3_affect.study.report.rendering import figures
from sb3_affect.study.report.rendering.document import fmt, sig
from sb3_affect.study.report.rendering.output_files import replacing
from sb3_affect.study.report.sections import joy_trace

WINDOWS = ((1, 10), (21, 40), (181, 200))


#: The profile's decision-weighted estimator: each episode number's decisions pooled over runs, then averaged over
#: the episodes of a window (the definitions name it beside the per-run and the fully pooled ones).
POOLED_PER_EPISODE = "decision-weighted, pooled per episode"

#: Episode numbers per part of ``agent_profile`` (the profile is per episode number: parts give the same numbers).
PROFILE_EPISODES = 50


def agent_profile(ctx: ReportContext, agent: str, last: int) -> pd.DataFrame:
    """``profile`` of ``agent``'s episodes, ``PROFILE_EPISODES`` episode numbers at a time (a few columns in memory)."""
    columns = ("episode", "decisions", *EMOTIONS, "random_moves")
    parts = [
        profile(ctx.paper.agent_episodes(agent, columns, lo, lo + PROFILE_EPISODES - 1))
        for lo in range(1, last + 1, PROFILE_EPISODES)
    ]
    return pd.concat(parts) if len(parts) > 1 else parts[0]


def mechanism_section(ctx: ReportContext) -> None:
    """Bimodal episodes, the meaning of equivalent epsilon, and Fig. 5 under both weightings."""

    ctx.doc.h("Why the affective agent behaves as it does")
    found = paper_scan(ctx)  # the report's one pass over the episode rows
    last = found.last_episode.get(AFFECTIVE, 0)
    if not last:
        ctx.doc.p("Skipped: no affective runs.")
        return
    first = SETTLED[0] if last >= SETTLED[1] else max(1, last // 4)
    if found.settled is not None and found.settled[0] == (first, last):
        _, per_run, decisions, joy = found.settled
    else:  # the scan guessed another window: read this one
        per_run, decisions, joy = settled_part(
            ctx.paper.agent_episodes(AFFECTIVE, ("episode", "decisions", "joy"), first, last), first, last
        )
    found.settled = None  # the section's own copy only from here
    b = settled_numbers(per_run, decisions, joy)
    del per_run, joy

    def ci(key: str, digits: int = 3) -> str:
        return f"{fmt(b[key], digits)} [95% CI {fmt(b[key + ' (low)'], digits)}, {fmt(b[key + ' (high)'], digits)}]"

    ctx.doc.p(
        "The appraisal compares act (decisions' cells so far plus the shortest known remaining path) with the norm "
        "(the power-law fit of past episode lengths). A decision that moves k cells adds k to the elapsed part and "
        "removes at most k from the known remaining part; act can fall only when a newly seen transition shortens the "
        "known remaining path, which a random walk rarely does. So once act reaches the norm the agent feels joy and "
        "joy is near-absorbing: joy moves in a random direction, and the rest of the episode is mostly a random walk "
        "on the grid until it stumbles on the goal. An episode is therefore either short and greedy (anger all the "
        "way) or long and mostly random (joy from the crossing on): the per-episode decisions are bimodal."
    )
    path = figures.decisions_histogram(
        decisions.astype(float),
        ctx.figure("mechanism_decisions"),
        LONG,
        f"Affective agent, episodes {first}-{last}: decisions per episode",
    )
    ctx.doc.img(
        path,
        f"Decisions per episode of the affective agent in episodes {first}-{last} ({int(b['runs'])} runs pooled): "
        "left, how many episodes; right, the share of all decisions they hold",
    )
    ctx.doc.ul(
        [
            f"Episodes {first}-{last}: median {fmt(b['median decisions'], 1)} decisions, mean "
            f"{fmt(b['mean decisions'], 1)} ({int(b['episodes']):,} episodes of {int(b['runs']):,} runs).",
            f"Episodes longer than {LONG} decisions: {ci('share of long episodes')} of the episodes, holding "
            f"{ci('share of decisions in long episodes')} of all decisions.",
            f"Joy's share of the decisions in those long episodes: {ci('joy share of decisions in long episodes')}; "
            f"in the short ones: {fmt(b['joy share of decisions in short episodes'], 3)}.",
            f"Share of episodes with any joy: {ci('share of episodes with any joy')}; mean per-episode joy fraction "
            f"(the paper's equivalent ε): {fmt(b['mean per-episode joy fraction (equivalent ε)'], 3)}; joy fraction of all "
            f"decisions pooled (fully pooled): {ci('decision-weighted joy fraction')} (all three over episodes "
            f"{first}-{last} of the paper sweep's runs).",
        ]
    )
    ctx.doc.p(
        "So the equivalent ε is not a graded exploration rate applied to every decision, as ε is for ε-greedy: it is, "
        "to a close approximation, the chance that an episode turns into a random walk (the mean per-episode joy "
        "fraction is close to the share of episodes with any joy). Per decision, the agent is random most of the time "
        "even late in training, which is why its steps per episode stay far above the 12-cell optimum."
    )
    ctx.cache["mechanism window"] = (first, last)


def fig5_section(ctx: ReportContext) -> None:
    """Joy near-absorbing (the traced runs), Fig. 5 under both weightings and Fig. 6 (appendix)."""
    found = paper_scan(ctx)
    last = found.last_episode.get(AFFECTIVE, 0)
    if not last:
        return
    ctx.doc.h("Joy and the weightings of Figs. 5 and 6")
    joy_section(ctx)
    ctx.doc.h("Fig. 5 under both weightings", 3)
    prof = found.profile if found.profile is not None else agent_profile(ctx, AFFECTIVE, last)
    with replacing(ctx.out / "tables" / "profile_per_episode.csv") as path:
        prof.to_csv(path)
    rows = {}
    for lo, hi in (w for w in WINDOWS if w[1] <= last):  # a short folder shows only the windows its runs reach
        for kind, label in (("mean", "mean of per-episode fractions"), ("weighted", POOLED_PER_EPISODE)):
            rows[(f"episodes {lo}-{hi}", label)] = {
                name: window_mean(prof, name, lo, hi, kind) for name in (*EMOTIONS, "equivalent_epsilon")
            }
    if not rows:
        return
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index = [f"{w} / {k}" for w, k in table.index]
    table.index.name = "window / weighting"
    ctx.table("profile_windows", table, "Emotion fractions and equivalent ε per window, under both weightings", 3)
    f5 = figures.emotion_profile(prof, ctx.figure("fig5_emotion_profile"))
    silent = [e for e in EMOTIONS if float(prof[f"{e}_mean"].max()) == 0.0]
    note = f" ({' and '.join(silent)} never occur: their lines lie on 0)" if silent else ""
    ctx.doc.img(f5, f"Fig. 5: fraction of decisions in each emotion per episode, both weightings{note}")
    late = next(w for w in reversed(WINDOWS) if w[1] <= last)
    late_mean = rows[(f"episodes {late[0]}-{late[1]}", "mean of per-episode fractions")]
    late_weighted = rows[(f"episodes {late[0]}-{late[1]}", POOLED_PER_EPISODE)]
    ctx.doc.p(
        "Reconciling with the paper's \"joy early, anger later\": averaging per-episode fractions (each episode counts "
        f"once, as the paper's figure does), late episodes are mostly anger (joy {fmt(late_mean['joy'], 3)}, anger "
        f"{fmt(late_mean['anger'], 3)} in episodes {late[0]}-{late[1]} of the paper sweep's runs), because most late "
        "episodes are "
        "short greedy ones. Weighting by decisions (each decision counts once; pooled per episode), joy stays the "
        f"dominant emotion (joy {fmt(late_weighted['joy'], 3)}, anger {fmt(late_weighted['anger'], 3)}), because the "
        "few random-walk "
        "episodes hold most of the decisions. Both are true: the agent exploits in most episodes and explores in most "
        "decisions. The paper's reading (\"will exploit more in the latter episodes\") holds per episode, not per step."
    )
    f6 = figures.equivalent_epsilon(prof, ctx.figure("fig6_equivalent_epsilon"))
    ctx.doc.img(f6, "Fig. 6: equivalent ε (fraction of random-direction decisions) per episode, both weightings")
    with_first, without = (window_mean(prof, "equivalent_epsilon", lo, 10) for lo in (1, 2))
    if last >= 10 and with_first == with_first:
        ctx.doc.p(
            f"Episode 1 is joy by construction (no finished episode yet, so no appraisal: the agent explores; equivalent "
            f"ε {fmt(window_mean(prof, 'equivalent_epsilon', 1, 1), 3)} there): it adds {fmt(with_first - without, 3)} "
            f"to the mean of episodes 1-10 ({fmt(with_first, 3)}; {fmt(without, 3)} over episodes 2-10). Fig. 6's "
            "\"about 0.3 early\" read on episodes 1-10 leans on that definitional episode (the windows table)."
        )


def joy_section(ctx: ReportContext) -> None:
    """Joy near-absorbing, and where late episodes cross the norm (the traced runs of ``DIR/joy_trace``)."""
    frame = joy_trace.traced(ctx.root / "joy_trace")
    if frame is None or ctx.verdict_refusal():
        return
    b = joy_trace.summary(frame)
    ctx.doc.h("Joy is near-absorbing; where late episodes cross the norm", 3)
    path = joy_trace.norm_figure(frame, ctx.figure("norm_crossings"), ctx.cache.get("shortest path"))
    ctx.doc.p(
        f"Traced decision by decision ({int(b['runs'])} runs of the paper's affective agent, seeds {frame.seed.min()}-"
        f"{frame.seed.max()}, {int(b['episodes'])} episodes; the episode log keeps only counts): of "
        f"{int(b['joy decisions']):,} joy decisions, {sig(b['exits per joy decision'])} per decision are followed by "
        f"another emotion in the same episode, and {b['share of joy episodes that ever leave joy']:.1%} of the episodes "
        "that feel joy ever leave it. Joy is near-absorbing, not absorbing: act can fall when a newly seen transition "
        "shortens the known remaining path. In episodes "
        f"{joy_trace.LATE[0]}-{joy_trace.LATE[1]}, {b['share of late episodes that cross the norm']:.1%} of the episodes "
        f"still cross the norm although Q has long converged: the norm has fallen to {sig(b['late norm, median'])} cells "
        f"(median), barely above the shortest path, and the crossing comes when act reaches "
        f"{sig(b['act at the crossing in late episodes, median (cells)'])} cells (median), at decision "
        f"{sig(b['first joy decision in crossing late episodes, median'])} (median) of an episode that without joy takes "
        f"{sig(b['late decisions without crossing, median'])} decisions: near the goal, once act has met a norm that "
        "leaves a greedy walk little room. From there joy turns the end of the episode into a random walk "
        f"({sig(b['decisions of crossing late episodes, median'])} decisions, median)."
    )
    ctx.doc.img(
        path,
        "The norm per episode (left) and, for the episodes that cross it, act at the decision where joy starts minus "
        "that run's own norm in that episode (right; cells)",
    )

