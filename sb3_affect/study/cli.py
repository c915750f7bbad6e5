"""The ``sb3-affect`` command: run sweeps, show their status, build the report, run the whole replication."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from typing import Any

from sb3_affect import __version__
from sb3_affect.core.extras import MissingExtraError, require_extra
from sb3_affect.study.studies import MINUTES, PARTS, TUNED_PARTS, part_description


def _positive_int(text: str) -> int:
    """argparse type of ``--workers``: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not allowed: give 1 or more parallel runs (default: CPU count)")
    return value


def _executor_arguments(parser: argparse.ArgumentParser, workers: str, default: int | None = None) -> None:
    """``--workers`` (its default ``default``, described as ``workers``), ``--backend`` and ``--ray-address``."""
    parser.add_argument("--workers", type=_positive_int, default=default, help=f"parallel runs, >= 1 (default: {workers})")
    parser.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes (default) or Ray tasks")
    parser.add_argument(
        "--ray-address", default=None, help="Ray cluster address, HOST:PORT or ray://HOST:PORT (default: a private instance)"
    )


def _replicate_help() -> str:
    """``replicate --help``: what it runs (from ``sb3_affect.study.studies.PARTS``, so it can not drift) and writes."""
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


def _floats(text: str) -> tuple[float, ...]:
    """argparse type of ``--alphas`` and ``--gammas``: numbers separated by commas, at least one."""
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers, e.g. 0.5,1.0") from None
    if not values:
        raise argparse.ArgumentTypeError("the list is empty; give at least one number, e.g. 0.8")
    return values


def _add_forensics_parser(sub: Any) -> None:
    """Add ``forensics`` to the ``sb3-affect`` subcommands."""
    parser = sub.add_parser(
        "forensics",
        help="which candidate implementation could have produced the paper's printed numbers (resumable)",
        description="Simulate the paper's protocol many times per candidate implementation, score the printed "
        "numbers of Tables IV and V and the 27.35 episodes under each, rank the candidates (docs/forensics.md). "
        "Writes DIR/forensics.md (tables and a figure); rerun the same command to resume. The study of the shipped "
        "sweep file experiments/forensics.yaml with the sizes and grid below: the same as `sb3-affect run forensics "
        "--out DIR --set forensics.reps=100 ...`.",
    )
    parser.add_argument("--out", required=True, help="results folder, e.g. runs/forensics")
    _executor_arguments(parser, "2", default=2)
    parser.add_argument("--screen-reps", type=int, default=3, help="replications per simulation in the screen (default: 3)")
    parser.add_argument("--leaders", type=int, default=4, help="affective simulations replicated in full (default: 4)")
    parser.add_argument("--reps", type=int, default=100, help="replications of each leader (default: 100)")
    parser.add_argument(
        "--alphas", type=_floats, default=None, help="learning rates of the grid (default: experiments/forensics.yaml's)"
    )
    parser.add_argument(
        "--gammas", type=_floats, default=None, help="discounts of the grid (default: experiments/forensics.yaml's)"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


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
    _executor_arguments(run, "CPU count; on a Ray cluster: as many as its CPUs allow")
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
    status = sub.add_parser(
        "status",
        help="show how far a results folder is",
        description="Count finished and failed runs per agent (each study of a `replicate` folder), and whether a "
        "launcher is using the folder; a deep study's runs are its task x agent x seed, the forensics' the replications "
        "its stages planned so far.",
    )
    status.add_argument("dir", metavar="DIR", help="a results folder (the --out of `run` or `replicate`)")
    report = sub.add_parser(
        "report",
        help="build DIR/report.html (and .md, tables, figures) from a results folder",
        description="Build DIR/report.md, DIR/report.html (self-contained), DIR/tables/*.csv and DIR/figures/*.png. "
        "A `replicate` folder gives the full report; a single sweep folder the sections its runs allow; a deep study's "
        "folder its section.",
    )
    report.add_argument("dir", metavar="DIR", help="a results folder (the --out of `run` or `replicate`)")
    report.add_argument(
        "--out", metavar="OUT", default=None, help="write the report here instead of into DIR (e.g. DIR is read-only)"
    )
    replicate = sub.add_parser(
        "replicate",
        help="the main job: paper protocol, DQN, baselines, hunters, engine studies (1,000 seeds), then the report",
        description=_replicate_help(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    replicate.add_argument("--out", default="runs", metavar="OUT", help="results folder (default: runs)")
    _executor_arguments(replicate, "CPU count")
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
    _add_forensics_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)  # --help, --version and usage errors end here, having imported little
    args.argv = list(sys.argv[1:] if argv is None else argv)  # (the ray backend's driver runs them again as a child)

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
    """Run the command: the module of its extra holds it, imported here only (not on ``--help``)."""
    from sb3_affect.study import sweep_commands  # (experiments extra: not on --help)

    if _EXTRA_OF.get(args.command) == "report":
        from sb3_affect.study import report_commands  # (report extra: not on --help)

        return sweep_commands.dispatch(args, report_commands.COMMANDS)
    return sweep_commands.dispatch(args)


if __name__ == "__main__":
    sys.exit(main())
