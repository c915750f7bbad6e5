"""The ``sb3-affect`` command: run sweeps, show their status, build the report, run the whole replication."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from sb3_affect import __version__
from sb3_affect.core.extras import MissingExtraError, require_extra
from sb3_affect.study.replicate import MINUTES, PARTS, TUNED_PARTS, forensics_extra, part_description
from sb3_affect.study.replicate import main as replicate

if TYPE_CHECKING:
    from sb3_affect.study.launcher.study_schema import ForensicsStudy


class UsageError(Exception):
    """A command-line argument that can not be used (printed as ``sb3-affect: error: ...``, exit 2)."""


def _positive_int(text: str) -> int:
    """argparse type of ``--workers``: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not allowed: give 1 or more parallel runs (default: CPU count)")
    return value


def _check_out(out: str) -> None:
    """``--out`` must be a folder (new, or one an earlier run wrote), not a file."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise UsageError(f"--out {out}: this is a file; give a results folder (a new one, or one an earlier run wrote)")


def _existing_folder(directory: str, command: str) -> Path:
    """The results folder given to ``status`` or ``report``, or a UsageError saying what is wrong with it."""
    path = Path(directory)
    if not path.exists():
        raise UsageError(f"{directory}: no such folder; give the --out folder of `sb3-affect run` or `sb3-affect replicate`")
    if not path.is_dir():
        hint = (
            f"; a sweep file is run with `sb3-affect run {directory} --out DIR`, then `sb3-affect {command} DIR`"
            if path.suffix in (".yaml", ".yml")
            else ""
        )
        raise UsageError(f"{directory}: this is a file, not a results folder{hint}")
    return path


def _cmd_run(args: argparse.Namespace) -> int:
    from sb3_affect.study.launcher import run_sweep  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.deep_schema import DeepStudy  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.deep_study import run_deep_study  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.signals import stop_on_sigterm  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.study_schema import ForensicsStudy  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.sweep_file import load_sweep_file  # (experiments extra: not on --help)

    _check_out(args.out)
    study = load_sweep_file(args.file, args.set or (), build=False)
    stop_on_sigterm()
    if isinstance(study, ForensicsStudy):
        return _run_forensics(study, args)
    if isinstance(study, DeepStudy):  # tasks x agents, each cell all its seeds together (study/launcher/deep_study.py)
        if args.logs:
            raise UsageError(f"--logs {args.logs}: the deep study records its own curves and writes no SB3 logs")
        done = run_deep_study(study, Path(args.out), workers=args.workers, backend=args.backend,
                              ray_address=args.ray_address, ray_timeout=args.ray_timeout)
        print(f"{done.name}: {done.total} cells, {done.reused} already done, {done.batches} batches now, "
              f"{done.seconds:.1f} s -> {done.out_dir}")
        return 0
    summary = run_sweep(
        args.file,
        args.out,
        workers=args.workers,
        backend=args.backend,
        ray_address=args.ray_address,
        ray_timeout=args.ray_timeout,
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


def _run_forensics(study: ForensicsStudy, args: argparse.Namespace) -> int:
    """``sb3-affect run`` of a forensics study file (``study: forensics``) on the launcher's executor."""
    from sb3_affect.study.forensics.study_run import run_study, summary_lines  # (report extra: not on --help)

    if args.logs:
        raise UsageError(f"--logs {args.logs}: the forensics study runs on the compiled engine and writes no SB3 logs")
    result = run_study(
        study,
        args.out,
        workers=args.workers,
        backend=args.backend,
        ray_address=args.ray_address,
        ray_timeout=args.ray_timeout,
        progress=not args.no_progress,
    )
    print("\n".join(summary_lines(study, result, args.out)))
    return 0


def _cmd_status(args: argparse.Namespace) -> int:
    from sb3_affect.study.forensics.unit_files import PROTOCOL_FILE, folder_status  # (report extra: not on --help)
    from sb3_affect.study.launcher import ResultsStore  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.deep_study import STUDY_FILE  # (experiments extra: not on --help)

    root = _existing_folder(args.dir, "status")
    if ResultsStore(root).saved_sweep() is not None:  # sweep.json, or a copy of it when it was deleted
        _print_status(root)
        return 0
    if (root / PROTOCOL_FILE).exists():  # a forensics folder (`sb3-affect run forensics`)
        print(folder_status(root))
        return 0
    if (root / STUDY_FILE).exists():  # a deep study's folder
        _print_deep_status(root)
        return 0
    # A `replicate` folder: one sweep folder per part (paper/, dqn/, ...), the forensics' and the deep study's.
    parts = sorted(p for p in root.iterdir() if (p / "sweep.json").exists())
    studies = sorted(p for p in root.iterdir() if (p / PROTOCOL_FILE).exists())
    deep = sorted(p for p in root.iterdir() if (p / STUDY_FILE).exists())
    if not parts and not studies and not deep:
        print(
            f"{root}: no sweep has been run here (no sweep.json, nor sub-folders with one); "
            "start one with `sb3-affect run FILE --out DIR`",
            file=sys.stderr,
        )
        return 2
    print(f"{root}: {len(parts)} sweeps" + (" and the forensics" if studies else "") + (" and the deep study" if deep else ""))
    for part in parts:
        _print_status(part)
    for folder in studies:
        print(folder_status(folder))
    for folder in deep:
        _print_deep_status(folder)
    report = root / "report.html"
    if report.exists():
        print(f"report: {report}")
    return 0


