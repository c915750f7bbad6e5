"""
rl-zoo3 with the deep agents and the deep controls: the zoo's own train and enjoy of AffectDQN on MiniGrid with the
package's hyperparameters (a small budget on the command line), every deep agent's table (DQN's settings, the deep
study's trainer.algo_kwargs, its own keywords), the Optuna samplers and the zoo's hyperparameter search with
AffectDQN's sampler.
"""

from __future__ import annotations

from pathlib import Path

import optuna
import pytest
import yaml

minigrid = pytest.importorskip("minigrid")
from minigrid.wrappers import FlatObsWrapper  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402

from sb3_affect.integrations.zoo import (  # noqa: E402
    HYPERPARAMS_FOLDER,
    SAMPLERS,
    ZOO_RECIPES,
    _conf_file,
    hyperparams,
    register_with_zoo,
)

ROOT = Path(__file__).resolve().parents[2]
#: The package's agents that share DQN's MiniGrid settings (their registry entries' zoo recipes).
DEEP = tuple(algo for algo, recipe in ZOO_RECIPES.items() if recipe.shares)
TASKS = ("MiniGrid-Empty-8x8-v0", "MiniGrid-DoorKey-5x5-v0", "MiniGrid-Empty-6x6-v0")
#: DQN's epsilon, which the affective agents do not take.
EPSILON = ("exploration_fraction", "exploration_final_eps")


def _agent(algo: str) -> type:
    import rl_zoo3

    register_with_zoo()
    return rl_zoo3.ALGOS[algo]


def test_zoo_trains_affect_dqn_on_minigrid_with_the_shipped_file_and_enjoy_replays_it(tmp_path: Path, zoo) -> None:
    common = ["--algo", "affectdqn", "--env", "MiniGrid-Empty-8x8-v0", "-f", "logs"]
    out = zoo(["train", *common, "-n", "600", "--eval-freq", "300", "--eval-episodes", "1", "--seed", "0"], tmp_path)
    run = tmp_path / "logs" / "affectdqn" / "MiniGrid-Empty-8x8-v0_1"
    assert "Eval num_timesteps=600" in out and (run / "MiniGrid-Empty-8x8-v0.zip").exists()
    config = yaml.load((run / "MiniGrid-Empty-8x8-v0" / "config.yml").read_text(), Loader=yaml.UnsafeLoader)
    assert dict(config)["env_wrapper"] == "minigrid.wrappers.FlatObsWrapper" and dict(config)["position"] == "minigrid"
    model = _agent("affectdqn").load(run / "MiniGrid-Empty-8x8-v0.zip")
    shipped = hyperparams("affectdqn")["MiniGrid-Empty-8x8-v0"]
    assert model.num_timesteps >= 600 and model.learning_starts == shipped["learning_starts"]  # (a repeat may end past it)
    out = zoo(["enjoy", *common, "--no-render", "-n", "300", "--seed", "0", "--deterministic"], tmp_path)  # > an episode (256)
    assert "Episode Reward" in out and "Episode Length" in out, out[-500:]


def test_every_deep_agent_has_the_minigrid_tasks_dqns_settings_and_the_studys_network() -> None:
    study = yaml.safe_load((ROOT / "experiments" / "minigrid_dqn.yaml").read_text())
    dqn, network = hyperparams("dqn"), study["trainer"]["algo_kwargs"]
    assert set(dqn) == set(TASKS) and {"affectdqn", "affectqrdqn", "ezgreedydqn", "speedepsilongreedydqn"} <= set(DEEP)
    assert all(task.items() >= network.items() for task in dqn.values())  # the study trains with the same network
    assert dqn["MiniGrid-Empty-8x8-v0"]["learning_rate"] == 0.0005 and dqn["MiniGrid-Empty-6x6-v0"]["n_timesteps"] == 50_000
    for algo in DEEP:
        recipe, table = ZOO_RECIPES[algo], hyperparams(algo)
        assert set(table) == set(TASKS), algo
        for task in TASKS:
            expected = {k: v for k, v in dqn[task].items() if not (recipe.shares == "network" and k in EPSILON)}
            assert table[task] == {**expected, **(recipe.minigrid or {})}, (algo, task)
            assert (recipe.shares == "epsilon") == (set(EPSILON) <= set(table[task])), (algo, task)


