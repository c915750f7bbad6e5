"""
The deep agents' model files (``sb3_affect.agents.deep_model_files``): safe loading rebuilds ``AffectDQN``,
``AffectQRDQN`` and the deep controls without unpickling anything; hostile files (pickle payloads in a new key, in
``wait_action``, in the weights; values the constructor refuses) are refused with one line and nothing in them runs.
Real SB3 models, real files.
"""

from __future__ import annotations

import base64
import io
import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th

from sb3_affect import AffectDQN, AffectQRDQN, Emotion, EmotionCallback
from sb3_affect.agents.deep_controls import EzGreedyDQN, SpeedEpsilonGreedyDQN
from sb3_affect.agents.serialization import ModelFileError

AGENTS = [
    (AffectDQN, "FrozenLake-v1", {"wait_action": 0, "position": "discrete", "behaviour_table": "table-iii-reversed"}),
    (AffectQRDQN, "FrozenLake-v1", {}),
    (EzGreedyDQN, "CartPole-v1", {"mu": 1.5, "max_duration": 20}),
    (SpeedEpsilonGreedyDQN, "CartPole-v1", {"speeds": [0, 3], "wait_action": 1}),
]


def small(agent: type, env: str, **kwargs: Any) -> Any:
    th.set_num_threads(1)
    return agent("MlpPolicy", env, learning_starts=16, batch_size=16, train_freq=4, seed=0,
                 policy_kwargs={"net_arch": [16]}, **kwargs)


