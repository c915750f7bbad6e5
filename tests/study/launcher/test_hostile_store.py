"""
Hostile input against the results store and the sweep file: every episode column reads back as the engine gave it
through both layouts (chunks and run files), or the value is refused with one line naming it; values a results
column can not hold (NaN or infinity in a sweep, lists and mappings as labels, equal grid values, names that differ
only by a trailing space) are refused before anything runs; labels of any accepted length fit in file names.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from sb3_affect.core.episode_log import EPISODE_COLUMNS, FLAG_COLUMNS, INT_COLUMNS
from sb3_affect.study.launcher import ResultsStore, SweepError, load_sweep, run_sweep
from sb3_affect.study.launcher.chunks import encode_chunk
from sb3_affect.study.launcher.folder_files import DamagedFile
from sb3_affect.study.launcher.folder_reading import read_folder
from sb3_affect.study.launcher.run_ids import run_config, run_id
from sb3_affect.study.launcher.store import run_file

ROOT = Path(__file__).resolve().parents[3]
ENV = "sb3_affect/GridPursuit-v0"
I64 = np.iinfo(np.int64)


def _extremes() -> dict[str, np.ndarray]:
    """One run's episode table holding each dtype's extremes: counts beyond 2**31 up to int64's, NaN flags, inf."""
    counts = np.array([0, 2**31, 2_500_000_000, I64.max, I64.min, -1], dtype=np.int64)
    floats = np.array([np.inf, -np.inf, np.nan, 1.7976931348623157e308, -0.0, 5e-324])
    flags = np.array([1.0, 0.0, np.nan, 1.0, np.nan, 0.0])  # moving prey: greedy_optimal NaN (the engine can not tell)
    table: dict[str, np.ndarray] = {}
    for column in EPISODE_COLUMNS:
        table[column] = counts if column in INT_COLUMNS else flags if column in FLAG_COLUMNS else floats
    table["episode"] = np.arange(1, 7, dtype=np.int64)
    table["decisions"] = counts
    return table


def _base(episodes: int) -> dict[str, Any]:
    return {
        "sweep": "extremes",
        "agent": "a",
        "algo": "QLearning",
        "algo_kwargs": {},
        "env_id": ENV,
        "env_kwargs": {},
        "seed": None,
        "episodes": episodes,
        "max_timesteps": None,
        "labels": {"epsilon": 0.1},
    }


def _plain(value: Any) -> Any:
    value = value.item()
    return None if isinstance(value, float) and np.isnan(value) else value


def test_each_dtype_extremes_read_back_as_written_through_both_layouts(tmp_path: Path) -> None:
    engine = _extremes()
    base = _base(len(engine["episode"]))
    chunk_runs = [(run_id(run_config(base, 7, 0)), 7, 0)]
    chunk = tmp_path / "chunks" / "extremes.parquet"
    chunk.parent.mkdir()
    episodes = {"seed": np.full(6, 7), **engine}
    chunk.write_bytes(encode_chunk("extremes", base, chunk_runs, episodes, {"wall_seconds": 1.0}, {}))
    config = run_config(base, 8, 1)
    rid = run_id(config)
    columns = {column: [_plain(v) for v in engine[column]] for column in EPISODE_COLUMNS}  # as ``execute_run`` gives
    json_file = tmp_path / "runs" / f"{rid}.json"
    json_file.parent.mkdir()
    json_file.write_bytes(run_file(rid, config, {"episodes": columns, "timings": {"wall_seconds": 1.0}}))
    for layout in ([], [chunk]), ([json_file], []):
        runs, data = read_folder(*layout, EPISODE_COLUMNS, tmp_path)
        assert len(runs) == 1
        for column in EPISODE_COLUMNS:  # counts: int32 unless a value needs int64; flags with NaN: float64
            wide = column in INT_COLUMNS and np.abs(engine[column]).max() > np.iinfo(np.int32).max
            expected = np.float64 if column in FLAG_COLUMNS else np.int64 if wide else np.int32 if column in INT_COLUMNS \
                else np.float64
            assert data[column].dtype == expected, column
            np.testing.assert_array_equal(data[column], engine[column], err_msg=f"{column} via {layout}")
        assert np.signbit(data["reward"][4])  # -0.0 stays -0.0


def test_flags_without_nan_read_back_as_booleans(tmp_path: Path) -> None:
    engine = _extremes()
    for column in FLAG_COLUMNS:
        engine[column] = np.array([True, False, True, True, False, False])
    base = _base(6)
    chunk = tmp_path / "extremes.parquet"
    chunk.write_bytes(encode_chunk("extremes", base, [(run_id(run_config(base, 7, 0)), 7, 0)],
                                   {"seed": np.full(6, 7), **engine}, {"wall_seconds": 1.0}, {}))
    _, data = read_folder([], [chunk], EPISODE_COLUMNS, tmp_path)
    for column in FLAG_COLUMNS:
        assert data[column].dtype == np.bool_
        np.testing.assert_array_equal(data[column], engine[column])


