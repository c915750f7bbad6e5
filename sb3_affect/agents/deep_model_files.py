"""
Safe model files for the deep agents (``AffectDQN``, ``AffectQRDQN`` and the controls of ``deep_controls``), as the
tabular agents have (``sb3_affect.agents.serialization``): ``save`` adds a plain-JSON member describing everything SB3
pickles (spaces, policy class, replay buffer class, train frequency, the last observations, the episode buffers;
the schedules are rebuilt from the rates they schedule), and ``load`` rebuilds the model from it and from the ``.pth``
members read with ``torch.load(weights_only=True)``: nothing in the file is unpickled unless the caller asks for SB3's
own loader by name (``load(path, safe=False)``). Every value read is checked as the constructor checks it (the agent's
``_setup_model`` checks its options again), and anything wrong is one ``ModelFileError`` line naming the file. The
weights are read only after the model is built from the file's settings: a ``.pth`` member the model does not save, or
one whose declared size is past what the model's own tensors take (``_weights_bounds``), is refused before a byte of
it is read (a small file whose member expands to gigabytes of zeros allocates nothing). The model's paths where
``learn`` writes (``tensorboard_log``, the emotion callback's ``episode_log_path``) are the caller's, never the file's.
"""

from __future__ import annotations

import io
import math
import pickle
from collections import deque
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer
from stable_baselines3.common.torch_layers import CombinedExtractor, FlattenExtractor, NatureCNN
from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit
from stable_baselines3.common.utils import check_for_correct_spaces

from sb3_affect.agents.sb3_fields import ModelFields
from sb3_affect.agents.serialization import (
    FORMAT,
    MAX_JSON_BYTES,
    PLAIN_MEMBER,
    SPACE_KEYS,
    WRITE_PATHS,
    ModelFileError,
    add_plain_description,
    check_declared_size,
    check_values,
    json_member,
    open_model_file,
    paths_from_caller,
    plain_description,
    plain_json,
    read_member,
    same_algorithm,
    schedule_from_plain,
)

#: Replay buffer classes a file names.
BUFFERS: dict[str, type] = {"ReplayBuffer": ReplayBuffer, "DictReplayBuffer": DictReplayBuffer}
#: Classes ``policy_kwargs`` may name (SB3's features extractors, torch's optimizers and activations), by their name.
KNOWN_CLASSES: dict[str, type] = {
    f"{cls.__module__}.{cls.__qualname__}": cls
    for cls in (
        th.optim.Adam, th.optim.AdamW, th.optim.RMSprop, th.optim.SGD, th.nn.ReLU, th.nn.Tanh, th.nn.ELU, th.nn.LeakyReLU,
        th.nn.GELU, th.nn.SiLU, th.nn.Sigmoid, FlattenExtractor, NatureCNN, CombinedExtractor,
    )
}
#: Array dtypes a file's arrays may have.
DTYPES = ("float64", "float32", "float16", "int64", "int32", "int16", "int8", "uint8", "bool")
#: The most numbers a space's bounds or a saved array may hold.
MAX_ENTRIES = 10_000_000
#: A weights member's bound (``_weights_bounds``): an optimizer's state per parameter (Adam with amsgrad, RMSprop:
#: three tensors of its shape), torch's bytes per tensor (its record's name and metadata) and per member (the zip).
OPTIMIZER_STATES = 3
TENSOR_OVERHEAD_BYTES = 4096
CONTAINER_BYTES = 2**20
#: Names of the keys ``_setup_model`` rebuilds (never read from the file).
_OBSERVATIONS = ("_last_obs", "_last_original_obs", "_last_episode_starts")


# -- plain forms -------------------------------------------------------------------------------------------------------
def space_to_plain(space: spaces.Space) -> dict[str, Any]:
    """A Box, Discrete, MultiDiscrete, MultiBinary or Dict space as plain data; a TypeError for any other."""
    if isinstance(space, spaces.Box):
        return {"type": "Box", "low": space.low.tolist(), "high": space.high.tolist(), "shape": list(space.shape),
                "dtype": str(space.dtype)}
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, spaces.MultiDiscrete):
        return {"type": "MultiDiscrete", "nvec": space.nvec.tolist(), "start": np.asarray(space.start).tolist()}
    if isinstance(space, spaces.MultiBinary):
        return {"type": "MultiBinary", "n": np.asarray(space.n).tolist()}
    if isinstance(space, spaces.Dict):
        return {"type": "Dict", "spaces": {str(key): space_to_plain(inner) for key, inner in space.spaces.items()}}
    raise TypeError(f"a {type(space).__name__} space has no plain form here")


