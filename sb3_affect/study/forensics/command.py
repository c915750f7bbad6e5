"""The ``sb3-affect forensics`` subcommand (its arguments and what it runs)."""

from __future__ import annotations

import argparse
from typing import Any


def _floats(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers, e.g. 0.5,1.0") from None
    if not values:
        raise argparse.ArgumentTypeError("the list is empty; give at least one number, e.g. 0.8")
    return values


def add_forensics_parser(sub: Any) -> argparse.ArgumentParser:
    """Add ``forensics`` to the ``sb3-affect`` subcommands."""
    parser = sub.add_parser(
        "forensics",
        help="which candidate implementation could have produced the paper's printed numbers (resumable)",
        description="Simulate the paper's protocol many times per candidate implementation, score the printed "
        "numbers of Tables IV and V and the 27.35 episodes under each, rank the candidates (docs/forensics.md). "
        "Writes DIR/forensics.md (tables and a figure); rerun the same command to resume. The study of the shipped "
        "sweep file experiments/forensics.yaml with the sizes and grid below: the same as `sb3-affect run forensics "
        "--out DIR --set reps=100 ...`.",
    )
    parser.add_argument("--out", required=True, help="results folder, e.g. runs/forensics")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    parser.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes (default) or Ray tasks")
    parser.add_argument(
        "--ray-address", default=None, help="Ray cluster address, HOST:PORT or ray://HOST:PORT (default: a private instance)"
    )
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
    parser.set_defaults(func=forensics_command)
    return parser


def forensics_command(args: argparse.Namespace) -> int:
    """Run the study of the shipped experiments/forensics.yaml with the command's sizes and grid."""
    from pydantic import ValidationError  # (lazy for --help)

    from sb3_affect.study.forensics.study_run import run_study, summary_lines  # (lazy for --help)
    from sb3_affect.study.launcher.signals import stop_on_sigterm  # (lazy for --help)
    from sb3_affect.study.launcher.study_schema import ForensicsStudy  # (lazy for --help)
    from sb3_affect.study.launcher.sweep_file import load_sweep_file, shipped_sweeps_folder  # (lazy for --help)

    if args.workers < 1:
        raise SystemExit(f"sb3-affect forensics: error: --workers={args.workers} must be >= 1")
    shipped = load_sweep_file(shipped_sweeps_folder() / "forensics.yaml", build=False)
    given = {"screen_reps": args.screen_reps, "leaders": args.leaders, "reps": args.reps}
    given.update({key: list(getattr(args, key)) for key in ("alphas", "gammas") if getattr(args, key)})
    try:
        study = ForensicsStudy.model_validate({**shipped.model_dump(), **given})
    except ValidationError as error:
        first = error.errors()[0]
        option = f"--{str(first['loc'][0]).replace('_', '-')}={first['input']!r}: " if first["loc"] else ""
        raise SystemExit(f"sb3-affect forensics: error: {option}{first['msg'].removeprefix('Value error, ')}") from None
    stop_on_sigterm()  # `kill`: stop like Ctrl-C (the pool's workers first), exit 143
    executor = {"backend": args.backend, "ray_address": args.ray_address}
    result = run_study(study, args.out, workers=args.workers, progress=not args.no_progress, **executor)
    print("\n".join(summary_lines(study, result, args.out)))
    return 0
