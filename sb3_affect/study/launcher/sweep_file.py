"""
Reading a sweep file: ``load_sweep_file`` parses the YAML, applies ``--set key.path=value`` overrides (each checked
against the schema of ``schema``, nested sections too, e.g. ``--set evaluation.every=1000``, naming the keys allowed
where one is unknown), validates the result and turns every problem into one ``SweepError`` that
names the file, the key (agents by name) and whether the file or an override caused it; for a sweep of runs
(``load_sweep``) it then builds the env and each agent once, so that a bad kwarg is reported before anything runs.

The YAML is read strictly: a key given twice in one mapping is an error (not "the last wins"), and a file that
expands to more than ``MAX_VALUES`` values (YAML aliases repeat what they name: a few hundred bytes can stand for
billions) or nests deeper than ``MAX_DEPTH`` is refused before anything walks it.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from sb3_affect.study.launcher.deep_schema import EvaluationSpec, TrainerSpec
from sb3_affect.study.launcher.old_forms import MOVED, old_key
from sb3_affect.study.launcher.one_run import check_configs_in_child
from sb3_affect.study.launcher.schema import (
    KIND_KEYS,
    KINDS,
    KWARG_REFERENCE,
    AgentSpec,
    EnvSpec,
    ForensicsSpec,
    ProtocolSpec,
    Sweep,
    SweepError,
    kind_of,
)
from sb3_affect.study.studies import shipped_sweeps_folder

__all__ = ["load_sweep", "load_sweep_file", "resolve_sweep_path", "shipped_sweeps"]


def shipped_sweeps() -> dict[str, Path]:
    """The sweep files installed with the package, by name (``paper``, ``smoke``, ...)."""
    return {path.stem: path for path in sorted(shipped_sweeps_folder().glob("*.yaml"))}


def resolve_sweep_path(path: str | Path) -> Path:
    """
    The file a sweep argument names: an existing path as it is; otherwise the shipped sweep of that name, given
    by name (``paper``) or by its path in the source tree (``experiments/paper.yaml``, which works from an
    installed wheel in any folder). Anything else is returned unchanged (``load_sweep`` says it can not be read).
    """
    given = Path(path)
    if given.exists():
        return given
    shipped = shipped_sweeps()
    by_name = given.suffix == "" and len(given.parts) == 1
    by_source_path = given.suffix in (".yaml", ".yml") and given.parts[:-1] == ("experiments",)
    if (by_name or by_source_path) and given.stem in shipped:
        return shipped[given.stem]
    return given

#: Limits of a sweep file: its size in bytes, the values it expands to (aliases counted each time) and its nesting.
MAX_BYTES, MAX_VALUES, MAX_DEPTH = 1_000_000, 100_000, 50


class _StrictLoader(yaml.SafeLoader):
    """
    PyYAML's safe loader, refusing a key given twice in one mapping (merge keys ``<<`` aside) and flow collections
    (``[``, ``{``) nested deeper than ``MAX_DEPTH`` as it scans them: the scanner's work per token grows with the
    nesting, so a file of thousands of ``[`` would otherwise take seconds before any check could refuse it.
    """

    def fetch_flow_collection_start(self, TokenClass: Any) -> None:  # (PyYAML's name)
        if self.flow_level >= MAX_DEPTH:
            raise yaml.scanner.ScannerError(None, None, f"nested deeper than {MAX_DEPTH}", self.get_mark())
        super().fetch_flow_collection_start(TokenClass)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Hashable, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge" or not isinstance(key_node, yaml.ScalarNode):
                continue
            key = self.construct_object(key_node)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first given at line {seen[key] + 1})", key_node.start_mark
                )
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


def _check_size(data: Any, where: str) -> None:
    """Refuse data that expands to more than ``MAX_VALUES`` values or nests deeper than ``MAX_DEPTH`` (iteratively)."""
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    count = 0
    while stack:
        value, key, depth = stack.pop()
        count += 1
        if count > MAX_VALUES or depth > MAX_DEPTH:
            what = f"more than {MAX_VALUES:,} values" if count > MAX_VALUES else f"nesting deeper than {MAX_DEPTH}"
            raise SweepError(
                f"{where}: {key or '(top level)'}: the file expands to {what} (YAML aliases repeat what they name); "
                "a sweep file needs far fewer"
            )
        if isinstance(value, float) and not math.isfinite(value):
            raise SweepError(
                f"{where}: {key or '(top level)'}: {value} is not a finite number; a sweep's numbers are finite (NaN "
                "and infinity can not be saved with its results and compared when it resumes)"
            )
        if isinstance(value, dict):
            stack.extend((v, f"{key}.{k}" if key else str(k), depth + 1) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, f"{key}[{i}]", depth + 1) for i, v in enumerate(value))


#: The sections of a sweep file whose keys an override's path is checked against, and their keys that hold more keys.
SECTIONS: dict[str, type[BaseModel]] = {
    "env": EnvSpec, "trainer": TrainerSpec, "evaluation": EvaluationSpec, "forensics": ForensicsSpec
}
NESTED = ("kwargs", "algo_kwargs", "wrappers", "protocol", "tuned")


def _override_path(assignment: str, data: dict[str, Any]) -> tuple[list[Any], Any]:
    """
    Check the key path of one ``--set key.path=value`` against the schema; return the path (list items as ints) and
    the parsed value. A key the schema does not know is named with the keys allowed there (and the closest one).
    A kwarg bound to a grid label (``$label``) can not be overridden: run ids and labels come from the grid, so the
    override would run one value under another value's label; the error says which grid to set instead.
    """
    if "=" not in assignment:
        raise SweepError(f"--set {assignment!r}: use key=value, e.g. --set seeds=5")
    raw_path, _, raw = assignment.partition("=")
    keys: list[Any] = raw_path.strip().split(".")
    try:
        value = yaml.load(raw, Loader=_StrictLoader)  # a safe loader
    except yaml.YAMLError as error:
        raise SweepError(f"--set {assignment!r}: the value is not valid YAML ({error})") from None
    _check_size(value, f"--set {assignment!r}")

    def unknown(key: str, allowed: list[str], where: str) -> SweepError:
        moved = MOVED.get(key, "").partition(".")[0] in allowed  # an old key of this kind: its new path
        close = [MOVED[key]] if moved else difflib.get_close_matches(key, allowed, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        return SweepError(
            f"--set {assignment!r}: {key!r} is not a key of {where}{hint} (allowed: {', '.join(allowed)})"
        )

    top = list(KIND_KEYS[kind_of(data)])
    if keys[0] not in top:
        raise unknown(keys[0], top, KINDS[kind_of(data)])
    section: type[BaseModel] | None = SECTIONS.get(keys[0]) if keys[0] != "tasks" else EnvSpec
    at = 2 if keys[0] == "tasks" else 1  # (tasks.<name>.<key>)
    if section is not None and len(keys) > at:
        where = ".".join(keys[:at])
        if keys[at] not in section.model_fields:
            raise unknown(keys[at], list(section.model_fields), where)
        if keys[at] == "protocol" and len(keys) > at + 1 and keys[at + 1] not in ProtocolSpec.model_fields:
            raise unknown(keys[at + 1], list(ProtocolSpec.model_fields), f"{where}.protocol")
        if keys[at] not in NESTED and len(keys) > at + 1:
            single = ".".join(keys[: at + 1])
            raise SweepError(f"--set {assignment!r}: {single!r} is a single value; use --set {single}=VALUE")
    if keys[0] in ("name", "episodes", "seeds", "max_timesteps", "logs") and len(keys) > 1:
        raise SweepError(f"--set {assignment!r}: {keys[0]!r} is a single value; use --set {keys[0]}=VALUE")
    if keys[0] == "agents" and len(keys) > 1:
        agents: list[Any] = data["agents"] if isinstance(data.get("agents"), list) else []
        names = [a.get("name") if isinstance(a, dict) else None for a in agents]
        if keys[1] in names:  # an agent by name: agents.affective.kwargs.gamma=0.9
            keys[1] = names.index(keys[1])
        elif keys[1].isdigit() and int(keys[1]) < len(agents):
            keys[1] = int(keys[1])
        else:
            raise SweepError(
                f"--set {assignment!r}: no agent {keys[1]!r}; give an index 0..{len(agents) - 1} or a name "
                f"({', '.join(str(n) for n in names)})"
            )
        if len(keys) > 2 and keys[2] not in AgentSpec.model_fields:
            raise unknown(keys[2], list(AgentSpec.model_fields), f"agents[{keys[1]}]")
        if len(keys) == 4 and keys[2] == "kwargs":
            agent = agents[keys[1]] if isinstance(agents[keys[1]], dict) else {}
            bound = (agent.get("kwargs") or {}).get(keys[3])
            match = KWARG_REFERENCE.match(bound) if isinstance(bound, str) else None
            if match and value != bound:
                label = match.group(1)
                raise SweepError(
                    f"--set {assignment!r}: kwargs.{keys[3]} of agent {names[keys[1]]!r} takes its value from the grid "
                    f"label {label!r}, which names its runs and labels its results; set the grid instead, e.g. "
                    f"--set agents.{names[keys[1]]}.grid.{label}=[{raw.strip()}]"
                )
    return keys, value


def _bound_kwargs(data: dict[str, Any]) -> dict[tuple[str, str], Any]:
    """
    ``(agent name, kwargs key path) -> value`` of every kwarg of every agent (its team members' too), where the value
    is the ``$label`` reference or whatever stands there instead (``None``: not given).
    """
    found: dict[tuple[str, str], Any] = {}
    agents: list[Any] = data["agents"] if isinstance(data.get("agents"), list) else []
    for agent in agents:
        if not isinstance(agent, dict) or not isinstance(agent.get("name"), str):
            continue
        places = [("kwargs", agent.get("kwargs"))]
        team: list[Any] = agent["team"] if isinstance(agent.get("team"), list) else []
        places += [(f"team.{i}.kwargs", m.get("kwargs")) for i, m in enumerate(team) if isinstance(m, dict)]
        for where, kwargs in places:
            for key, value in (kwargs if isinstance(kwargs, dict) else {}).items():
                found[(agent["name"], f"{where}.{key}")] = value
    return found


def _check_still_bound(before: dict[tuple[str, str], Any], data: dict[str, Any], assignment: str, path: Path) -> None:
    """
    Refuse an override that replaces (or drops) a kwarg bound to a grid label (``$label``) of an agent it leaves in
    the file, whatever key path it set (``agents.0.kwargs={...}``, ``agents.0={...}``): the runs would be labelled
    with grid values they did not run with.
    """
    after = _bound_kwargs(data)
    agents: list[Any] = data["agents"] if isinstance(data.get("agents"), list) else []
    names = {agent.get("name") for agent in agents if isinstance(agent, dict)}
    for (name, key), value in before.items():
        match = KWARG_REFERENCE.match(value) if isinstance(value, str) else None
        if match is None or name not in names:
            continue
        now = after.get((name, key))
        if not (isinstance(now, str) and KWARG_REFERENCE.match(now)):
            label = match.group(1)
            raise SweepError(
                f"--set {assignment!r}: {key} of agent {name!r} takes its value from the grid label {label!r}, which "
                f"names its runs and labels its results; keep it {value} and set the grid instead, e.g. "
                f"--set agents.{name}.grid.{label}=[...] [sweep file: {path}]"
            )


def _apply_override(data: dict[str, Any], assignment: str) -> list[Any]:
    """
    ``key.path=value`` (value parsed as YAML; list items by index or agent name, e.g. ``agents.0.kwargs.gamma=0.9``).

    :return: the key path it set (agents by index), to tell which validation errors the override caused
    """
    keys, value = _override_path(assignment, data)
    target: Any = data
    for key in keys[:-1]:
        target = target[int(key)] if isinstance(target, list) else target.setdefault(key, {})
    last = keys[-1]
    if isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value
    return keys


def _overlaps(location: tuple[Any, ...], keys: list[Any]) -> bool:
    """Whether a validation error at ``location`` concerns the key path an override set (one is a prefix of the other)."""
    n = min(len(location), len(keys))
    return n > 0 and [str(k) for k in location[:n]] == [str(k) for k in keys[:n]]


def _key_path(location: tuple[Any, ...], data: dict[str, Any]) -> str:
    """Render a pydantic error location as a readable key path, naming agents by their name."""
    parts: list[str] = []
    node: Any = data
    for item in location:
        if isinstance(item, int) and isinstance(node, list) and item < len(node):
            name = node[item].get("name") if isinstance(node[item], dict) else None
            parts[-1] = f"{parts[-1]}[{item}]" + (f" ({name})" if name else "") if parts else f"[{item}]"
            node = node[item]
        else:
            parts.append(str(item))
            node = node.get(item) if isinstance(node, dict) else None
    return ".".join(parts)


def load_sweep(
    path: str | Path, overrides: tuple[str, ...] | list[str] = (), *, build: bool = True, deep: bool = False
) -> Sweep:
    """
    Read, override and validate a sweep file of runs; every problem is a ``SweepError`` naming the file and the key.

    :param build: also build the env and each agent once (without training, in a short-lived child process), so
        that an unknown or impossible kwarg is reported now rather than by every run of the sweep
    :param deep: a study's file the launcher runs too (a deep study, the forensics: ``Sweep.kind``) is one too
    """
    sweep = load_sweep_file(path, overrides, build=build)
    if sweep.kind != "sweep" and not deep:
        raise SweepError(
            f"{resolve_sweep_path(path)}: the {sweep.kind} study has no runs of its own; run it with "
            f"`sb3-affect run {path} --out DIR`"
        )
    return sweep


def load_sweep_file(path: str | Path, overrides: tuple[str, ...] | list[str] = (), *, build: bool = True) -> Sweep:
    """
    Read, override and validate a sweep file (a sweep of runs, a deep study or the forensics: ``Sweep.kind``); every
    problem is a ``SweepError`` naming the file and the key. A file in an old form (``study: deep``, ...) is refused
    with the key to write instead (``old_forms.old_key``).

    :param build: for a sweep of runs, also build the env and each agent once (``load_sweep``)
    """
    path = resolve_sweep_path(path)
    try:
        with path.open("rb") as handle:
            raw = handle.read(MAX_BYTES + 1)
    except OSError as error:
        names = ", ".join(shipped_sweeps())
        raise SweepError(
            f"{path}: can not read the sweep file ({error.strerror}); give a YAML path or a shipped sweep: {names}"
        ) from None
    if len(raw) > MAX_BYTES:
        raise SweepError(f"{path}: the sweep file is larger than {MAX_BYTES:,} bytes; a sweep file is a few lines of YAML")
    try:
        text = raw.decode()
    except UnicodeDecodeError as error:
        raise SweepError(f"{path}: the sweep file is not UTF-8 text ({error})") from None
    try:
        data = yaml.load(text, Loader=_StrictLoader)  # a safe loader
    except RecursionError:
        raise SweepError(f"{path}: malformed YAML: nested too deeply") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error)
        raise SweepError(f"{path}: malformed YAML{where}: {problem}") from None
    if not isinstance(data, dict):
        raise SweepError(f"{path}: a sweep file must be a YAML mapping with name, episodes, seeds and agents")
    _check_size(data, str(path))
    old = old_key(data)
    if old is not None:
        raise SweepError(f"{path}: {old}")
    overridden: list[tuple[str, list[Any]]] = []
    for assignment in overrides:
        bound = _bound_kwargs(data)
        try:
            overridden.append((assignment, _apply_override(data, assignment)))
        except SweepError as error:
            raise SweepError(f"{error} [sweep file: {path}]") from None
        except (KeyError, IndexError, ValueError, TypeError, AttributeError) as error:
            raise SweepError(f"--set {assignment!r} does not apply to {path} ({error})") from None
        _check_still_bound(bound, data, assignment, path)
    _check_size(data, str(path))
    try:
        sweep = Sweep.validate_file(data)
    except ValidationError as error:
        lines, from_file = [], False
        for item in error.errors():
            location = tuple(item["loc"])
            key = _key_path(location, data) or "(top level)"
            value = item.get("input")
            text = repr(value) if len(repr(value)) <= 80 else f"{repr(value)[:77]}..."
            shown = "" if isinstance(value, (dict, list)) or item["type"] == "missing" else f" (got {text})"
            message = item["msg"].removeprefix("Value error, ")
            setters = [a for a, keys in overridden if _overlaps(location, keys)]
            from_file = from_file or not setters
            lines.append(f"  {key}: {message}{shown}" + (f" [from --set {setters[-1]}]" if setters else ""))
        allowed = f"allowed top-level keys of {KINDS[kind_of(data)]}: " + ", ".join(KIND_KEYS[kind_of(data)])
        what = "invalid sweep file" if from_file else "invalid --set value"
        raise SweepError(f"{path}: {what}\n" + "\n".join(lines) + f"\n  ({allowed})") from None
    if build and sweep.kind == "sweep":
        index = {agent.name: i for i, agent in enumerate(sweep.agents)}
        problems = check_configs_in_child([cell.config(0) for cell in sweep.cells()])
        if problems:
            lines = [
                f"  {f'agents[{index[agent]}] ({agent}).kwargs' if agent in index else 'env.kwargs'}: {message}"
                for agent, message in problems
            ]
            raise SweepError(f"{path}: invalid sweep file\n" + "\n".join(lines))
    return sweep