def _print_deep_status(root: Path) -> None:
    from sb3_affect.study.launcher.deep_study import deep_status  # (experiments extra: not on --help)

    try:
        print("\n".join(deep_status(root)))
    except (ValueError, TypeError) as error:  # pydantic's ValidationError is a ValueError
        raise UsageError(f"{root}: its deep_study.json is not a valid deep study ({type(error).__name__}); "
                         "rerun `sb3-affect run FILE --out DIR` into a new folder") from None


def _print_status(root: Path) -> None:
    from sb3_affect.study.launcher import ResultsStore  # (experiments extra: not on --help)

    store = ResultsStore(root)
    name, per_agent, rejected = store.progress()  # agent -> (runs, done, failed); files that do not count
    total, done, failed = (sum(counts[i] for counts in per_agent.values()) for i in range(3))
    print(f"sweep {name!r} in {store.root}: {done}/{total} runs done, {failed} failed")
    for agent, (runs, done_agent, failed_agent) in per_agent.items():
        print(f"  {agent:24s} {done_agent:5d}/{runs:<5d} done  {failed_agent} failed")
    for path, why in rejected:
        print(f"  not counted: {path} {why}; the next run moves it to damaged/ and runs its runs again")
    owner = store.lock_owner()
    if owner is not None:
        print(f"  in use by launcher pid {owner} (running)")


def _cmd_report(args: argparse.Namespace) -> int:
    from sb3_affect.study.report import build_report  # (report extra: not on --help)

    root = _existing_folder(args.dir, "report")
    if not any(root.iterdir()):
        raise UsageError(f"{args.dir}: the folder is empty; run a sweep into it (`sb3-affect run FILE --out {args.dir}`)")
    out = Path(args.out) if args.out else root
    _check_out(str(out))
    unwritable = f"{out}: not writable, so the report can not be written there; write it elsewhere with --out DIR"
    if out.exists() and not os.access(out, os.W_OK | os.X_OK):
        raise UsageError(unwritable)

    extra = forensics_extra(root / "forensics")  # the forensics section, when the folder holds its results
    try:
        command = " ".join(["sb3-affect", *sys.argv[1:]])
        path = build_report(root, out=out, extra_sections=[extra] if extra is not None else [], command=command)
    except PermissionError as error:
        raise UsageError(f"{unwritable} ({error.strerror}: {error.filename})") from None
    except (FileNotFoundError, ValueError) as error:  # no results in a layout the report knows, or no finished run
        raise UsageError(f"{args.dir}: no report can be built: {error}") from None
    print(f"report: {path} and {path.with_suffix('.html')} (open it in a browser)")
    return 0


def _cmd_replicate(args: argparse.Namespace) -> int:
    from sb3_affect.study.launcher.signals import stop_on_sigterm  # (experiments extra: not on --help)

    stop_on_sigterm()

    _check_out(args.out)
    start = time.perf_counter()
    report = replicate(
        out_dir=Path(args.out), workers=args.workers, large_seeds=args.large_seeds, forensics=not args.no_forensics,
        command=" ".join(["sb3-affect", *sys.argv[1:]]), backend=args.backend, ray_address=args.ray_address,
    )
    minutes, seconds = divmod(time.perf_counter() - start, 60)
    print(f"done in {int(minutes)} min {seconds:.0f} s. Open {report.with_suffix('.html')} in a browser to read the report.")
    return 0


