"""
Batches and chunked storage, end to end with real processes and files: a killed launcher resumes without losing or
duplicating a run, a batch whose worker dies is recorded for each of its runs and retried, and a results folder of
the one-JSON-file-per-run layout (written before chunks) is still read, resumed and reported.
"""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import pandas as pd
import pytest
from test_experiments_local import EXPERIMENTS, children, contents, launcher, linux_only, no_partial_files, running

from sb3_affect.study.cli import main
from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.launcher.chunks import chunk_meta
from sb3_affect.study.report.reading.run_tables import load_results, run_metrics

SMOKE = EXPERIMENTS / "smoke.yaml"


def smoke_file(tmp_path: Path, seeds: int, episodes: int, size: int | None = None) -> Path:
    """smoke.yaml with other seeds, episodes (and grid size), as a file (the launcher subprocess takes no --set here)."""
    path = tmp_path / "smoke.yaml"
    text = SMOKE.read_text().replace("episodes: 20", f"episodes: {episodes}").replace("seeds: 2", f"seeds: {seeds}")
    if size is not None:
        env = "env: {id: sb3_affect/GridPursuit-v0}"
        assert env in text
        kwargs = f"{{size: {size}, goal: [{size - 1}, {size - 1}]}}"
        text = text.replace(env, f"env: {{id: sb3_affect/GridPursuit-v0, kwargs: {kwargs}}}")
    path.write_text(text)
    return path


def stored_once(out: Path) -> int:
    """The number of runs stored, checking that no run is stored twice (in two chunks, or a chunk and a file)."""
    ids = [run[0] for path in (out / "chunks").glob("[!.]*.parquet") for run in chunk_meta(path)["runs"]]
    ids += [path.stem for path in (out / "runs").glob("[!.]*.json")]
    assert len(ids) == len(set(ids)), "a run is stored twice"
    return len(ids)


