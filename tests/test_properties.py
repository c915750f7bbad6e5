"""Property-based tests (hypothesis): the env, the appraisal, the power fit and safe save/load for any input."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from sb3_affect import AffectQ, Appraisal, Appraiser, Emotion, PowerFit, QLearning, table_ii
from sb3_affect.envs import GridPursuitEnv


@st.composite
def grids(draw: st.DrawFn) -> dict:
    size = draw(st.integers(2, 8))
    cell = st.tuples(st.integers(0, size - 1), st.integers(0, size - 1))
    start, goal = draw(cell), draw(cell)
    assume(start != goal)
    obstacles = draw(st.lists(cell.filter(lambda c: c not in (start, goal)), max_size=size * size // 4))
    return {"size": size, "start": start, "goal": goal, "obstacles": obstacles}


@settings(max_examples=60, deadline=None)
@given(grid=grids(), actions=st.lists(st.integers(0, 3), min_size=1, max_size=300))
def test_random_actions_stay_on_the_grid_and_pay_only_at_the_goal(grid: dict, actions: list[int]) -> None:
    try:
        env = GridPursuitEnv(**grid)
    except ValueError as error:  # walled-off goal: refused at construction, which is right
        assert "unreachable" in str(error)
        return
    size = grid["size"]
    blocked = {env.to_state(o) for o in env.obstacles}
    state, _ = env.reset()
    for action in actions:
        state, reward, terminated, truncated, _ = env.step(action)
        assert 0 <= state < size * size and state not in blocked
        assert terminated == (state == env.goal_state) == (reward == env.goal_reward)
        assert reward in (0.0, env.goal_reward) and not truncated
        if terminated:
            state, _ = env.reset()


values = st.floats(min_value=-1e300, max_value=1e300, allow_nan=False) | st.sampled_from([0.0, 1e308, -1e308, math.inf])


@settings(max_examples=300, deadline=None)
@given(norm=values, exp1=values, act=values)
def test_table_ii_gives_exactly_one_emotion_for_any_input(norm, exp1, act) -> None:
    for comparison in ("literal", "valence"):
        emotion = table_ii(Appraisal(norm, exp1, act), comparison)
        assert isinstance(emotion, Emotion)


@settings(max_examples=60, deadline=None)
@given(
    history=st.lists(st.floats(min_value=0.0, max_value=1e12, allow_nan=False), min_size=1, max_size=40),
    elapsed=st.integers(0, 10**9),
    act=st.sampled_from(["episode", "remaining"]),
    units=st.sampled_from(["cells", "decisions"]),
)
def test_the_appraisal_is_always_one_emotion(history, elapsed, act, units) -> None:
    appraiser = Appraiser(4, act=act, units=units)
    appraiser.fit = PowerFit.from_state(history)
    appraiser.known.add(0, 1)
    appraiser.known.add_goal(1)
    appraiser.start_episode()
    appraiser.elapsed_cells = appraiser.elapsed_decisions = elapsed
    for state in range(4):
        appraisal = appraiser.appraise(state)
        assert appraisal is not None and all(not math.isnan(v) for v in appraisal)
        assert isinstance(table_ii(appraisal), Emotion) and isinstance(table_ii(appraisal, "valence"), Emotion)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(min_value=1e-9, max_value=1e12, allow_nan=False), min_size=1, max_size=300))
def test_the_power_fit_stays_finite_for_any_positive_step_counts(ys) -> None:
    fit = PowerFit()
    for y in ys:
        fit.add(y)
        a, b = fit.coefficients()
        assert math.isfinite(a) and math.isfinite(b)
        assert math.isfinite(fit.predict(len(fit.values) + 1))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    affective=st.booleans(),
    learning_rate=st.floats(min_value=0.01, max_value=1.0),
    gamma=st.floats(min_value=0.0, max_value=1.0),
    q_init=st.floats(min_value=-10, max_value=10),
    epsilon=st.floats(min_value=0.0, max_value=1.0),
    seed=st.integers(0, 2**31 - 1),
    comparison=st.sampled_from(["literal", "valence"]),
)
def test_safe_save_load_round_trip_preserves_every_field(
    affective, learning_rate, gamma, q_init, epsilon, seed, comparison
) -> None:
    kwargs = {"comparison": comparison} if affective else {"exploration_rate": epsilon}
    cls = AffectQ if affective else QLearning
    env = gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 3))
    model = cls(
        "Grid", env, learning_rate=learning_rate, gamma=gamma, q_init=q_init, seed=seed, max_episode_decisions=200, **kwargs
    )
    model.learn(600)
    with tempfile.TemporaryDirectory() as folder:
        model.save(Path(folder) / "m.zip")
        loaded = cls.load(Path(folder) / "m.zip")
    np.testing.assert_array_equal(loaded.q_table, model.q_table)
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    for key in ("learning_rate", "gamma", "q_init", "max_episode_decisions", "num_timesteps", "seed", *kwargs):
        assert getattr(loaded, key) == getattr(model, key), key
    assert loaded._rng.getstate() == model._rng.getstate()
