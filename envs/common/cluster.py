"""Starting or joining Ray for the project's parallel jobs (the leaderboard's rows, the swarm's workers, the
calibration matrix's cases)."""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path
from typing import Any

ADDRESS_TIMEOUT = 5.0
"""Seconds to wait for a cluster's address to answer before it is refused (``ray.init`` retries for minutes)."""


class ClusterError(RuntimeError):
    """A Ray cluster that cannot be joined: the message says why and what to do, in one line."""


def check_address(address: str, timeout: float = ADDRESS_TIMEOUT) -> None:
    """Refuse at once a cluster address that is not ``HOST:PORT`` (or ``ray://HOST:PORT``, or ``auto``) or where
    nothing answers: ``ray.init`` would retry such an address for minutes before it failed."""
    if address == "auto":
        return
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ClusterError(f"--address {address!r}: expected HOST:PORT, as `ray start --head` prints it")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise ClusterError(f"--address {address}: nothing answers there ({exc.strerror or exc}); start the cluster "
                           "with `ray start --head` and give the address it prints") from None  # fmt: skip


def _token_available() -> bool:
    """Whether a Ray authentication token is at hand: ``RAY_AUTH_TOKEN``, the file at ``RAY_AUTH_TOKEN_PATH``, or
    ``~/.ray/auth_token`` (where ``ray start`` and ``ray get-auth-token --generate`` keep it)."""
    if os.environ.get("RAY_AUTH_TOKEN"):
        return True
    path = os.environ.get("RAY_AUTH_TOKEN_PATH") or Path.home() / ".ray" / "auth_token"
    return Path(path).is_file()


def init_ray(address: str | None = None, **kwargs: Any) -> None:
    """``ray.init`` for a job of ours: join the cluster at ``address``, or start a local instance whose workers run
    at the driver's priority. Ray lowers its workers' priority (niceness 15) by default, so on a machine shared
    with other work (a test suite, another benchmark) a local job's tasks got a small share of the CPU while the
    driver waited on them; the measured wall time then said more about the neighbours than about the job.

    Joining: Ray 2.59 and later start a head (``ray start --head``) with token authentication on a machine that
    holds a token (``~/.ray/auth_token``), while a driver that joins an address sends none unless
    ``RAY_AUTH_MODE=token``. Where the user has not set
    ``RAY_AUTH_MODE`` and a token is at hand, the driver sends it (a cluster without authentication ignores it);
    this takes effect only before Ray is first imported in the process. A cluster that cannot be joined raises
    :class:`ClusterError`."""
    if address and "RAY_AUTH_MODE" not in os.environ and "ray" not in sys.modules and _token_available():
        os.environ["RAY_AUTH_MODE"] = "token"
    import ray

    local = {} if address else {"_system_config": {"worker_niceness": 0}}
    try:
        ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False, **local,
                 **kwargs)  # fmt: skip
    except ConnectionError as exc:
        if not address:
            raise
        chain, link = [], exc
        while link is not None and len(chain) < 10:
            chain.append(str(link))
            link = link.__cause__ or link.__context__
        if any("uthentication" in text for text in chain):
            raise ClusterError(f"--address {address}: the Ray cluster there asks for its authentication token: set "
                               "RAY_AUTH_MODE=token and RAY_AUTH_TOKEN, or keep the head's token (`ray get-auth-token` "
                               "there) in ~/.ray/auth_token") from None  # fmt: skip
        raise ClusterError(f"--address {address}: cannot join the Ray cluster there ({str(exc).strip() or 'no answer'})"
                           ) from None  # fmt: skip


def ensure_ray(address: str | None = None, **kwargs: Any):
    """The ``ray`` module, joined to ``address`` (or a local instance started) by :func:`init_ray` unless this process
    already runs Ray; Ray is imported only after :func:`init_ray` has set up the token."""
    running = sys.modules.get("ray")
    if running is None or not running.is_initialized():
        init_ray(address, **kwargs)
    import ray

    return ray
