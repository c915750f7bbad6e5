"""
``python -m sb3_affect.integrations.zoo enjoy`` and ``record_video`` on a logs folder someone else wrote: nothing in it
runs. The zoo's own loaders would ``eval`` a string ``normalize``, unpickle ``vecnormalize.pkl``, import the module an
``env_wrapper`` names and follow a symlinked run; the check sees the folder and algorithm the zoo's argparse parsed.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import gymnasium as gym
import pytest

from sb3_affect import QLearning
from sb3_affect.envs import GRID_PURSUIT_ID

ENV_NAME = GRID_PURSUIT_ID.replace("/", "-")


class _Payload:
    """Unpickled, it touches the marker file."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        import os

        return os.system, (f"touch {self.marker}",)


def _run(folder: Path, run_id: int = 1, config: str | None = None) -> Path:
    """A logs folder's run of QLearning on the grid (``folder/qlearning/<env>_<id>``) with ``config`` as its config.yml."""
    run = folder / "qlearning" / f"{ENV_NAME}_{run_id}"
    (run / ENV_NAME).mkdir(parents=True)
    QLearning("Grid", gym.make(GRID_PURSUIT_ID), seed=0).learn(20).save(run / f"{ENV_NAME}.zip")
    if config is not None:
        (run / ENV_NAME / "config.yml").write_text(config)
    return run


def _refused(zoo, args: list[str], cwd: Path) -> str:
    with pytest.raises(SystemExit) as exit_info:
        zoo(["enjoy", "--env", GRID_PURSUIT_ID, "--no-render", "-n", "5", *args], cwd)
    message = str(exit_info.value.code)
    assert "\n" not in message, message
    return message


def test_a_string_normalize_is_not_evaluated(tmp_path: Path, zoo) -> None:
    marker = tmp_path / "PWNED"
    run = _run(tmp_path / "logs", config=f"normalize: \"__import__('os').system('touch {marker}')\"\n")
    message = _refused(zoo, ["--algo", "qlearning", "-f", "logs"], tmp_path)
    assert message.startswith(f"{Path('logs') / run.relative_to(tmp_path / 'logs') / ENV_NAME / 'config.yml'}: normalize=")
    assert "vecnormalize.pkl" in message and not marker.exists()


def test_vecnormalize_statistics_are_never_unpickled(tmp_path: Path, zoo) -> None:
    marker = tmp_path / "PWNED"
    run = _run(tmp_path / "logs", config="normalize: true\n")
    (run / ENV_NAME / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    message = _refused(zoo, ["--algo", "qlearning", "-f", "logs"], tmp_path)
    assert "normalize=True" in message and "pickle" in message and not marker.exists()
    (run / ENV_NAME / "config.yml").unlink()  # no config: the zoo takes an obs_rms.pkl for normalisation
    (run / ENV_NAME / "obs_rms.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    message = _refused(zoo, ["--algo", "qlearning", "-f", "logs"], tmp_path)
    assert message.startswith(f"{Path('logs', 'qlearning', f'{ENV_NAME}_1', ENV_NAME, 'obs_rms.pkl')}: normalize=True")
    assert not marker.exists()


@pytest.mark.parametrize(
    "args",
    [
        ["--algo=qlearning", "-f", "logs"],
        ["--algo", "qlearning", "--folder=logs"],
        ["--algo", "qlearning", "--fold", "logs"],  # an argparse abbreviation
        ["--algo", "qlearning", "-f", "empty", "-f", "logs"],  # argparse takes the last
    ],
)
def test_the_check_reads_the_folder_and_algorithm_argparse_gives_the_zoo(args: list[str], tmp_path: Path, zoo) -> None:
    marker = tmp_path / "PWNED"
    _run(tmp_path / "logs", config=f"!!python/object/apply:os.system ['touch {marker}']\n")
    (tmp_path / "empty").mkdir()
    message = _refused(zoo, args, tmp_path)
    assert message.startswith(str(Path("logs", "qlearning", f"{ENV_NAME}_1", ENV_NAME, "config.yml"))), message
    assert "not plain YAML" in message and not marker.exists()


def test_a_symlinked_run_folder_is_refused(tmp_path: Path, zoo) -> None:
    marker = tmp_path / "PWNED"
    _run(tmp_path / "logs")
    elsewhere = _run(tmp_path / "elsewhere", config=f"!!python/object/apply:os.system ['touch {marker}']\n")
    (tmp_path / "logs" / "qlearning" / f"{ENV_NAME}_2").symlink_to(elsewhere, target_is_directory=True)
    message = _refused(zoo, ["--algo", "qlearning", "-f", "logs"], tmp_path)  # the zoo takes the latest run, _2
    assert message.startswith(f"{Path('logs', 'qlearning', f'{ENV_NAME}_2')}: is a symlink"), message
    assert not marker.exists()


def test_an_env_wrapper_naming_a_module_of_the_folder_is_not_imported(tmp_path: Path, zoo) -> None:
    marker = tmp_path / "PWNED"
    (tmp_path / "logs" / "evil.py").parent.mkdir()
    (tmp_path / "logs" / "evil.py").write_text(f"import os\nos.system('touch {marker}')\nWrapper = None\n")
    _run(tmp_path / "logs", config="env_wrapper: logs.evil.Wrapper\n")
    message = _refused(zoo, ["--algo", "qlearning", "-f", "logs"], tmp_path)
    assert "env_wrapper='logs.evil.Wrapper' is not a wrapper class of gymnasium.wrappers" in message
    assert not marker.exists()


def test_sb3s_own_algorithms_whose_files_are_unpickled_are_refused(tmp_path: Path, zoo) -> None:
    run = tmp_path / "logs" / "dqn" / f"{ENV_NAME}_1"
    run.mkdir(parents=True)
    (run / f"{ENV_NAME}.zip").write_bytes(b"not looked at")
    message = _refused(zoo, ["--algo", "dqn", "-f", "logs"], tmp_path)
    assert message.startswith("--algo dqn: this entry point replays only the package's agents (qlearning, affectq")