class Payload:
    """Unpickling it creates ``path`` (what a hostile file would do with worse code)."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> Any:
        return (open, (str(self.path), "w"))


def serialized(value: Any) -> dict[str, str]:
    """An entry as SB3 writes a pickled one in ``data``."""
    return {":type:": "<class 'int'>", ":serialized:": base64.b64encode(pickle.dumps(value)).decode()}


def rewrite(source: Path, target: Path, data: dict[str, Any] | None = None, drop: tuple[str, ...] = (),
            members: dict[str, bytes] | None = None) -> Path:
    """A copy of a model file with ``data`` entries replaced or added, members dropped or replaced."""
    with zipfile.ZipFile(source) as archive:
        contents = {name: archive.read(name) for name in archive.namelist() if name not in drop}
    if data:
        stored = json.loads(contents["data"])
        stored.update(data)
        contents["data"] = json.dumps(stored).encode()
    contents.update(members or {})
    with zipfile.ZipFile(target, "w") as archive:
        for name, raw in contents.items():
            archive.writestr(name, raw)
    return target


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("deep") / "affect.zip"
    small(AffectDQN, "FrozenLake-v1", wait_action=0).learn(200).save(path)
    return path


@pytest.mark.parametrize(("agent", "env", "kwargs"), AGENTS)
def test_safe_loading_rebuilds_every_deep_agent(agent: type, env: str, kwargs: dict[str, Any], tmp_path: Path) -> None:
    model = small(agent, env, **kwargs).learn(300)
    model.save(tmp_path / "model.zip")
    loaded = agent.load(tmp_path / "model.zip", env=model.get_env(), safe=True)
    assert "safe" not in loaded.__dict__  # the keyword, not a model attribute
    for key in kwargs:
        assert getattr(loaded, key) == getattr(model, key), key
    for (key, a), b in zip(model.policy.state_dict().items(), loaded.policy.state_dict().values()):
        assert th.equal(a, b), key
    optimizer = loaded.policy.optimizer.state_dict()["state"]
    assert optimizer and all(th.equal(optimizer[k]["exp_avg"], v["exp_avg"])
                             for k, v in model.policy.optimizer.state_dict()["state"].items())
    assert (loaded.num_timesteps, loaded.train_freq, loaded.replay_buffer_class) == (
        model.num_timesteps, model.train_freq, model.replay_buffer_class)
    observations = np.stack([model.observation_space.sample() for _ in range(8)])
    np.testing.assert_array_equal(model.predict(observations, deterministic=True)[0],
                                  loaded.predict(observations, deterministic=True)[0])
    loaded.learn(100, reset_num_timesteps=False)
    assert loaded.num_timesteps >= 400


def one_line(error: pytest.ExceptionInfo[BaseException], *texts: str) -> None:
    message = str(error.value)
    assert "\n" not in message and all(text in message for text in texts), message


def test_a_pickle_payload_anywhere_is_refused_and_never_runs(saved: Path, tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    payload = Payload(marker)
    hostile = {
        "new key": rewrite(saved, tmp_path / "a.zip", data={"innocent": serialized(payload)}),
        "wait_action": rewrite(saved, tmp_path / "b.zip", data={"wait_action": serialized(payload)}),
        "emotion state": rewrite(saved, tmp_path / "c.zip", data={"_affect_state": serialized(payload)}),
    }
    for name, path in hostile.items():
        with pytest.raises(ModelFileError) as raised:
            AffectDQN.load(path)
        one_line(raised, "pickled Python", "safe=False")
        assert not marker.exists(), name
    weights = io.BytesIO()
    th.save({"q_net.q_net.0.weight": payload}, weights)
    path = rewrite(saved, tmp_path / "d.zip", members={"policy.pth": weights.getvalue()})
    with pytest.raises(ModelFileError) as raised:
        AffectDQN.load(path)
    one_line(raised, "policy.pth is not plain tensor data")
    path = rewrite(saved, tmp_path / "e.zip", drop=("sb3_affect.json",))
    with pytest.raises(ModelFileError) as raised:
        AffectDQN.load(path)
    one_line(raised, "no plain-data description")
    assert not marker.exists()


def test_values_the_constructor_refuses_are_refused_from_a_file(saved: Path, tmp_path: Path) -> None:
    table = {"joy": [True, [1, 2]], "sadness": [False, [0, 1]], "fear": [False, [0, 1]], "anger": [False, [1, 2]]}
    cases = [
        ({"behaviour_table": {**table, "joy": [True, [-5]]}}, "behaviour_table[joy].speeds=(-5,)"),
        ({"behaviour_table": {**table, "joy": [True, [10**12]]}}, "behaviour_table[joy].speeds=(1000000000000,)"),
        ({"behaviour_table": {**table, "fear": 3}}, "behaviour_table[fear]=3 is invalid"),
        ({"behaviour_table": 7}, "behaviour_table must be a mapping"),
        ({"wait_action": 2**70}, f"wait_action={2**70} is outside the action space"),
        ({"wait_action": "6"}, "wait_action must be an integer action"),
        ({"position": "grid"}, "position='grid' is not supported"),
        ({"position": "minigrid"}, "position='minigrid': the env has no agent_pos"),
        ({"_affect_state": {"comparison": "sideways"}}, "comparison='sideways' is not supported"),
        ({"_affect_state": {"appraisers": [{"known": {"n_states": 10**12, "edges": [], "goals": []}}]}},
         "known.n_states=1000000000000"),
        ({"predict": 1}, "names a method of AffectDQN"),
    ]
    for index, (data, text) in enumerate(cases):
        path = rewrite(saved, tmp_path / f"v{index}.zip", data=data)
        with pytest.raises(ModelFileError) as raised:
            AffectDQN.load(path, env=gym.make("FrozenLake-v1") if "position" in data else None)
        one_line(raised, str(path), text)
    for data, text in (({"speeds": [-5]}, "speeds=[-5]"), ({"speeds": [10**12]}, "speeds=[1000000000000]"),
                       ({"wait_action": 2**70}, "is outside the action space")):
        source = tmp_path / "speed.zip"
        small(SpeedEpsilonGreedyDQN, "FrozenLake-v1").save(source)
        with pytest.raises(ModelFileError) as raised:
            SpeedEpsilonGreedyDQN.load(rewrite(source, tmp_path / "s.zip", data=data))
        one_line(raised, text)


def custom_rule(appraisal: Any) -> Emotion:
    return Emotion.FEAR


def test_a_custom_emotion_rule_loads_only_through_sb3s_loader(tmp_path: Path) -> None:
    model = small(AffectDQN, "FrozenLake-v1", emotion_callback=EmotionCallback(emotion_rule=custom_rule)).learn(200)
    model.save(tmp_path / "model.zip")
    with pytest.raises(ModelFileError) as raised:
        AffectDQN.load(tmp_path / "model.zip")
    one_line(raised, "'_affect_objects' is pickled Python", "AffectDQN.load(path, safe=False)")
    loaded = AffectDQN.load(tmp_path / "model.zip", safe=False)  # the user trusts the file
    assert loaded.emotion_callback.emotion_rule(None) == Emotion.FEAR
    assert loaded.episode_log.equals(model.episode_log)


def test_a_minigrid_model_loads_without_an_env_and_keeps_its_appraisal(tmp_path: Path) -> None:
    """position="minigrid" takes its map's size from the env: a file loaded with no env keeps the saved appraiser."""
    pytest.importorskip("minigrid")
    from sb3_affect import minigrid_vec_env

    env = minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=0, obs="view")
    model = AffectDQN("MlpPolicy", env, position="minigrid", learning_starts=50, seed=0)
    model.learn(300)
    model.save(tmp_path / "m.zip")
    loaded = AffectDQN.load(tmp_path / "m.zip")
    saved_cells = model.emotion_callback.appraiser.known.n_states
    assert loaded.emotion_callback.appraiser.known.n_states == saved_cells == 25
    assert len(loaded.episode_log) == len(model.episode_log) > 0
    observation = env.reset()
    np.testing.assert_array_equal(loaded.predict(observation, deterministic=True)[0],
                                  model.predict(observation, deterministic=True)[0])
    loaded.set_env(env)
    loaded.learn(100, reset_num_timesteps=False)  # the env given later fits the saved map
    assert loaded.emotion_callback.appraiser.known.n_states == 25


def test_a_weights_member_larger_than_the_models_shapes_is_refused_before_it_is_read(saved: Path, tmp_path: Path) -> None:
    bomb = tmp_path / "bomb.zip"
    with zipfile.ZipFile(saved) as source, zipfile.ZipFile(bomb, "w", compression=zipfile.ZIP_DEFLATED) as target:
        for name in source.namelist():
            if name != "policy.pth":
                target.writestr(name, source.read(name))
        with target.open("policy.pth", "w", force_zip64=True) as member:  # 256 MiB of zeros in about 250 kB
            for _ in range(16):
                member.write(bytes(2**24))
    assert bomb.stat().st_size < 2**20
    with pytest.raises(ModelFileError) as raised:
        AffectDQN.load(bomb)
    one_line(raised, "the 'policy.pth' entry expands to 268,435,456 bytes", "more than the", "a model of this size needs")
    extra = rewrite(saved, tmp_path / "extra.zip", members={"more.pth": b"x"})
    with pytest.raises(ModelFileError) as raised:
        AffectDQN.load(extra)
    one_line(raised, "the entry 'more.pth' is not one of the model's weights (policy.pth, policy.optimizer.pth, "
             "pytorch_variables.pth)")