@pytest.mark.parametrize("bad", [np.nan, np.inf, 2.5, 2.0**63])
def test_a_count_that_is_not_an_integer_is_refused_naming_the_column(tmp_path: Path, bad: float) -> None:
    engine = {column: values.astype(np.float64) for column, values in _extremes().items()}
    for column in INT_COLUMNS:
        engine[column] = np.arange(1.0, 7.0)
    engine["cells"] = np.array([1.0, 2.0, bad, 4.0, 5.0, 6.0])
    base = _base(6)
    runs = [(run_id(run_config(base, 7, 0)), 7, 0)]
    with pytest.raises(ValueError, match=r"^batch b: episode column 'cells': row 2 holds .*not a count"):
        encode_chunk("b", base, runs, {"seed": np.full(6, 7), **engine}, {"wall_seconds": 1.0}, {})
    config = run_config(base, 8, 1)
    rid = run_id(config)
    columns = {column: [_plain(v) for v in engine[column]] for column in EPISODE_COLUMNS}
    path = tmp_path / f"{rid}.json"
    path.write_bytes(run_file(rid, config, {"episodes": columns, "timings": {}}))
    with pytest.raises(DamagedFile, match=rf"^{path}: damaged data .*'cells'"):
        read_folder([path], [], EPISODE_COLUMNS, tmp_path)


def _sweep(tmp_path: Path, agents: list[dict[str, Any]], **top: Any) -> Path:
    data = {"name": "hostile", "env": {"id": ENV}, "episodes": 2, "seeds": 1, "agents": agents, **top}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("agent", "where"),
    [
        ({"grid": {"x": [[10, 20]]}}, r"grid.x\[0\]: \[10, 20\] is a list"),
        ({"labels": {"x": {"a": 1}}}, r"labels.x: \{'a': 1\} is a mapping"),
        ({"grid": {"x": [0.1, 0.1]}}, r"grid.x\[1\]: 0.1 repeats"),
        ({"grid": {"x": [1, 1.0, True]}}, r"grid.x\[1\]: 1.0 equals 1 \(an equal value of another type\)"),
    ],
)
def test_label_values_a_column_can_not_hold_are_refused_naming_them(tmp_path: Path, agent: dict[str, Any],
                                                                     where: str) -> None:
    path = _sweep(tmp_path, [{"name": "a", "algo": "QLearning", **agent}])
    with pytest.raises(SweepError, match=where):
        load_sweep(path, build=False)


def test_one_labels_values_of_different_types_over_the_agents_are_refused(tmp_path: Path) -> None:
    agents = [{"name": "a", "algo": "QLearning", "grid": {"x": [1]}}, {"name": "b", "algo": "AffectQ", "grid": {"x": [True]}}]
    with pytest.raises(SweepError, match=r"label 'x': True \(agent 'b'\) equals 1 \(agent 'a'\)"):
        load_sweep(_sweep(tmp_path, agents), build=False)


def test_agent_names_that_differ_by_a_trailing_space_are_refused(tmp_path: Path) -> None:
    agents = [{"name": "a b", "algo": "QLearning"}, {"name": "a b ", "algo": "QLearning"}]
    with pytest.raises(SweepError, match=r"agents\[1\] \(a b \).name"):
        load_sweep(_sweep(tmp_path, agents), build=False)


@pytest.mark.parametrize(
    ("text", "overrides", "key"),
    [
        ("grid: {epsilon: [.nan]}", [], r"agents\[0\].grid.epsilon\[0\]: nan is not a finite number"),
        ("kwargs: {gamma: .inf}", [], r"agents\[0\].kwargs.gamma: inf is not a finite number"),
        ("kwargs: {}", ["env.kwargs={size: 1.0e+400}"], r"--set 'env.kwargs=\{size: 1.0e\+400\}'.*size: inf is not a"),
    ],
)
def test_nan_or_infinity_anywhere_in_a_sweep_is_refused_naming_the_key(tmp_path: Path, text: str, overrides: list[str],
                                                                       key: str) -> None:
    path = tmp_path / "sweep.yaml"
    path.write_text(f"name: n\nepisodes: 2\nseeds: 1\nagents:\n  - name: a\n    algo: QLearning\n    {text}\n")
    with pytest.raises(SweepError, match=key) as error:
        load_sweep(path, overrides, build=False)
    assert "\n" not in str(error.value)


def test_a_label_too_long_for_a_file_name_still_names_its_files(tmp_path: Path) -> None:
    long = "L" * 300
    agents = [
        {"name": "batched", "algo": "QLearning", "grid": {"what": [long]}},  # a chunk
        {"name": "traced", "algo": "AffectQ", "grid": {"what": [long]}, "trace": True},  # a run file
    ]
    out = tmp_path / "out"
    summary = run_sweep(_sweep(tmp_path, agents), out, workers=1, progress=False)
    assert (summary.total, summary.finished, summary.failed) == (2, 2, 0)
    names = [p.name for p in (*(out / "chunks").glob("*.parquet"), *(out / "runs").glob("*.json"))]
    assert len(names) == 2 and all(len(name.encode()) <= 200 for name in names)
    runs, _ = ResultsStore(out).results()
    assert sorted(runs.what) == [long, long]
    assert json.loads((out / "sweep.json").read_text())["sweep"]["agents"][0]["grid"]["what"] == [long]
