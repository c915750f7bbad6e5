"""``TabularMiniGrid`` refuses the MiniGrid envs its state can not represent, and its check leaves the env's draws alone."""

from __future__ import annotations

import gymnasium as gym
import pytest

pytest.importorskip("minigrid")
import minigrid  # noqa: F401  (registers the envs)

from sb3_affect import TabularMiniGrid


@pytest.mark.parametrize(
    ("env_id", "words"),
    [
        ("MiniGrid-FourRooms-v0", r"puts the goal at another cell after a reset .* holds the agent's cell, not the goal's"),
        ("MiniGrid-MultiRoom-N6-v0", r"puts the goal at another cell after a reset"),
        ("MiniGrid-GoToDoor-5x5-v0", r"gives another mission after a reset \('go to the .* does not hold the mission"),
    ],
)
def test_envs_whose_goal_or_mission_is_not_in_the_state_are_refused_in_one_line(env_id: str, words: str) -> None:
    with pytest.raises(ValueError, match=rf"^TabularMiniGrid: {env_id} {words}") as raised:
        TabularMiniGrid(gym.make(env_id))
    assert "\n" not in str(raised.value)


@pytest.mark.parametrize("env_id", ["MiniGrid-Empty-8x8-v0", "MiniGrid-DoorKey-5x5-v0", "MiniGrid-LavaGapS5-v0"])
def test_envs_whose_goal_and_mission_stay_put_are_taken(env_id: str) -> None:
    assert TabularMiniGrid(gym.make(env_id)).observation_space.n > 0


def test_the_check_puts_the_envs_random_generator_back() -> None:
    def layouts(wrap: bool) -> list[tuple[int, ...]]:
        env = gym.make("MiniGrid-DoorKey-8x8-v0")
        env.reset(seed=5)
        if wrap:
            TabularMiniGrid(env)  # its probes, then one reset with the env's own generator
        else:
            env.reset()
        seen = []
        for _ in range(3):
            env.reset()
            base = env.unwrapped
            seen.append((*base.agent_pos, base.agent_dir, *next(o.cur_pos for o in base.grid.grid if o and o.type == "key")))
        return seen

    assert layouts(wrap=True) == layouts(wrap=False)
