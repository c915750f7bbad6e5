"""Safe model files: nothing pickled runs, nothing is lost, bad files give one clear error."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import os
import zipfile
from pathlib import Path

import cloudpickle
import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
from stable_baselines3.common.utils import LinearSchedule

from sb3_affect import AffectQ, QLearning
from sb3_affect.agents.baselines import Boltzmann, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, UCBQLearning
from sb3_affect.agents.serialization import PLAIN_MEMBER, ModelFileError

ENV_ID = "sb3_affect/GridPursuit-v0"


def trained(cls: type, episodes: int = 15, seed: int = 3, **kwargs):
    model = cls("Grid", gym.make(ENV_ID), seed=seed, **kwargs)
    model.learn(10**7, callback=StopTrainingOnMaxEpisodes(episodes))
    return model


class Boom:
    """Pickles to a call that creates a marker file: what a malicious model file would do."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (QLearning, {"exploration_rate": LinearSchedule(0.5, 0.05, 0.5), "learning_rate": 0.7, "q_init": 0.5}),
        (AffectQ, {"comparison": "valence", "act": "remaining", "units": "decisions", "personality": "optimistic"}),
        (UCBQLearning, {}),
        (Boltzmann, {}),
        (DecayingEpsilonGreedy, {}),
        (SpeedEpsilonGreedy, {}),
        (OptimisticQLearning, {}),
    ],
)
def test_safe_round_trip_keeps_everything_and_training_continues(tmp_path: Path, cls: type, kwargs: dict) -> None:
    model = trained(cls, **kwargs)
    model.save(tmp_path / "model")  # SB3 adds .zip
    with zipfile.ZipFile(tmp_path / "model.zip") as archive:
        assert PLAIN_MEMBER in archive.namelist()
    loaded = cls.load(tmp_path / "model", env=gym.make(ENV_ID))
    np.testing.assert_array_equal(loaded.q_table, model.q_table)
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    assert loaded.num_timesteps == model.num_timesteps
    assert loaded._rng.getstate() == model._rng.getstate()
    for key in ("gamma", "q_init", "max_episode_decisions", "comparison", "act", "units", "personality"):
        assert getattr(loaded, key, None) == getattr(model, key, None), key
    if "exploration_rate" in kwargs:
        assert loaded.exploration_rate(0.3) == model.exploration_rate(0.3)
    for m in (model, loaded):
        m.learn(10**7, callback=StopTrainingOnMaxEpisodes(4), reset_num_timesteps=False)
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    np.testing.assert_array_equal(loaded.q_table, model.q_table)


def test_files_still_load_with_sb3s_legacy_loader(tmp_path: Path) -> None:
    model = trained(AffectQ)
    model.save(tmp_path / "m.zip")
    legacy = AffectQ.load(tmp_path / "m.zip", safe=False)
    np.testing.assert_array_equal(legacy.q_table, model.q_table)


def _rewrite(path: Path, out: Path, replace: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(out, "w") as target:
        for name in source.namelist():
            target.writestr(name, replace.get(name, source.read(name)))


def test_a_pickled_payload_in_data_never_runs(tmp_path: Path) -> None:
    model = trained(QLearning)
    model.save(tmp_path / "good.zip")
    marker = tmp_path / "pwned"
    with zipfile.ZipFile(tmp_path / "good.zip") as archive:
        data = json.loads(archive.read("data"))
    payload = base64.b64encode(cloudpickle.dumps(Boom(marker))).decode()
    data["gamma"] = {":type:": "<class 'float'>", ":serialized:": payload}
    _rewrite(tmp_path / "good.zip", tmp_path / "evil.zip", {"data": json.dumps(data).encode()})
    with pytest.raises(ModelFileError, match=r"entry 'gamma' is pickled Python .*safe=False"):
        QLearning.load(tmp_path / "evil.zip")
    assert not marker.exists()
    # the danger is real: SB3's legacy loader runs the payload
    with contextlib.suppress(Exception):  # the payload's return value is no valid gamma; what matters is that it ran
        QLearning.load(tmp_path / "evil.zip", safe=False)
    assert marker.exists()


def test_a_pickled_payload_in_the_weights_never_runs(tmp_path: Path) -> None:
    model = trained(QLearning)
    model.save(tmp_path / "good.zip")
    marker = tmp_path / "pwned"
    buffer = io.BytesIO()
    th.save({"q_table": Boom(marker)}, buffer)
    _rewrite(tmp_path / "good.zip", tmp_path / "evil.zip", {"policy.pth": buffer.getvalue()})
    with pytest.raises(ModelFileError, match="weights-only"):
        QLearning.load(tmp_path / "evil.zip")
    assert not marker.exists()


def test_bad_files_give_one_clear_error(tmp_path: Path) -> None:
    model = trained(QLearning)
    model.save(tmp_path / "good.zip")
    raw = (tmp_path / "good.zip").read_bytes()
    (tmp_path / "random.zip").write_bytes(os.urandom(2000))
    (tmp_path / "empty.zip").write_bytes(b"")
    (tmp_path / "truncated.zip").write_bytes(raw[: len(raw) // 2])
    with zipfile.ZipFile(tmp_path / "nodata.zip", "w") as archive:
        archive.writestr("hello.txt", "hi")
    _rewrite(tmp_path / "good.zip", tmp_path / "badjson.zip", {"data": b"{not json"})
    cases = {
        "random.zip": "not a model file",
        "empty.zip": "not a model file",
        "truncated.zip": "not a model file",
        "nodata.zip": "no 'data' entry",
        "badjson.zip": "not valid JSON",
    }
    for name, words in cases.items():
        with pytest.raises(ModelFileError) as info:
            QLearning.load(tmp_path / name)
        message = str(info.value)
        assert name in message and words in message, message
        assert "\n" not in message
    with pytest.raises(FileNotFoundError, match="no such model file"):
        QLearning.load(tmp_path / "missing.zip")


def test_foreign_and_mismatched_files_are_refused_with_the_way_out(tmp_path: Path) -> None:
    DQN("MlpPolicy", gym.make(ENV_ID), learning_starts=10).save(tmp_path / "dqn.zip")
    with pytest.raises(ModelFileError, match=r"no plain-data description .*QLearning.load\(path, safe=False\)"):
        QLearning.load(tmp_path / "dqn.zip")
    trained(QLearning).save(tmp_path / "q.zip")
    with pytest.raises(ModelFileError, match=r"holds a QLearning model; load it with QLearning.load"):
        AffectQ.load(tmp_path / "q.zip")
    with pytest.raises(ValueError, match=r"Observation spaces do not match"):
        QLearning.load(tmp_path / "q.zip", env=gym.make(ENV_ID, size=5, goal=(2, 2)))
