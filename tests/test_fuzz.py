"""
Fuzzing (hypothesis) the two kinds of file a user may be handed: sweep files and model files. Whatever the bytes,
reading one gives a valid result or one clear error (the store's or the loader's own, naming the file, no
traceback), imports no module, runs nothing, and stays within bounded time and memory.
"""

from __future__ import annotations

import contextlib
import io
import json
import resource
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sb3_affect import QLearning
from sb3_affect.agents.serialization import ModelFileError
from sb3_affect.study.launcher import SweepError, load_sweep
from sb3_affect.study.launcher.schema import Sweep
from sb3_affect.study.launcher.sweep_file import MAX_DEPTH, _StrictLoader

MEMORY_MB = 300  # growth of the peak RSS over a whole fuzz run

VALID = {
    "name": "fuzz",
    "env": {"id": "sb3_affect/GridPursuit-v0", "kwargs": {"size": 5, "goal": [2, 2]}},
    "episodes": 5,
    "seeds": 2,
    "agents": [
        {"name": "q", "algo": "QLearning", "grid": {"e": [0.1, 0.5]}, "kwargs": {"exploration_rate": "$e"}},
        {"name": "affective", "algo": "AffectQ"},
    ],
}

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=30),
    st.sampled_from(["QLearning", "AffectQ", "$e", "fuzzmod:Marker", "subprocess:Popen", "collections:OrderedDict",
                     "sb3_affect/GridPursuit-v0", "fuzzmod:Env-v0", ".hidden", "x" * 300, "1e12", "-7"]),
)
values = st.recursive(
    scalars, lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=12
)
KEY_PATHS = [
    ("name",), ("episodes",), ("seeds",), ("max_timesteps",), ("logs",), ("env",), ("env", "id"), ("env", "kwargs"),
    ("env", "kwargs", "size"), ("agents",), ("agents", 0), ("agents", 0, "name"), ("agents", 0, "algo"),
    ("agents", 0, "grid"), ("agents", 0, "grid", "e"), ("agents", 0, "kwargs"), ("agents", 0, "kwargs", "exploration_rate"),
    ("agents", 1, "team"), ("unknown",),
]


def _set(data: Any, path: tuple[Any, ...], value: Any) -> None:
    for key in path[:-1]:
        data = data[key]
    data[path[-1]] = value


@st.composite
def sweep_texts(draw: st.DrawFn) -> str:
    """A sweep file: the valid one with a few keys replaced by anything, or raw text, or YAML tricks."""
    kind = draw(st.sampled_from(["mutated", "mutated", "mutated", "raw", "yaml"]))
    if kind == "raw":
        return draw(st.text(max_size=300))
    if kind == "yaml":
        return draw(st.sampled_from([
            "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
            "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]\n"
            "e: [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\n",
            "name: x\nname: y\n",
            "a: &r [*r]\n",
            "!!python/object/apply:os.system ['echo PWNED']\n",
            "name: !!python/name:os.system\n",
            "[" * 5000,
        ]))
    data = json.loads(json.dumps(VALID))
    for path in draw(st.lists(st.sampled_from(KEY_PATHS), min_size=1, max_size=3)):
        with contextlib.suppress(KeyError, IndexError, TypeError):
            _set(data, path, draw(values))
    return yaml.safe_dump(data)


