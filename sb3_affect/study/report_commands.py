"""
What ``sb3-affect report``, ``sb3-affect replicate`` and ``sb3-affect forensics`` do (the report extra). The parser is
``sb3_affect.study.cli``, which imports this module only when one of these commands runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

from pydantic import ValidationError

from sb3_affect.study import replicate
from sb3_affect.study.forensics.section import report_section
from sb3_affect.study.forensics.study_run import run_study, summary_lines
from sb3_affect.study.launcher.schema import Sweep
from sb3_affect.study.launcher.signals import stop_on_sigterm
from sb3_affect.study.launcher.sweep_file import load_sweep_file
from sb3_affect.study.report import build_report
from sb3_affect.study.studies import shipped_sweeps_folder
from sb3_affect.study.sweep_commands import UsageError, check_out, existing_folder


def report(args: argparse.Namespace) -> int:
    """``sb3-affect report DIR``: the report of a results folder, into it or into ``--out``."""
    root = existing_folder(args.dir, "report")
    if not any(root.iterdir()):
        raise UsageError(f"{args.dir}: the folder is empty; run a sweep into it (`sb3-affect run FILE --out {args.dir}`)")
    out = Path(args.out) if args.out else root
    check_out(str(out))
    unwritable = f"{out}: not writable, so the report can not be written there; write it elsewhere with --out DIR"
    if out.exists() and not os.access(out, os.W_OK | os.X_OK):
        raise UsageError(unwritable)

    extra = report_section(root / "forensics")  # the forensics section, when the folder holds its results
    try:
        command = " ".join(["sb3-affect", *sys.argv[1:]])
        path = build_report(root, out=out, extra_sections=[extra] if extra is not None else [], command=command)
    except PermissionError as error:
        raise UsageError(f"{unwritable} ({error.strerror}: {error.filename})") from None
    except (FileNotFoundError, ValueError) as error:  # no results in a layout the report knows, or no finished run
        raise UsageError(f"{args.dir}: no report can be built: {error}") from None
    print(f"report: {path} and {path.with_suffix('.html')} (open it in a browser)")
    return 0


def replicate_command(args: argparse.Namespace) -> int:
    """``sb3-affect replicate``: the main job (``sb3_affect.study.replicate``)."""
    stop_on_sigterm()
    check_out(args.out)
    start = time.perf_counter()
    report = replicate.main(
        out_dir=Path(args.out), workers=args.workers, large_seeds=args.large_seeds, forensics=not args.no_forensics,
        command=" ".join(["sb3-affect", *sys.argv[1:]]), backend=args.backend, ray_address=args.ray_address,
    )
    minutes, seconds = divmod(time.perf_counter() - start, 60)
    print(f"done in {int(minutes)} min {seconds:.0f} s. Open {report.with_suffix('.html')} in a browser to read the report.")
    return 0


def forensics(args: argparse.Namespace) -> int:
    """``sb3-affect forensics``: the study of the shipped experiments/forensics.yaml with the command's sizes and grid."""
    path = shipped_sweeps_folder() / "forensics.yaml"
    shipped = load_sweep_file(path, build=False)
    given = {"screen_reps": args.screen_reps, "leaders": args.leaders, "reps": args.reps}
    given.update({key: list(getattr(args, key)) for key in ("alphas", "gammas") if getattr(args, key)})
    try:
        study = Sweep.validate_saved({**shipped.model_dump(), "forensics": {**shipped.model_dump()["forensics"], **given}})
    except ValidationError as error:
        first = error.errors()[0]
        option = f"--{str(first['loc'][-1]).replace('_', '-')}={first['input']!r}: " if first["loc"] else ""
        raise SystemExit(f"sb3-affect forensics: error: {option}{first['msg'].removeprefix('Value error, ')}") from None
    stop_on_sigterm()  # `kill`: stop like Ctrl-C (the pool's workers first), exit 143
    executor = {"backend": args.backend, "ray_address": args.ray_address}
    overrides = [f"forensics.{key}={value}" for key, value in given.items()]  # as `sb3-affect run forensics --set ...`
    result = run_study(path, args.out, overrides, workers=args.workers, progress=not args.no_progress, **executor)
    print("\n".join(summary_lines(study, result, args.out)))
    return 0


#: The commands this module runs, by name.
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    "report": report, "replicate": replicate_command, "forensics": forensics,
}
