"""The seeds of a team run's hunters: one independent stream per hunter and run, derived from the run's seed."""

from __future__ import annotations

import hashlib
import json


def member_seed(seed: int, index: int) -> int:
    """The seed of hunter ``index`` in a team run with ``seed`` (sha256: independent streams per hunter and run)."""
    digest = hashlib.sha256(json.dumps(["hunter", int(seed), int(index)]).encode()).digest()
    return int.from_bytes(digest[:4], "big") & 0x7FFFFFFF
