"""
The list of studies of the main job is the one source of replicate's parts (and so of its --help, which
tests/study/test_cli.py checks against them) and names the report's sections that read each study.
"""

from __future__ import annotations

import inspect

import pytest

from sb3_affect.study import studies
from sb3_affect.study.report import build
from sb3_affect.study.report.build import APPENDIX, SECTIONS, study_section, with_studies
from sb3_affect.study.studies import STUDIES, Study


def test_replicate_runs_the_studies_in_their_order() -> None:
    assert [name for name, _ in (*studies.PARTS, *studies.TUNED_PARTS)] == [study.name for study in STUDIES]
    assert {name for name, _, _ in studies.PART_PACKAGES} == {study.name for study in STUDIES if study.extra}
    assert set(studies.SIZED) == {study.name for study in STUDIES if study.size and not study.tuned}


def test_every_study_has_its_sweep_file() -> None:
    folder = studies.shipped_sweeps_folder()
    missing = [study.name for study in STUDIES if not (folder / f"{study.name}.yaml").is_file()]
    assert not missing, f"studies without a sweep file in {folder}: {missing}"


def test_the_report_places_each_studys_sections_where_the_list_says() -> None:
    main, appendix = with_studies(SECTIONS, "sections"), with_studies(APPENDIX, "appendix")
    for study in STUDIES:
        for name in study.sections:
            assert study_section(name) in main or name in {f"build:{s.__name__}" for s in main}, (study.name, name)
        for name in study.appendix:
            assert study_section(name) in appendix, (study.name, name)
    assert main == SECTIONS and appendix == APPENDIX  # every study's section is already in the report's own lists


def test_a_new_studys_section_joins_the_report_without_an_entry_there(monkeypatch: pytest.MonkeyPatch) -> None:
    new = Study("new_study", "a study the report's lists do not know", sections=("sections.mechanism:joy_section",))
    monkeypatch.setattr(build, "STUDIES", (*STUDIES, new))
    main = build.with_studies(SECTIONS, "sections")
    assert main[: len(SECTIONS)] == SECTIONS and main[len(SECTIONS) :] == [study_section(new.sections[0])]


def test_every_section_takes_the_report_context_only() -> None:
    for section in [*SECTIONS, *APPENDIX]:
        assert list(inspect.signature(section).parameters) == ["ctx"], section.__name__



def test_every_studys_folder_is_one_the_sections_may_read() -> None:
    assert {study.name for study in STUDIES if study.name != "paper"} <= set(build.FOLDERS)