def wait_until(condition: object, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


@linux_only
def test_sigkill_then_resume_with_chunks_loses_and_duplicates_nothing(tmp_path: Path) -> None:
    sweep, out = smoke_file(tmp_path, seeds=20, episodes=10, size=60), tmp_path / "out"  # batches of a tenth of a second
    first = launcher(sweep, out)  # --workers 2: 80 runs in batches of 5
    try:
        wait_until(lambda: (out / "chunks").exists() and any((out / "chunks").glob("[!.]*.parquet")), 120, "a chunk")
        os.kill(first.pid, signal.SIGKILL)
        first.wait(timeout=10)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    before = stored_once(out)
    assert 0 < before < 80
    summary = run_sweep(sweep, out, workers=1, progress=False)  # another batch size: batching does not change runs
    assert (summary.skipped, summary.finished, summary.failed) == (before, 80 - before, 0)
    assert stored_once(out) == 80
    no_partial_files(out)
    reference = tmp_path / "reference"
    run_sweep(sweep, reference, workers=2, progress=False)
    assert contents(out) == contents(reference)


@linux_only
def test_batch_whose_worker_dies_is_recorded_per_run_and_retried(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A 60 x 60 grid: a batch of 10 runs takes a few tenths of a second on the kernel, so the kill lands mid-batch
    # (on the default grid a batch lasts milliseconds and may have sent its result before the kill).
    sweep, out = smoke_file(tmp_path, seeds=40, episodes=10, size=60), tmp_path / "out"
    proc = launcher(sweep, out)
    try:
        # After sweep.json the launcher's children are batch workers (the kwargs check ran before it).
        wait_until(lambda: (out / "sweep.json").exists() and any(running(p) for p in children(proc.pid)), 120, "a worker")
        worker = next(p for p in children(proc.pid) if running(p))
        os.kill(worker, signal.SIGSTOP)  # mid-batch: its result is not sent
        os.kill(worker, signal.SIGKILL)
        wait_until(lambda: len(list((out / "failed").glob("[!.]*.json"))) == 10, 60, "the failure records")
        os.killpg(proc.pid, signal.SIGINT)  # no need to finish the sweep: the rerun does
        proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    failed = [json.loads(p.read_text()) for p in (out / "failed").glob("[!.]*.json")]
    assert len(failed) == 10 and all("killed by SIGKILL" in r["error"] for r in failed)  # every run of the batch
    assert len({json.dumps(r["config"]["labels"], sort_keys=True) for r in failed}) == 10
    assert not {r["run_id"] for r in failed} & ResultsStore(out).done_ids()
    capsys.readouterr()
    assert main(["status", str(out)]) == 0
    assert "10 failed" in capsys.readouterr().out
    summary = run_sweep(sweep, out, workers=2, progress=False)
    assert summary.failed == 0 and summary.total == 160 and stored_once(out) == 160
    assert list((out / "failed").glob("[!.]*.json")) == []


def test_folder_of_one_json_file_per_run_is_still_read_resumed_and_reported(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    chunked, old = tmp_path / "chunked", tmp_path / "old"
    overrides = ["episodes=12"]
    run_sweep(SMOKE, chunked, workers=2, overrides=overrides, progress=False)
    run_sweep(SMOKE, old, workers=2, overrides=[*overrides, "logs=[csv]"], progress=False)  # one JSON file per run
    # sweep.json as the launcher wrote it before chunks: every run config listed.
    saved = json.loads((old / "sweep.json").read_text())
    runs = {r["run_id"]: r["config"] for r in ResultsStore(old).load_runs()}
    (old / "sweep.json").write_text(json.dumps({"name": saved["name"], "sweep": saved["sweep"], "runs": runs}))
    assert list((old / "chunks").glob("*.parquet")) == [] and len(list((old / "runs").glob("*.json"))) == 8
    assert main(["status", str(old)]) == 0
    assert "8/8 runs done, 0 failed" in capsys.readouterr().out
    assert run_sweep(SMOKE, old, workers=2, overrides=overrides, progress=False).skipped == 8  # the same sweep
    assert main(["run", str(SMOKE), "--out", str(old), "--set", "seeds=3", "--no-progress"]) == 2
    assert "different sweep" in capsys.readouterr().err
    # The report's loader gives the same tables from either layout.
    from_json, from_chunks = load_results(old), load_results(chunked)
    pd.testing.assert_frame_equal(from_json.episodes, from_chunks.episodes)
    same = ["run_id", "agent", "algo", "seed", "epsilon", "replicate", "decisions", "episodes", "max_timesteps"]
    pd.testing.assert_frame_equal(from_json.runs[same], from_chunks.runs[same])
    pd.testing.assert_frame_equal(run_metrics(from_json.episodes), run_metrics(from_chunks.episodes))


def test_batch_workers_take_batch_after_batch_and_single_runs_get_a_process_each(tmp_path: Path) -> None:
    from test_experiments_local import sweep_file

    # 4 single runs (a user's class: one process each), then 4 AffectQ batches of one run (one worker, forked once)
    sweep, out = sweep_file(tmp_path, ["none"], seeds=4), tmp_path / "out"
    summary = run_sweep(sweep, out, workers=1, progress=False)
    assert (summary.finished, summary.failed) == (8, 0)
    batch_pids = [chunk_meta(path)["timings"]["pid"] for path in (out / "chunks").glob("[!.]*.parquet")]
    single_pids = [json.loads(path.read_text())["timings"]["pid"] for path in (out / "runs").glob("[!.]*.json")]
    assert len(batch_pids) == 4 and len(set(batch_pids)) == 1
    assert len(single_pids) == 4 and len(set(single_pids)) == 4
    assert not (set(batch_pids) | set(single_pids)) & {os.getpid()}
    assert not set(batch_pids) & set(single_pids)
    reference = tmp_path / "reference"
    run_sweep(sweep, reference, workers=2, progress=False)  # other workers, other batch sizes: the same runs
    assert contents(out) == contents(reference)


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 4097])
def test_chunk_columns_are_the_arrow_arrays_of_pa_array(n: int) -> None:
    """``arrow_array`` builds a chunk's columns from their bytes (no pandas): the arrays ``pa.array`` gives."""
    import numpy as np
    import pyarrow as pa

    from sb3_affect.study.launcher.chunks import arrow_array

    rng = np.random.default_rng(n)
    cases = [
        (pa.int32(), rng.integers(-5, 10**6, n), np.int32),
        (pa.int64(), rng.integers(-(2**62), 2**62, n), np.int64),
        (pa.float64(), np.r_[rng.normal(size=n)[: max(0, n - 2)], [np.nan, -0.0][: min(n, 2)]], np.float64),
        (pa.bool_(), rng.random(n) < 0.3, bool),
    ]
    for kind, values, dtype in cases:
        made = arrow_array(values, kind)
        made.validate(full=True)
        expected = pa.array(values.astype(dtype))
        assert made.type == kind and made.null_count == 0 and len(made) == n, kind
        assert made.to_numpy(zero_copy_only=False).tobytes() == expected.to_numpy(zero_copy_only=False).tobytes(), kind
    flags, missing = rng.random(n) < 0.5, rng.random(n) < 0.3  # flags a run can not tell: nulls where pa.array has them
    made = arrow_array(flags, pa.bool_(), missing)
    made.validate(full=True)
    assert made.to_pylist() == pa.array([None if m else bool(f) for f, m in zip(flags, missing)], pa.bool_()).to_pylist()
