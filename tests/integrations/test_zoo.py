"""
rl-zoo3 and the Hugging Face Hub with the tabular agents: the zoo's own train, enjoy, record_video and plot_train
(tiny budgets, real files), the Optuna samplers, the safe loader with the zoo's custom_objects, the Hub packaging
offline, and the envs' registered time limit.
"""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import optuna
import pytest

from sb3_affect import AffectQ, QLearning
from sb3_affect.core.settings import TabularSettings
from sb3_affect.envs import GRID_PURSUIT_ID, MAX_EPISODE_STEPS
from sb3_affect.integrations.zoo import SAMPLERS, hyperparams


@pytest.mark.parametrize(
    ("algo", "env_id", "video"), [("affectq", GRID_PURSUIT_ID, True), ("qlearning", "FrozenLake-v1", False)]
)
def test_zoo_trains_enjoys_records_and_plots(algo: str, env_id: str, video: bool, tmp_path: Path, zoo) -> None:
    common = ["--algo", algo, "--env", env_id, "-f", "logs"]
    out = zoo(["train", *common, "-n", "1000", "--eval-freq", "500", "--eval-episodes", "2", "--seed", "0"], tmp_path)
    run = tmp_path / "logs" / algo / f"{env_id.replace('/', '-')}_1"
    assert "Eval num_timesteps=1000" in out and (run / f"{env_id.replace('/', '-')}.zip").exists()
    assert (run / "0.monitor.csv").exists() and (tmp_path / "logs" / algo / f"{env_id.replace('/', '-')}_1").is_dir()
    out = zoo(["enjoy", *common, "--no-render", "-n", "600", "--seed", "0"], tmp_path)  # >= one time limit
    assert "Episode Reward" in out and "Episode Length" in out, out[-500:]
    if video:
        zoo(["record_video", *common, "-n", "20", "--seed", "0"], tmp_path)
        assert list((run / "videos").glob("*.mp4"))
    zoo(["plot_train", *common, "-w", "2", "-y", "length", "--output", "curve.png"], tmp_path)
    assert (tmp_path / "curve.png").stat().st_size > 1000


def test_hyperparameter_files_build_every_agent_on_every_env() -> None:
    for algo, cls in (("qlearning", QLearning), ("affectq", AffectQ)):
        table = hyperparams(algo)  # the agent's own file
        assert {GRID_PURSUIT_ID, "sb3_affect/MazePursuit-v0", "sb3_affect/MovingPursuit-v0", "FrozenLake-v1",
                "CliffWalking-v1", "Taxi-v4"} <= set(table)
        for env_id, params in table.items():
            params = dict(params)
            params.pop("n_timesteps")
            env = gym.make(env_id, **params.pop("env_kwargs", {}))
            cls(env=env, **params).learn(20)


@pytest.mark.parametrize(("algo", "cls"), [("qlearning", QLearning), ("affectq", AffectQ)])
def test_optuna_samplers_give_valid_agents(algo, cls) -> None:
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    for _ in range(5):
        params = SAMPLERS[algo](study.ask(), 4, 1, {})
        cls("Grid", gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2)), seed=0, **params).learn(50)


def test_zoo_optimizes_qlearning_with_its_sampler(tmp_path: Path, zoo) -> None:
    out = zoo(["train", "--algo", "qlearning", "--env", "FrozenLake-v1", "-f", "logs", "-n", "400",
               "--optimize-hyperparameters", "--n-trials", "2", "--n-jobs", "1", "--sampler", "random", "--pruner",
               "none", "--n-evaluations", "1", "--eval-episodes", "2", "--seed", "0"], tmp_path)
    assert "Number of finished trials:  2" in out and "exploration_rate: " in out and "gamma: " in out


