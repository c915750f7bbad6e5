"""
The list of studies of the main job is the one source of replicate's parts (and so of its --help, which
tests/test_cli.py checks against them) and names the report's sections that read each study.
"""

from __future__ import annotations

from sb3_affect.study import replicate
from sb3_affect.study.report.build import APPENDIX, SECTIONS
from sb3_affect.study.studies import STUDIES


def test_replicate_runs_the_studies_in_their_order() -> None:
    assert [name for name, _ in (*replicate.PARTS, *replicate.TUNED_PARTS)] == [study.name for study in STUDIES]
    assert {name for name, _, _ in replicate.PART_PACKAGES} == {study.name for study in STUDIES if study.extra}
    assert set(replicate.SIZED) == {study.name for study in STUDIES if study.size and not study.tuned}


def test_every_study_has_its_sweep_file() -> None:
    folder = replicate.sweeps_folder()
    missing = [study.name for study in STUDIES if not (folder / f"{study.name}.yaml").is_file()]
    assert not missing, f"studies without a sweep file in {folder}: {missing}"


def test_the_report_holds_each_studys_sections_where_the_list_says() -> None:
    main = {section.__name__ for section in SECTIONS}
    appendix = {section.__name__ for section in APPENDIX}
    for study in STUDIES:
        assert set(study.sections) <= main, f"{study.name}: {set(study.sections) - main} not in the report's main text"
        assert set(study.appendix) <= appendix, f"{study.name}: {set(study.appendix) - appendix} not in its appendix"

