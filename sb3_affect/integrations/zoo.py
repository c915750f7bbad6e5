"""
The package's agents in rl-zoo3 (the ``zoo`` extra: ``pip install "sb3-affect[zoo]"``).

``register_with_zoo()`` adds the package's agents to the zoo's algorithms (the zoo's ``ALGOS`` dict, as SBX does it)
under their lower-case names (``ZOO_ALGOS``): the tabular ``qlearning`` and ``affectq``, the deep ``affectdqn`` and
``affectqrdqn`` and the deep controls ``ezgreedydqn`` and ``speedepsilongreedydqn``; and their Optuna samplers, which
sample each agent's own arguments besides DQN's, to its hyperparameter search.
Both come from the agents' registry entries (``sb3_affect.core.registry.AGENT_ENTRIES``: each one's ``ZooRecipe``).
``python -m sb3_affect.integrations.zoo COMMAND ARGS`` runs a zoo command with them registered; ``train`` gives the
zoo the package's hyperparameters (``hyperparams``: for the tabular agents their files
``sb3_affect/integrations/zoo_hyperparams/<algo>.yml``, on the package's envs, FrozenLake, CliffWalking and Taxi; for
the deep agents and for ``dqn`` MiniGrid's Empty-8x8, DoorKey-5x5 and Empty-6x6: DQN's settings, each task's keys of
``dqn.yml`` with the deep study's ``trainer.algo_kwargs``, and each agent's own keywords from its recipe, written to a
temporary file the zoo reads as its ``--conf-file``; the deep study's settings, which do not make every agent solve them:
trained through the zoo with ``--seed 0``, ``dqn``'s greedy policy reached the goal of Empty-8x8 in 20 of 20 episodes
and ``affectdqn``'s in none, see docs/deep_agents.md) unless ``--conf-file`` is given; for ``dqn``, whose file the zoo
has, only on the envs ``dqn.yml`` lists. The zoo's ``enjoy`` acts stochastically on MiniGrid (as on Atari)
unless given ``--deterministic``, which replays the greedy policy. ``affectqrdqn`` costs 5 to 6 times
``affectdqn`` per step and 1.2 times QR-DQN, which costs 4.5 times DQN (its quantile loss; measured in
docs/use_it_in_your_project.md)::

    python -m sb3_affect.integrations.zoo train --algo affectq --env sb3_affect/GridPursuit-v0 -f logs
    python -m sb3_affect.integrations.zoo train --algo affectdqn --env MiniGrid-Empty-8x8-v0 -f logs
    python -m sb3_affect.integrations.zoo enjoy --algo affectdqn --env MiniGrid-Empty-8x8-v0 -f logs --no-render -n 300 \
        --deterministic
    python -m sb3_affect.integrations.zoo enjoy --algo affectq --env sb3_affect/GridPursuit-v0 -f logs --no-render -n 500
    python -m sb3_affect.integrations.zoo record_video --algo affectq --env sb3_affect/GridPursuit-v0 -f logs -n 200
    python -m sb3_affect.integrations.zoo plot_train --algo affectq --env sb3_affect/GridPursuit-v0 -f logs -w 10 \
        --output curve.png

``plot_train`` plots the Monitor's episode lengths, which count env steps (cells); the tabular agents' logger key
``rollout/ep_len_mean`` counts decisions (a decision moves 0, 1 or 2 cells) and ``rollout/ep_cells_mean`` cells.
``--output FILE`` (this module's option) saves the figure the zoo would only show.

Nothing a logs folder holds runs through this entry point's ``enjoy`` and ``record_video``, which the zoo's own
``python -m rl_zoo3.enjoy`` does not promise (use this entry point for logs folders you did not write). rl-zoo3 reads
a run's ``config.yml`` and ``args.yml`` with PyYAML's unsafe loader, ``eval``s a string ``normalize``, unpickles
``vecnormalize.pkl``, imports the module an ``env_wrapper`` names, and SB3's own model files hold pickles. While the
zoo's command runs, this entry point takes the place of the zoo's ``get_model_path`` and ``get_saved_hyperparams``,
so it checks exactly the run the zoo's argparse chose (``--folder=logs``, ``--fold logs``, the last ``-f``) and
refuses, in one line naming the file: an algorithm outside the package's agents; a symlink below the ``-f`` folder
(the run, the model, its files, ``videos``); a ``config.yml`` or ``args.yml`` with a Python tag other than the
``OrderedDict`` the zoo writes; a run that normalised (``normalize`` set, or an ``obs_rms.pkl``: its statistics are
a pickle); a wrapper that is not a wrapper class of ``WRAPPER_MODULES``. ``config.yml`` is read with the safe loader
and nothing in it is evaluated. ``enjoy`` and ``record_video`` load a deep agent with a replay buffer of one transition
(``buffer_size=1``), as the zoo loads its own off-policy algorithms: replaying stores nothing, and the trained
model's buffer (50,000 MiniGrid observations in the shipped files, about 280 MB) would be allocated for nothing. A
hyperparameter the agent refuses (``--hyperparams exploration_rate:5``) is one error
line, not a traceback.

Commands: ``train``, ``enjoy``, ``record_video``, ``plot_train``, ``all_plots`` (the zoo's modules of those names).
"""

