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


@pytest.mark.parametrize("cls", [QLearning, AffectQ])
@pytest.mark.parametrize("entry", ["state", "last_obs", "count"])
def test_an_episode_in_progress_outside_the_table_is_refused(tmp_path: Path, cls: type, entry: str) -> None:
    """A file whose episode in progress indexes outside the Q-table (the kernel would write there) is refused at load."""
    model = cls("Grid", gym.make(ENV_ID), seed=1)
    model.learn(7)  # mid-episode: the file holds the episode in progress
    model.save(tmp_path / "good.zip")
    with zipfile.ZipFile(tmp_path / "good.zip") as archive:
        data, twin = json.loads(archive.read("data")), json.loads(archive.read(PLAIN_MEMBER))
    assert isinstance(data["_episode_state"], dict)
    if entry == "state":
        data["_episode_state"]["state"] = 10**7
    elif entry == "count":
        data["_episode_state"]["cells"] = -5
    else:
        data["_episode_state"] = None
        twin["values"]["_last_obs"]["array"] = [-(10**6)]
    replace = {"data": json.dumps(data).encode(), PLAIN_MEMBER: json.dumps(twin).encode()}
    _rewrite(tmp_path / "good.zip", tmp_path / "evil.zip", replace)
    with pytest.raises(ModelFileError) as info:
        cls.load(tmp_path / "evil.zip", env=gym.make(ENV_ID), force_reset=False)
    message = str(info.value)
    assert "evil.zip" in message and "\n" not in message
    named = {"state": "_episode_state['state']=10000000", "count": "_episode_state['cells']=-5"}.get(entry, "_last_obs")
    assert named in message


def test_a_caller_set_episode_state_outside_the_table_is_refused_before_the_kernel_runs(tmp_path: Path) -> None:
    """The same index set by a caller: one error from ``learn`` on either engine (run apart: a crash must not end pytest)."""
    import subprocess
    import sys

    script = f"""
import gymnasium as gym
from sb3_affect import QLearning
for engine in ("compiled", "python"):
    model = QLearning("Grid", gym.make({ENV_ID!r}), seed=1, engine=engine)
    model.learn(7)
    model._episode_state["state"] = 10**7
    try:
        model.learn(100, reset_num_timesteps=False)
    except ValueError as error:
        print(engine, error)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    lines = done.stdout.splitlines()
    assert [line.split()[0] for line in lines] == ["compiled", "python"]
    assert all("_episode_state['state']=10000000 is not a state: integers 0..224" in line for line in lines), lines


def test_values_that_would_fail_later_are_refused_where_given(tmp_path: Path) -> None:
    """Caps, seeds and speeds out of the kernel's range: one error at the constructor, not a failing run."""
    env = gym.make(ENV_ID)
    with pytest.raises(ValueError, match=r"max_episode_decisions=10{30} must be in \[1, 1e\+15\]"):
        QLearning("Grid", env, max_episode_decisions=10**30)
    with pytest.raises(ValueError, match=r"seed=18446744073709551615 must be in \[0, 2\*\*32 - 1\]"):
        QLearning("Grid", env, seed=np.uint64(2**64 - 1))
    model = QLearning("Grid", env, seed=np.uint64(7))
    assert model.seed == 7 and type(model.seed) is int
    model.learn(20)
    with pytest.raises(ValueError, match=r"speeds=\[1, 1180591620717411303424\] is invalid: .* in \[0, 10,000\]"):
        SpeedEpsilonGreedy("Grid", env, speeds=[1, 2**70])
    from sb3_affect.core.behaviour import TABLE_III
    from sb3_affect.core.emotions import Emotion

    table = {**TABLE_III, Emotion.JOY: (True, (1, 2**70))}
    with pytest.raises(ValueError, match=r"behaviour_table\[joy\]\.speeds=.* in \[0, 10,000\]"):
        AffectQ("Grid", env, behaviour_table=table)


def test_a_table_of_nan_or_complex_values_and_a_doubled_entry_are_refused(tmp_path: Path) -> None:
    model = trained(QLearning)
    model.save(tmp_path / "good.zip")
    with zipfile.ZipFile(tmp_path / "good.zip") as archive:
        weights = th.load(io.BytesIO(archive.read("policy.pth")), weights_only=True)
    for name, table, words in (
        ("nan", weights["q_table"].clone().fill_(float("nan")), "holds NaN or infinite values"),
        ("inf", weights["q_table"].clone().fill_(float("inf")), "holds NaN or infinite values"),
        ("complex", weights["q_table"].to(th.complex128), "not a tensor of real numbers"),
    ):
        buffer = io.BytesIO()
        th.save({**weights, "q_table": table}, buffer)
        _rewrite(tmp_path / "good.zip", tmp_path / f"{name}.zip", {"policy.pth": buffer.getvalue()})
        with pytest.raises(ModelFileError, match=rf"{name}\.zip: policy\.pth entry 'q_table' .*{words}"):
            QLearning.load(tmp_path / f"{name}.zip")
    with zipfile.ZipFile(tmp_path / "good.zip") as source, zipfile.ZipFile(tmp_path / "twice.zip", "w") as target:
        for entry in source.namelist():
            target.writestr(entry, source.read(entry))
        with pytest.warns(UserWarning, match="Duplicate name"):
            target.writestr("data", source.read("data").replace(b'"gamma": 0.8', b'"gamma": 0.1'))
    with pytest.raises(ModelFileError, match=r"twice\.zip: the entry 'data' is in the zip more than once"):
        QLearning.load(tmp_path / "twice.zip")


def test_custom_objects_are_checked_at_load(tmp_path: Path) -> None:
    trained(QLearning).save(tmp_path / "model.zip")
    for custom, words in (
        ({"exploration_rate": 5.0}, "exploration_rate"),
        ({"learning_rate": 5}, "learning_rate"),
        ({"learning_rate": "fast"}, "learning_rate"),
    ):
        with pytest.raises(ModelFileError, match=rf"model\.zip: custom_objects: a value is not allowed: .*{words}") as info:
            QLearning.load(tmp_path / "model.zip", custom_objects=custom)
        assert "\n" not in str(info.value)
    assert QLearning.load(tmp_path / "model.zip", custom_objects={"exploration_rate": 0.5}).exploration_rate == 0.5


class _Rewarding(gym.Wrapper):
    """The grid, every reward replaced by ``value``."""

    def __init__(self, env: gym.Env, value: float) -> None:
        super().__init__(env)
        self.value = value

    def step(self, action: int):
        obs, _, terminated, truncated, info = self.env.step(action)
        return obs, self.value, terminated, truncated, info


@pytest.mark.parametrize("reward", [float("nan"), 1e308])
def test_rewards_that_make_the_table_non_finite_are_warned_once(reward: float) -> None:
    import warnings

    model = QLearning("Grid", _Rewarding(gym.make(ENV_ID), reward), seed=0, engine="python", max_episode_decisions=50)
    with pytest.warns(RuntimeWarning, match=r"Q-values are NaN or infinite after learn"):
        model.learn(200)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.learn(200, reset_num_timesteps=False)  # once per model
