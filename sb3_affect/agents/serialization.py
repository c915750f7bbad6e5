"""
Safe model files.

SB3's ``load`` unpickles parts of a model file with cloudpickle, so opening a file from an untrusted source can run
arbitrary code (a known risk of pickle, which SB3's own docs warn about). Files saved by this package carry, next to
SB3's usual members, a plain-JSON member ``sb3_affect.json`` that describes everything SB3 pickles (spaces, policy
class, schedules, buffers). ``load_safe`` rebuilds a model from JSON and from ``policy.pth`` read with
``torch.load(weights_only=True)``: it never unpickles Python objects. A file it can not rebuild that way is refused
with an error that says how to opt in to SB3's legacy loader (``safe=False``) for a file the user trusts. SB3's own
loader still reads these files.
"""

from __future__ import annotations

import io
import json
import pathlib
import pickle
import zipfile
from collections import deque
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.utils import ConstantSchedule, FloatSchedule, LinearSchedule, check_for_correct_spaces

from sb3_affect.agents.agent_checks import MAX_TABLE_ENTRIES, check_episode_in_progress, check_table_size
from sb3_affect.agents.sb3_fields import ModelFields
from sb3_affect.core.registry import FORMER_MODULES

PLAIN_MEMBER = "sb3_affect.json"
FORMAT = 1
SPACE_KEYS = ("observation_space", "action_space")
#: The largest JSON member (``data``, ``sb3_affect.json``) a file may declare, before anything is read.
MAX_JSON_BYTES = 64 * 2**20
#: Room in ``policy.pth`` beyond the Q-table's own bytes (torch's zip container and names).
POLICY_OVERHEAD_BYTES = 2**20


#: Where ``learn`` writes, as a model holds it: set from the caller's ``load`` keywords, never from the file.
WRITE_PATHS = ("tensorboard_log", "episode_log_path")


def paths_from_caller(model: Any, given: dict[str, Any]) -> Any:
    """
    Give a loaded ``model`` the paths ``learn`` writes to (``WRITE_PATHS``: SB3's ``tensorboard_log``, the emotion
    callback's ``episode_log_path``) from ``given``, the caller's ``load`` keywords, else None, whatever the file says:
    a model file does not choose which files training appends to or which folders it creates.
    """
    model.tensorboard_log = given.get("tensorboard_log")
    callback = getattr(model, "emotion_callback", None)
    if callback is not None:
        callback.episode_log_path = given.get("episode_log_path")
    return model


class ModelFileError(ValueError):
    """A model file that is missing, corrupt, foreign or can not be loaded safely (one line: the causes quoted in it,
    torch's and zipfile's, are folded onto it)."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


# -- plain forms ------------------------------------------------------------------------------------------------------
def space_to_plain(space: spaces.Space) -> dict[str, Any]:
    if not isinstance(space, spaces.Discrete):
        raise TypeError(f"only Discrete spaces have a plain form here, got {space}")
    return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}


def space_from_plain(plain: Any, where: str) -> spaces.Discrete:
    if not isinstance(plain, dict) or plain.get("type") != "Discrete":
        raise ModelFileError(f"{where}: unsupported space description {plain!r} (tabular models use Discrete spaces)")
    n, start = plain.get("n"), plain.get("start", 0)
    if not isinstance(n, int) or isinstance(n, bool) or n < 1 or not isinstance(start, int) or isinstance(start, bool):
        raise ModelFileError(f"{where}: invalid Discrete space {plain!r}")
    if n > MAX_TABLE_ENTRIES or abs(start) > 2**62:
        raise ModelFileError(f"{where}: Discrete space of n={n:,} (start={start}) is larger than a Q-table can be")
    return spaces.Discrete(n, start=start)


def schedule_to_plain(value: Any) -> Any:
    """A float, or a dict describing an SB3 schedule object; ``None`` when the value has no plain form."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, FloatSchedule):
        inner = schedule_to_plain(value.value_schedule)
        return None if inner is None else {"type": "FloatSchedule", "inner": inner}
    if isinstance(value, ConstantSchedule):
        return {"type": "ConstantSchedule", "val": float(value.val)}
    if isinstance(value, LinearSchedule):
        return {
            "type": "LinearSchedule",
            "start": float(value.start),
            "end": float(value.end),
            "end_fraction": float(value.end_fraction),
        }
    return None


