"""
How the Ray backend fails, importable without Ray (the CLI reports these, and importing Ray before the backend has set
the environment Ray reads on import would bind a private instance beyond 127.0.0.1: ``launcher.executor``).
"""

from __future__ import annotations


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