def _int(value: Any, what: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ModelFileError(f"{what}={value!r} must be an integer in [{low:,}, {high:,}]")
    return value


def _shape(value: Any, what: str) -> tuple[int, ...]:
    if not isinstance(value, list) or not 1 <= len(value) <= 8:
        raise ModelFileError(f"{what}: shape {value!r} must be a list of 1 to 8 sizes")
    shape = tuple(_int(n, f"{what}: a size", 1, MAX_ENTRIES) for n in value)
    if math.prod(shape) > MAX_ENTRIES:
        raise ModelFileError(f"{what}: shape {value!r} holds more than {MAX_ENTRIES:,} numbers")
    return shape


def space_from_plain(plain: Any, where: str, depth: int = 0) -> spaces.Space:
    """The space ``space_to_plain`` wrote, checked (a ``ModelFileError`` naming what is wrong)."""
    what = f"{where}: space"
    if not isinstance(plain, dict):
        raise ModelFileError(f"{what} {str(plain)[:80]!r} is not a space description")
    kind = plain.get("type")
    try:
        if kind == "Box":
            shape = _shape(plain.get("shape"), what)
            dtype = plain.get("dtype")
            if dtype not in DTYPES:
                raise ModelFileError(f"{what}: Box dtype {dtype!r} is not one of {', '.join(DTYPES)}")
            low, high = (np.asarray(plain.get(b), dtype=np.float64) for b in ("low", "high"))
            if low.shape != shape or high.shape != shape:
                raise ModelFileError(f"{what}: Box bounds do not have the shape {list(shape)}")
            return spaces.Box(low=low.astype(dtype), high=high.astype(dtype), shape=shape, dtype=dtype)
        if kind == "Discrete":
            return spaces.Discrete(_int(plain.get("n"), f"{what}: n", 1, 2**62),
                                   start=_int(plain.get("start", 0), f"{what}: start", -(2**62), 2**62))
        if kind == "MultiDiscrete":
            nvec = np.asarray(plain.get("nvec"), dtype=np.int64)
            start = np.asarray(plain.get("start", 0), dtype=np.int64)
            if nvec.size > MAX_ENTRIES or (nvec < 1).any() or (np.abs(start) > 2**62).any():
                raise ModelFileError(f"{what}: MultiDiscrete nvec must hold integers >= 1")
            return spaces.MultiDiscrete(nvec, start=start if start.shape == nvec.shape else None)
        if kind == "MultiBinary":
            n = plain.get("n")
            return spaces.MultiBinary(list(_shape(n, what)) if isinstance(n, list) else _int(n, f"{what}: n", 1, MAX_ENTRIES))
        if kind == "Dict" and depth < 4:
            inner = plain.get("spaces")
            if not isinstance(inner, dict) or not inner or len(inner) > 64:
                raise ModelFileError(f"{what}: a Dict space needs 1 to 64 named spaces")
            return spaces.Dict({str(key): space_from_plain(value, where, depth + 1) for key, value in inner.items()})
    except (TypeError, ValueError, OverflowError) as error:
        if isinstance(error, ModelFileError):
            raise
        raise ModelFileError(f"{what}: invalid {kind} description ({error})") from None
    raise ModelFileError(f"{what}: unsupported space type {kind!r} (Box, Discrete, MultiDiscrete, MultiBinary, Dict)")


def _array_to_plain(value: Any) -> Any:
    if value is None:
        return None
    if isinstance(value, dict):
        return {"dict": {str(key): _array_to_plain(inner) for key, inner in value.items()}}
    array = np.asarray(value)
    return {"array": array.tolist(), "dtype": str(array.dtype), "shape": list(array.shape)}


def _array_from_plain(plain: Any, what: str, depth: int = 0) -> Any:
    if plain is None:
        return None
    if isinstance(plain, dict) and "dict" in plain and isinstance(plain["dict"], dict) and depth < 4:
        return {str(key): _array_from_plain(inner, what, depth + 1) for key, inner in plain["dict"].items()}
    if not isinstance(plain, dict) or "array" not in plain:
        raise ModelFileError(f"{what}: not an array description")
    dtype = plain.get("dtype")
    if dtype not in DTYPES:
        raise ModelFileError(f"{what}: dtype {dtype!r} is not one of {', '.join(DTYPES)}")
    try:
        array = np.asarray(plain["array"], dtype=dtype)
    except (TypeError, ValueError, OverflowError) as error:
        raise ModelFileError(f"{what}: not an array of {dtype} ({error})") from None
    if array.size > MAX_ENTRIES:
        raise ModelFileError(f"{what}: more than {MAX_ENTRIES:,} numbers")
    return array


def _kwargs_to_plain(value: Any) -> Any:
    """``policy_kwargs`` with the classes it names as ``{"class": name}``; None when something has no plain form."""
    if isinstance(value, type):
        name = f"{value.__module__}.{value.__qualname__}"
        return {"class": name} if KNOWN_CLASSES.get(name) is value else None
    if isinstance(value, dict):
        plain = {str(key): _kwargs_to_plain(inner) for key, inner in value.items()}
        return None if any(v is None and value[k] is not None for k, v in zip(value, plain.values())) else plain
    if isinstance(value, (list, tuple)):
        items = [_kwargs_to_plain(inner) for inner in value]
        return None if any(v is None and x is not None for v, x in zip(items, value)) else {"sequence": items}
    try:
        return plain_json(value)
    except TypeError:
        return None


def _kwargs_from_plain(plain: Any, what: str, depth: int = 0) -> Any:
    if depth > 8:
        raise ModelFileError(f"{what}: nested too deep")
    if isinstance(plain, dict) and set(plain) == {"class"}:
        cls = KNOWN_CLASSES.get(plain["class"])
        if cls is None:
            raise ModelFileError(f"{what}: class {plain['class']!r} is not one of {', '.join(KNOWN_CLASSES)}")
        return cls
    if isinstance(plain, dict) and set(plain) == {"sequence"} and isinstance(plain["sequence"], list):
        return [_kwargs_from_plain(inner, what, depth + 1) for inner in plain["sequence"]]
    if isinstance(plain, dict):
        return {key: _kwargs_from_plain(inner, what, depth + 1) for key, inner in plain.items()}
    return plain


def deep_description(model: Any, data: dict[str, Any]) -> dict[str, Any]:
    """The plain-JSON member for a deep ``model``, given the JSON of SB3's ``data`` member it was saved with: the tabular
    models' (``plain_description``) with the deep agents' own values and any space ``space_to_plain`` writes."""
    return plain_description(model, data, special=_deep_value, space_form=space_to_plain)


def _deep_value(key: str, value: Any) -> dict[str, Any] | None:
    """The plain form of a value only the deep agents hold, or None (then the tabular models' forms apply)."""
    if key in _OBSERVATIONS:
        return {"observation": _array_to_plain(value)}
    buffer = next((name for name, cls in BUFFERS.items() if value is cls), None)
    if buffer is not None:
        return {"buffer": buffer}
    kwargs = _kwargs_to_plain(value) if key == "policy_kwargs" else None
    if kwargs is not None:
        return {"policy_kwargs": kwargs}
    if isinstance(value, TrainFreq):
        return {"train_freq": [int(value.frequency), TrainFrequencyUnit(value.unit).value]}
    return None


def _rebuild(key: str, plain: Any, where: str) -> Any:
    what = f"{where}: {key}"
    if not isinstance(plain, dict):
        raise ModelFileError(f"{what}: invalid plain form")
    if "observation" in plain:
        return _array_from_plain(plain["observation"], what)
    if "deque" in plain:
        items, maxlen = plain["deque"], plain.get("maxlen")
        if not isinstance(items, list) or not (maxlen is None or (isinstance(maxlen, int) and 0 <= maxlen <= MAX_ENTRIES)):
            raise ModelFileError(f"{what}: invalid deque")
        return deque(items, maxlen=maxlen)
    if "buffer" in plain:
        if plain["buffer"] not in BUFFERS:
            raise ModelFileError(f"{what}: replay buffer {plain['buffer']!r} is not one of {', '.join(BUFFERS)}")
        return BUFFERS[plain["buffer"]]
    if "policy_kwargs" in plain:
        return _kwargs_from_plain(plain["policy_kwargs"], what)
    if "train_freq" in plain:
        pair = plain["train_freq"]
        if not isinstance(pair, list) or len(pair) != 2 or pair[1] not in {u.value for u in TrainFrequencyUnit}:
            raise ModelFileError(f"{what}: invalid train frequency {pair!r}")
        return TrainFreq(_int(pair[0], what, 1, 2**62), TrainFrequencyUnit(pair[1]))
    if "schedule" in plain:
        return schedule_from_plain(plain["schedule"], what)
    raise ModelFileError(f"{what}: invalid plain form")


# -- save and load ----------------------------------------------------------------------------------------------------
def add_deep_description(path: Any, model: Any) -> None:
    """Append the plain description to the zip SB3 has just written at ``path``."""
    add_plain_description(path, model, describe=deep_description)


def load_deep_safe(cls: Any, path: Any, env: Any = None, device: Any = "auto", force_reset: bool = True,
                   custom_objects: dict[str, Any] | None = None, **kwargs: Any) -> Any:
    """
    Rebuild a deep ``cls`` model from ``path`` without unpickling anything (see the module docstring): a model, or a
    ``ModelFileError`` naming the file, whatever the file holds.
    """
    where = str(path if isinstance(path, str) or hasattr(path, "__fspath__") else getattr(path, "name", "<file object>"))
    try:
        return _load(cls, path, where, env, device, force_reset, custom_objects, **kwargs)
    except (ModelFileError, FileNotFoundError):
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, RuntimeError, MemoryError) as error:
        if env is not None and "spaces" in str(error).lower():  # check_for_correct_spaces: the caller's env, not the file
            raise
        message = " ".join(str(error).split())
        raise ModelFileError(f"{where}: not a model this loader can rebuild ({type(error).__name__}: {message})") from None


