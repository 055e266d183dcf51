"""``Idempotency-Key`` on multipart uploads: a retry of the same upload is replayed whatever
boundary the client picks; another file, file name or field with the same key is refused.

The fingerprint is made by python-multipart's streaming parser (``Fingerprint``): the parts'
names, file names, content types and contents, not the raw bytes (which hold the boundary).
"""

from __future__ import annotations

import asyncio
import hashlib
import time

import httpx2
import numpy as np
import pytest
from _svc_signals import csv_bytes, ringdown

from service.api.idempotency import MAX_PARTS, Fingerprint

pytestmark = pytest.mark.anyio

T, W = ringdown(400, dt=0.002)
CSV = csv_bytes(T, W)
FORM = {"control_value": "1.25", "control_name": "load"}


def _multipart(files: dict, data: dict, boundary: str | None = None) -> tuple[str, bytes]:
    """The Content-Type and body httpx sends (a fresh random boundary unless one is given)."""
    headers = {"content-type": f"multipart/form-data; boundary={boundary}"} if boundary else None
    req = httpx2.Request("POST", "http://x/v1/signals", files=files, data=data, headers=headers)
    return req.headers["content-type"], req.read()


def _fp(ctype: str | None, body: bytes, chunk: int = 1 << 16) -> str:
    f = Fingerprint("POST", "/v1/signals", ctype)
    for i in range(0, len(body), chunk):
        f.update(body[i : i + chunk])
    return f.hexdigest()


def _key() -> dict[str, str]:
    return {"idempotency-key": f"mp-{time.time_ns()}"}


async def _total(client) -> int:  # noqa: ANN001
    return (await client.get("/v1/signals", params={"limit": 1})).json()["total"]


# --- the fingerprint ------------------------------------------------------------------------
def test_fingerprint_ignores_the_boundary_and_the_chunking() -> None:
    files = {"file": ("run.csv", CSV, "text/csv")}
    a = _multipart(files, FORM, "aaaa1111")
    b = _multipart(files, FORM, "Zz-other-boundary-0987654321")
    assert a[1] != b[1]
    assert _fp(*a) == _fp(*b) == _fp(*a, chunk=7) == _fp(*b, chunk=1)


@pytest.mark.parametrize(
    "change",
    ["bytes", "filename", "content-type", "field value", "field name", "extra field", "order"],
)
def test_fingerprint_tells_different_uploads_apart(change: str) -> None:
    files = {"file": ("run.csv", CSV, "text/csv")}
    data = dict(FORM)
    if change == "bytes":
        files = {"file": ("run.csv", CSV[:-2] + b"9\n", "text/csv")}
    elif change == "filename":
        files = {"file": ("run2.csv", CSV, "text/csv")}
    elif change == "content-type":
        files = {"file": ("run.csv", CSV, "application/octet-stream")}
    elif change == "field value":
        data["control_value"] = "1.26"
    elif change == "field name":
        data = {"control_valu": "1.25", "control_name": "load"}
    elif change == "extra field":
        data["dt"] = "0.002"
    else:
        data = dict(reversed(list(FORM.items())))
    assert _fp(*_multipart({"file": ("run.csv", CSV, "text/csv")}, FORM)) != _fp(
        *_multipart(files, data)
    )


def test_content_is_not_confused_with_the_framing() -> None:
    """A field whose value looks like the next part is not the same as that part."""
    one = _multipart({}, {"a": "x", "b": "y"})
    two = _multipart({}, {"a": 'x", "b'})
    assert _fp(*one) != _fp(*two)


def test_json_fingerprint_is_unchanged() -> None:
    """Non-multipart bodies: the SHA-256 of method, path and bytes (as keys stored before)."""
    body = b'{"dt":0.1,"w":[1,2,3]}'
    want = hashlib.sha256(b"POST /v1/signals\n" + body).hexdigest()
    assert _fp("application/json", body) == _fp(None, body, chunk=3) == want


