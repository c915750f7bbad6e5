"""The benchmark script runs (it times nothing here: speed targets live in benchmarks/bench.py, not in tests)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_benchmark_smoke_run_writes_its_table(tmp_path: Path) -> None:
    out = tmp_path / "bench.csv"
    result = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench.py"), "--smoke", "--csv", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    assert "bare pure-Python loop" in result.stdout and "cores" in result.stdout
    rows = list(csv.DictReader(out.open()))
    names = [row["measure"] for row in rows]
    assert any(n.startswith("QLearning.learn") for n in names) and any(n.startswith("AffectQ.learn") for n in names)
    assert all(float(row["value"]) > 0 for row in rows)


def test_benchmark_minigrid_smoke_run_writes_its_rows(tmp_path: Path) -> None:
    pytest.importorskip("minigrid")
    out = tmp_path / "bench.csv"
    subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench.py"), "--smoke", "--minigrid", "--csv", str(out)],
        capture_output=True,
        timeout=600,
        check=True,
    )
    names = [row["measure"] for row in csv.DictReader(out.open())]
    assert any(n.startswith("AffectDQN.learn, MiniGrid") for n in names)
    assert any(n.startswith("AffectQ.learn on TabularMiniGrid") for n in names)
    assert any(n.startswith("minigrid_vec_env step, MiniGrid-DoorKey-8x8-v0") for n in names)


def test_benchmark_many_seeds_refuses_an_unknown_row_in_one_line() -> None:
    result = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_many_seeds.py"), "--rows", "sb3,gpu"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "--rows has 'gpu'; allowed: sb3, many, gradient, jax" in result.stderr.splitlines()[-1]


def test_benchmark_learn_parts_smoke_run_splits_both_envs_runs() -> None:
    pytest.importorskip("minigrid")
    result = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_learn_parts.py"), "--smoke", "--algo", "PPO"],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    lines = result.stdout.splitlines()
    for part in ("env step_wait + reset", "train", "SB3's collecting work", "learn"):
        row = next(line for line in lines if line.strip().startswith(part + " "))
        farama, compiled = row.split("Farama's")[1].split("compiled")
        assert float(farama) > 0 and float(compiled) > 0
    assert lines[-1].startswith("pair 0: compiled / Farama's ") and "with a step that cost nothing" in lines[-1]
