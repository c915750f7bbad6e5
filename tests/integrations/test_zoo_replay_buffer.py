"""
``python -m sb3_affect.integrations.zoo enjoy`` of a deep agent loads it with a replay buffer of one transition, as
rl-zoo3's enjoy loads its own DQN (the shipped files' 50,000 MiniGrid observations would be allocated for nothing),
and leaves the zoo's algorithms as they were.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("minigrid")

from sb3_affect import AffectDQN


def test_enjoy_loads_a_deep_agent_with_a_buffer_of_one_transition(tmp_path: Path, zoo, monkeypatch) -> None:
    import rl_zoo3

    common = ["--algo", "affectdqn", "--env", "MiniGrid-Empty-6x6-v0", "-f", "logs"]
    zoo(["train", *common, "-n", "200", "--seed", "0"], tmp_path)
    trained = AffectDQN.load(tmp_path / "logs" / "affectdqn" / "MiniGrid-Empty-6x6-v0_1" / "MiniGrid-Empty-6x6-v0.zip")
    assert trained.buffer_size == 50_000  # what enjoy would allocate again without the zoo's keywords
    loaded: list[Any] = []
    real_load = AffectDQN.load.__func__  # type: ignore[attr-defined]

    def spy(cls: type, path: Any, **kwargs: Any) -> Any:
        model = real_load(cls, path, **kwargs)
        loaded.append(model)
        return model

    monkeypatch.setattr(AffectDQN, "load", classmethod(spy))
    out = zoo(["enjoy", *common, "--no-render", "-n", "160", "--seed", "0"], tmp_path)
    assert "Episode Reward" in out, out[-500:]  # (Empty-6x6 ends an episode within 144 steps)
    assert len(loaded) == 1 and loaded[0].buffer_size == 1 and loaded[0].replay_buffer.buffer_size == 1
    assert rl_zoo3.ALGOS["affectdqn"] is AffectDQN  # the zoo's algorithms as they were