def test_safe_loader_applies_custom_objects_as_sb3_does(tmp_path: Path) -> None:
    model = AffectQ("Grid", gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2)), seed=0, learning_rate=0.5).learn(200)
    model.save(tmp_path / "m")
    zoo_objects = {"learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}  # rl-zoo3's enjoy
    loaded = AffectQ.load(tmp_path / "m", custom_objects=zoo_objects, seed=3)
    assert loaded.learning_rate == 0.0 and loaded.lr_schedule(1.0) == 0.0
    assert not hasattr(loaded, "clip_range")  # names the file does not hold are ignored, as in SB3
    assert (loaded.q_table == model.q_table).all() and loaded.seed == 3
    assert AffectQ.load(tmp_path / "m").learning_rate == 0.5


def test_hub_packaging_offline_names_sb3_affect_and_how_to_load(tmp_path: Path) -> None:
    from sb3_affect.integrations.hub import package_model

    model = QLearning("Grid", gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2), max_episode_steps=50), seed=0).learn(2000)
    folder = package_model(model, tmp_path / "hub", GRID_PURSUIT_ID, repo_id="someone/qlearning-grid",
                           eval_env=gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2), max_episode_steps=50),
                           n_eval_episodes=3)
    card = (folder / "README.md").read_text()
    assert "sb3-affect" in card and "from sb3_affect import QLearning" in card and "QLearning.load(path)" in card
    assert 'repo_id="someone/qlearning-grid"' in card and "tags:" in card and "mean_reward" in card
    results = json.loads((folder / "results.json").read_text())
    assert results["n_eval_episodes"] == 3 and np.isfinite(results["mean_reward"])
    assert json.loads((folder / "config.json").read_text())["gamma"] == model.gamma
    loaded = QLearning.load(folder / "qlearning-sb3_affect-GridPursuit-v0.zip")
    assert (loaded.q_table == model.q_table).all()


def test_package_envs_are_registered_with_a_time_limit_the_agents_cap_never_reaches() -> None:
    assert gym.spec(GRID_PURSUIT_ID).max_episode_steps == MAX_EPISODE_STEPS
    assert 2 * TabularSettings().max_episode_decisions <= MAX_EPISODE_STEPS  # at most 2 cells a decision
    env = gym.make(GRID_PURSUIT_ID, max_episode_steps=7)  # evaluations of a stuck policy end
    env.reset(seed=0)
    truncated = [env.step(0)[3] for _ in range(7)]
    assert truncated == [False] * 6 + [True]


def test_zoo_refuses_a_bad_hyperparameter_in_one_line_and_a_logs_folder_with_python_tags(tmp_path: Path, zoo) -> None:
    with pytest.raises(SystemExit) as exit_info:
        zoo(["train", "--algo", "qlearning", "--env", GRID_PURSUIT_ID, "-f", "logs", "-n", "50",
             "--hyperparams", "exploration_rate:5.0"], tmp_path)
    message = str(exit_info.value.code)
    assert message.startswith("sb3_affect.integrations.zoo train: error: ") and "exploration_rate" in message
    assert "\n" not in message
    env_name = GRID_PURSUIT_ID.replace("/", "-")
    run = tmp_path / "logs" / "qlearning" / f"{env_name}_1"
    (run / env_name).mkdir(parents=True, exist_ok=True)  # (train made it before it stopped)
    QLearning("Grid", gym.make(GRID_PURSUIT_ID), seed=0).learn(50).save(run / f"{env_name}.zip")
    marker = tmp_path / "PWNED"
    config = run / env_name / "config.yml"
    config.write_text(f"!!python/object/apply:os.system ['touch {marker}']\n")
    with pytest.raises(SystemExit) as exit_info:
        zoo(["enjoy", "--algo", "qlearning", "--env", GRID_PURSUIT_ID, "-f", "logs", "--no-render", "-n", "5"], tmp_path)
    message = str(exit_info.value.code)
    assert message.startswith(f"{config.relative_to(tmp_path)}: not plain YAML") and "\n" not in message, message
    assert not marker.exists()