from __future__ import annotations

import copy
import functools
import importlib
import runpy
import sys
import tempfile
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

from sb3_affect.core.extras import MissingExtraError, require_extra
from sb3_affect.core.registry import AGENT_ENTRIES, AgentEntry, Suggest, ZooRecipe, split_algo

#: The hyperparameter files of the package's agents, one per algorithm (``<algo>.yml``), and DQN's MiniGrid settings.
HYPERPARAMS_FOLDER = Path(__file__).with_name("zoo_hyperparams")
#: The package's agents in the zoo (those whose registry entry has a zoo recipe): the zoo's name (``--algo``) -> the
#: agent's name in the registry of agent names.
ZOO_ALGOS = {entry.name.lower(): entry.name for entry in AGENT_ENTRIES if entry.zoo is not None}
#: Each zoo name's recipe (its hyperparameters and sampler).
ZOO_RECIPES = {entry.name.lower(): entry.zoo for entry in AGENT_ENTRIES if entry.zoo is not None}
#: The zoo's size names of an MLP (its own samplers' ``net_arch`` choices).
NET_ARCHS = {"small": [64, 64], "medium": [128, 128], "big": [256, 256]}
#: ``python -m sb3_affect.integrations.zoo COMMAND``: the zoo module each command runs.
COMMANDS = {
    "train": "rl_zoo3.train",
    "enjoy": "rl_zoo3.enjoy",
    "record_video": "rl_zoo3.record_video",
    "plot_train": "rl_zoo3.plots.plot_train",
    "all_plots": "rl_zoo3.plots.all_plots",
}


def _sample_off_policy(trial: Any) -> dict[str, Any]:
    """DQN's arguments a deep agent shares with it, without its epsilon (the affective agents have none)."""
    train_freq = trial.suggest_categorical("train_freq", [1, 4, 8])
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 2e-3, log=True),
        "gamma": trial.suggest_categorical("gamma", [0.9, 0.95, 0.99]),
        "batch_size": trial.suggest_categorical("batch_size", [32, 64, 128]),
        "buffer_size": trial.suggest_categorical("buffer_size", [10_000, 50_000, 100_000]),
        "train_freq": train_freq,
        "gradient_steps": max(1, train_freq // trial.suggest_categorical("subsample_steps", [1, 2, 4])),
        "target_update_interval": trial.suggest_categorical("target_update_interval", [100, 500, 1000, 5000]),
        "policy_kwargs": {"net_arch": NET_ARCHS[trial.suggest_categorical("net_arch", list(NET_ARCHS))]},
    }


def _sample_epsilon(trial: Any) -> dict[str, Any]:
    """SB3's linear epsilon schedule (the deep controls explore with it)."""
    return {
        "exploration_fraction": trial.suggest_float("exploration_fraction", 0.05, 0.7),
        "exploration_final_eps": trial.suggest_float("exploration_final_eps", 0.0, 0.2),
    }


def _suggest(trial: Any, suggest: Suggest) -> Any:
    """One argument of a sampler's space drawn from the trial (``Suggest``)."""
    if suggest.kind == "categorical":
        choice = trial.suggest_categorical(suggest.name, list(suggest.bounds))
        return suggest.bounds[choice] if isinstance(suggest.bounds, dict) else choice
    low, high = suggest.bounds
    return getattr(trial, f"suggest_{suggest.kind}")(suggest.name, low, high, log=suggest.log)


