"""
The list of studies of the main job is the one source of replicate's parts (and so of its --help, which
tests/study/test_cli.py checks against them); the report's one list of sections places every section once.
"""

from __future__ import annotations

import inspect

from sb3_affect.study import studies
from sb3_affect.study.report import build
from sb3_affect.study.report.build import REPORT, extra_slot
from sb3_affect.study.studies import STUDIES


def test_replicate_runs_the_studies_in_their_order() -> None:
    assert [name for name, _ in (*studies.PARTS, *studies.TUNED_PARTS)] == [study.name for study in STUDIES]
    assert {name for name, _, _ in studies.PART_PACKAGES} == {study.name for study in STUDIES if study.extra}
    assert set(studies.SIZED) == {study.name for study in STUDIES if study.size and not study.tuned}


def test_every_study_has_its_sweep_file() -> None:
    folder = studies.shipped_sweeps_folder()
    missing = [study.name for study in STUDIES if not (folder / f"{study.name}.yaml").is_file()]
    assert not missing, f"studies without a sweep file in {folder}: {missing}"


def test_the_report_places_each_section_once_and_the_extra_sections_at_their_slot() -> None:
    names = [(section.__module__, section.__name__) for section in REPORT]
    assert len(names) == len(set(names))
    assert REPORT.count(extra_slot) == 1
    pages = [section.__name__ for section in REPORT if section.__name__.startswith("part_")]
    assert REPORT.index(extra_slot) > REPORT.index(next(s for s in REPORT if s.__name__ == pages[-2]))
    assert REPORT.index(extra_slot) < REPORT.index(next(s for s in REPORT if s.__name__ == pages[-1]))


def test_every_section_takes_the_report_context_only() -> None:
    for section in REPORT:
        assert list(inspect.signature(section).parameters) == ["ctx"], section.__name__


def test_every_studys_folder_is_one_the_sections_may_read() -> None:
    assert {study.name for study in STUDIES if study.name != "paper"} <= set(build.FOLDERS)
