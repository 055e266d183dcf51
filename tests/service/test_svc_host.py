"""DNS rebinding: a keyless loopback server answers only requests naming a loopback ``Host``
(or one of ``SNAPWARN_ALLOWED_HOSTS``), whether or not the browser sent ``Origin`` or
``Sec-Fetch-*`` (Safari 15 sends neither on a GET). Servers that need keys take any ``Host``.
"""

from __future__ import annotations

import socket
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from urllib.parse import urlsplit

import httpx2
import pytest
from _svc_helpers import start_server

from service.api import create_app
from service.api.settings import Settings

pytestmark = pytest.mark.anyio
W = {"dt": 0.1, "w": [0.0, 1.0, 0.5, -0.2, 0.1, 0.0, 0.05, -0.01]}


def _refused(r: httpx2.Response, host: str) -> None:
    assert r.status_code == 403, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    doc = r.json()
    assert doc["status"] == 403 and "Host" in doc["detail"]
    assert any(e.get("field") == "host" and e.get("value") == host for e in doc["errors"]), doc


@asynccontextmanager
async def _app(tmp_path, base_url: str = "http://asgi", **kw) -> AsyncIterator[httpx2.AsyncClient]:  # noqa: ANN001
    kw = {"api_key": None, **kw}
    settings = Settings(db_url=f"sqlite:///{tmp_path / 'h.db'}", executor="thread",
                        warm_pool=False, run_jobs=False, **kw)  # fmt: skip
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url=base_url) as c:
            yield c


# --- a real uvicorn on 127.0.0.1 without keys (the tester's case) -----------------------------
@pytest.mark.parametrize(
    "host", ["evil.example", "evil.example:8000", "127.0.0.1.evil.example", "localhost.evil",
             "10.0.0.5", "[fe80::1]:80", "0.0.0.0", ""],
)  # fmt: skip
def test_rebound_host_without_browser_headers_is_refused(live_server, host: str) -> None:  # noqa: ANN001
    with httpx2.Client(base_url=live_server.url, timeout=120) as c:
        for method, path, kw in (("GET", "/v1/signals", {}), ("GET", "/v1/jobs", {}),
                                 ("POST", "/v1/signals", {"json": W})):  # fmt: skip
            r = c.request(method, path, headers={"host": host}, **kw)
            _refused(r, host)


def test_loopback_hosts_are_served(live_server) -> None:  # noqa: ANN001
    port = urlsplit(live_server.url).port
    hosts = [f"127.0.0.1:{port}", f"localhost:{port}", "localhost", "LocalHost.", "127.0.0.2",
             f"[::1]:{port}", "[::1]"]  # fmt: skip
    with httpx2.Client(base_url=live_server.url, timeout=120) as c:
        for host in hosts:
            r = c.get("/v1/signals", headers={"host": host})
            assert r.status_code == 200, (host, r.text)


def test_request_without_host_is_served(live_server) -> None:  # noqa: ANN001
    """HTTP/1.0 needs no ``Host`` (and no browser omits it): not a rebinding."""
    u = urlsplit(live_server.url)
    with socket.create_connection((u.hostname, u.port), timeout=10) as s:
        s.sendall(b"GET /v1/signals?limit=1 HTTP/1.0\r\n\r\n")
        answer = b""
        while chunk := s.recv(65536):
            answer += chunk
    assert answer.startswith(b"HTTP/1.1 200"), answer[:200]