def sampler(entry: AgentEntry) -> Callable[..., dict[str, Any]]:
    """
    The Optuna sampler of an agent in the zoo (the zoo's sampler signature), from its entry's recipe: DQN's
    arguments first when it shares them (``_sample_off_policy``, and ``_sample_epsilon`` for "epsilon"), then its
    own ``space``, in order.
    """
    assert entry.zoo is not None
    recipe = entry.zoo

    def sample(trial: Any, n_actions: int, n_envs: int, additional_args: dict[str, Any]) -> dict[str, Any]:
        params = _sample_off_policy(trial) if recipe.shares else {}
        if recipe.shares == "epsilon":
            params.update(_sample_epsilon(trial))
        for suggest in recipe.space:
            (params.setdefault(suggest.into, {}) if suggest.into else params)[suggest.name] = _suggest(trial, suggest)
        return params

    sample.__name__ = sample.__qualname__ = f"sample_{entry.name.lower()}_params"
    sample.__doc__ = f"Optuna sampler of {entry.name}'s hyperparameters: {', '.join(s.name for s in recipe.space)}."
    return sample


#: Each zoo name's Optuna sampler (from its registry entry's recipe).
SAMPLERS = {entry.name.lower(): sampler(entry) for entry in AGENT_ENTRIES if entry.zoo is not None}
#: The deep study's sweep file whose ``trainer.algo_kwargs`` every MiniGrid task of ``dqn.yml`` takes (the one place of DQN's
#: shared MiniGrid settings: the study trains with them, the zoo's DQN and the agents that share them too).
STUDY_NETWORK = ("sb3_affect.sweeps", "minigrid_dqn.yaml")


def _read_yaml(path: Any) -> Any:
    import yaml

    return yaml.safe_load(path.read_text())


def _dqn_minigrid() -> dict[str, dict[str, Any]]:
    """DQN's MiniGrid settings: each task's keys of ``dqn.yml`` with the deep study's ``trainer.algo_kwargs``
    (``STUDY_NETWORK``), a copy of it for each task (the table written for the zoo then holds no YAML aliases)."""
    network = _read_yaml(resources.files(STUDY_NETWORK[0]) / STUDY_NETWORK[1])["trainer"]["algo_kwargs"]
    return {task: {**keys, **copy.deepcopy(network)} for task, keys in _read_yaml(HYPERPARAMS_FOLDER / "dqn.yml").items()}


def hyperparams(algo: str) -> dict[str, dict[str, Any]]:
    """
    The hyperparameter table ``train`` gives the zoo for ``algo`` (env id -> keywords): for ``dqn``, and for a package
    agent that shares DQN's settings, ``_dqn_minigrid()`` (without DQN's epsilon for "network") and the agent's own
    MiniGrid keywords; for any other package agent its file ``<algo>.yml``. KeyError for an algorithm of neither.
    """
    recipe = ZOO_RECIPES[algo] if algo != "dqn" else ZooRecipe((), "epsilon")
    if not recipe.shares:
        table: dict[str, dict[str, Any]] = _read_yaml(HYPERPARAMS_FOLDER / f"{algo}.yml")
        return table
    epsilon = () if recipe.shares == "epsilon" else ("exploration_fraction", "exploration_final_eps")
    return {
        task: {**{key: value for key, value in keys.items() if key not in epsilon}, **copy.deepcopy(recipe.minigrid or {})}
        for task, keys in _dqn_minigrid().items()
    }


def register_with_zoo() -> None:
    """Add the package's agents (``ZOO_ALGOS``) to rl-zoo3's algorithms and hyperparameter samplers (idempotent)."""
    require_extra("zoo", "the rl-zoo3 recipe")
    import rl_zoo3
    from rl_zoo3 import hyperparams_opt

    for zoo_name, name in ZOO_ALGOS.items():
        module_name, attr = split_algo(name)
        rl_zoo3.ALGOS[zoo_name] = getattr(importlib.import_module(module_name), attr)  # one dict, shared by the zoo
    hyperparams_opt.HYPERPARAMS_SAMPLER.update(SAMPLERS)


def _conf_file(algo: str | None, argv: list[str], folder: Path) -> Path | None:
    """
    The hyperparameter file ``train`` gives the zoo for ``algo``: always for the package's agents (its own file, or
    its table of ``hyperparams`` written into ``folder``); for ``dqn`` (``hyperparams("dqn")`` written there) only when
    its table lists the env, so the zoo's own settings stay in force for any other env and algorithm.
    """
    if algo is None or "--conf-file" in argv or "-conf" in argv:
        return None
    if algo in ZOO_RECIPES and not ZOO_RECIPES[algo].shares:
        return HYPERPARAMS_FOLDER / f"{algo}.yml"
    if algo not in ZOO_RECIPES and algo != "dqn":
        return None
    table = hyperparams(algo)
    env = argv[argv.index("--env") + 1] if "--env" in argv and argv.index("--env") + 1 < len(argv) else None
    if algo == "dqn" and env not in table:
        return None
    import yaml

    conf = folder / f"{algo}.yml"
    conf.write_text(yaml.safe_dump(table, sort_keys=False))
    return conf


