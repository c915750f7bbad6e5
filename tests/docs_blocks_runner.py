"""
Run docs code blocks as a reader pastes them, each alone: ``python docs_blocks_runner.py BLOCKS.json RESULTS.json``.

``BLOCKS.json`` is a list of ``{"id", "code", "folder"}``. Each block runs in a process of its own (forked from this one
after it imported the third-party libraries every block starts with: torch, Stable-Baselines3, numba; nothing of
sb3_affect), with a fresh namespace, in its own empty folder, its output in ``output.txt`` there. Nothing reaches the
network: ``huggingface_hub.upload_folder`` records its arguments instead of uploading. ``RESULTS.json`` maps each id to
its exit status, its CPU seconds (the forked process's own), its error and its uploads.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import traceback
from pathlib import Path
from typing import Any

import numba  # noqa: F401  (imported once here, not in every block's process)
import stable_baselines3  # noqa: F401


def run_block(code: str, name: str, folder: Path) -> None:
    """In the forked process: run ``code`` in ``folder`` and exit (0: it ran; 1: it raised, the error in error.txt)."""
    os.chdir(folder)
    with open("output.txt", "w") as output:
        os.dup2(output.fileno(), 1)
        os.dup2(output.fileno(), 2)
    sys.argv = [name]
    uploads: list[dict[str, Any]] = []
    status = 0
    try:
        if "upload_folder(" in code:
            import huggingface_hub

            huggingface_hub.upload_folder = lambda **kwargs: uploads.append({k: str(v) for k, v in kwargs.items()})
        exec(compile(code, name, "exec"), {"__name__": "__main__"})
    except BaseException as error:
        Path("error.txt").write_text(f"{type(error).__name__}: {error}\n{traceback.format_exc()}")
        status = 1
    Path("uploads.json").write_text(json.dumps(uploads))
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def main(blocks_file: str, results_file: str) -> None:
    results = {}
    for block in json.loads(Path(blocks_file).read_text()):
        folder = Path(block["folder"])
        folder.mkdir(parents=True, exist_ok=True)
        pid = os.fork()
        if pid == 0:
            run_block(block["code"], block["id"], folder)
        _, status, usage = os.wait4(pid, 0)
        error = folder / "error.txt"
        results[block["id"]] = {
            "status": os.waitstatus_to_exitcode(status),
            "cpu_seconds": usage.ru_utime + usage.ru_stime,
            "error": error.read_text() if error.exists() else "",
            "output": (folder / "output.txt").read_text()[-3000:],
            "uploads": json.loads((folder / "uploads.json").read_text()) if (folder / "uploads.json").exists() else [],
        }
    Path(results_file).write_text(json.dumps(results, indent=1))
    print(f"{len(results)} blocks; this process: {resource.getrusage(resource.RUSAGE_SELF).ru_utime:.1f} CPU s")


if __name__ == "__main__":
    main(*sys.argv[1:3])