# --- in-process clients, settings ---------------------------------------------------------------
async def test_in_process_clients_name_their_own_server(tmp_path) -> None:  # noqa: ANN001
    """httpx's ASGITransport and Starlette's TestClient have no socket: their ASGI ``server``
    is the URL's name, which their Host names (accepted); another Host is refused."""
    async with _app(tmp_path) as c:
        assert (await c.get("/v1/signals")).status_code == 200  # Host: asgi, server ("asgi", ..)
        _refused(await c.get("/v1/signals", headers={"host": "evil.example"}), "evil.example")
        _refused(await c.get("/v1/signals", headers={"host": "testserver"}), "testserver")
    from fastapi.testclient import TestClient

    settings = Settings(db_url=f"sqlite:///{tmp_path / 't.db'}", executor="thread",
                        warm_pool=False, run_jobs=False, api_key=None)  # fmt: skip
    with TestClient(create_app(settings)) as tc:
        assert tc.get("/v1/signals").status_code == 200  # Host: testserver
        _refused(tc.get("/v1/signals", headers={"host": "evil.example"}), "evil.example")
    # an IP address as the ASGI server is a socket's: only loopback ones pass
    async with _app(tmp_path, base_url="http://127.0.0.1:8000") as c:
        assert (await c.get("/v1/signals")).status_code == 200
        _refused(await c.get("/v1/signals", headers={"host": "asgi"}), "asgi")


async def test_allowed_hosts_are_served(tmp_path) -> None:  # noqa: ANN001
    async with _app(tmp_path, allowed_hosts=["Lab.Example", "pi.local:8000"]) as c:
        for host in ("lab.example", "LAB.EXAMPLE:8000", "pi.local", "pi.local:9000"):
            r = await c.get("/v1/signals", headers={"host": host})
            assert r.status_code == 200, (host, r.text)
        _refused(await c.get("/v1/signals", headers={"host": "evil.example"}), "evil.example")


async def test_keyed_server_takes_any_host(tmp_path) -> None:  # noqa: ANN001
    """A server exposed on purpose (keys required, e.g. behind a reverse proxy under a public
    name) is unaffected: its keys are the defence."""
    host = {"host": "api.example.com"}
    async with _app(tmp_path, base_url="http://127.0.0.1", api_key="s3cret") as c:
        assert (await c.get("/v1/signals", headers=host)).status_code == 401
        r = await c.get("/v1/signals", headers={**host, "authorization": "Bearer s3cret"})
        assert r.status_code == 200, r.text
    async with _app(tmp_path, base_url="http://127.0.0.1", auth="on") as c:
        assert (await c.get("/v1/signals", headers=host)).status_code == 401


async def test_keyless_server_beyond_loopback_holds_browsers_only(tmp_path) -> None:  # noqa: ANN001
    """``SNAPWARN_AUTH=off`` on 0.0.0.0 (an explicit opt-out, e.g. a private network): any Host
    from a script, but a browser request must still name a loopback or allowed host."""
    async with _app(tmp_path, base_url="http://10.1.2.3", host="0.0.0.0", auth="off") as c:
        assert (await c.get("/v1/signals", headers={"host": "snapwarn:8000"})).status_code == 200
        browser = {"host": "evil.example", "sec-fetch-site": "same-origin"}
        r = await c.get("/v1/signals", headers=browser)
        _refused(r, "evil.example")


def test_exposed_server_with_a_key_over_uvicorn(tmp_path) -> None:  # noqa: ANN001
    """`snapwarn serve` with a key, behind a trusted proxy, named by the proxy's Host."""
    server = start_server(f"sqlite:///{tmp_path / 'k.db'}", tmp_path,
                          extra_env={"SNAPWARN_API_KEY": "k3y-for-host-test",
                                     "SNAPWARN_FORWARDED_ALLOW_IPS": '["127.0.0.1"]'})  # fmt: skip
    try:
        with httpx2.Client(base_url=server.url, timeout=30) as c:
            h = {"host": "api.example.com", "x-forwarded-for": "203.0.113.9",
                 "x-forwarded-proto": "https"}  # fmt: skip
            assert c.get("/v1/signals", headers=h).status_code == 401
            r = c.get("/v1/signals", headers={**h, "authorization": "Bearer k3y-for-host-test"})
            assert r.status_code == 200, r.text
    finally:
        server.stop()