def _algo(argv: list[str]) -> str | None:
    """The value of ``--algo`` in a zoo command line (``--algo X`` or ``--algo=X``; the last, as argparse takes it), if
    any (``train`` picks the package's hyperparameter file by it; ``enjoy`` and ``record_video`` check the algorithm
    the zoo's own argparse gives, ``check_run``)."""
    algo = None
    for at, arg in enumerate(argv):
        if arg == "--algo" and at + 1 < len(argv):
            algo = argv[at + 1]
        elif arg.startswith("--algo="):
            algo = arg.removeprefix("--algo=")
    return algo


def _eval_env_kwargs(conf: Path, argv: list[str]) -> list[str]:
    """
    ``--eval-env-kwargs`` for the file's ``env_kwargs`` of the env being trained: the zoo gives the evaluation env the
    file's env keywords (its time limit) only when ``--env-kwargs`` is on the command line, so pass them explicitly.
    """
    import yaml

    if "--env-kwargs" in argv or "--eval-env-kwargs" in argv or "--env" not in argv:
        return []
    env_id = argv[argv.index("--env") + 1] if argv.index("--env") + 1 < len(argv) else ""
    env_kwargs = (yaml.safe_load(conf.read_text()).get(env_id) or {}).get("env_kwargs") or {}
    return ["--eval-env-kwargs", *(f"{key}:{value!r}" for key, value in env_kwargs.items())] if env_kwargs else []


def _config_loader() -> Any:
    """A safe loader that also reads the ``OrderedDict`` tag rl-zoo3 writes (as a dict); any other Python tag fails."""
    import yaml

    class ZooConfigLoader(yaml.SafeLoader):
        pass

    def ordered_dict(loader: Any, node: Any) -> dict[Any, Any]:
        return dict(*loader.construct_sequence(node, deep=True))

    ZooConfigLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", ordered_dict)
    return ZooConfigLoader


#: Wrappers a logs folder's ``env_wrapper`` / ``vec_env_wrapper`` may name: classes of these installed modules (the zoo
#: imports the module a name gives, so a name of a module in the folder itself would run its code).
WRAPPER_MODULES = (
    "gymnasium.wrappers", "minigrid.wrappers", "rl_zoo3.wrappers", "stable_baselines3.common.atari_wrappers",
    "stable_baselines3.common.vec_env", "sb3_affect.envs",
)
#: What ``enjoy`` and ``record_video`` read or write in a run folder besides the model (checked not to be symlinks).
RUN_FILES = ("config.yml", "args.yml", "vecnormalize.pkl", "obs_rms.pkl")


def _refuse(path: Any, why: str) -> SystemExit:
    return SystemExit(f"{path}: {' '.join(why.split())}")


def _read_config(path: Path) -> Any:
    """A run's ``config.yml`` or ``args.yml`` read with ``_config_loader`` (``SystemExit`` for a Python tag)."""
    import yaml

    try:
        return yaml.load(path.read_text(), Loader=_config_loader())  # (a SafeLoader with one more constructor)
    except yaml.YAMLError as error:
        problem = " ".join(str(getattr(error, "problem", None) or error).split())
        raise _refuse(path, f"not plain YAML ({problem}); rl-zoo3 would load it with an unsafe loader, which runs Python "
                      "tags, so it is refused") from None
    except (OSError, UnicodeDecodeError) as error:
        raise _refuse(path, f"can not be read ({error})") from None


def _no_symlinks(top: Path, paths: list[Path]) -> None:
    """Refuse any of ``paths`` that is a symlink, or lies under one below ``top`` (the ``-f`` folder itself is the user's)."""
    for path in paths:
        for part in [path, *path.parents]:
            if part == top or top not in part.parents:
                break
            if part.is_symlink():
                raise _refuse(part, "is a symlink; this entry point reads only the logs folder's own files, so it is "
                              "refused")


