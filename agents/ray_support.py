"""Ray for RLlib training and parallel evaluation: importing it with a one-line hint, a local Ray or a cluster.

``local_or_cluster_ray(address)`` starts a local Ray (and stops it afterwards) when ``address`` is None, else
connects to the cluster at ``address`` (``HOST:PORT`` of ``ray start --head``, or ``ray://HOST:PORT``) after
checking within ``CONNECT_TIMEOUT_S`` that something answers there: Ray itself would retry for minutes.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator

DISTRIBUTED_HINT = 'pip install "infonav-gym[distributed]"'
CONNECT_TIMEOUT_S = 10.0
DEFAULT_GCS_PORT = 6379  # ray start --head's default


def import_ray():
    """The ``ray`` module, or ``ValueError`` saying how to install it."""
    try:
        import ray
    except ImportError as error:
        raise ValueError(f"Ray is not installed ({error}): {DISTRIBUTED_HINT}") from None
    return ray


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """``ValueError`` unless a TCP connection to ``address`` (``[ray://]HOST[:PORT]``) opens within ``timeout_s``."""
    host, _, port_text = address.removeprefix("ray://").rpartition(":")
    if not host:
        host, port_text = port_text, str(DEFAULT_GCS_PORT)
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"Ray address {address!r} is not HOST:PORT (e.g. 127.0.0.1:6379)") from None
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as error:
        raise ValueError(f"cannot reach a Ray cluster at {address!r} within {timeout_s:g} s ({error})") from None


@contextlib.contextmanager
def local_or_cluster_ray(address: str | None = None) -> Iterator:
    """Ray connected to the cluster at ``address``, or a local Ray started (and stopped) here; yields ``ray``.

    Inside an already initialized Ray (a caller's), that one is used and left running (``address`` is still
    checked: a wrong one is an error, not ignored).
    """
    ray = import_ray()
    if address is not None:
        check_reachable(address)
    if ray.is_initialized():
        yield ray
        return
    ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        yield ray
    finally:
        ray.shutdown()
