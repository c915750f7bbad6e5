"""
What ``sb3-affect run`` and ``sb3-affect status`` do (the experiments extra), and how every command's errors end: one
line on stderr and exit 2 for bad input, 130 or 143 for an interruption (``dispatch``). The parser is
``sb3_affect.study.cli``, which imports this module only when one of these commands runs.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

from sb3_affect.study.launcher import ResultsStore
from sb3_affect.study.launcher.driver_process import is_driver, run_as_child
from sb3_affect.study.launcher.ray_errors import ClusterLost, RayClusterError
from sb3_affect.study.launcher.schema import SweepError
from sb3_affect.study.launcher.signals import Terminated, stop_on_sigterm
from sb3_affect.study.launcher.store import StoreError, folder_kind
from sb3_affect.study.running import run_file


class UsageError(Exception):
    """A command-line argument that can not be used (printed as ``sb3-affect: error: ...``, exit 2)."""


def dispatch(args: argparse.Namespace, commands: Mapping[str, Callable[[argparse.Namespace], int]] | None = None) -> int:
    """
    Run the command ``args`` names, from ``commands`` (default: this module's ``COMMANDS``); its errors end in one line
    on stderr (exit 2), an interruption in 130 or 143. On the ray backend the command runs in a child process
    (``driver_process``).
    """
    try:
        if getattr(args, "backend", "local") == "ray" and not is_driver():  # Ray may end its driver abruptly: a child
            return run_as_child(args.argv, args.out, args.ray_address)  # drives it (run, forensics, replicate)
        return int((commands or COMMANDS)[args.command](args))
    except (SweepError, StoreError, UsageError, RayClusterError) as error:
        print(f"sb3-affect: error: {error}", file=sys.stderr)
        return 2
    except (ValueError, RuntimeError) as error:  # the launcher's checks of its arguments: one line, never a traceback
        print(f"sb3-affect: error: {' '.join(str(error).split()) or type(error).__name__}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as interrupt:
        how = "terminated" if isinstance(interrupt, Terminated) else "interrupted"
        if isinstance(interrupt, ClusterLost):
            how = interrupt.message
        print(f"\nsb3-affect: {how}; finished runs are kept, rerun the same command to resume", file=sys.stderr)
        return 143 if isinstance(interrupt, Terminated) else 130


def check_out(out: str) -> None:
    """``--out`` must be a folder (new, or one an earlier run wrote), not a file."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise UsageError(f"--out {out}: this is a file; give a results folder (a new one, or one an earlier run wrote)")


def existing_folder(directory: str, command: str) -> Path:
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


def run(args: argparse.Namespace) -> int:
    """``sb3-affect run FILE --out DIR``: a study file of any kind (``running.run_file``), resumed."""
    check_out(args.out)
    stop_on_sigterm()
    done = run_file(
        args.file,
        args.out,
        args.set or (),
        args.logs,
        workers=args.workers,
        backend=args.backend,
        ray_address=args.ray_address,
        ray_timeout=args.ray_timeout,
        progress=not args.no_progress,
    )
    print("\n".join(done.lines))
    return 1 if done.failed else 0


def status(args: argparse.Namespace) -> int:
    """``sb3-affect status DIR``: how far the study in a folder is, or each study of a `replicate` folder."""
    root = existing_folder(args.dir, "status")
    held = folder_kind(root)  # (a study of an earlier layout: refused, in one line)
    if held is not None and held[0] == "sweep":
        folders = [root]
    else:  # a `replicate` folder: one study per sub-folder (paper/, dqn/, ..., the forensics', the deep study's)
        folders = [sub for sub in sorted(root.iterdir()) if sub.is_dir() and (folder_kind(sub) or ("",))[0] == "sweep"]
    if not folders:
        print(
            f"{root}: no sweep has been run here (no sweep.json, nor sub-folders with one); "
            "start one with `sb3-affect run FILE --out DIR`",
            file=sys.stderr,
        )
        return 2
    if folders != [root]:
        print(f"{root}: {len(folders)} {'study' if len(folders) == 1 else 'studies'}")
    for folder in folders:
        _print_status(folder)
    for name in REPORTS:
        if (root / name).exists():
            print(f"report: {root / name}")
    return 0


def _print_status(root: Path) -> None:
    store = ResultsStore(root)
    try:  # agent -> (runs, done, failed); files that do not count
        name, per_agent, rejected = store.progress()
    except FileNotFoundError as error:  # sweep.json and its copies unreadable
        raise UsageError(f"{error}: its sweep.json and the copies of it can not be read") from None
    total, done, failed = (sum(counts[i] for counts in per_agent.values()) for i in range(3))
    print(f"sweep {name!r} in {store.root}: {done}/{total} runs done, {failed} failed")
    for agent, (runs, done_agent, failed_agent) in per_agent.items():
        if runs:
            print(f"  {agent:24s} {done_agent:5d}/{runs:<5d} done  {failed_agent} failed")
    if failed:
        print(f"  failed runs: their tracebacks are in {store.failed}; the next run retries them")
    plan = store.plan()
    if plan is not None and not plan[1]:
        print("  a study in stages: the runs of its next stage are planned once these are done (rerun the same command)")
    for path, why in rejected:
        print(f"  not counted: {path} {why}; the next run moves it to damaged/ and runs its runs again")
    owner = store.lock_owner()
    if owner is not None:
        print(f"  in use by launcher pid {owner} (running)")


#: The reports ``status`` names when a folder holds them (``sb3-affect report``'s, the forensics' own section).
REPORTS = ("report.html", "forensics.md")
#: The commands this module runs, by name.
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {"run": run, "status": status}