def schedule_from_plain(plain: Any, where: str) -> Any:
    if isinstance(plain, (int, float)) and not isinstance(plain, bool):
        return float(plain)
    if not isinstance(plain, dict):
        raise ModelFileError(f"{where}: invalid schedule description {plain!r}")
    kind = plain.get("type")
    try:
        if kind == "FloatSchedule":
            return FloatSchedule(schedule_from_plain(plain["inner"], where))
        if kind == "ConstantSchedule":
            return ConstantSchedule(float(plain["val"]))
        if kind == "LinearSchedule":
            return LinearSchedule(float(plain["start"]), float(plain["end"]), float(plain["end_fraction"]))
    except (KeyError, TypeError, ValueError) as error:
        raise ModelFileError(f"{where}: invalid {kind} description {plain!r} ({error})") from None
    raise ModelFileError(f"{where}: unknown schedule type {kind!r} (known: FloatSchedule, ConstantSchedule, LinearSchedule)")


def plain_json(value: Any) -> Any:
    """``value`` if it survives a strict JSON round trip unchanged in meaning; raises TypeError otherwise."""
    return json.loads(json.dumps(value, default=_numpy_default))


def _numpy_default(value: Any) -> Any:
    if isinstance(value, (np.integer, np.floating, np.bool_)):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not plain data")


# -- save ---------------------------------------------------------------------------------------------------------------
def plain_description(model: Any, data: dict[str, Any], special: Any = None, space_form: Any = None) -> dict[str, Any]:
    """
    The ``sb3_affect.json`` member for ``model``, given the JSON of SB3's ``data`` member it was saved with.
    ``special(key, value)``: the plain form of a value that only another kind of model holds (the deep agents': their
    last observations, replay buffer class, policy keywords and train frequency), or None for the forms here;
    ``space_form(space)``: how the spaces are written (default ``space_to_plain``, Discrete only).
    """
    policy_alias = next((alias for alias, cls in model.policy_aliases.items() if cls is model.policy_class), None)
    values: dict[str, Any] = {}
    derived: list[str] = []
    opaque: list[str] = []
    for key, stored in data.items():
        if not (isinstance(stored, dict) and ":serialized:" in stored) or key in (*SPACE_KEYS, "policy_class"):
            continue
        value = getattr(model, key, None)
        form = None if special is None else special(key, value)
        if form is not None:
            values[key] = form
        elif key.endswith("_schedule"):
            derived.append(key)  # rebuilt by _setup_model from the rate it schedules
        elif key in ("_last_obs", "_last_episode_starts"):
            values[key] = (
                None if value is None else {"array": np.asarray(value).tolist(), "dtype": str(np.asarray(value).dtype)}
            )
        elif isinstance(value, deque):
            try:
                values[key] = {"deque": plain_json(list(value)), "maxlen": value.maxlen}
            except TypeError:
                opaque.append(key)
        else:
            plain = schedule_to_plain(value)
            if plain is None:
                opaque.append(key)
            else:
                values[key] = {"schedule": plain}
    cls = type(model)
    space = space_form or space_to_plain
    return {
        "format": FORMAT,
        "algorithm": f"{cls.__module__}:{cls.__qualname__}",
        "policy": policy_alias,
        "observation_space": space(model.observation_space),
        "action_space": space(model.action_space),
        "values": values,
        "derived": derived,
        "opaque": opaque,
    }


def same_algorithm(saved: str, cls: type) -> bool:
    """Whether ``saved`` (``module:qualname``, as written) names ``cls``, in the module where it lives now or where it
    lived before the package's modules moved into layer folders (``registry.FORMER_MODULES``). Compared, never imported."""
    module, _, qualname = saved.rpartition(":")
    return qualname == cls.__qualname__ and FORMER_MODULES.get(module, module) == cls.__module__