def check_run(folder: str, algo: str, env_name: str, model_path: str, log_path: str) -> None:
    """
    Refuse (``SystemExit``, one line naming the file) what ``enjoy`` or ``record_video`` would load from a logs folder
    and run code with: an algorithm whose model files SB3 unpickles (any outside ``ZOO_ALGOS``), a symlink in the run
    (the model, the run folder, its files, ``videos``), and a ``config.yml`` or ``args.yml`` with a Python tag other
    than ``OrderedDict`` (rl-zoo3 loads them with an unsafe loader). Called by the zoo with the folder its own argparse
    parsed (``get_model_path``).
    """
    if algo not in ZOO_ALGOS:
        raise SystemExit(
            f"--algo {algo}: this entry point replays only the package's agents ({', '.join(ZOO_ALGOS)}); SB3's own "
            "model files hold pickled objects, which run code when loaded (python -m rl_zoo3.enjoy loads a folder you "
            "wrote)"
        )
    run, stats = Path(log_path), Path(log_path) / env_name
    _no_symlinks(Path(folder), [Path(model_path), run / "videos", *(stats / name for name in RUN_FILES)])
    for name in ("config.yml", "args.yml"):
        if (stats / name).is_file():
            _read_config(stats / name)


def _wrapper_names(value: Any) -> list[Any]:
    names = value if isinstance(value, list) else [value]
    return [next(iter(name)) if isinstance(name, dict) and len(name) == 1 else name for name in names]


def _check_wrappers(config: Path, hyperparams: dict[str, Any]) -> None:
    """Refuse a wrapper name outside ``WRAPPER_MODULES``, or not a wrapper class there, before the zoo imports it."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import VecEnvWrapper

    for key in ("env_wrapper", "vec_env_wrapper"):
        for name in _wrapper_names(hyperparams.get(key)) if hyperparams.get(key) is not None else []:
            module, _, attr = name.rpartition(".") if isinstance(name, str) else ("", "", "")
            wrapper = getattr(importlib.import_module(module), attr, None) if module in WRAPPER_MODULES else None
            if not (isinstance(wrapper, type) and issubclass(wrapper, (gym.Wrapper, VecEnvWrapper))):
                raise _refuse(config, f"{key}={name!r} is not a wrapper class of {', '.join(WRAPPER_MODULES)}; the zoo "
                              "would import the module it names, so it is refused")


def saved_hyperparams(stats_path: str, norm_reward: bool = False, test_mode: bool = False) -> tuple[dict[str, Any], Any]:
    """
    rl-zoo3's ``get_saved_hyperparams`` without running anything: ``config.yml`` read with the safe loader (no string
    ``eval``), its wrapper names checked (``WRAPPER_MODULES``), and normalisation refused: ``vecnormalize.pkl`` is a
    pickle, which runs code when loaded, so a run that normalised (``normalize`` set, or an ``obs_rms.pkl``) is one
    error line.
    """
    stats = Path(stats_path)
    if not stats.is_dir():
        return {}, None
    config = stats / "config.yml"
    hyperparams = _read_config(config) if config.is_file() else {}
    if not isinstance(hyperparams, dict):
        raise _refuse(config, f"holds {type(hyperparams).__name__}, not the mapping of hyperparameters the zoo writes")
    normalize = hyperparams.get("normalize", False) if config.is_file() else (stats / "obs_rms.pkl").is_file()
    if normalize:
        raise _refuse(
            config if config.is_file() else stats / "obs_rms.pkl",
            f"normalize={normalize!r}: the run normalised with VecNormalize, whose statistics (vecnormalize.pkl) are a "
            "pickle, which runs code when loaded; this entry point does not load them",
        )
    _check_wrappers(config, hyperparams)
    return {**hyperparams, "normalize": False}, str(stats)


def _checked_model_path(original: Any) -> Any:
    """The zoo's ``get_model_path``, then ``check_run`` on the run it found (the folder argparse gave the zoo)."""

    def get_model_path(exp_id: int, folder: str, algo: str, env_name: Any, *args: Any, **kwargs: Any) -> Any:
        name_prefix, model_path, log_path = original(exp_id, folder, algo, env_name, *args, **kwargs)
        check_run(folder, algo, str(env_name), model_path, log_path)
        return name_prefix, model_path, log_path

    return get_model_path


def _guard_replay() -> list[tuple[Any, str, Any]]:
    """Put ``check_run`` and ``saved_hyperparams`` in the zoo's modules' places of the functions ``enjoy`` and
    ``record_video`` import (they import them when run); returns what it replaced (for ``_restore``)."""
    import rl_zoo3
    import rl_zoo3.utils

    replaced: list[tuple[Any, str, Any]] = []
    for module in (rl_zoo3, rl_zoo3.utils):
        for name, guard in (("get_model_path", _checked_model_path), ("get_saved_hyperparams", None)):
            if hasattr(module, name):
                replaced.append((functools.partial(setattr, module), name, getattr(module, name)))
                setattr(module, name, saved_hyperparams if guard is None else guard(getattr(module, name)))
    return replaced


