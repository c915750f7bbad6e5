"""Appraisal (norm, exp1, act), Table II under every option, Table III."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sb3_affect import TABLE_III, Appraisal, Appraiser, Behaviour, Emotion, KnownMap, PowerFit, table_ii
from sb3_affect.core.behaviour import validate_behaviour_table


def test_power_fit_matches_a_hand_computed_fit() -> None:
    ys = [120.0, 80.0, 50.0, 52.0, 30.0]
    fit = PowerFit()
    for y in ys:
        fit.add(y)
    # least squares on (ln t, ln y), by hand with numpy's polyfit
    b, ln_a = np.polyfit(np.log(np.arange(1, 6)), np.log(ys), 1)
    a, b_ours = fit.coefficients()
    assert b_ours == pytest.approx(b, rel=1e-12)
    assert a == pytest.approx(math.exp(ln_a), rel=1e-12)
    assert fit.predict(6) == pytest.approx(math.exp(ln_a) * 6**b, rel=1e-12)


def test_power_fit_two_points_is_exact_and_one_point_is_flat() -> None:
    fit = PowerFit()
    fit.add(261.0)
    assert fit.predict(2) == 261.0  # one finished episode: norm = its value
    fit.add(140.0)
    b = math.log(140 / 261) / math.log(2)
    assert fit.predict(3) == pytest.approx(261 * 3**b, rel=1e-12)


def test_norm_is_the_fit_at_the_next_episode() -> None:
    appraiser = Appraiser(4)
    appraiser.start_episode()
    assert appraiser.appraise(0) is None  # first episode: nothing to appraise
    for _ in range(10):
        appraiser.observe(0, 1, False)
    appraiser.end_episode(True)
    appraiser.start_episode()
    assert appraiser.norm == 10.0


def test_known_map_distances_update_incrementally() -> None:
    known = KnownMap(5)
    known.add(0, 1)
    known.add(1, 2)
    assert known.distance[0] == math.inf  # no goal known yet
    known.add_goal(2)
    assert known.distance[:3] == [2.0, 1.0, 0.0]
    known.add(3, 0)
    assert known.distance[3] == 3.0
    known.add(3, 2)  # a shortcut found later lowers the distance
    assert known.distance[3] == 1.0
    known.add(4, 4)  # a bump adds nothing
    assert known.distance[4] == math.inf


def _appraiser_after_one_episode(act: str, units: str, cells: int = 8, decisions: int = 5) -> Appraiser:
    """One finished episode 0 -> 1 -> 2 (goal) ... with `cells` cells over `decisions` decisions."""
    appraiser = Appraiser(6, act=act, units=units)
    appraiser.start_episode()
    appraiser.observe(0, 1, False)
    appraiser.observe(1, 2, True)
    appraiser.elapsed_cells = cells
    appraiser.elapsed_decisions = decisions
    appraiser.end_episode(True)
    appraiser.start_episode()
    return appraiser


@pytest.mark.parametrize(
    ("act", "units", "norm", "act_value"),
    [
        ("episode", "cells", 8.0, 2.0),
        ("remaining", "cells", 8.0, 2.0),
        ("episode", "decisions", 5.0, 2.0),
        ("remaining", "decisions", 5.0, 2.0),
    ],
)
def test_appraisal_values_under_each_option(act: str, units: str, norm: float, act_value: float) -> None:
    appraiser = _appraiser_after_one_episode(act, units)
    assert appraiser.appraise(0) == Appraisal(norm=norm, exp1=norm, act=act_value)
    # walk one cell (one decision): elapsed grows; exp1 stays max(norm, elapsed)
    appraiser.observe(0, 1, False)
    appraiser.elapsed_decisions += 1
    got = appraiser.appraise(1)
    assert got is not None
    assert got.act == (1 + 1 if act == "episode" else 1)
    assert got.exp1 == norm
    # past the norm, exp1 follows elapsed
    appraiser.elapsed_cells = appraiser.elapsed_decisions = 50
    got = appraiser.appraise(1)
    assert got is not None and got.exp1 == 50


def test_act_keeps_its_previous_value_off_the_known_map() -> None:
    appraiser = _appraiser_after_one_episode("episode", "cells")
    first = appraiser.appraise(0)
    assert first is not None
    unknown = appraiser.appraise(5)  # cell 5 has no known path to the goal
    assert unknown is not None and unknown.act == first.act


# Table II, first match wins: fear (exp1 < norm), anger (act < norm, exp1 > act), sadness (act < norm, exp1 <= act), joy
@pytest.mark.parametrize(
    ("norm", "exp1", "act", "literal", "valence"),
    [
        (10, 9, 20, Emotion.FEAR, Emotion.ANGER),
        (10, 12, 5, Emotion.ANGER, Emotion.FEAR),
        (10, 10, 10, Emotion.JOY, Emotion.JOY),
        (10, 4, 5, Emotion.FEAR, Emotion.JOY),
        (10, 12, 20, Emotion.JOY, Emotion.FEAR),
        (10, 10, 20, Emotion.JOY, Emotion.ANGER),
        (10, 10, 5, Emotion.ANGER, Emotion.JOY),
        (10, 9, 9, Emotion.FEAR, Emotion.JOY),
    ],
)
def test_table_ii_literal_and_valence(norm: float, exp1: float, act: float, literal: Emotion, valence: Emotion) -> None:
    appraisal = Appraisal(float(norm), float(exp1), float(act))
    assert table_ii(appraisal, "literal") == literal
    assert table_ii(appraisal, "valence") == valence


def test_table_ii_never_gives_sadness_first_match_wins() -> None:
    """Sadness needs exp1 <= act < norm (literal) or exp1 >= act > norm (valence): rule 1 (fear) always matches first."""
    rng = np.random.default_rng(0)
    for norm, exp1, act in rng.integers(0, 30, size=(5000, 3)).astype(float):
        for comparison in ("literal", "valence"):
            assert table_ii(Appraisal(norm, exp1, act), comparison) != Emotion.SADNESS
    # ... but a custom rule can make it (the emotion rule is swappable): see test_algorithms


def test_table_ii_no_appraisal_is_joy_and_bad_option_is_named() -> None:
    assert table_ii(None, "literal") == Emotion.JOY
    with pytest.raises(ValueError, match="comparison='backwards'"):
        table_ii(Appraisal(1.0, 1.0, 1.0), "backwards")


def test_table_iii_and_its_validation() -> None:
    assert TABLE_III[Emotion.JOY] == Behaviour(True, (1, 2))
    assert TABLE_III[Emotion.ANGER] == Behaviour(False, (1, 2))
    assert TABLE_III[Emotion.SADNESS] == TABLE_III[Emotion.FEAR] == Behaviour(False, (0, 1))
    with pytest.raises(ValueError, match="no entry for fear"):
        validate_behaviour_table({e: TABLE_III[e] for e in Emotion if e != Emotion.FEAR})
    bad = dict(TABLE_III)
    bad[Emotion.JOY] = Behaviour(True, (-1,))
    with pytest.raises(ValueError, match=r"behaviour_table\[joy\].speeds=\(-1,\)"):
        validate_behaviour_table(bad)
    with pytest.raises(ValueError, match="act='total'"):
        Appraiser(4, act="total")
    with pytest.raises(ValueError, match="units='steps'"):
        Appraiser(4, units="steps")