@pytest.fixture(scope="module")
def fuzzmod(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``fuzzmod``: a module whose class records any instance made of it (and whose import is recorded too)."""
    folder = tmp_path_factory.mktemp("fuzzmod")
    (folder / "fuzzmod.py").write_text(
        "import pathlib\nHERE = pathlib.Path(__file__).parent\n(HERE / 'IMPORTED').touch()\n"
        "class Marker:\n    def __init__(self, *a, **k):\n        (HERE / 'INSTANTIATED').touch()\n"
    )
    sys.path.insert(0, str(folder))
    yield folder
    sys.path.remove(str(folder))
    sys.modules.pop("fuzzmod", None)


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _new_modules(before: set[str]) -> set[str]:
    """Modules imported since ``before`` (text codecs the standard library loads on first use aside)."""
    return {name for name in set(sys.modules) - before if not name.startswith("encodings.")}


@contextlib.contextmanager
def _scanner_work() -> Iterator[dict[str, int]]:
    """Count the tokens the sweep files' YAML scanner fetches and the deepest flow level it reaches."""
    work = {"tokens": 0, "flow_level": 0}
    fetch = _StrictLoader.fetch_more_tokens

    def counted(loader: Any) -> None:
        work["tokens"] += 1
        work["flow_level"] = max(work["flow_level"], loader.flow_level)
        fetch(loader)

    _StrictLoader.fetch_more_tokens = counted  # type: ignore[method-assign]
    try:
        yield work
    finally:
        _StrictLoader.fetch_more_tokens = fetch  # type: ignore[method-assign]


def test_deep_flow_nesting_is_refused_after_max_depth_levels(tmp_path: Path) -> None:
    """Thousands of ``[`` (seconds of PyYAML's scanning): refused once ``MAX_DEPTH`` levels are open."""
    path = tmp_path / "deep.yaml"
    for opener in ("[", "{", "a: [{"):
        path.write_text(opener * 5000)
        with _scanner_work() as work, pytest.raises(SweepError, match=rf"nested deeper than {MAX_DEPTH}"):
            load_sweep(path, build=False)
        assert work["tokens"] <= 2 * MAX_DEPTH + 8 and work["flow_level"] <= MAX_DEPTH, work


def _one_clear_error(message: str, where: str) -> None:
    assert "Traceback" not in message and message.startswith(where), message
    assert all(len(line) < 2000 for line in message.splitlines()), message


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(text=sweep_texts())
def test_fuzzed_sweep_files(text: str, tmp_path: Path, fuzzmod: Path) -> None:
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    before = _peak_mb()
    with _scanner_work() as work:
        try:
            sweep = load_sweep(path, build=False)
        except SweepError as error:
            _one_clear_error(str(error), str(path))
        else:
            assert isinstance(sweep, Sweep) and sweep.cells()
    # the work is bounded by the input, not timed: at most a token per character, scanned at most MAX_DEPTH flow
    # levels deep (the scanner's work per token grows with the nesting)
    assert work["tokens"] <= len(path.read_bytes()) + 8 and work["flow_level"] <= MAX_DEPTH, work
    assert _peak_mb() - before < MEMORY_MB
    assert not (fuzzmod / "INSTANTIATED").exists(), "a class a sweep file named was instantiated"


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(data=st.data())
def test_fuzzed_saved_sweeps_import_nothing(data: st.DataObject, fuzzmod: Path) -> None:
    """A results folder's ``sweep.json`` (what ``status`` and ``report`` read) is validated without any import."""
    saved = json.loads(json.dumps(VALID))
    for path in data.draw(st.lists(st.sampled_from(KEY_PATHS), min_size=1, max_size=3)):
        with contextlib.suppress(KeyError, IndexError, TypeError):
            _set(saved, path, data.draw(values))
    sys.modules.pop("fuzzmod", None)  # (the sweep-file fuzz may have imported it: a sweep file names code to run)
    (fuzzmod / "IMPORTED").unlink(missing_ok=True)
    modules = set(sys.modules)
    with contextlib.suppress(ValueError):
        Sweep.validate_saved(saved)
    assert not _new_modules(modules), _new_modules(modules)
    assert not (fuzzmod / "IMPORTED").exists() and not (fuzzmod / "INSTANTIATED").exists()


# -- model files ---------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    model = QLearning("Grid", gym.make("sb3_affect/GridPursuit-v0"), seed=0)
    model.learn(300)
    path = tmp_path_factory.mktemp("model") / "model.zip"
    model.save(path)
    return path


def _members(raw: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(raw)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _zip(members: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return buffer.getvalue()


@st.composite
def model_files(draw: st.DrawFn, raw: bytes) -> bytes:
    """A model file with its bytes flipped or cut, a JSON entry changed to anything, or a member replaced."""
    kind = draw(st.sampled_from(["bytes", "json", "json", "member"]))
    if kind == "bytes":
        data = bytearray(raw)
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        return bytes(data[: draw(st.integers(0, len(data)))])
    members = _members(raw)
    if kind == "member":
        name = draw(st.sampled_from(sorted(members)))
        members[name] = draw(st.binary(max_size=200))
        return _zip(members)
    name = draw(st.sampled_from(["data", "sb3_affect.json"]))
    document = json.loads(members[name])
    keys = [*sorted(document), "predict", "learn", "__class__", "observation_space"]
    for key in draw(st.lists(st.sampled_from(keys), min_size=1, max_size=3)):
        document[key] = draw(values)
    if name == "sb3_affect.json" and draw(st.booleans()):
        document["observation_space"] = {"type": "Discrete", "n": draw(st.integers(1, 10**25))}
    members[name] = json.dumps(document).encode()
    return _zip(members)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(data=st.data())
def test_fuzzed_model_files(data: st.DataObject, model_file: Path, tmp_path: Path) -> None:
    path = tmp_path / "model.zip"
    path.write_bytes(data.draw(model_files(model_file.read_bytes())))
    modules = set(sys.modules)
    before = _peak_mb()
    try:
        model = QLearning.load(path)
    except ModelFileError as error:
        _one_clear_error(str(error), str(path))
        assert "\n" not in str(error)
    else:  # a file that loads is a working model
        action, _ = model.predict(0, deterministic=True)
        assert 0 <= int(action) < model.action_space.n
    assert _peak_mb() - before < MEMORY_MB
    assert not _new_modules(modules), _new_modules(modules)
