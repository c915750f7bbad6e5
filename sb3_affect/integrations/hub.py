"""
A trained tabular agent packaged for the Hugging Face Hub, offline (the ``zoo`` extra: ``huggingface-sb3``).

``package_model`` does what ``huggingface_sb3.package_to_hub`` does before it uploads, with that library's own
helpers: save the model, write ``config.json`` from the saved file, evaluate the agent (``results.json``), and write
the model card (``README.md``, with the Hub's metadata), whose usage section names sb3-affect and shows how to load
the model. Uploading the folder is then one call that needs the network::

    from huggingface_hub import upload_folder
    upload_folder(repo_id="you/affectq-GridPursuit-v0", folder_path=folder)
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from sb3_affect.core.extras import require_extra

MODEL_CARD = """
# **{algo}** agent playing **{env_id}**

A trained **{algo}** agent of sb3-affect (affective tabular Q-learning
as a Stable-Baselines3 plugin) playing **{env_id}**. Mean reward over {episodes} evaluation episodes:
{mean_reward:.2f} +/- {std_reward:.2f}.

## Usage (with sb3-affect)

The model is a tabular agent of sb3-affect, not one of Stable-Baselines3's own algorithms: install the package
and load the file with its class (loading never unpickles anything from the file).

```bash
pip install sb3-affect huggingface-sb3
```

```python
import gymnasium as gym
import sb3_affect  # registers the package's envs
from huggingface_sb3 import load_from_hub
from sb3_affect import {algo}

path = load_from_hub(repo_id="{repo_id}", filename="{model_name}.zip")
model = {algo}.load(path)
env = gym.make("{env_id}")
obs, _ = env.reset()
action, _ = model.predict(obs, deterministic=True)
```
"""


#: A Hub repository id (``user/name``) and a model file's name: what the card's code quotes, so nothing else.
_REPO_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,95}/[A-Za-z0-9][A-Za-z0-9._-]{0,95}")
_FILE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,199}")


def _check_names(repo_id: Any, model_name: Any, env_id: Any) -> None:
    """The names the card's code quotes: a Hub repository id, a plain file name, a registered env id."""
    import gymnasium as gym

    if not isinstance(repo_id, str) or not _REPO_ID.fullmatch(repo_id) or ".." in repo_id:
        raise ValueError(f"repo_id={repo_id!r} is not a Hub repository id: USER/NAME of letters, digits, '.', '_', '-'")
    plain = isinstance(model_name, str) and _FILE_NAME.fullmatch(model_name) is not None and ".." not in model_name
    if model_name is not None and not plain:
        raise ValueError(f"model_name={model_name!r} must be a file name of letters, digits, '.', '_', '-' (not a path)")
    if not isinstance(env_id, str) or ":" in env_id or env_id not in gym.registry:
        raise ValueError(f"env_id={env_id!r} is not a registered Gymnasium env id (module:Env ids are not imported)")


def _check_env(model: Any, env: Any, env_id: str) -> None:
    """The evaluation env is the one the card names, and the model's spaces are its spaces."""
    from stable_baselines3.common.vec_env import VecEnv

    spec = getattr(env, "spec", None) if not isinstance(env, VecEnv) else None
    if spec is not None and spec.id != env_id:
        raise ValueError(f"eval_env is {spec.id!r}, not env_id={env_id!r}: the card would label its results with another env")
    if env.observation_space != model.observation_space or env.action_space != model.action_space:
        raise ValueError(
            f"env_id={env_id!r} has spaces {env.observation_space} / {env.action_space}; the model was trained on "
            f"{model.observation_space} / {model.action_space}"
        )


def package_model(
    model: Any,
    folder: str | Path,
    env_id: str,
    repo_id: str = "USER/REPO",
    model_name: str | None = None,
    eval_env: Any = None,
    n_eval_episodes: int = 10,
    deterministic: bool = True,
) -> Path:
    """
    Write ``folder`` ready to upload to the Hub: the model file, ``config.json``, ``results.json`` and ``README.md``.

    :param model: a trained agent of this package (``QLearning``, ``AffectQ``, ...)
    :param folder: where to write (created)
    :param env_id: the Gymnasium id of the env it was trained on
    :param repo_id: the Hub repository the card's usage code loads from
    :param model_name: name of the model file (default ``<algo>-<env id with "/" as "-">``)
    :param eval_env: env to evaluate on (default ``gym.make(env_id)``)
    :param n_eval_episodes: evaluation episodes
    :param deterministic: evaluate the greedy policy
    :return: the folder
    """
    require_extra("zoo", "packaging a model for the Hugging Face Hub")
    import gymnasium as gym
    from huggingface_sb3.push_to_hub import _evaluate_agent, _generate_config, _save_model_card, generate_metadata
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

    if n_eval_episodes < 1:
        raise ValueError(f"n_eval_episodes={n_eval_episodes} must be >= 1")
    _check_names(repo_id, model_name, env_id)
    algo = type(model).__name__
    name = model_name or f"{algo.lower()}-{env_id.replace('/', '-')}"
    env = eval_env if eval_env is not None else gym.make(env_id)
    _check_env(model, env, env_id)
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"folder={str(folder)!r} is a file; give a folder to write the model, its card and results into")
    folder.mkdir(parents=True, exist_ok=True)
    model.save(folder / name)
    _generate_config(name, folder)
    if not isinstance(env, VecEnv):
        monitored = Monitor(env)
        env = DummyVecEnv([lambda: monitored])
    mean_reward, std_reward = _evaluate_agent(model, env, n_eval_episodes, deterministic, folder)
    metadata = generate_metadata(algo, env_id, mean_reward, std_reward)
    metadata["tags"] = [*metadata["tags"], "sb3-affect", "tabular"]
    card = MODEL_CARD.format(
        algo=algo,
        env_id=env_id,
        repo_id=repo_id,
        model_name=name,
        episodes=n_eval_episodes,
        mean_reward=mean_reward,
        std_reward=std_reward,
    )
    _save_model_card(folder, card, metadata)
    return folder


__all__ = ["MODEL_CARD", "package_model"]
