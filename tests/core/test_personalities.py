"""Personalities: a bias on the appraisal's norm, named presets on AffectQ, saved with the model."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import AffectQ, EmotionCallback
from sb3_affect.core.personalities import PERSONALITIES, PersonalityAppraiser

ENV_ID = "sb3_affect/GridPursuit-v0"


def run(seed: int, episodes: int = 200, **kwargs: object) -> AffectQ:
    model = AffectQ("Grid", gym.make(ENV_ID), seed=seed, **kwargs)  # type: ignore[arg-type]
    model.learn(10**8, callback=StopTrainingOnMaxEpisodes(episodes))
    return model


def joy_fraction(personality: str) -> float:
    fractions = []
    for seed in range(3):
        log = run(seed, personality=personality).episode_log
        fractions.append(log["joy"].sum() / log["decisions"].sum())
    return float(np.mean(fractions))


def test_optimist_feels_more_joy_and_pessimist_less() -> None:
    optimistic, neutral, pessimistic = (joy_fraction(p) for p in ("optimistic", "neutral", "pessimistic"))
    assert optimistic > neutral + 0.02
    assert pessimistic < neutral - 0.02


def test_the_norm_is_scaled_and_the_history_is_not() -> None:
    base = run(0, episodes=5)
    optimist = run(0, episodes=5, personality="optimistic")
    first = base.episode_log["cells"].iloc[0]
    assert optimist.episode_log["cells"].iloc[0] == first  # episode 1 is all joy either way
    assert optimist.episode_log["norm"].iloc[1] == pytest.approx(PERSONALITIES["optimistic"] * first)
    assert base.episode_log["norm"].iloc[1] == first
    appraiser = optimist.emotion_callback.appraiser  # type: ignore[union-attr]
    assert isinstance(appraiser, PersonalityAppraiser)
    assert appraiser.fit.values == optimist.episode_log["cells"].astype(float).tolist()


def test_neutral_scale_is_the_paper_appraisal() -> None:
    plain = run(4, episodes=40).episode_log
    cb = EmotionCallback(appraiser=PersonalityAppraiser(225, norm_scale=1.0))
    scaled = run(4, episodes=40, emotion_callback=cb).episode_log
    assert plain.equals(scaled)


def test_personality_is_saved_with_the_model(tmp_path: Path) -> None:
    model = run(1, episodes=10, personality="pessimistic")
    model.save(tmp_path / "pessimist")
    loaded = AffectQ.load(tmp_path / "pessimist", env=gym.make(ENV_ID))
    assert loaded.personality == "pessimistic"
    appraiser = loaded.emotion_callback.appraiser  # type: ignore[union-attr]
    assert isinstance(appraiser, PersonalityAppraiser) and appraiser.norm_scale == PERSONALITIES["pessimistic"]
    assert appraiser.fit.values == model.emotion_callback.appraiser.fit.values  # type: ignore[union-attr]


def test_invalid_personality() -> None:
    with pytest.raises(ValueError, match="personality='cheerful'"):
        AffectQ("Grid", ENV_ID, personality="cheerful")
    with pytest.raises(ValueError, match="not both"):
        AffectQ("Grid", ENV_ID, personality="optimistic", emotion_callback=EmotionCallback())
    with pytest.raises(ValueError, match="norm_scale"):
        PersonalityAppraiser(10, norm_scale=0.0)
