"""Ray for RLlib training and parallel evaluation: importing it with a one-line hint, a local Ray or a cluster, whose
address is first probed with one gRPC call within ``CONNECT_TIMEOUT_S`` (Ray itself would retry for minutes)."""

from __future__ import annotations

import contextlib
import socket
import time
from collections.abc import Iterator

DISTRIBUTED_HINT = 'pip install "infonav-gym[distributed]"'
CONNECT_TIMEOUT_S = 2.0  # connection and one call: a wrong address is an error within a few seconds
DEFAULT_GCS_PORT = 6379  # ray start --head's default
HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n"
HTTP2_DATA, HTTP2_HEADERS, HTTP2_SETTINGS, HTTP2_GOAWAY = 0, 1, 4, 7  # frame types
END_STREAM, END_HEADERS = 1, 4  # frame flags
STREAM_1 = (1).to_bytes(4, "big")  # the one stream of the call
GRPC_PROBE_PATH = "/ray.rpc.NodeInfoGcsService/GetClusterId"  # Ray's GCS; any gRPC server answers it with HTTP 200
HPACK_STATUS_200 = 0x88  # HPACK's static-table entry 8, ``:status: 200``, as gRPC servers send it


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


def _host_and_port(address: str) -> tuple[str, int]:
    """``[ray://]HOST[:PORT]`` as ``(HOST, PORT)``; ``ValueError`` for anything else."""
    host, separator, port_text = address.removeprefix("ray://").rpartition(":")
    if not separator:
        host, port_text = port_text, str(DEFAULT_GCS_PORT)
    bracketed = host.startswith("[") and host.endswith("]")  # an IPv6 address
    if host and (bracketed or ":" not in host) and port_text.isdigit() and 1 <= int(port_text) <= 65535:
        return host.strip("[]"), int(port_text)
    raise ValueError(f"Ray address {address!r} is not HOST:PORT with a port from 1 to 65535 (e.g. 127.0.0.1:6379)")


def _frame(kind: int, flags: int, payload: bytes = b"") -> bytes:
    """An HTTP/2 frame on stream 1 (stream 0 for SETTINGS)."""
    stream = bytes(4) if kind == HTTP2_SETTINGS else STREAM_1
    return len(payload).to_bytes(3, "big") + bytes([kind, flags]) + stream + payload


def _grpc_call(authority: str) -> bytes:
    """The connection preface and one gRPC call of ``GRPC_PROBE_PATH`` with an empty message (HPACK literals)."""
    fields = {":method": "POST", ":scheme": "http", ":path": GRPC_PROBE_PATH, ":authority": authority}
    fields |= {"content-type": "application/grpc", "te": "trailers"}
    block = b"".join(
        b"\x00" + bytes([len(name)]) + name.encode() + bytes([len(value)]) + value.encode()
        for name, value in fields.items()
    )
    headers = _frame(HTTP2_HEADERS, END_HEADERS, block)
    message = _frame(HTTP2_DATA, END_STREAM, bytes(5))  # an empty message: not compressed, length 0
    return HTTP2_PREFACE + _frame(HTTP2_SETTINGS, 0) + headers + message


def _answers_grpc(connection: socket.socket, deadline: float) -> bool:
    """Whether the first response headers on stream 1 say ``:status: 200`` (a gRPC server's answer)."""
    received = b""
    while True:
        connection.settimeout(max(deadline - time.monotonic(), 0.01))
        chunk = connection.recv(4096)
        if not chunk:
            return False
        received += chunk
        while len(received) >= 9 and len(received) >= 9 + int.from_bytes(received[:3], "big"):
            length, kind, stream = int.from_bytes(received[:3], "big"), received[3], received[5:9]
            payload, received = received[9 : 9 + length], received[9 + length :]
            if kind == HTTP2_GOAWAY:
                return False
            if kind == HTTP2_HEADERS and stream == STREAM_1:
                return payload[:1] == bytes([HPACK_STATUS_200])


def check_reachable(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """``ValueError`` unless a gRPC server (Ray's GCS or client server) at ``address`` (``[ray://]HOST[:PORT]``)
    answers a call within ``timeout_s``: an HTTP proxy or a port that only accepts connections is no cluster."""
    host, port = _host_and_port(address)
    deadline = time.monotonic() + timeout_s
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as connection:
            connection.sendall(_grpc_call(f"{host}:{port}"))
            answered = _answers_grpc(connection, deadline)
    except TimeoutError:
        raise ValueError(
            f"cannot reach a Ray cluster at {address!r}: it did not answer within {timeout_s:g} s"
        ) from None
    except OSError as error:
        raise ValueError(f"cannot reach a Ray cluster at {address!r} ({error.strerror or error})") from None
    if not answered:
        raise ValueError(f"cannot reach a Ray cluster at {address!r}: the port answers, but not as Ray's gRPC server")


@contextlib.contextmanager
def local_or_cluster_ray(address: str | None = None) -> Iterator:
    """Ray connected to the cluster at ``address``, or a local Ray started (and stopped) here; yields ``ray``. Inside a
    caller's initialized Ray, that one is used and left running (a wrong ``address`` is still an error)."""
    ray = import_ray(address)
    if ray.is_initialized():
        yield ray
        return
    ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        yield ray
    finally:
        ray.shutdown()
