"""
The old forms of a sweep file (``study: deep``, ``study: forensics``, their keys at the top level): a results folder
saved in one resumes and reads through ``new_form``; a sweep file still in one is refused by ``old_key``, which says
what to write instead.
"""

from __future__ import annotations

from typing import Any

from sb3_affect.study.launcher.schema import Sweep

#: Where each top-level key of the old deep and forensics forms went (``env`` only when it names the vec env).
MOVED = {"env": "trainer.vec_env", "obs": "trainer.obs", "n_envs": "trainer.n_envs",
         "seeds_per_batch": "trainer.seeds_per_batch", "network": "trainer.algo_kwargs", "eval_every": "evaluation.every",
         "eval_episodes": "evaluation.episodes", "screen_reps": "forensics.screen_reps", "leaders": "forensics.leaders",
         "reps": "forensics.reps", "alphas": "forensics.alphas", "gammas": "forensics.gammas",
         "protocol": "forensics.protocol"}  # fmt: skip
#: Where each key of an old deep task went.
MOVED_IN_TASKS = {"budget": "total_timesteps", "learning_rate": "tuned.learning_rate",
                  "exploration_fraction": "tuned.exploration_fraction", "count_bonus": "tuned.count_bonus"}  # fmt: skip
STUDY_KEYS = {"deep": "trainer (and evaluation)", "forensics": "forensics"}


def _old_keys(data: dict[str, Any]) -> list[tuple[str, str]]:
    """``(old key path, new key path)`` of every key of ``data`` in an old form."""
    found = [(key, new) for key, new in MOVED.items() if key in data and not (key == "env" and isinstance(data[key], dict))]
    tasks = data.get("tasks")
    for name, task in tasks.items() if isinstance(tasks, dict) else []:
        found += [(f"tasks.{name}.{key}", f"tasks.{name}.{new}") for key, new in MOVED_IN_TASKS.items()
                  if isinstance(task, dict) and key in task]  # fmt: skip
    return found


def old_key(data: dict[str, Any]) -> str | None:
    """The one line refusing a sweep file's data in an old form (which key to write instead), or None."""
    study = data.get("study")
    if "study" in data:
        instead = STUDY_KEYS.get(study, "trainer (a deep study) or forensics") if isinstance(study, str) else "trainer"
        return f"study: {study} is the old form of a sweep file; give a {instead} section instead (docs/experiment_files.md)"
    moved = _old_keys(data)
    return f"{moved[0][0]} is the old form of a sweep file's key; write {moved[0][1]}" if moved else None


def new_form(data: dict[str, Any]) -> dict[str, Any]:
    """
    A saved sweep (``sweep.json``'s ``sweep``) in the new form: one in an old form (``study: deep``, ``study:
    forensics``) with its keys moved (``MOVED``; null ones are not given), validated without imports and dumped as a
    sweep of the new form saves; any other as it is.
    """
    if data.get("study") not in STUDY_KEYS:
        return data
    top = {key: value for key, value in data.items() if key != "study"}
    if isinstance(top.get("tasks"), dict):
        top["tasks"] = {name: _moved(task, MOVED_IN_TASKS) for name, task in top["tasks"].items()}
    return Sweep.validate_saved(_moved(top, dict(_old_keys(data)))).model_dump(mode="json")


def _moved(data: dict[str, Any], moves: dict[str, str]) -> dict[str, Any]:
    """``data`` with each key of ``moves`` at its new key path (null values: not given)."""
    out: dict[str, Any] = {}
    for key, value in data.items():
        if value is None:
            continue
        *parents, last = moves.get(key, key).split(".")
        target = out
        for parent in parents:
            target = target.setdefault(parent, {})
        target[last] = value
    return out
