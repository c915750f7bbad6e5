"""
Run ids: the name of each run of a sweep (its run file, its row in a chunk's footer), a readable prefix and a hash of
its resolved config.

The hash is of the config's JSON with sorted keys, so it does not depend on the order of the grid's labels; the
prefix lists the labels sorted by name too, so the launcher (which reads the sweep file) and ``status`` / ``report``
(which read ``sweep.json``, saved with sorted keys) name every run alike. Folders written when the prefix followed the
grid's order are still read: a stored id counts as its run's when it carries the run's hash and the prefix's
characters (``stored_matches``).
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Sequence
from typing import Any

from sb3_affect.core.episode_log import EPISODE_COLUMNS, TRACE_COLUMNS

#: The columns of the run table besides the labels (one column per label, ``replicate`` included).
RUN_COLUMNS = ("run_id", "agent", "algo", "seed", "decisions", "episodes", "wall_seconds", "max_timesteps")
#: Names a grid label can not take: the results' own columns (a label named so would replace one).
RESERVED_LABELS = frozenset({*RUN_COLUMNS, "replicate", "run", *EPISODE_COLUMNS, *TRACE_COLUMNS})

_SEED, _REPLICATE = 8_101_999_202_707_303, 8_101_999_202_707_404  # stand-ins no real config holds


def run_config(base: dict[str, Any], seed: int, replicate: int) -> dict[str, Any]:
    """The run config of one run of a cell, a batch or a chunk: the base with its seed and replicate."""
    return {**base, "seed": seed, "labels": {**base["labels"], "replicate": replicate}}


def run_id(config: dict[str, Any]) -> str:
    """Readable prefix (agent, labels sorted by name, seed) + hash of the resolved config (the file name of the run)."""
    digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
    labels = "-".join(f"{k}{v}" for k, v in sorted(config["labels"].items()) if k != "replicate")
    prefix = re.sub(r"[^A-Za-z0-9_.+-]+", "_", f"{config['agent']}-{labels}-s{config['seed']}".replace("--", "-"))
    return f"{readable(prefix)}-{digest}"


#: The most characters of a file name's readable part (run ids, chunks): with the hash and the suffixes the store adds
#: (``.json``, ``.parquet``, ``damaged/chunks-...``) a name stays far below the 255 bytes file systems allow.
MAX_READABLE = 160


def readable(prefix: str) -> str:
    """A readable prefix of a file name cut to ``MAX_READABLE`` characters (the hash after it keeps names distinct)."""
    return prefix[:MAX_READABLE]


def base_run_ids(base: dict[str, Any], runs: Sequence[tuple[Any, Any]]) -> list[str]:
    """
    ``run_id`` of each ``(seed, replicate)`` of a base config, encoding its JSON once: the texts of its runs differ
    only in the seed and the replicate number (checked on the first run; ``run_id`` per run if anything differs, or
    for a seed or replicate that is not a plain integer).
    """
    if not runs:
        return []
    probe = run_config(base, _SEED, _REPLICATE)
    text = json.dumps(probe, sort_keys=True)
    prefix = run_id(probe).rsplit("-", 1)[0]
    seed, replicate = str(_SEED), str(_REPLICATE)
    ids = []
    plain = all(type(s) is int and type(r) is int for s, r in runs)
    if plain and text.count(seed) == 1 and text.count(replicate) == 1 and prefix.count(seed) == 1 and replicate not in prefix:
        for value, index in runs:
            digest = hashlib.sha256(text.replace(replicate, str(index)).replace(seed, str(value)).encode()).hexdigest()
            ids.append(f"{prefix.replace(seed, str(value))}-{digest[:12]}")
    if not ids or ids[0] != run_id(run_config(base, *runs[0])):
        ids = [run_id(run_config(base, value, index)) for value, index in runs]
    return ids


def stored_matches(stored: str, canonical: str) -> bool:
    """
    Whether a run id stored in a file names the run whose ``run_id`` is ``canonical``: equal, or (a file written when
    the prefix followed the grid's label order) the same hash and a prefix of the same characters.
    """
    if stored == canonical:
        return True
    head, _, digest = stored.rpartition("-")
    own_head, _, own_digest = canonical.rpartition("-")
    return digest == own_digest and (sorted(head) == sorted(own_head) or readable(head) == own_head)