def _replicate_help() -> str:
    """``replicate --help``: what it runs (from ``sb3_affect.study.replicate.PARTS``, so it can not drift) and writes."""
    lines = [
        "The main job (`make replicate` runs it): runs these sweep files, each into its own sub-folder of OUT (local",
        "processes, or Ray tasks with --backend ray), then writes one report from all of them.",
        "",
        *(
            f"  OUT/{name + '/':16s} experiments/{name}.yaml: {part_description(name, d)}"
            for name, d in (*PARTS, *TUNED_PARTS)
        ),
        f"  {'OUT/report.html':20s} the report (also report.md, tables/*.csv, figures/*.png): open it in a browser",
        "",
        f"{MINUTES[0].upper() + MINUTES[1:]} on 2 idle cores. Interrupted? Rerun the same command: finished runs are kept",
        "and skipped.",
    ]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sb3-affect",
        description="Run experiment sweeps, show their status, build the report, run the whole replication.",
        epilog="`sb3-affect COMMAND --help` describes each command. Documentation: docs/ (make docs).",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser(
        "run",
        help="run (or resume) an experiment sweep",
        description="Run every run of an experiment file that DIR does not hold yet (rerun the same command to resume).",
    )
    run.add_argument(
        "file",
        help="experiment YAML, e.g. experiments/smoke.yaml, or the name of a sweep shipped with the package, e.g. paper "
        "(see the experiment-file reference)",
    )
    run.add_argument("--out", required=True, metavar="DIR", help="results folder (created; an earlier run's folder resumes)")
    run.add_argument(
        "--workers",
        type=_positive_int,
        default=None,
        help="parallel runs, >= 1 (default: CPU count; on a Ray cluster: as many as its CPUs allow)",
    )
    run.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes (default) or Ray tasks")
    run.add_argument(
        "--ray-address", default=None, help="Ray cluster address, HOST:PORT or ray://HOST:PORT (default: a private instance)"
    )
    run.add_argument(
        "--ray-timeout", type=float, default=60.0, metavar="SECONDS", help="give up on an unresponsive Ray cluster after this"
    )
    run.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override one key of the file (repeatable), e.g. --set seeds=5, --set agents.affective.kwargs.gamma=0.9",
    )
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.add_argument(
        "--logs", metavar="FORMATS", default=None, help="per-run SB3 logger output under DIR/logs/: csv, tensorboard or both"
    )
    run.set_defaults(func=_cmd_run)
    status = sub.add_parser(
        "status",
        help="show how far a results folder is",
        description="Count finished and failed runs per agent (each sweep of a `replicate` folder), and whether a "
        "launcher is using the folder; of a deep study, the cells done of planned (task x agent) and each cell's batches.",
    )
    status.add_argument("dir", metavar="DIR", help="a results folder (the --out of `run` or `replicate`)")
    status.set_defaults(func=_cmd_status)
    report = sub.add_parser(
        "report",
        help="build DIR/report.html (and .md, tables, figures) from a results folder",
        description="Build DIR/report.md, DIR/report.html (self-contained), DIR/tables/*.csv and DIR/figures/*.png. "
        "A `replicate` folder gives the full report; a single sweep folder the sections its runs allow.",
    )
    report.add_argument("dir", metavar="DIR", help="a results folder (the --out of `run` or `replicate`)")
    report.add_argument(
        "--out", metavar="OUT", default=None, help="write the report here instead of into DIR (e.g. DIR is read-only)"
    )
    report.set_defaults(func=_cmd_report)
    replicate = sub.add_parser(
        "replicate",
        help="the main job: paper protocol, DQN, baselines, hunters, engine studies (1,000 seeds), then the report",
        description=_replicate_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    replicate.add_argument("--out", default="runs", metavar="OUT", help="results folder (default: runs)")
    replicate.add_argument("--workers", type=_positive_int, default=None, help="parallel runs, >= 1 (default: CPU count)")
    replicate.add_argument(
        "--large-seeds",
        type=_positive_int,
        default=None,
        metavar="N",
        help="seeds per cell of the large-N study (default: 1000)",
    )
    replicate.add_argument(
        "--no-forensics", action="store_true", help="leave out the replication forensics (the report says so)"
    )
    replicate.add_argument(
        "--backend", choices=("local", "ray"), default="local", help="every part on local processes (default) or Ray tasks"
    )
    replicate.add_argument(
        "--ray-address", default=None, help="Ray cluster address, HOST:PORT or ray://HOST:PORT (default: a private instance)"
    )
    replicate.set_defaults(func=_cmd_replicate)
    from sb3_affect.study.forensics.command import add_forensics_parser  # (report extra: not on --help)

    add_forensics_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)  # --help, --version and usage errors end here, having imported little

    try:
        require_extra(_EXTRA_OF.get(args.command, "experiments"), f"sb3-affect {args.command}")
        return _dispatch(args)
    except MissingExtraError as error:  # a study tool whose extra is not installed: one line saying which
        print(f"sb3-affect: error: {error}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `sb3-affect status DIR | head -1`: the reader has gone; say nothing more
        with contextlib.suppress(OSError):  # (the interpreter's last flush of stdout would raise it again)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # as a shell reports a command that SIGPIPE ended


#: The extra each command needs (``run`` and ``status``: the launcher's).
_EXTRA_OF = {"report": "report", "replicate": "report", "forensics": "report"}


def _dispatch(args: argparse.Namespace) -> int:
    from sb3_affect.study.launcher.ray_cluster import ClusterLost, RayClusterError  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.schema import SweepError  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.signals import Terminated  # (experiments extra: not on --help)
    from sb3_affect.study.launcher.store import StoreError  # (experiments extra: not on --help)

    try:
        return int(args.func(args))
    except (SweepError, StoreError, UsageError, RayClusterError) as error:
        print(f"sb3-affect: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        how = "terminated" if isinstance(interrupt, Terminated) else "interrupted"
        if isinstance(interrupt, ClusterLost):
            how = interrupt.message
        print(f"\nsb3-affect: {how}; finished runs are kept, rerun the same command to resume", file=sys.stderr)
        return 143 if isinstance(interrupt, Terminated) else 130


if __name__ == "__main__":
    sys.exit(main())