def add_plain_description(path: Any, model: Any, describe: Any = None) -> None:
    """
    Append ``sb3_affect.json`` to a zip SB3 has just written at ``path`` (a path or a seekable file object):
    ``describe(model, data)`` (default ``plain_description``, the tabular models') of the ``data`` member's JSON.
    """
    if isinstance(path, (str, pathlib.Path)):
        target: Any = pathlib.Path(path)
        if target.suffix == "":
            target = pathlib.Path(f"{target}.zip")
    elif getattr(path, "closed", True) or not path.seekable():
        return  # a file object SB3 has closed: no plain description (safe loading will then refuse the file)
    else:
        target = path
        target.seek(0)
    with zipfile.ZipFile(target, "r") as archive:
        data = json.loads(archive.read("data"))
    if not isinstance(target, pathlib.Path):
        target.seek(0)
    with zipfile.ZipFile(target, "a") as archive:
        archive.writestr(PLAIN_MEMBER, json.dumps((describe or plain_description)(model, data), indent=1))


# -- load ---------------------------------------------------------------------------------------------------------------
def open_model_file(path: Any) -> tuple[zipfile.ZipFile, str]:
    if isinstance(path, (str, pathlib.Path)):
        candidate = pathlib.Path(path)
        if not candidate.exists() and candidate.suffix == "" and pathlib.Path(f"{candidate}.zip").exists():
            candidate = pathlib.Path(f"{candidate}.zip")
        where = str(candidate)
        if not candidate.exists():
            raise FileNotFoundError(f"{where}: no such model file")
        source: Any = candidate
    else:
        where, source = getattr(path, "name", "<file object>"), path
    try:
        return zipfile.ZipFile(source, "r"), str(where)
    except zipfile.BadZipFile:
        raise ModelFileError(f"{where}: not a model file (not a zip archive, or a truncated one)") from None
    except OSError as error:
        raise ModelFileError(f"{where}: can not read the model file ({error})") from None


