"""The ``sb3-affect`` command: run sweeps, show their status, build the report, run the whole replication."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch scheduler): stop like Ctrl-C, workers first, then exit 143."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def _cmd_run(args: argparse.Namespace) -> int:
    from sb3_affect.experiments import run_sweep

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _on_sigterm)
    summary = run_sweep(
        args.file,
        args.out,
        workers=args.workers,
        backend=args.backend,
        ray_address=args.ray_address,
        overrides=[*(args.set or ()), *([f"logs=[{args.logs}]"] if args.logs else [])],
        progress=not args.no_progress,
    )
    print(
        f"{summary.name}: {summary.total} runs, {summary.skipped} already done, {summary.finished} finished now, "
        f"{summary.failed} failed, {summary.seconds:.1f} s -> {summary.out_dir}"
    )
    if summary.failed:
        print(f"failed runs and their tracebacks: {summary.out_dir / 'failed'}; rerun the same command to retry them")
        return 1
    return 0


def _cmd_status(args: argparse.Namespace) -> int:
    from sb3_affect.experiments import ResultsStore

    store = ResultsStore(args.dir)
    saved = store.root / "sweep.json"
    if not saved.exists():
        print(f"{store.root}: no sweep has been run here (no sweep.json)", file=sys.stderr)
        return 2
    name, per_agent = store.progress()  # agent -> (runs, done, failed)
    total, done, failed = (sum(counts[i] for counts in per_agent.values()) for i in range(3))
    print(f"sweep {name!r} in {store.root}: {done}/{total} runs done, {failed} failed")
    for agent, (runs, done_agent, failed_agent) in per_agent.items():
        print(f"  {agent:24s} {done_agent:5d}/{runs:<5d} done  {failed_agent} failed")
    lock = store.root / ".lock"
    if lock.exists():
        owner = store.lock_owner()
        recorded = lock.read_text().split()[:1] or ["?"]
        state = "running" if owner is not None else "gone: stale lock, the next run takes it over"
        print(f"  locked by launcher pid {recorded[0]} ({state})")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from sb3_affect.report import build_report

    path = build_report(Path(args.dir))
    print(f"report: {path}")
    return 0


def _cmd_replicate(args: argparse.Namespace) -> int:
    from sb3_affect.replicate import main as replicate

    replicate(out_dir=Path(args.out), workers=args.workers)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sb3-affect", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run (or resume) an experiment sweep")
    run.add_argument("file", help="experiment YAML, e.g. experiments/paper.yaml")
    run.add_argument("--out", required=True, help="results folder")
    run.add_argument("--workers", type=int, default=None, help="parallel runs (default: CPU count)")
    run.add_argument("--backend", choices=("local", "ray"), default="local")
    run.add_argument("--ray-address", default=None, help="Ray cluster address (default: start a local instance)")
    run.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one key, e.g. --set seeds=5")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.add_argument(
        "--logs", metavar="FORMATS", default=None, help="per-run SB3 logger output under DIR/logs/: csv, tensorboard or both"
    )
    run.set_defaults(func=_cmd_run)
    status = sub.add_parser("status", help="show how far a results folder is")
    status.add_argument("dir")
    status.set_defaults(func=_cmd_status)
    report = sub.add_parser("report", help="build DIR/report.md (and .html, tables, figures) from a results folder")
    report.add_argument("dir")
    report.set_defaults(func=_cmd_report)
    replicate = sub.add_parser("replicate", help="the main job: paper protocol, DQN subset, ablation, then the report")
    replicate.add_argument("--out", default="runs")
    replicate.add_argument("--workers", type=int, default=None)
    replicate.set_defaults(func=_cmd_replicate)
    return parser


def main(argv: list[str] | None = None) -> int:
    from sb3_affect.experiments.schema import SweepError
    from sb3_affect.experiments.store import StoreError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (SweepError, StoreError) as error:
        print(f"sb3-affect: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        how = "terminated" if isinstance(interrupt, Terminated) else "interrupted"
        print(f"\nsb3-affect: {how}; finished runs are kept, rerun the same command to resume", file=sys.stderr)
        return 143 if isinstance(interrupt, Terminated) else 130


if __name__ == "__main__":
    sys.exit(main())
