"""Deployment hazards: loopback trust only from the socket's peer, sessions that are not keys,
security headers, secrets out of the logs, keys off beyond loopback only on purpose.

The audit: behind a reverse proxy that forwards ``Host: 127.0.0.1`` every request became the
keyless local admin; ``--host 0.0.0.0 --auth off`` logged "no API key needed (loopback)"; the
login cookie held the raw API key without ``Secure``; pages sent no CSP/X-Frame-Options; an API
key in a query string was written to the access log.
"""

from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.anyio


@pytest.mark.parametrize(
    "header",
    [("x-forwarded-for", "203.0.113.9"), ("forwarded", "for=203.0.113.9;proto=https"),
     ("x-real-ip", "203.0.113.9"), ("x-forwarded-host", "snapwarn.example")],
)  # fmt: skip
async def test_a_proxied_request_to_a_loopback_server_needs_a_key(asgi, header) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.get("/v1/signals", headers={"host": "127.0.0.1", header[0]: header[1]})
    assert r.status_code == 401, r.text
    assert (await client.get("/v1/signals", headers={"host": "127.0.0.1"})).status_code == 200


async def test_pages_carry_csp_and_frame_protection(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    for path in ("/", "/v1/signals", "/docs"):
        r = await client.get(path)
        csp = r.headers["content-security-policy"]
        assert "frame-ancestors 'none'" in csp and "default-src 'self'" in csp, (path, csp)
        assert r.headers["x-frame-options"] == "DENY"
        assert r.headers["x-content-type-options"] == "nosniff"
    home = (await client.get("/")).headers["content-security-policy"]
    assert "script-src 'self';" in home  # no inline scripts on the pages (only /docs has one)


async def test_the_page_session_is_a_random_token_stored_hashed(asgi) -> None:  # noqa: ANN001
    import hashlib

    app, client = asgi
    store = app.state.snapwarn.store
    key = store.create_key(owner="page-owner")[0]
    r = await client.post("/login", data={"key": key, "next": "/"},
                          headers={"x-forwarded-proto": "https"})  # fmt: skip
    assert r.status_code == 303, r.text
    cookie = r.headers["set-cookie"]
    token = r.cookies["snapwarn_session"]
    assert key not in cookie and token != key
    assert "Secure" in cookie and "HttpOnly" in cookie and "samesite=strict" in cookie.lower()
    from service.api.storage.keys import PageSessionRow

    with store.session() as s:
        row = s.get(PageSessionRow, hashlib.sha256(token.encode()).hexdigest())
        assert row is not None and row.owner == "page-owner"
    plain = await client.post("/login", data={"key": key, "next": "/"})
    assert "Secure" not in plain.headers["set-cookie"]  # plain HTTP on loopback


def test_a_key_in_a_query_string_never_reaches_the_access_log() -> None:
    from service.api.security import redact_logs

    redact_logs()
    rec = logging.LogRecord("uvicorn.access", logging.INFO, __file__, 1,
                            '%s - "%s %s HTTP/%s" %d',
                            ("127.0.0.1:5", "GET", "/v1/signals?limit=2&key=sw_abc_SECRET", "1.1",
                             200), None)  # fmt: skip
    for f in logging.getLogger("uvicorn.access").filters:
        f.filter(rec)
    line = rec.getMessage()
    assert "SECRET" not in line and "key=***" in line and "limit=2" in line


def test_auth_off_beyond_loopback_is_refused_without_i_know(tmp_path) -> None:  # noqa: ANN001
    exe = str(Path(sys.executable).with_name("snapwarn"))
    cmd = [exe, "serve", "--host", "0.0.0.0", "--port", "0",
           "--auth", "off", "--db", f"sqlite:///{tmp_path / 'x.db'}"]  # fmt: skip
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert r.returncode != 0
    assert "--i-know" in r.stderr and "admin" in r.stderr, r.stderr