def _load(cls: Any, path: Any, where: str, env: Any, device: Any, force_reset: bool,
          custom_objects: dict[str, Any] | None, **kwargs: Any) -> Any:
    archive, where = open_model_file(path)
    with archive:  # open while the model is built: its weights are read once their bounds are known
        return _load_open(archive, cls, where, env, device, force_reset, custom_objects, **kwargs)


def _weights_bounds(model: Any) -> dict[str, int]:
    """
    The most bytes each ``.pth`` member of a file may declare for ``model`` (built from the file's settings): the
    bytes of the tensors the model holds there (an optimizer's state: ``OPTIMIZER_STATES`` times its parameters'),
    plus room for torch's container. A member past its bound is refused before a byte of it is read.
    """
    names, variables = ModelFields(model).torch_save_params()
    bounds: dict[str, int] = {}
    for name in [*names, "pytorch_variables"]:
        if name == "pytorch_variables":
            tensors = [_attribute(model, variable) for variable in variables or []]
            factor = 1
        else:
            target = _attribute(model, name)
            if isinstance(target, th.optim.Optimizer):
                tensors, factor = [p for group in target.param_groups for p in group["params"]], OPTIMIZER_STATES
            else:
                tensors, factor = list(target.state_dict().values()), 1
        sizes = [t.numel() * t.element_size() for t in tensors if isinstance(t, th.Tensor)]
        bounds[f"{name}.pth"] = factor * sum(sizes) + (factor + 1) * TENSOR_OVERHEAD_BYTES * len(sizes) + CONTAINER_BYTES
    return bounds


