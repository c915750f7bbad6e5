"""
Reaching a Ray cluster without hanging: the address tried with a TCP connection and one gRPC call to the head node's GCS
(a wrong port, a port that is not Ray's, a silent address or a missing token each get a message at once, where
``ray.init`` retries forever), then ``ray.init`` given a deadline. Used by :mod:`sb3_affect.study.launcher.ray_cluster`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import grpc
from ray.core.generated import gcs_service_pb2, gcs_service_pb2_grpc

from sb3_affect.study.launcher.ray_errors import RayClusterError


def plain_text(text: str) -> str:
    """Ray's error messages without their terminal colour codes."""
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


def _auth_hint(address: str) -> str:
    mode = os.environ.get("RAY_AUTH_MODE")
    return (
        f"could not authenticate with the Ray cluster at {address} (RAY_AUTH_MODE={mode or 'unset'}): a cluster started "
        "with token authentication (Ray writes ~/.ray/auth_token when it first starts one) needs RAY_AUTH_MODE=token here, "
        "and the cluster's token in RAY_AUTH_TOKEN or ~/.ray/auth_token; a cluster without it needs RAY_AUTH_MODE=disabled"
    )


def _driver_token() -> str | None:
    """The token this driver would present (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH`` or ``~/.ray/auth_token``)."""
    if os.environ.get("RAY_AUTH_TOKEN"):
        return os.environ["RAY_AUTH_TOKEN"].strip()
    path = Path(os.environ.get("RAY_AUTH_TOKEN_PATH") or Path.home() / ".ray" / "auth_token")
    with contextlib.suppress(OSError):
        return path.read_text().strip() or None
    return None


def handshake(address: str, host: str, port: int, timeout: float) -> None:
    """
    Ask the head node's GCS for its cluster id (one gRPC call) before ``ray.init``, which retries a wrong port or a
    missing token forever: raise :class:`RayClusterError` saying what is wrong, or return if Ray would get in.
    """
    token_mode = os.environ.get("RAY_AUTH_MODE", "").lower() == "token"
    token = _driver_token() if token_mode else None
    metadata = [("authorization", f"Bearer {token}")] if token else []
    channel = grpc.insecure_channel(f"{host}:{port}")
    try:
        stub = gcs_service_pb2_grpc.NodeInfoGcsServiceStub(channel)
        request = gcs_service_pb2.GetClusterIdRequest()  # type: ignore[attr-defined]
        stub.GetClusterId(request, timeout=timeout, metadata=metadata)
    except grpc.RpcError as error:
        code = error.code()
        if code == grpc.StatusCode.UNAUTHENTICATED:
            if token_mode and token:
                raise RayClusterError(
                    f"the Ray cluster at {address} rejected this driver's token (RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or "
                    "~/.ray/auth_token): use the token of the machine that started the head node"
                ) from None
            raise RayClusterError(_auth_hint(address)) from None
        if code == grpc.StatusCode.UNIMPLEMENTED:
            raise RayClusterError(
                f"{address} answers, but it is not a Ray head node's GCS port: give the port of `ray start --head --port` "
                "(6379 by default), or ray://HOST:10001 for Ray's client server"
            ) from None
        raise RayClusterError(
            f"no Ray cluster answered at {address} within {timeout:g} s ({code.name}): check --ray-address, or raise "
            "--ray-timeout"
        ) from None
    finally:
        channel.close()


class _DropMessage(logging.Filter):
    """A logging filter that drops records containing ``text``."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text

    def filter(self, record: logging.LogRecord) -> bool:
        return self.text not in record.getMessage()


def init_with_timeout(ray: Any, address: str, timeout: float, runtime_env: dict[str, Any]) -> None:
    """``ray.init(address)`` that gives up after ``timeout`` seconds (Ray itself retries a silent address forever)."""
    outcome: dict[str, BaseException | None] = {}

    def connect() -> None:
        try:
            ray.init(address=address, log_to_driver=False, runtime_env=runtime_env)
            outcome["error"] = None
        except BaseException as error:
            outcome["error"] = error

    thread = threading.Thread(target=connect, name="sb3-affect:ray-connect", daemon=True)
    quiet = _DropMessage("SIGTERM handler is not set")  # ray.init in a thread; the CLI has its own SIGTERM handler
    logging.getLogger("ray._private.worker").addFilter(quiet)
    thread.start()
    thread.join(timeout)
    logging.getLogger("ray._private.worker").removeFilter(quiet)
    if thread.is_alive():
        raise RayClusterError(
            f"no Ray cluster answered at {address} within {timeout:g} s (the port is open, but Ray did not respond): "
            "check --ray-address (the head node's GCS port, 6379 by default, or ray://HOST:10001), or raise --ray-timeout"
        )
    error = outcome.get("error")
    if error is None:
        return
    text = plain_text(str(error))
    if type(error).__name__ == "AuthenticationError" or "authenticat" in text.lower() or "auth_token" in text:
        raise RayClusterError(_auth_hint(address)) from None
    raise RayClusterError(f"could not connect to the Ray cluster at {address}: {type(error).__name__}: {text}") from None


@contextlib.contextmanager
def working_directory(path: Path) -> Iterator[None]:
    previous = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(previous)


def shutdown_within(ray: Any, timeout: float = 20.0) -> None:
    """``ray.shutdown()``, given up after ``timeout`` seconds (it can wait long for a cluster that is gone)."""
    thread = threading.Thread(target=ray.shutdown, name="sb3-affect:ray-shutdown", daemon=True)
    thread.start()
    thread.join(timeout)
