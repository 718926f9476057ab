"""Ray for RLlib training and parallel evaluation: importing it with a one-line hint, a local Ray or a cluster.

``local_or_cluster_ray(address)`` starts a local Ray (and stops it afterwards) when ``address`` is None, else
connects to the cluster at ``address`` (``HOST:PORT`` of ``ray start --head``, or ``ray://HOST:PORT``) after
checking within ``CONNECT_TIMEOUT_S`` that a gRPC server answers there: Ray itself would retry for minutes.
"""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Iterator

DISTRIBUTED_HINT = 'pip install "infonav-gym[distributed]"'
CONNECT_TIMEOUT_S = 3.0  # connection and handshake: a wrong address is an error within 10 s, imports included
HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])  # + an empty SETTINGS frame
HTTP2_FRAME_HEADER_BYTES = 9  # length (3 bytes), type, flags, stream id (4)
HTTP2_SETTINGS = 4  # the frame type a gRPC server sends first
DEFAULT_GCS_PORT = 6379  # ray start --head's default


def import_ray(address: str | None = None):
    """The ``ray`` module, or ``ValueError`` saying how to install it; with ``address``, once ``check_reachable``
    has found a cluster there (checked first: importing Ray takes seconds)."""
    if address is not None:
        check_reachable(address)
    try:
        import ray
    except ImportError as error:
        raise ValueError(f"Ray is not installed ({error}): {DISTRIBUTED_HINT}") from None
    return ray


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """``ValueError`` unless a gRPC server (Ray's GCS or client server) answers at ``address`` (``[ray://]HOST[:PORT]``)
    within ``timeout_s``: a TCP connection opens and the HTTP/2 handshake comes back."""
    host, _, port_text = address.removeprefix("ray://").rpartition(":")
    if not host:
        host, port_text = port_text, str(DEFAULT_GCS_PORT)
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"Ray address {address!r} is not HOST:PORT (e.g. 127.0.0.1:6379)") from None
    deadline = time.monotonic() + timeout_s
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as connection:
            connection.settimeout(max(deadline - time.monotonic(), 0.01))
            connection.sendall(HTTP2_PREFACE)
            reply = connection.recv(HTTP2_FRAME_HEADER_BYTES, socket.MSG_WAITALL)
    except OSError as error:
        raise ValueError(f"cannot reach a Ray cluster at {address!r} within {timeout_s:g} s ({error})") from None
    if len(reply) < HTTP2_FRAME_HEADER_BYTES or reply[3] != HTTP2_SETTINGS:
        raise ValueError(
            f"cannot reach a Ray cluster at {address!r}: the port answers, but not as a gRPC server (Ray's GCS) does"
        )


@contextlib.contextmanager
def local_or_cluster_ray(address: str | None = None) -> Iterator:
    """Ray connected to the cluster at ``address``, or a local Ray started (and stopped) here; yields ``ray``.

    Inside an already initialized Ray (a caller's), that one is used and left running (``address`` is still
    checked: a wrong one is an error, not ignored).
    """
    ray = import_ray(address)
    if ray.is_initialized():
        yield ray
        return
    ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        yield ray
    finally:
        ray.shutdown()