def _attribute(model: Any, dotted: str) -> Any:
    target = model
    for part in dotted.split("."):
        target = getattr(target, part)
    return target


def _load_open(archive: Any, cls: Any, where: str, env: Any, device: Any, force_reset: bool,
               custom_objects: dict[str, Any] | None, **kwargs: Any) -> Any:
    optin = f"if you trust this file, load it with {cls.__name__}.load(path, safe=False)"
    names = archive.namelist()
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise ModelFileError(f"{where}: the entry {twice[0]!r} is in the zip more than once; a model holds each once")
    for name in ("data", PLAIN_MEMBER):
        check_declared_size(archive, name, MAX_JSON_BYTES, where)
    data = json_member(read_member(archive, "data", where), "data", where)
    if not isinstance(data, dict):
        raise ModelFileError(f"{where}: the 'data' entry is not a JSON object")
    if PLAIN_MEMBER not in names:
        raise ModelFileError(
            f"{where}: no plain-data description ({PLAIN_MEMBER}): the file was not saved by sb3-affect, so loading "
            f"it means unpickling code from it, which safe loading refuses; {optin}"
        )
    twin = json_member(read_member(archive, PLAIN_MEMBER, where), PLAIN_MEMBER, where)
    if not isinstance(twin, dict) or twin.get("format") != FORMAT:
        raise ModelFileError(f"{where}: unsupported {PLAIN_MEMBER} format")
    if not same_algorithm(str(twin.get("algorithm", "")), cls):
        saved = str(twin.get("algorithm", "?")).rpartition(":")[2]
        raise ModelFileError(f"{where}: this file holds a {saved} model; load it with {saved}.load (not {cls.__name__}.load)")
    policy_class = cls.policy_aliases.get(twin.get("policy"))
    if policy_class is None:
        raise ModelFileError(
            f"{where}: policy {twin.get('policy')!r} is not one of {sorted(cls.policy_aliases)}; a custom policy class "
            f"can only be unpickled; {optin}"
        )
    observation_space = space_from_plain(twin.get("observation_space"), where)
    action_space = space_from_plain(twin.get("action_space"), where)
    values = twin.get("values", {})
    derived = twin.get("derived", [])
    if not isinstance(values, dict) or not isinstance(derived, list):
        raise ModelFileError(f"{where}: {PLAIN_MEMBER} values must be an object and derived a list")
    custom = custom_objects or {}
    restored: dict[str, Any] = {}
    for key, stored in data.items():
        if key in custom:
            restored[key] = custom[key]
        elif not (isinstance(stored, dict) and ":serialized:" in stored):
            restored[key] = stored
        elif key in (*SPACE_KEYS, "policy_class") or (key in derived and key.endswith("_schedule")):
            continue
        elif key in values:
            restored[key] = _rebuild(key, values[key], where)
        else:
            kind = stored.get(":type:", "a Python object")
            raise ModelFileError(f"{where}: entry {key!r} is pickled Python ({kind}) with no plain-data form; {optin}")
    if "policy_kwargs" in restored and not isinstance(restored["policy_kwargs"], dict):
        raise ModelFileError(f"{where}: policy_kwargs must be a JSON object")
    (restored.get("policy_kwargs") or {}).pop("device", None)
    check_values(cls, restored, where)
    if env is not None:
        env = cls._wrap_env(env, restored.get("verbose", 0))
        check_for_correct_spaces(env, observation_space, action_space)
        if force_reset:
            restored["_last_obs"] = None
        restored["n_envs"] = env.num_envs
    if isinstance(restored.get("_affect_state"), dict):  # the emotion callback's: its path is the caller's
        restored["_affect_state"] = {**restored["_affect_state"], "episode_log_path": None}
    model = cls(policy=policy_class, env=env, device=device, _init_setup_model=False)
    model.__dict__.update(restored)
    model.__dict__.update({key: value for key, value in kwargs.items() if key not in WRITE_PATHS})
    model.observation_space, model.action_space, model.policy_class = observation_space, action_space, policy_class
    try:
        ModelFields(model).setup_model()  # the agent's options checked again, as the constructor checks them
    except (TypeError, ValueError) as error:
        raise ModelFileError(f"{where}: a saved value is not allowed: {' '.join(str(error).split())}") from None
    paths_from_caller(model, kwargs)
    bounds = _weights_bounds(model)
    members = [name for name in names if name.endswith(".pth")]
    other = next((name for name in members if name not in bounds), None)
    if other is not None:
        raise ModelFileError(f"{where}: the entry {other!r} is not one of the model's weights ({', '.join(bounds)})")
    for name in members:
        check_declared_size(archive, name, bounds[name], where)
    weights = {name[: -len(".pth")]: read_member(archive, name, where) for name in members}
    params: dict[str, Any] = {}
    for name, raw in weights.items():
        try:
            params[name] = th.load(io.BytesIO(raw), map_location=model.device, weights_only=True)
        except (pickle.UnpicklingError, RuntimeError, EOFError, ValueError) as error:
            message = " ".join(str(error).split())[:300]
            raise ModelFileError(f"{where}: {name}.pth is not plain tensor data, refused by weights-only loading "
                                 f"({message}); {optin}") from None
    variables = params.pop("pytorch_variables", None)
    try:
        model.set_parameters(params, exact_match=True, device=model.device)
    except (RuntimeError, ValueError, KeyError, TypeError, AttributeError) as error:
        message = " ".join(str(error).split())[:300]
        raise ModelFileError(f"{where}: the weights do not fit a {cls.__name__} with the saved settings ({message})") from None
    _, variable_names = ModelFields(model).torch_save_params()
    if variable_names and not isinstance(variables, dict):
        raise ModelFileError(f"{where}: pytorch_variables.pth is missing or not a mapping of tensors")
    for name in variable_names or []:
        value = variables.get(name) if isinstance(variables, dict) else None
        target = _attribute(model, name)
        if not isinstance(value, th.Tensor) or not isinstance(target, th.Tensor) or value.shape != target.shape:
            raise ModelFileError(f"{where}: pytorch_variables.pth has no tensor {name!r} of the model's shape")
        target.data = value.data
    return model
