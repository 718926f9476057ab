"""``infonav train``'s input checked before any work: hyperparameters, options per backend, --timesteps against the
rollout, --init-from-planner files, Ray addresses; nothing half-written, no temp folders left behind."""

import contextlib
import socket
import threading
import time

import pytest
from conftest import unused_address

from agents.ray_support import check_reachable
from infonav_gym.experiments.cli import main

LANDMARK_ID = "infonav/LandmarkSelection-v0"


def refused(capsys, argv) -> str:
    """``infonav ARGV`` exits 2 with one line on stderr and no traceback, before any work; the line."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    out, err = capsys.readouterr()
    assert exit_info.value.code == 2 and "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith(f"infonav {argv[0]}: error: ")
    return err.strip()


@contextlib.contextmanager
def http2_server(status: bytes | None):
    """``127.0.0.1:PORT`` of a server that answers any HTTP/2 request with a SETTINGS frame, then response headers
    starting with the HPACK byte ``status`` (``b"\\x88"``: 200, a gRPC server; ``b"\\x8d"``: 404, an HTTP proxy);
    ``None``: it accepts connections and never answers."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()

        def answer():
            connection, _ = listener.accept()
            with connection:
                connection.recv(4096)
                connection.sendall(bytes(3) + b"\x04" + bytes(5) + b"\x00\x00\x01\x01\x05\x00\x00\x00\x01" + status)

        thread = threading.Thread(target=answer, daemon=True)
        if status is not None:
            thread.start()
        yield f"127.0.0.1:{listener.getsockname()[1]}"
        if status is not None:
            thread.join(timeout=5)


def test_a_grpc_server_passes_the_ray_address_check():
    with http2_server(b"\x88") as address:
        check_reachable(address)


@pytest.mark.parametrize(
    ("address", "message"),
    [
        (unused_address, "(Connection refused)"),
        (lambda: http2_server(None), "it did not answer within 1 s"),
        (lambda: http2_server(b"\x8d"), "the port answers, but not as Ray's gRPC server"),  # e.g. an HTTP/2 proxy
    ],
    ids=["refused", "silent", "http-proxy"],
)
def test_an_address_without_a_ray_cluster_is_refused_within_seconds(address, message):
    with address() as where:
        start = time.perf_counter()
        with pytest.raises(ValueError, match=f"^cannot reach a Ray cluster at '{where}'") as error:
            check_reachable(where, timeout_s=1.0)
    assert message in str(error.value) and time.perf_counter() - start < 2


@pytest.mark.parametrize("address", ["localhost:99999", "localhost:0", ":6379", "a:b:6379", "host:port", "ray://"])
def test_a_malformed_ray_address_is_refused_naming_it(capsys, address):
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10", "--address", address]
    assert f"Ray address {address!r} is not HOST:PORT with a port from 1 to 65535" in refused(capsys, argv)


def test_train_refuses_an_http_proxy_as_a_ray_cluster_in_one_line(capsys):
    with http2_server(b"\x8d") as address:
        argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10", "--address", address]
        assert "not as Ray's gRPC server" in refused(capsys, argv)