@pytest.mark.parametrize("algo", DEEP)
def test_the_deep_agents_files_build_the_agent_on_every_task(algo: str) -> None:
    for task, params in hyperparams(algo).items():
        params = dict(params)
        params.pop("n_timesteps"), params.pop("env_wrapper")
        env = make_vec_env(task, n_envs=params.pop("n_envs"), seed=0, wrapper_class=FlatObsWrapper)
        model = _agent(algo)(env=env, seed=0, **{**params, "learning_starts": 20, "buffer_size": 100})
        assert model.learn(40).num_timesteps >= 40  # (a repeat may end past the budget)


@pytest.mark.parametrize("algo", DEEP)
def test_the_deep_samplers_give_valid_agents_with_their_own_arguments(algo: str) -> None:
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    own = [suggest.name for suggest in ZOO_RECIPES[algo].space]  # the agent's own arguments, besides DQN's
    for _ in range(2):
        params = SAMPLERS[algo](study.ask(), 7, 1, {})
        position = {k: v for k, v in (ZOO_RECIPES[algo].minigrid or {}).items() if k not in params}  # (position)
        assert set(own) <= {**params, **params["policy_kwargs"]}.keys()
        assert (ZOO_RECIPES[algo].shares == "epsilon") == (set(EPSILON) <= set(params)), params
        env = make_vec_env("MiniGrid-Empty-5x5-v0", n_envs=1, seed=0, wrapper_class=FlatObsWrapper)
        params = {**params, "buffer_size": 100, "learning_starts": 20}
        assert _agent(algo)("MlpPolicy", env, seed=0, **position, **params).learn(30).num_timesteps >= 30  # (repeats)


def test_the_zoo_optimizes_affect_dqn_with_its_sampler(tmp_path: Path, zoo) -> None:
    out = zoo(["train", "--algo", "affectdqn", "--env", "MiniGrid-Empty-6x6-v0", "-f", "logs", "-n", "100",
               "--optimize-hyperparameters", "--n-trials", "1", "--n-jobs", "1", "--sampler", "random", "--pruner",
               "none", "--n-evaluations", "1", "--eval-episodes", "1", "--seed", "0",
               "--hyperparams", "learning_starts:50", "buffer_size:500"], tmp_path)
    assert "Number of finished trials:  1" in out and "behaviour_table: " in out and "net_arch: " in out


def test_the_package_tables_are_given_for_its_agents_and_for_dqn_on_the_envs_it_lists(tmp_path: Path) -> None:
    assert {"qlearning", "affectq", *DEEP} == set(ZOO_RECIPES)
    conf = _conf_file("affectdqn", ["--env", "MiniGrid-Empty-8x8-v0"], tmp_path)
    assert conf == tmp_path / "affectdqn.yml" and yaml.safe_load(conf.read_text()) == hyperparams("affectdqn")
    assert "&" not in conf.read_text()  # each task its own values, no YAML aliases
    conf = _conf_file("dqn", ["--env", "MiniGrid-DoorKey-5x5-v0"], tmp_path)
    assert conf == tmp_path / "dqn.yml" and yaml.safe_load(conf.read_text()) == hyperparams("dqn")
    assert _conf_file("qlearning", ["--env", "FrozenLake-v1"], tmp_path) == HYPERPARAMS_FOLDER / "qlearning.yml"
    assert _conf_file("dqn", ["--env", "CartPole-v1"], tmp_path) is None  # the zoo's own dqn.yml
    assert _conf_file("ppo", ["--env", "MiniGrid-Empty-8x8-v0"], tmp_path) is None
    assert _conf_file("affectdqn", ["--env", "MiniGrid-Empty-8x8-v0", "--conf-file", "mine.yml"], tmp_path) is None


def test_the_deep_agents_page_trains_with_the_shipped_settings() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "deep_agents.md").read_text()
    code = page[page.index("settings = dict(") : page.index("env = make_vec_env(")]
    namespace: dict[str, object] = {}
    exec(code, namespace)
    shipped = dict(hyperparams("affectdqn")["MiniGrid-Empty-8x8-v0"])
    for key in ("env_wrapper", "n_envs", "n_timesteps", "policy", "position", "wait_action"):
        shipped.pop(key)
    assert namespace["settings"] == {key: value for key, value in shipped.items() if key != "gradient_steps"}
    assert shipped["gradient_steps"] == 1  # DQN's default
    table = hyperparams("affectdqn")["MiniGrid-Empty-8x8-v0"]
    assert "the runs below took 100_000" in page and table["n_timesteps"] == 100_000
    assert "n_envs=4" in page and table["n_envs"] == 4