def test_hub_packaging_refuses_paths_code_and_other_envs(tmp_path: Path) -> None:
    from sb3_affect.integrations.hub import package_model

    model = QLearning("Grid", gym.make(GRID_PURSUIT_ID, size=4, goal=(2, 2)), seed=0).learn(200)
    small = {"size": 4, "goal": (2, 2)}
    cases = [
        ({"model_name": "../../x"}, r"model_name='../../x' must be a file name"),
        ({"repo_id": 'a/b"); import os; os.system("x'}, r"repo_id=.* is not a Hub repository id"),
        ({"eval_env": gym.make("FrozenLake-v1")}, r"eval_env is 'FrozenLake-v1', not env_id='sb3_affect/GridPursuit-v0'"),
        ({"eval_env": gym.make(GRID_PURSUIT_ID)}, r"has spaces Discrete\(225\) / Discrete\(4\); the model was trained on"),
    ]
    for kwargs, words in cases:
        arguments = {"eval_env": gym.make(GRID_PURSUIT_ID, **small), **kwargs}
        with pytest.raises(ValueError, match=words):
            package_model(model, tmp_path / "hub", GRID_PURSUIT_ID, n_eval_episodes=1, **arguments)
    with pytest.raises(ValueError, match=r"env_id='evilmod:Env-v0' is not a registered Gymnasium env id"):
        package_model(model, tmp_path / "hub", "evilmod:Env-v0", n_eval_episodes=1)
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match=r"folder=.*file' is a file"):
        package_model(model, tmp_path / "file", GRID_PURSUIT_ID, eval_env=gym.make(GRID_PURSUIT_ID, **small),
                      n_eval_episodes=1)
    assert not (tmp_path.parent / "x.zip").exists() and not list(tmp_path.glob("hub/*"))


def test_the_kernel_steps_gymnasiums_time_limit_while_rl_zoo3_has_rebound_it_and_refuses_rl_zoo3s() -> None:
    import rl_zoo3.gym_patches
    from conftest import TIME_LIMIT, TIME_LIMIT_MODULES

    from sb3_affect.agents.compiled import compiled_reason

    for module in TIME_LIMIT_MODULES:  # as after `import rl_zoo3` (conftest puts Gymnasium's back after the test)
        module.TimeLimit = rl_zoo3.gym_patches.PatchedTimeLimit
    zoo_env = gym.make(GRID_PURSUIT_ID)
    reason = compiled_reason(QLearning("Grid", zoo_env), zoo_env, None)
    assert reason == "the env is wrapped in PatchedTimeLimit, which may change what a step does"
    plain = TIME_LIMIT(gym.make(GRID_PURSUIT_ID).unwrapped, MAX_EPISODE_STEPS)  # Gymnasium's own, made before the rebinding
    assert compiled_reason(QLearning("Grid", plain), plain, None) is None
    model = QLearning("Grid", plain, seed=0).learn(300)
    assert model.num_timesteps == 300 and model.engine_used == "compiled"


def test_the_zoo_extra_brings_every_module_the_zoos_plots_import() -> None:
    import ast
    from importlib import metadata

    import rl_zoo3.plots
    import tomllib
    from packaging.requirements import Requirement

    def names(requirements: list[str]) -> set[str]:
        return {Requirement(r).name.lower().replace("_", "-") for r in requirements if "extra ==" not in r}

    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())["project"]
    given = names(project["dependencies"]) | names(project["optional-dependencies"]["zoo"])
    for package in ("rl-zoo3", "stable-baselines3"):  # what the extra's packages bring themselves
        given |= names(metadata.requires(package) or [])
    given |= {"rl-zoo3", "stable-baselines3"}
    distributions = metadata.packages_distributions()
    for command in ("plot_train.py", "all_plots.py"):
        tree = ast.parse((Path(rl_zoo3.plots.__file__).parent / command).read_text())
        imported = {alias.name.split(".")[0] for node in tree.body if isinstance(node, ast.Import) for alias in node.names}
        imported |= {node.module.split(".")[0] for node in tree.body if isinstance(node, ast.ImportFrom) and node.module}
        for module in sorted(imported - set(__import__("sys").stdlib_module_names)):
            owners = {name.lower().replace("_", "-") for name in distributions.get(module, [module])}
            assert owners & given, f"{command} imports {module} ({owners}), which the zoo extra does not bring"