def check_declared_size(archive: zipfile.ZipFile, name: str, limit: int, where: str) -> None:
    """Refuse a member whose declared size is over ``limit`` (a zip bomb: reading stops at the declared size)."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        return
    if info.file_size > limit:
        raise ModelFileError(
            f"{where}: the {name!r} entry expands to {info.file_size:,} bytes ({info.compress_size:,} compressed), "
            f"more than the {limit:,} a model of this size needs"
        )


def check_values(cls: Any, restored: dict[str, Any], where: str) -> None:
    """
    The saved values, checked as the constructor checks its arguments (the agent's settings class), and no saved
    entry may replace a method or property of the class (``predict: "x"``).
    """
    for key in restored:
        attribute = getattr(cls, key, None)
        if key.startswith("__") or callable(attribute) or isinstance(attribute, property):
            raise ModelFileError(f"{where}: the saved entry {key!r} names a method of {cls.__name__}, not a saved value")
    settings = getattr(cls, "settings_class", None)
    if settings is None:
        return
    given = {name: restored[name] for name in settings.names() if name in restored}
    table = given.get("behaviour_table")
    if isinstance(table, dict) and all(isinstance(k, str) for k in table):  # stored by emotion name: as given
        from sb3_affect.core.emotions import Emotion

        names = {e.name.lower(): e for e in Emotion}
        given["behaviour_table"] = {names.get(k, k): v for k, v in table.items()}
    try:
        settings(**given)
    except (TypeError, ValueError) as error:
        raise ModelFileError(f"{where}: a saved value is not allowed: {error}") from None


def read_member(archive: zipfile.ZipFile, name: str, where: str) -> bytes:
    try:
        return archive.read(name)
    except KeyError:
        raise ModelFileError(f"{where}: no {name!r} entry; not a Stable-Baselines3 model saved by sb3-affect") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as error:  # CRC errors, truncation
        raise ModelFileError(f"{where}: the {name!r} entry is corrupt ({error})") from None


def json_member(raw: bytes, name: str, where: str) -> Any:
    try:
        return json.loads(raw)
    except (ValueError, UnicodeDecodeError) as error:
        raise ModelFileError(f"{where}: the {name!r} entry is not valid JSON ({error})") from None


def load_safe(
    cls: Any,
    path: Any,
    env: Any = None,
    device: Any = "auto",
    force_reset: bool = True,
    custom_objects: dict[str, Any] | None = None,
    **kwargs: Any,
) -> Any:
    """
    Rebuild a ``cls`` model from ``path`` without unpickling anything (see the module docstring). Whatever the file
    holds, the outcome is a model or a ``ModelFileError`` naming the file (a value of the wrong type anywhere in its
    JSON included), never another exception from deep inside the rebuild.

    :param custom_objects: values replacing saved entries of the same name, as SB3 applies them: the entry is not
        read at all (a pickled one is not unpickled); names the file does not hold are ignored
    """
    where = str(path if isinstance(path, (str, pathlib.Path)) else getattr(path, "name", "<file object>"))
    try:
        return _load_safe(cls, path, env, device, force_reset, custom_objects, **kwargs)
    except (ModelFileError, FileNotFoundError):
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, RuntimeError) as error:
        if env is not None and "spaces" in str(error).lower():  # check_for_correct_spaces: the caller's env, not the file
            raise
        raise ModelFileError(f"{where}: not a model this loader can rebuild ({type(error).__name__}: {error})") from None


def _load_safe(
    cls: Any, path: Any, env: Any, device: Any, force_reset: bool, custom_objects: dict[str, Any] | None, **kwargs: Any
) -> Any:
    archive, where = open_model_file(path)
    optin = f"if you trust this file, load it with {cls.__name__}.load(path, safe=False)"
    with archive:
        names = archive.namelist()
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:  # zipfile reads the last of them, SB3's loader may read another: which one counts is ambiguous
            raise ModelFileError(f"{where}: the entry {twice[0]!r} is in the zip more than once; a model holds each once")
        for name in ("data", PLAIN_MEMBER):
            check_declared_size(archive, name, MAX_JSON_BYTES, where)
        data = json_member(read_member(archive, "data", where), "data", where)
        if not isinstance(data, dict):
            raise ModelFileError(f"{where}: the 'data' entry is not a JSON object")
        if PLAIN_MEMBER not in archive.namelist():
            raise ModelFileError(
                f"{where}: no plain-data description ({PLAIN_MEMBER}): the file was not saved by sb3-affect, so loading "
                f"it means unpickling code from it, which safe loading refuses; {optin}"
            )
        twin = json_member(read_member(archive, PLAIN_MEMBER, where), PLAIN_MEMBER, where)
        if not isinstance(twin, dict) or twin.get("format") != FORMAT:
            raise ModelFileError(
                f"{where}: unsupported {PLAIN_MEMBER} format {twin.get('format') if isinstance(twin, dict) else twin!r}"
            )
        observation_space = space_from_plain(twin.get("observation_space"), where)
        action_space = space_from_plain(twin.get("action_space"), where)
        try:
            check_table_size(observation_space.n, action_space.n, f"{where}: observation space {observation_space}")
        except ValueError as error:
            raise ModelFileError(str(error)) from None
        table_bytes = int(observation_space.n) * int(action_space.n) * 8
        check_declared_size(archive, "policy.pth", table_bytes + POLICY_OVERHEAD_BYTES, where)
        policy_bytes = read_member(archive, "policy.pth", where)
        if len(policy_bytes) < table_bytes > POLICY_OVERHEAD_BYTES:  # torch stores a tensor's bytes whole: a large
            # table the file declares and does not hold is refused before it is allocated
            raise ModelFileError(
                f"{where}: policy.pth holds {len(policy_bytes):,} bytes, fewer than the {table_bytes:,} of the "
                f"{observation_space.n} x {action_space.n} Q-table the file declares"
            )
    if not same_algorithm(str(twin.get("algorithm", "")), cls):
        saved = str(twin.get("algorithm", "?")).rpartition(":")[2]
        raise ModelFileError(f"{where}: this file holds a {saved} model; load it with {saved}.load (not {cls.__name__}.load)")
    policy_class = cls.policy_aliases.get(twin.get("policy"))
    if policy_class is None:
        raise ModelFileError(
            f"{where}: policy {twin.get('policy')!r} is not one of {sorted(cls.policy_aliases)}; a custom policy class "
            f"can only be unpickled; {optin}"
        )
    values, derived = twin.get("values", {}), set(twin.get("derived", []))
    restored: dict[str, Any] = {}
    custom = custom_objects or {}
    for key, stored in data.items():
        if key in custom:
            restored[key] = custom[key]
        elif not (isinstance(stored, dict) and ":serialized:" in stored):
            restored[key] = stored
        elif key in (*SPACE_KEYS, "policy_class") or key in derived:
            continue
        elif key in values:
            restored[key] = _rebuild(key, values[key], where)
        else:
            kind = stored.get(":type:", "a Python object")
            raise ModelFileError(f"{where}: entry {key!r} is pickled Python ({kind}) with no plain-data form; {optin}")
    if "policy_kwargs" in restored and not isinstance(restored["policy_kwargs"], dict):
        raise ModelFileError(f"{where}: policy_kwargs must be a JSON object")
    (restored.get("policy_kwargs") or {}).pop("device", None)
    check_values(cls, {k: v for k, v in restored.items() if k not in custom}, where)  # the file's, not the caller's
    if custom:
        checked = dict(restored)
        rate = custom.get("learning_rate")
        if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate == 0:  # SB3's and rl-zoo3's way of
            del checked["learning_rate"]  # loading for inference only: no learning
        try:
            check_values(cls, checked, where)
        except ModelFileError as error:
            reason = str(error).removeprefix(f"{where}: a saved value is not allowed: ")
            raise ModelFileError(f"{where}: custom_objects: a value is not allowed: {reason}") from None
    try:
        check_episode_in_progress(
            restored.get("_episode_state"), restored.get("_last_obs"), int(observation_space.n), int(observation_space.start)
        )
    except ValueError as error:
        raise ModelFileError(f"{where}: {error}") from None

    if env is not None:
        env = cls._wrap_env(env, restored.get("verbose", 0))
        check_for_correct_spaces(env, observation_space, action_space)
        if force_reset:
            restored["_last_obs"] = None
        restored["n_envs"] = env.num_envs
    model = cls(policy=policy_class, env=env, device=device, _init_setup_model=False)
    model.__dict__.update(restored)
    model.__dict__.update({key: value for key, value in kwargs.items() if key not in WRITE_PATHS})
    model.observation_space, model.action_space, model.policy_class = observation_space, action_space, policy_class
    ModelFields(model).setup_model()
    paths_from_caller(model, kwargs)
    try:
        state = th.load(io.BytesIO(policy_bytes), map_location=model.device, weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, ValueError) as error:
        raise ModelFileError(
            f"{where}: policy.pth is not plain tensor data, refused by weights-only loading ({error}); {optin}"
        ) from None
    weird = next((k for k, v in state.items() if not isinstance(v, th.Tensor) or not v.is_floating_point()), None)
    if weird is not None:
        raise ModelFileError(f"{where}: policy.pth entry {weird!r} is not a tensor of real numbers (float)")
    broken = next((k for k, v in state.items() if not bool(th.isfinite(v).all())), None)
    if broken is not None:
        raise ModelFileError(f"{where}: policy.pth entry {broken!r} holds NaN or infinite values; Q-values are finite numbers")
    try:
        model.policy.load_state_dict(state, strict=True)
    except (RuntimeError, TypeError, AttributeError) as error:
        raise ModelFileError(f"{where}: policy.pth does not fit a {cls.__name__} Q-table policy ({error})") from None
    return model


def _rebuild(key: str, plain: Any, where: str) -> Any:
    if plain is None:
        return None
    if not isinstance(plain, dict):
        raise ModelFileError(f"{where}: invalid plain form for {key!r}")
    if "array" in plain:
        dtype = str(plain.get("dtype", "float64"))
        if dtype not in ("int64", "int32", "bool", "float64", "float32", "uint8"):
            raise ModelFileError(f"{where}: {key!r} has an unsupported dtype {dtype!r}")
        return np.asarray(plain["array"], dtype=dtype)
    if "deque" in plain:
        maxlen = plain.get("maxlen")
        return deque(plain["deque"], maxlen=maxlen if isinstance(maxlen, int) else None)
    if "schedule" in plain:
        return schedule_from_plain(plain["schedule"], f"{where}: {key}")
    raise ModelFileError(f"{where}: invalid plain form for {key!r}")


__all__ = ["PLAIN_MEMBER", "WRITE_PATHS", "ModelFileError", "add_plain_description", "load_safe", "paths_from_caller"]
