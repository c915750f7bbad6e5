"""The report's pages and formats: the main text and its appendix pages, one format per quantity, and the tables whose
columns must agree (synthetic documents and per-run tables with known answers)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from number_formats import column_problem, mixed_formats

from sb3_affect.study.report.rendering.document import MAIN_PAGE, CardSpec, Document, fmt, pval
from sb3_affect.study.report.rendering.formats import with_separators
from sb3_affect.study.report.sections.lead_sources import lead_numbers, mechanism_sentence
from sb3_affect.study.report.sections.speed_ablation import SPEED_ONE_POOLED, speed_one_per_eps


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
        {"quote": ["q"], "verdict (1,000 seeds)": ["reproduced: inside"], "verdict (20 seeds)": ["not reproduced: far"],
         "cells": ["n/a"]},
        index=pd.Index(["claim one"], name="claim"),
    )  # fmt: skip
    spec = CardSpec("quote", markdown={"verdict (1,000 seeds)": "verdict", "verdict (20 seeds)": "at 20 seeds",
                                       "cells": "in cells"}, words=("verdict (20 seeds)",))  # fmt: skip
    doc = Document("r")
    doc.cards(frame, "cards", spec)
    text = doc.markdown(tmp_path)
    assert "- **claim one**. verdict: reproduced: inside. at 20 seeds: not reproduced." in text
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


def test_the_speed_one_difference_column_is_the_columns_beside_it_subtracted() -> None:
    """The speed-1 agent ignores ε: every ε is compared with all its runs, and its column prints that pooled mean."""
    main, slow = _speed_runs()
    table = speed_one_per_eps(main, slow)
    pooled = slow.decisions_before_optimal.mean()
    assert (table[SPEED_ONE_POOLED] == f"{pooled:,.0f}").all()  # one pooled mean, not each label's own (2,900 at 0.1)

    def number(text: str) -> float:
        return float(text.split(" [")[0].replace(",", ""))

    for eps, row in table.iterrows():
        difference = number(row["ε-greedy minus speed 1 [95% CI]"])
        assert difference == pytest.approx(number(row["ε-greedy"]) - number(row[SPEED_ONE_POOLED]), abs=1.0), eps


def test_the_lead_is_split_per_metric_into_what_remains_at_speed_one() -> None:
    """Synthetic leads: 2,000 decisions with 2-cell moves, 1,600 at speed 1 (80%); behind in cells per episode."""
    eps = np.round(np.arange(0.1, 1.0, 0.1), 1)
    main = pd.DataFrame(
        [{"agent": a, "epsilon": e, "decisions_before_optimal": v, "cells_per_episode": c}
         for e in eps for r in range(2)
         for a, v, c in (("epsilon-greedy", 5000.0 + r, 50.0 + r), ("affective", 3000.0 + r, 65.0 + r))]
    )  # fmt: skip
    slow = pd.DataFrame([{"agent": "affective-speed-1", "epsilon": e, "decisions_before_optimal": 3400.0 + r,
                          "cells_per_episode": 55.0 + r} for e in eps for r in range(2)])  # fmt: skip
    table = lead_numbers(main, slow)
    before = table.loc["decisions before the optimal path"]
    assert before["lead, 1 or 2 cells"] == pytest.approx(2000.0) and before["remains at speed 1"] == pytest.approx(0.8)
    cells = table.loc["cells per episode"]
    assert cells["lead share, 1 or 2 cells"] == pytest.approx(-15.0 / 50.5) and np.isnan(cells["remains at speed 1"])
    sentence = mechanism_sentence(table, "speed 1 wins only against ε >= 0.4")
    assert "in cells per episode the affective agent is behind ε-greedy by 29.7% (15)" in sentence
    assert "its lead of 2,000 becomes 1,600 at speed 1 (80% remains: mostly its direction rule" in sentence
    assert sentence.endswith("Per ε, speed 1 wins only against ε >= 0.4.")
