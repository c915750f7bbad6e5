"""
``ModelFiles``: what a tabular model's ``save`` and ``load`` add to SB3's. The agent's random generator and run state
are stored as plain data, the episode log as a list of rows; loading unpickles nothing by default
(``sb3_affect.agents.serialization.load_safe``).
"""

from __future__ import annotations

import contextlib
import importlib
import random
import sys
from collections.abc import Iterator
from typing import Any, TypeVar

import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.type_aliases import GymEnv

from sb3_affect.agents.serialization import WRITE_PATHS, add_plain_description, load_safe, paths_from_caller
from sb3_affect.core.episode_blocks import EpisodeBlocks
from sb3_affect.core.registry import FORMER_MODULES

SelfFiles = TypeVar("SelfFiles", bound="ModelFiles")


@contextlib.contextmanager
def _former_module_names() -> Iterator[None]:
    """SB3's legacy loader unpickles classes by module name: for files pickled before the package's modules moved into
    layer folders, the former names (``registry.FORMER_MODULES``) stand for the modules while it runs."""
    added = [name for name in FORMER_MODULES if name not in sys.modules]
    for name in added:
        sys.modules[name] = importlib.import_module(FORMER_MODULES[name])
    try:
        yield
    finally:
        for name in added:
            sys.modules.pop(name, None)

__all__ = ["ModelFiles"]


class ModelFiles(BaseAlgorithm):
    """The save and load of ``TabularQAlgorithm`` (its base class; it defines what is declared here)."""

    _rng: random.Random
    _rng_state: list[Any] | None
    _episode_blocks: EpisodeBlocks

    def _sync_policy(self) -> None:
        """Write the loop's Q-table into the policy's tensor (``TabularQAlgorithm``)."""
        raise NotImplementedError

    def save(self, path: Any, exclude: Any = None, include: Any = None) -> None:
        """Save as SB3 does; the agent's random generator and run state are stored as plain data."""
        self._sync_policy()
        version, internal, gauss = self._rng.getstate()
        self._rng_state = [version, list(internal), gauss]
        self._episode_rows = self._episode_blocks.rows()  # the file's form of the episode log: a list of rows
        try:
            super().save(path, exclude=exclude, include=include)
            add_plain_description(path, self)
        finally:
            self._rng_state = None
            del self._episode_rows

    @classmethod
    def load(
        cls: type[SelfFiles],
        path: Any,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        safe: bool = True,
        **kwargs: Any,
    ) -> SelfFiles:
        """
        Load a model saved with ``save``.

        By default (``safe=True``) nothing in the file is unpickled: spaces, schedules and buffers are rebuilt from the
        file's plain-JSON description and the Q-table is read with ``torch.load(weights_only=True)``; files that need
        unpickling (saved by other code, custom policies or schedules) are refused with a ``ModelFileError``.
        ``safe=False`` uses SB3's legacy loader, which runs pickled code: only for files you trust.

        :param path: the model file (``.zip`` may be left out)
        :param env: the env to continue training on (its spaces must match); None to only predict
        :param device: torch device
        :param custom_objects: values replacing saved entries of the same name (as SB3 applies them; the safe loader
            never unpickles the replaced entry), e.g. rl-zoo3's ``{"learning_rate": 0.0, "lr_schedule": ...}``
        :param print_system_info: legacy loader only: print the saving and the current system info
        :param force_reset: reset the env before the next ``learn`` (SB3 convention)
        :param safe: load without unpickling (default); False for SB3's legacy loader
        :param kwargs: attributes to change on the loaded model; ``tensorboard_log`` is None unless given here, whatever
            the file says (a model file does not choose where ``learn`` writes)
        :return: the loaded model
        """
        if not safe:
            with _former_module_names():
                model = super().load(
                    path,
                    env=env,
                    device=device,
                    custom_objects=custom_objects,
                    print_system_info=print_system_info,
                    force_reset=force_reset,
                    **{key: value for key, value in kwargs.items() if key not in WRITE_PATHS},
                )
            return paths_from_caller(model, kwargs)
        return load_safe(cls, path, env=env, device=device, force_reset=force_reset, custom_objects=custom_objects, **kwargs)
