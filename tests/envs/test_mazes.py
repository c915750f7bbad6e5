"""Text-map mazes: parsing, validation with clear errors, the shipped maps, and learning on one."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import QLearning
from sb3_affect.envs.maze import MazeError, load_maze, maze_kwargs, parse_maze, shipped_mazes
from sb3_affect.envs.maze_pursuit import MazePursuitEnv

SMALL = """
; a comment
S.#.
..#.
....
.#.G
"""


def test_parse_a_map() -> None:
    maze = parse_maze(SMALL, "small")
    assert maze.size == 4 and maze.start == (0, 0) and maze.goal == (3, 3)
    assert maze.obstacles == ((0, 2), (1, 2), (3, 1))
    env = MazePursuitEnv.__new__(MazePursuitEnv)
    env.__init__(maze="open")  # type: ignore[misc]
    assert env.shortest_path_length == 12


def test_shipped_mazes_are_reachable_and_match_their_description() -> None:
    names = shipped_mazes()
    assert {"open", "wall", "rooms", "zigzag"} <= set(names)
    lengths = {}
    for name in names:
        env = gym.make("sb3_affect/MazePursuit-v0", maze=name).unwrapped
        assert env.distances[env.start_state] == env.shortest_path_length < float("inf")
        lengths[name] = env.shortest_path_length
    assert lengths["open"] == 12  # the paper's task
    assert lengths["wall"] > 12 and lengths["zigzag"] > 100


def test_open_maze_is_the_paper_task() -> None:
    assert maze_kwargs("open") == {"size": 15, "start": (0, 0), "goal": (6, 6), "obstacles": []}
    paper = gym.make("sb3_affect/GridPursuit-v0").unwrapped
    maze = gym.make("sb3_affect/MazePursuit-v0", maze="open").unwrapped
    assert maze.transitions == paper.transitions and maze.distances == paper.distances


def test_user_file(tmp_path: Path) -> None:
    path = tmp_path / "mine.txt"
    path.write_text(SMALL)
    env = gym.make("sb3_affect/MazePursuit-v0", maze=str(path)).unwrapped
    assert env.size == 4 and env.obstacles == ((0, 2), (1, 2), (3, 1))
    assert env.shortest_path_length == 6


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("S.#.\n..#.\n###.\n...G\n", "unreachable"),
        ("S..\n...\n..G.\n", "must be square"),
        ("S.\n..\n", "exactly one goal"),
        ("SG.\nS..\n...\n", "exactly one start"),
        ("S.x\n...\n..G\n", "unknown character 'x' at row 0, column 2"),
        ("\n; only a comment\n", "empty"),
    ],
)
def test_invalid_maps_give_clear_errors(text: str, message: str) -> None:
    with pytest.raises(MazeError, match=message):
        parse_maze(text, "bad")


def test_unknown_name_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(MazeError, match=r"unknown maze 'nowhere'.*rooms"):
        load_maze("nowhere")
    with pytest.raises(MazeError, match="can not read"):
        load_maze(str(tmp_path / "missing.txt"))
    with pytest.raises(MazeError, match="unreachable"):
        path = tmp_path / "walled.txt"
        path.write_text("S#.\n##.\n..G\n")
        gym.make("sb3_affect/MazePursuit-v0", maze=str(path))


def test_walls_block_the_hunter() -> None:
    env = gym.make("sb3_affect/MazePursuit-v0", maze="wall").unwrapped
    env.reset()
    for _ in range(3):
        env.step(1)  # down from (0, 0): rows 1, 2, then the wall at row 3
    assert env.to_cell(env.state) == (2, 0)


def test_tabular_agent_learns_a_maze() -> None:
    greedy_optimal = 0
    for seed in range(3):
        model = QLearning("Grid", gym.make("sb3_affect/MazePursuit-v0", maze="wall"), exploration_rate=0.1, seed=seed)
        model.learn(10**8, callback=StopTrainingOnMaxEpisodes(200))
        log = model.episode_log
        assert log["cells"].min() >= 24  # nothing shorter than the way round the wall
        assert log["cells"].tail(20).mean() < 40 < 100 < log["cells"].head(20).mean()
        greedy_optimal += bool(log["greedy_optimal"].iloc[-1])
    assert greedy_optimal >= 1


def test_a_binary_or_oversized_map_file_is_refused_naming_it(tmp_path: Path) -> None:
    from sb3_affect.envs.maze import MAX_MAZE_BYTES

    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"S..\n\xff\xfe.\n..G\n")
    with pytest.raises(MazeError, match=r"maze file '.*binary\.txt' is not UTF-8 text \(byte 4: invalid start byte\)"):
        load_maze(str(binary))
    big = tmp_path / "big.txt"
    big.write_bytes(b"S" + b"." * (MAX_MAZE_BYTES + 10) + b"\n.G\n")  # refused from its size: never parsed
    with pytest.raises(MazeError, match=rf"maze file '.*big\.txt' is more than {MAX_MAZE_BYTES:,} bytes"):
        load_maze(str(big))
    with pytest.raises(MazeError, match=r"1001 rows x 2 columns: a map has at most 1000 x 1000 cells"):
        parse_maze("S.\n" + ".G\n" * 1000, "tall")
