"""
What every report section gets: ``ReportContext`` (the document, the output folder, the loaded results, the
large-N table and the claims judged so far).

A section is a function ``section(ctx: ReportContext) -> None`` that adds blocks to ``ctx.doc`` (headings,
paragraphs, lists, tables, figures, or a ready-made markdown fragment with ``ctx.doc.md``); ``report.build.SECTIONS``
lists them in order. A new section is one function in its own module, appended to that list.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.study.report.reading.run_tables import Results
from sb3_affect.study.report.reading.study_tables import study
from sb3_affect.study.report.rendering.document import CardSpec, Document
from sb3_affect.study.report.rendering.output_files import replacing

STANDARD, AFFECTIVE = "epsilon-greedy", "affective"
#: Fewest runs per (agent, epsilon) cell, epsilon values and episodes for a verdict (the smoke sweep has fewer).
MIN_RUNS_PER_CELL, MIN_EPSILONS, MIN_EPISODES = 5, 9, 200


@dataclass
class ReportContext:
    """
    The shared state of one report build.

    :param doc: the document sections add to
    :param out: the output folder (``tables/`` and ``figures/`` inside)
    :param root: the folder the report was asked for (a replicate folder or one results folder)
    :param paper: the paper sweep's results (``metrics`` holds one row per run)
    :param metrics: per-run metrics of ``paper``
    :param folders: other results folders found in ``root`` by name (dqn, ablation, baselines, ...)
    :param large: per-run metrics of the large-N study (``report.reading.study_tables``), or None
    :param large_meta: its seeds, episodes and wall time
    :param judgements: the claims judged (filled by the verdict section)
    :param timings: wall time of each sweep (for the reproducibility record)
    :param cache: results computed once and shared between sections (e.g. the verdict)
    :param command: the command line that produced the folder (for the reproducibility record)
    """

    doc: Document
    out: Path
    root: Path
    paper: Results
    metrics: pd.DataFrame
    folders: dict[str, Path] = field(default_factory=dict)
    large: pd.DataFrame | None = None
    large_meta: dict[str, Any] | None = None
    judgements: list[Any] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    cache: dict[str, Any] = field(default_factory=dict)
    command: str = ""
    _later: list[tuple[int, Callable[[ReportContext], None]]] = field(default_factory=list, repr=False)

    def later(self, section: Callable[[ReportContext], None]) -> None:
        """
        Run ``section(ctx)`` once every section has run (``place_later``), its blocks placed here: a section that
        quotes what later sections compute (the abstract).
        """
        self._later.append((len(self.doc.blocks), section))

    def place_later(self) -> None:
        """The sections of ``later``, in order, each one's blocks placed where it was asked for."""
        later, self._later = self._later, []
        document, shift = self.doc, 0
        for at, section in later:
            self.doc = Document(document.title)
            try:
                section(self)
            finally:
                blocks, self.doc = self.doc.blocks, document
            document.blocks[at + shift : at + shift] = blocks
            shift += len(blocks)

    @property
    def episodes(self) -> pd.DataFrame:
        return self.paper.episodes

    def table(self, name: str, frame: pd.DataFrame, caption: str, digits: int = 2) -> None:
        """Write ``tables/<name>.csv`` and add the table to the document."""
        with replacing(self.out / "tables" / f"{name}.csv") as path:
            frame.to_csv(path)
        self.doc.table(frame, caption + f" (tables/{name}.csv)", digits)

    def cards(self, name: str, frame: pd.DataFrame, caption: str, spec: CardSpec, digits: int = 2) -> None:
        """Write ``tables/<name>.csv`` (every column) and add the table as cards (HTML) / a table (Markdown)."""
        frame.to_csv(self.out / "tables" / f"{name}.csv")
        self.doc.cards(frame, caption + f" (tables/{name}.csv)", spec, digits)

    def study(self, name: str) -> pd.DataFrame | None:
        """The per-run table of the engine study ``root/<name>`` (``report.reading.study_tables``), or None."""

        found = study(self.root, name)
        return found[0] if found else None

    def figure(self, name: str) -> Path:
        return self.out / "figures" / f"{name}.png"

    def agent(self, name: str) -> pd.DataFrame:
        return self.metrics[self.metrics.agent == name]

    @property
    def has_paper_agents(self) -> bool:
        m = self.metrics
        return {STANDARD, AFFECTIVE} <= set(m.agent) and "epsilon" in m.columns

    def verdict_refusal(self) -> str | None:
        """Why these results are too few for a verdict (None: enough)."""
        if not self.has_paper_agents:
            return f"the paper's comparison needs both agents `{STANDARD}` and `{AFFECTIVE}` with an `epsilon` label"
        m = self.metrics[self.metrics.agent.isin([STANDARD, AFFECTIVE])]
        per_cell = int(m.groupby(["agent", "epsilon"]).run_id.count().min())
        epsilons = int(m.epsilon.nunique())
        episodes = int(m.episodes.max())
        problems = []
        if per_cell < MIN_RUNS_PER_CELL:
            problems.append(f"the smallest (agent, ε) cell has {per_cell} runs (a verdict needs {MIN_RUNS_PER_CELL})")
        if epsilons < MIN_EPSILONS:
            problems.append(f"there are {epsilons} ε values (the paper's protocol has {MIN_EPSILONS})")
        if episodes < MIN_EPISODES:
            problems.append(f"runs have {episodes} episodes (the paper's protocol has {MIN_EPISODES})")
        return "; ".join(problems) or None
