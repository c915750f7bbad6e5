"""
How the Ray backend fails, and whether a cluster's head still answers (a TCP connection to its GCS port), importable
without Ray (the CLI reports these, and importing Ray before the backend has set the environment Ray reads on import
would bind a private instance beyond 127.0.0.1: ``launcher.executor``).
"""

from __future__ import annotations

import re
import socket
import time


class RayClusterError(RuntimeError):
    """The Ray cluster can not be used for this sweep (unreachable, authentication, other package versions)."""


class ClusterLost(KeyboardInterrupt):
    """
    The Ray cluster stopped answering mid-sweep: stop like Ctrl-C (finished runs are kept).

    :param message: what was lost and how it showed
    """

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message

    @classmethod
    def of(cls, address: str | None, why: str) -> ClusterLost:
        """The one wording of a lost cluster: ``the Ray cluster at ADDRESS was lost mid-sweep: WHY``."""
        return cls(f"the Ray cluster at {address} was lost mid-sweep: {why}")


def host_port(address: str) -> tuple[str, int] | None:
    """``(host, port)`` of ``HOST:PORT``, ``ray://HOST:PORT`` or ``[IPv6]:PORT``; ``None`` for anything else."""
    match = re.fullmatch(r"(?:ray://)?\[?([^\]]+?)\]?:(\d+)", address.strip())
    return (match.group(1), int(match.group(2))) if match else None


def reachable(host: str, port: int, timeout: float) -> str | None:
    """``None`` if a TCP connection to ``host:port`` opens within ``timeout`` seconds, else why not."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as error:
        return error.strerror or type(error).__name__ if not isinstance(error, socket.timeout) else "timed out"
    return None


def head_stopped_answering(host: str, port: int) -> str | None:
    """Why the head node at ``host:port`` counts as gone (its GCS port refuses connections for 3 s), or ``None``."""
    for attempt in range(4):
        why = reachable(host, port, timeout=2.0)
        if why is None:
            return None
        if attempt < 3:
            time.sleep(1.0)
    return f"its head node at {host}:{port} stopped answering ({why})"