@pytest.mark.parametrize("case", ["truncated", "garbage", "no boundary", "too many parts"])
def test_unparsable_multipart_falls_back_to_the_raw_bytes(case: str) -> None:
    ctype, body = _multipart({"file": ("run.csv", CSV, "text/csv")}, FORM, "bnd123")
    if case == "truncated":
        body = body[: len(body) // 2]
    elif case == "garbage":
        body = b"not a multipart body at all\r\n"
    elif case == "no boundary":
        ctype = "multipart/form-data"
    else:
        ctype, body = _multipart({}, {f"f{i}": "v" for i in range(MAX_PARTS + 1)}, "bnd123")
    raw = hashlib.sha256(b"POST /v1/signals\n" + body).hexdigest()
    assert _fp(ctype, body) == raw


# --- the API (in-process and over a real uvicorn) ------------------------------------------
async def test_multipart_retry_is_replayed(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    key = _key()
    files = {"file": ("run.csv", CSV, "text/csv")}
    total0 = await _total(client)
    first = await client.post("/v1/signals", files=files, data=FORM, headers=key)
    again = await client.post("/v1/signals", files=files, data=FORM, headers=key)
    assert first.status_code == 201, first.text
    assert again.status_code == 201, again.text
    assert again.headers["idempotent-replayed"] == "true"
    assert again.json()["id"] == first.json()["id"]
    assert again.headers["location"] == f"/v1/signals/{first.json()['id']}"
    assert await _total(client) == total0 + 1
    # an explicit, different boundary: still the same request
    ctype, body = _multipart(files, FORM, "explicit-boundary-42")
    third = await client.post("/v1/signals", content=body, headers={**key, "content-type": ctype})
    assert third.status_code == 201 and third.json()["id"] == first.json()["id"]
    assert third.headers["idempotent-replayed"] == "true"
    assert await _total(client) == total0 + 1


@pytest.mark.parametrize("change", ["file", "filename", "field"])
async def test_multipart_with_the_key_of_another_upload_is_refused(asgi, change) -> None:  # noqa: ANN001
    _, client = asgi
    key = _key()
    files = {"file": ("run.csv", CSV, "text/csv")}
    first = await client.post("/v1/signals", files=files, data=FORM, headers=key)
    assert first.status_code == 201, first.text
    data = dict(FORM)
    if change == "file":
        files = {"file": ("run.csv", csv_bytes(T, W * 2.0), "text/csv")}
    elif change == "filename":
        files = {"file": ("other.csv", CSV, "text/csv")}
    else:
        data["control_value"] = "2.5"
    total0 = await _total(client)
    other = await client.post("/v1/signals", files=files, data=data, headers=key)
    assert other.status_code == 422, other.text
    assert "different request" in other.json()["detail"]
    assert any(e.get("field") == "idempotency-key" for e in other.json().get("errors", []))
    assert await _total(client) == total0


async def test_concurrent_multipart_retries_create_one_signal(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    key = _key()
    files = {"file": ("run.csv", CSV, "text/csv")}
    rs = await asyncio.gather(
        *[client.post("/v1/signals", files=files, data=FORM, headers=key) for _ in range(5)]
    )
    assert all(r.status_code in (201, 409) for r in rs), [(r.status_code, r.text) for r in rs]
    assert len({r.json()["id"] for r in rs if r.status_code == 201}) == 1


def test_multipart_retry_over_uvicorn(live_server) -> None:  # noqa: ANN001
    """The tester's case: the same file posted twice with one key, over a real server."""
    key = _key()
    w = np.sin(np.arange(300) * 0.1)
    body = csv_bytes(np.arange(300) * 0.01, w)
    with httpx2.Client(base_url=live_server.url, timeout=120) as c:
        a = c.post("/v1/signals", files={"file": ("r.csv", body)}, headers=key)
        b = c.post("/v1/signals", files={"file": ("r.csv", body)}, headers=key)
        assert a.request.headers["content-type"] != b.request.headers["content-type"]
        assert a.status_code == 201, a.text
        assert b.status_code == 201, b.text
        assert b.headers["idempotent-replayed"] == "true" and b.json()["id"] == a.json()["id"]
        other = c.post("/v1/signals", files={"file": ("r.csv", body + b"3,4\n")}, headers=key)
        assert other.status_code == 422, other.text


def test_an_immediate_retry_finds_the_key_settled_over_uvicorn(live_server) -> None:  # noqa: ANN001
    """The key is stored (or released) before the answer's last byte leaves: a client that
    retries as soon as it has the answer is replayed (or runs), never told 409 'running'."""
    files = {"file": ("r.csv", csv_bytes(np.arange(200) * 0.01, np.cos(np.arange(200) * 0.1)))}
    with httpx2.Client(base_url=live_server.url, timeout=120) as c:
        for i in range(15):
            key = _key()
            first = c.post("/v1/signals", json={"dt": 0.1, "w": [0.0, 1.0, 0.5, -0.2]}, headers=key)
            again = c.post("/v1/signals", json={"dt": 0.1, "w": [0.0, 1.0, 0.5, -0.2]}, headers=key)
            assert (first.status_code, again.status_code) == (201, 201), (i, again.text)
            assert again.headers["idempotent-replayed"] == "true"
            key = _key()
            bad = c.post("/v1/signals", files=files, data={"dt": "-1"}, headers=key)
            good = c.post("/v1/signals", files=files, headers=key)
            assert (bad.status_code, good.status_code) == (422, 201), (i, good.text)
