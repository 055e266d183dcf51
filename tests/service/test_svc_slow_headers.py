"""Slowloris on the headers: a real uvicorn (``snapwarn serve``, httptools and h11) and raw
sockets. A client that trickles its header lines, or connects and sends nothing, is cut off
after SNAPWARN_HEADER_READ_TIMEOUT_S (408 when a request had begun); more header bytes than
SNAPWARN_MAX_HEADER_BYTES: 431; a request whose headers arrive in time, and a kept-alive
connection's later requests, are untouched. (uvicorn alone holds such connections for ever:
its keep-alive timer stops at a request's first byte and is never set on a new connection.)"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from urllib.parse import urlsplit

import pytest
from _svc_helpers import Server, start_server

TIMEOUT_S = 2.0
SLACK_S = 3.0  # the server's timer fires on a loaded machine (2 cores shared)


@pytest.fixture(scope="module", params=["httptools", "h11"])
def server(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Server]:
    tmp = tmp_path_factory.mktemp(f"headers-{request.param}")
    s = start_server(f"sqlite:///{tmp / 'h.db'}", tmp, extra_env={
        "SNAPWARN_HEADER_READ_TIMEOUT_S": str(TIMEOUT_S), "SNAPWARN_MAX_HEADER_BYTES": "4096",
        "SNAPWARN_HTTP_IMPL": request.param, "SNAPWARN_WARM_POOL": "false"})  # fmt: skip
    yield s
    s.stop()


def _connect(server: Server) -> socket.socket:
    u = urlsplit(server.url)
    sock = socket.create_connection((u.hostname, u.port), timeout=TIMEOUT_S + SLACK_S + 5)
    return sock


def _read_all(sock: socket.socket) -> bytes:
    """Everything until the server closes (a socket timeout fails the test: still open)."""
    out = b""
    while chunk := sock.recv(65536):
        out += chunk
    return out


def test_trickled_headers_get_408_and_the_connection_closed(server: Server) -> None:
    sock = _connect(server)
    t0 = time.monotonic()
    sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    answer = b""
    try:
        for _ in range(int((TIMEOUT_S + SLACK_S) / 0.25) + 20):  # one byte of a header a tick
            sock.sendall(b"x")
            time.sleep(0.25)
    except (BrokenPipeError, ConnectionResetError):
        pass
    try:
        answer = _read_all(sock)
    except ConnectionResetError:
        pass
    elapsed = time.monotonic() - t0
    sock.close()
    assert answer.startswith(b"HTTP/1.1 408 "), answer[:200]
    assert b"SNAPWARN_HEADER_READ_TIMEOUT_S" in answer
    assert TIMEOUT_S - 0.1 <= elapsed <= TIMEOUT_S + SLACK_S + 1, elapsed


def test_a_silent_connection_is_closed(server: Server) -> None:
    sock = _connect(server)
    t0 = time.monotonic()
    assert _read_all(sock) == b""  # closed without an answer: no request had begun
    assert time.monotonic() - t0 <= TIMEOUT_S + SLACK_S, time.monotonic() - t0
    sock.close()


def test_too_many_header_bytes_get_431(server: Server) -> None:
    sock = _connect(server)
    sock.sendall(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n")
    try:
        for _ in range(10):
            sock.sendall(b"X-Padding: " + b"a" * 1000 + b"\r\n")
    except (BrokenPipeError, ConnectionResetError):
        pass
    answer = _read_all(sock)
    sock.close()
    assert answer.startswith((b"HTTP/1.1 431 ", b"HTTP/1.1 400 ")), answer[:200]


def test_headers_in_time_and_kept_alive_requests_pass(server: Server) -> None:
    """Headers sent in pieces within the bound; then, on the same connection after a pause
    longer than the bound's half, a second request: both answered 200."""
    sock = _connect(server)
    head = b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    for k in range(0, len(head), 8):  # ~0.6 s in all
        sock.sendall(head[k : k + 8])
        time.sleep(0.1)
    first = sock.recv(65536)
    assert first.startswith(b"HTTP/1.1 200 "), first[:200]
    time.sleep(TIMEOUT_S * 0.6)  # idle, within uvicorn's keep-alive (5 s)
    sock.sendall(head)
    second = sock.recv(65536)
    assert second.startswith(b"HTTP/1.1 200 "), second[:200]
    sock.close()
