"""The report's pages and formats: the main text and its appendix pages, one format per quantity, and the tables whose
columns must agree (synthetic documents and per-run tables with known answers)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from number_formats import column_problem, mixed_formats

from sb3_affect.study.report.rendering.document import MAIN_PAGE, CardSpec, Document, fmt, pval
from sb3_affect.study.report.rendering.formats import with_separators
from sb3_affect.study.report.sections.lead_sources import lead_numbers, mechanism_sentence, mechanism_summary, shown_leads
from sb3_affect.study.report.sections.speed_ablation import DEFINITIONS, speed_one_per_eps
from sb3_affect.study.report.sections.verdict import units_table
from sb3_affect.study.report.verdicts.censoring import UNBOUNDED, difference_sign, marked


def test_the_scan_finds_each_mixed_format_and_leaves_consistent_ones_alone() -> None:
    text = "\n".join(
        [
            "We ran 19000 runs (19,000 in the table), p 0.0002 here and p 0.000215 there.",
            "Episodes 1801-2000, Broekens et al. 2015, Jonker 2015, `seed 12345`, [a file](runs/12345.json).",
            "",
            "| agent | fixed | sig | counts | mixed | as printed |",
            "|---|---|---|---|---|---|",
            "| a | 45.0 | 76.1 | 3 | 35 | 1626.05 |",
            "| b | 1,463 | 142 | 9,000 | 45.0 | 9.80 |",
            "| c | 3.5 | 1,187 | 12 | 19.3 | 76689863 |",
        ]
    )
    found = mixed_formats(text.replace("| as printed |", "| printed |"))
    assert found == [
        "line 1: 19000 without thousands separators",
        "line 1: p 0.0002 in fixed decimals (small p: 3 significant digits)",
        "table at line 4, column 'mixed': 35 beside 45.0",
    ]
    assert column_problem(["0.672", "0.0288", "0.000215"]) == ""  # 3 significant digits: one format
    assert column_problem(["55.9831", "3.29"]) == "decimals [2, 4]"
    assert with_separators("large (19000 runs), Jonker 2015, episodes 1801-2000") == (
        "large (19,000 runs), Jonker 2015, episodes 1801-2000"
    )


def test_p_values_and_floats_have_one_format_each() -> None:
    assert [pval(p) for p in (0.6719, 0.0288, 0.000215, 0.05, 2e-5)] == ["0.672", "0.0288", "0.000215", "0.0500", "2.00e-05"]
    assert fmt(35.0, 1) == "35.0" and fmt(45.25, 1) == "45.2" and fmt(35, 1) == "35" and fmt(19000.0) == "19,000"


def test_parts_become_appendix_pages_linked_from_the_main_page(tmp_path) -> None:  # type: ignore[no-untyped-def]
    doc = Document("report")
    doc.h("Verdict")
    doc.p("The main text.")
    doc.part("appendix-a", "Appendix A: tables")
    doc.h("Table IV")
    doc.table(pd.DataFrame({"x": range(20)}), "a `code` caption")
    doc.part("appendix-b", "Appendix B: the record")
    doc.h("Record")
    pages = doc.markdown_pages(tmp_path)
    assert list(pages) == [f"{MAIN_PAGE}.md", "appendix-a.md", "appendix-b.md"]
    main = pages["report.md"]
    assert "Table IV" not in main and "Record" not in main and main == doc.markdown(tmp_path)
    assert "- [Appendix A: tables](appendix-a.md)" in main and "- [Appendix B: the record](appendix-b.md)" in main
    assert pages["appendix-a.md"].startswith("# Appendix A: tables\n\nPart of [report](report.md).")
    html = doc.html_pages()
    assert list(html) == ["report.html", "appendix-a.html", "appendix-b.html"] and html["report.html"] == doc.html()
    assert "<a href='appendix-a.html'>Appendix A: tables</a>" in html["report.html"]
    assert "<li class='page'><b>Appendix A: tables</b></li>" in html["appendix-a.html"]
    # the appendix page folds its long table; its caption renders code and stands outside the scrolling box
    page = html["appendix-a.html"]
    assert "<details><summary>a <code>code</code> caption (20 rows)</summary>" in page
    assert "<p class='tcap'>a <code>code</code> caption</p><div class='tablebox'>" in page.replace("\n", "")
    with pytest.raises(ValueError, match="part name 'report'"):
        doc.part("report", "again")


def test_markdown_cards_show_the_chosen_columns_labelled_and_some_in_a_word(tmp_path) -> None:  # type: ignore[no-untyped-def]
    frame = pd.DataFrame(
        {"quote": ["q", "q"], "verdict (1,000 seeds)": ["reproduced: inside", "not reproduced: far"],
         "verdict (20 seeds)": ["not reproduced: far", "not reproduced: farther"], "cells": ["n/a", "n/a"]},
        index=pd.Index(["claim one", "claim two"], name="claim"),
    )  # fmt: skip
    spec = CardSpec("quote", ("verdict (1,000 seeds)",), markdown={"verdict (1,000 seeds)": "verdict",
                    "verdict (20 seeds)": "at 20 seeds", "cells": "in cells"}, words=("verdict (20 seeds)",))  # fmt: skip
    doc = Document("r")
    doc.cards(frame, "cards", spec)
    text = doc.markdown(tmp_path)
    assert "- **claim one**. verdict: reproduced: inside. at 20 seeds: not reproduced." in text
    assert "- **claim two**. verdict: not reproduced: far." in text  # its verdict at 20 seeds in the same words: left out
    assert "in cells" not in text and "| claim |" not in text


def _speed_runs() -> tuple[pd.DataFrame, pd.DataFrame]:
    """ε-greedy at 1,000 + 1,000 ε decisions; the affective agent 2,000; speed 1: label 0.1 at 2,900, the rest 3,100."""
    rng = np.random.default_rng(0)
    eps = np.round(np.arange(0.1, 1.0, 0.1), 1)
    rows, slow = [], []
    for e in eps:
        for _ in range(40):
            standard = 1000 + 1000 * e + rng.normal(0, 50)
            rows.append({"agent": "epsilon-greedy", "epsilon": e, "decisions_before_optimal": standard})
            rows.append({"agent": "affective", "epsilon": e, "decisions_before_optimal": 2000 + rng.normal(0, 50)})
            slow.append({"agent": "affective-speed-1", "epsilon": e,
                         "decisions_before_optimal": (2900.0 if e == 0.1 else 3100.0) + rng.normal(0, 50)})  # fmt: skip
    return pd.DataFrame(rows), pd.DataFrame(slow)


def test_the_speed_one_difference_is_epsilon_greedy_minus_all_speed_one_runs_under_both_definitions() -> None:
    """The speed-1 agent ignores ε: every ε is compared with all its runs (one pooled mean), walked and greedy alike."""
    main, slow = _speed_runs()
    main["decisions_to_greedy_optimal"] = main.decisions_before_optimal + 100.0
    slow["decisions_to_greedy_optimal"] = slow.decisions_before_optimal + 300.0
    for frame in (main, slow):
        frame["censored"] = frame["greedy_censored"] = False
    table = speed_one_per_eps(main, slow)

    def number(text: str) -> float:
        return float(text.split(" [")[0].replace(",", "").replace(">= ", ""))

    for column, name in DEFINITIONS:
        pooled = slow[column].mean()  # one pooled mean, not each label's own (2,900 at 0.1)
        for eps, row in table.iterrows():
            own = main[(main.agent == "epsilon-greedy") & (main.epsilon == float(str(eps)))][column].mean()
            difference = number(row[f"minus speed 1, {name} [95% CI]"])
            assert difference == pytest.approx(own - pooled, abs=1.0), (name, eps)
            assert number(row[f"ε-greedy, {name}"]) == pytest.approx(own, abs=1.0)
            assert row[f"Holm p, {name}"]  # each outcome with the Holm-adjusted p it is judged on


def test_the_lead_is_split_per_metric_and_under_both_definitions_into_what_remains_at_speed_one() -> None:
    """
    Synthetic leads: walked, 2,000 decisions with 2-cell moves, 1,600 at speed 1 (80%), with censored ε-greedy runs
    (so bounds); greedy, 500 becoming -100 (none remains); behind in cells per episode.
    """
    eps = np.round(np.arange(0.1, 1.0, 0.1), 1)
    main = pd.DataFrame(
        [{"agent": a, "epsilon": e, "decisions_before_optimal": v, "decisions_to_greedy_optimal": g,
          "cells_per_episode": c, "censored": a == "epsilon-greedy" and r == 0, "greedy_censored": False}
         for e in eps for r in range(2)
         for a, v, g, c in (("epsilon-greedy", 5000.0 + r, 3000.0 + r, 50.0 + r),
                            ("affective", 3000.0 + r, 2500.0 + r, 65.0 + r))]
    )  # fmt: skip
    slow = pd.DataFrame([{"agent": "affective-speed-1", "epsilon": e, "decisions_before_optimal": 3400.0 + r,
                          "decisions_to_greedy_optimal": 3100.0 + r, "cells_per_episode": 55.0 + r, "censored": False,
                          "greedy_censored": False} for e in eps for r in range(2)])  # fmt: skip
    table = lead_numbers(main, slow)
    walked = table.loc["decisions before the optimal path (walked)"]
    greedy = table.loc["decisions until the greedy policy stays optimal (greedy)"]
    assert walked["lead, 1 or 2 cells"] == pytest.approx(2000.0) and walked["remains at speed 1"] == pytest.approx(0.8)
    assert greedy["lead, 1 or 2 cells"] == pytest.approx(500.0) and greedy["lead, speed 1"] == pytest.approx(-100.0)
    # censored ε-greedy runs: its mean and both leads are lower bounds; the share rises with ε-greedy's mean (speed 1
    # is slower than the affective agent), so it is a lower bound too; no censored run, no mark
    assert list(walked["censored (ε-greedy, affective, speed 1)"]) == [9, 0, 0]
    assert (walked["bound, ε-greedy"], walked["bound, 1 or 2 cells"], walked["bound, speed 1"]) == (">=", ">=", ">=")
    assert walked["bound, remains"] == ">="
    assert (greedy["bound, ε-greedy"], greedy["bound, 1 or 2 cells"], greedy["bound, remains"]) == ("", "", "")
    shown = shown_leads(table)
    assert shown.loc["decisions before the optimal path (walked)", "ε-greedy"] == ">= 5,000"
    assert shown.loc["decisions before the optimal path (walked)", "share of the lead that remains at speed 1"] == ">= 80%"
    assert not shown.loc["decisions until the greedy policy stays optimal (greedy)", "ε-greedy"].startswith(">=")
    cells = table.loc["cells per episode"]
    assert cells["lead share, 1 or 2 cells"] == pytest.approx(-15.0 / 50.5) and np.isnan(cells["remains at speed 1"])
    sentence = mechanism_sentence(table, "speed 1 wins only against ε >= 0.4")
    assert "in cells per episode the affective agent is behind ε-greedy by 29.7% (15)" in sentence
    assert "its lead of >= 2,000 becomes >= 1,600 at speed 1 (>= 80% remains; 9 of 18 ε-greedy runs censored" in sentence
    assert "direction rule" not in sentence  # the share says how much remains, not why
    assert sentence.endswith("Per ε, speed 1 wins only against ε >= 0.4.")
    summary = mechanism_summary(table)
    assert summary.startswith("At speed 1")
    assert ">= 80% remains under the walked definition (9 ε-greedy runs censored)" in summary
    assert "none remains under the greedy definition (0 ε-greedy runs censored)" in summary


def test_a_difference_of_censored_means_is_marked_as_the_bound_it_is() -> None:
    assert difference_sign(True, False) == ">=" and difference_sign(False, True) == "<="
    assert difference_sign(False, False) == "" and difference_sign(True, True) == UNBOUNDED
    assert marked("8,937", ">=") == ">= 8,937" and marked("80%", UNBOUNDED) == f"80% ({UNBOUNDED})"


def test_the_per_epsilon_lead_marks_censored_cells_and_gives_kaplan_meier_in_place_of_welch() -> None:
    """ε 0.9: half of ε-greedy's runs never found the path (counted at their total): a bound, with its KM interval."""
    rng = np.random.default_rng(1)
    rows = []
    for e in (0.1, 0.9):
        for r in range(60):
            censored = e == 0.9 and r % 2 == 0
            value = 9000.0 if censored else 3000.0 + rng.normal(0, 100)
            rows.append({"agent": "epsilon-greedy", "epsilon": e, "decisions_before_optimal": value,
                         "cells_before_optimal": value, "censored": censored})  # fmt: skip
            affective = 2000.0 + rng.normal(0, 100)
            rows.append({"agent": "affective", "epsilon": e, "decisions_before_optimal": affective,
                         "cells_before_optimal": 1.5 * affective, "censored": False})  # fmt: skip
    table = units_table(pd.DataFrame(rows))
    assert table.loc["0.1", "ε-greedy runs censored"] == "0 of 60"
    assert table.loc["0.9", "ε-greedy runs censored"] == "30 of 60"
    assert not table.loc["0.1", "lead in decisions [95% CI]"].startswith(">=")
    lead = table.loc["0.9", "lead in decisions [95% CI]"]
    assert lead.startswith(">= ") and "; KM to " in lead
    assert table.loc["0.9", "ε-greedy, decisions"].startswith(">= ")
    assert table.loc["0.9", "lead in decisions, share"].startswith(">=")


def test_the_verdicts_sentence_on_time_and_distance_is_read_from_the_leads() -> None:
    """Ahead in decisions per episode, behind in cells: the sentence says so, with the leads' own numbers."""
    from sb3_affect.study.report.sections.verdict import units_sentence

    eps = np.round(np.arange(0.1, 1.0, 0.1), 1)
    m = pd.DataFrame(
        [{"agent": a, "epsilon": e, "decisions_per_episode": d + r, "cells_per_episode": c + r}
         for e in eps for r in range(3) for a, d, c in (("epsilon-greedy", 56.0, 56.0), ("affective", 49.0, 73.0))]
    )  # fmt: skip
    assert units_sentence(m) == (
        "a lead in decisions is not one in cells: per episode, averaged over ε, it is 7 decisions ahead of ε-greedy "
        "and 17 cells behind"
    )


def test_a_value_too_small_for_its_columns_decimals_is_the_bound_it_is_below_not_scientific() -> None:
    assert [fmt(v, 3) for v in (1.47e-4, -1.32e-5, 0.0, 0.0153)] == ["< 0.001", "> -0.001", "0.000", "0.015"]
    assert fmt(7.67e7, 3) == "76,700,000" and fmt(5094589.0, 3) == "5,094,589"  # one notation in one table