def _restore(replaced: list[tuple[Any, str, Any]]) -> None:
    """Put back what ``_guard_replay`` and ``_load_for_replay`` replaced: ``(setter, name, value)``, a module's
    attribute or an ``ALGOS`` entry."""
    for setter, name, value in replaced:
        setter(name, value)


class ReplayLoader:
    """What the zoo's ``ALGOS`` holds for an off-policy agent of the package while the zoo replays it: the agent's
    ``load`` with a replay buffer of one transition (the keywords the zoo's ``enjoy`` passes for its own)."""

    def __init__(self, cls: type) -> None:
        self.cls = cls

    def load(self, path: Any, **kwargs: Any) -> Any:
        return self.cls.load(path, **{"buffer_size": 1, "optimize_memory_usage": False, **kwargs})  # type: ignore[attr-defined]


def _agent_error(error: BaseException) -> bool:
    """Whether ``error`` was raised by this package's code (an agent's check of a value), not by the zoo's."""
    tb = error.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    package = Path(__file__).resolve().parents[1]  # sb3_affect/
    return tb is not None and Path(tb.tb_frame.f_code.co_filename).resolve().is_relative_to(package)


def _load_for_replay() -> list[tuple[Any, str, Any]]:
    """Put a ``ReplayLoader`` in the zoo's ``ALGOS`` for each off-policy agent of the package; returns what it replaced
    (for ``_restore``)."""
    import rl_zoo3
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

    algos: dict[str, Any] = rl_zoo3.ALGOS
    replaced: list[tuple[Any, str, Any]] = []
    for algo in ZOO_ALGOS:
        cls = algos.get(algo)
        if isinstance(cls, type) and issubclass(cls, OffPolicyAlgorithm):
            replaced.append((algos.__setitem__, algo, cls))
            algos[algo] = ReplayLoader(cls)
    return replaced


def _run(command: str, rest: list[str]) -> None:
    """The zoo's ``command`` with the arguments ``rest`` (``main``'s, the hyperparameter file added for ``train``)."""
    output = None
    if command in ("plot_train", "all_plots"):
        if "--output" in rest:  # ours: save the figure (the zoo only shows it)
            at = rest.index("--output")
            output = rest[at + 1]
            del rest[at : at + 2]
        import gymnasium as gym

        # the zoo names its run folders after the env id with "/" replaced by "-"; plot_train looks them up by id
        rest = [arg.replace("/", "-") if "/" in arg and arg in gym.registry else arg for arg in rest]
    replaced: list[tuple[Any, str, Any]] = []
    if command in ("enjoy", "record_video"):
        replaced = [*_guard_replay(), *_load_for_replay()]
    saved = sys.argv
    sys.argv = [COMMANDS[command], *rest]
    try:
        runpy.run_module(COMMANDS[command], run_name="__main__", alter_sys=False)
    except (ValueError, TypeError) as error:
        if not _agent_error(error):
            raise
        raise SystemExit(f"sb3_affect.integrations.zoo {command}: error: {' '.join(str(error).split())}") from None
    finally:
        sys.argv = saved
        _restore(replaced)
    if output is not None:
        import matplotlib.pyplot as plt

        plt.gcf().savefig(output)
        print(f"figure: {output}")


def main(argv: list[str] | None = None) -> None:
    """``python -m sb3_affect.integrations.zoo COMMAND ARGS``: the zoo's command with the package's agents registered."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] not in COMMANDS:
        commands = ",".join(COMMANDS)
        raise SystemExit(f"usage: python -m sb3_affect.integrations.zoo {{{commands}}} [the zoo command's arguments]")
    command, rest = args[0], args[1:]
    try:
        register_with_zoo()
    except MissingExtraError as error:  # one line naming the extra, as the sb3-affect command says it
        print(f"python -m sb3_affect.integrations.zoo: error: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    with tempfile.TemporaryDirectory(prefix="sb3_affect_zoo_") as folder:  # a table built for train (hyperparams)
        conf = _conf_file(_algo(rest), rest, Path(folder)) if command == "train" else None
        if conf is not None:
            rest += ["--conf-file", str(conf), *_eval_env_kwargs(conf, rest)]
        _run(command, rest)


if __name__ == "__main__":
    main()
