"""Hostile and malformed input: every case is a clear 4xx naming the field, never a 5xx.

The corpus is ``_svc_attacks.CASES`` (the cases a fuzzer and a hand-made corpus found); the
zip bomb must be refused cheaply; concurrent DELETEs answer 204 once; a retried POST with an
``Idempotency-Key`` does not create a duplicate.
"""

from __future__ import annotations

import asyncio
import time

import pytest
from _svc_attacks import CASES, W, mat_bomb, npz_bomb

pytestmark = pytest.mark.anyio


def _field_named(doc: dict, field: str) -> bool:
    return any(
        e.get("field") == field or str(e.get("field", "")).startswith(field + "[")
        or str(e.get("field", "")).startswith(field + ".")
        for e in doc.get("errors", [])
    )


@pytest.mark.parametrize(
    ("label", "method", "path", "kw", "allowed", "field"), CASES, ids=[c[0] for c in CASES]
)
async def test_attack_is_a_clear_4xx(asgi, label, method, path, kw, allowed, field) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.request(method, path, **kw)
    assert r.status_code in allowed, (label, r.status_code, r.text[:500])
    if r.status_code >= 400:
        doc = r.json()
        assert r.headers["content-type"].startswith("application/problem+json")
        assert doc["status"] == r.status_code and doc["detail"]
        if field is not None:
            assert _field_named(doc, field), (label, doc)
        assert "Traceback" not in r.text and "/work/" not in r.text and ".py" not in r.text
    else:  # accepted: the answer is strict JSON (no NaN/Infinity tokens)
        assert "Infinity" not in r.text and "NaN" not in r.text


@pytest.fixture
def small_unpack_cap(asgi):  # noqa: ANN001, ANN201
    """The app's unpacked-size cap lowered to 16 MiB (so that the bombs are quick to make)."""
    settings = asgi[0].state.snapwarn.settings
    old = settings.max_decompressed_bytes
    settings.max_decompressed_bytes = 16 << 20
    yield
    settings.max_decompressed_bytes = old


@pytest.mark.parametrize("kind", ["npz", "mat"])
async def test_zip_bombs_are_refused_from_their_headers(asgi, small_unpack_cap, kind) -> None:  # noqa: ANN001
    """A file that inflates to 4x the cap is refused (413 naming the file) without inflating
    it; the 1 GiB versions (a ~1 MB file) take the same path (timed at under 0.03 s)."""
    _, client = asgi
    bomb = (npz_bomb if kind == "npz" else mat_bomb)(64 << 20)
    assert len(bomb) < 200_000
    if kind == "mat":  # a real MAT file: scipy sees the 2^23 doubles
        import io

        from scipy.io import whosmat

        assert whosmat(io.BytesIO(bomb)) == [("w", (1 << 23, 1), "double")]
    t0 = time.perf_counter()
    r = await client.post(
        "/v1/signals", files={"file": (f"bomb.{kind}", bomb, "application/octet-stream")}
    )
    took = time.perf_counter() - t0
    assert r.status_code == 413, r.text
    assert _field_named(r.json(), "file") and "unpacks to 67108" in r.json()["detail"]
    assert took < 2.0, f"the bomb cost {took:.1f} s"


async def test_concurrent_deletes_answer_204_once(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    sid = (await client.post("/v1/signals", json={"dt": 0.1, "w": W})).json()["id"]
    rs = await asyncio.gather(*[client.delete(f"/v1/signals/{sid}") for _ in range(8)])
    codes = sorted(r.status_code for r in rs)
    assert codes == [204] + [404] * 7, codes
    assert (await client.delete(f"/v1/signals/{sid}")).status_code == 404


async def test_idempotency_key_replays_the_first_answer(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    key = {"idempotency-key": f"upload-{time.time_ns()}"}
    doc = {"dt": 0.1, "w": W, "name": "retried"}
    total0 = (await client.get("/v1/signals", params={"limit": 1})).json()["total"]
    first = await client.post("/v1/signals", json=doc, headers=key)
    again = await client.post("/v1/signals", json=doc, headers=key)
    assert first.status_code == again.status_code == 201
    assert again.json()["id"] == first.json()["id"]
    assert again.headers["idempotent-replayed"] == "true"
    assert again.headers["location"] == f"/v1/signals/{first.json()['id']}"
    total1 = (await client.get("/v1/signals", params={"limit": 1})).json()["total"]
    assert total1 == total0 + 1
    other = await client.post("/v1/signals", json={**doc, "name": "other"}, headers=key)
    assert other.status_code == 422 and _field_named(other.json(), "idempotency-key")
    # a failed first request does not hold the key: the corrected retry runs
    key2 = {"idempotency-key": f"bad-{time.time_ns()}"}
    bad = await client.post("/v1/signals", json={"dt": -1, "w": W}, headers=key2)
    assert bad.status_code == 422
    good = await client.post("/v1/signals", json={"dt": 0.1, "w": W}, headers=key2)
    assert good.status_code == 201 and "idempotent-replayed" not in good.headers


async def test_concurrent_retries_with_one_key_create_one_signal(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    key = {"idempotency-key": f"race-{time.time_ns()}"}
    rs = await asyncio.gather(
        *[client.post("/v1/signals", json={"dt": 0.1, "w": W}, headers=key) for _ in range(6)]
    )
    ids = {r.json()["id"] for r in rs if r.status_code == 201}
    assert len(ids) == 1, [(r.status_code, r.text[:100]) for r in rs]
    assert all(r.status_code in (201, 409) for r in rs)


async def test_500_closes_the_connection_and_hides_the_traceback() -> None:
    """An unexpected error: a correlation id, no traceback or path, ``Connection: close``."""
    import httpx2
    from fastapi import APIRouter

    from service.api import create_app
    from service.api.settings import Settings

    app = create_app(Settings(db_url="sqlite://", warm_pool=False, run_jobs=False))
    boom = APIRouter()

    @boom.get("/v1/boom")
    async def _boom() -> None:
        raise RuntimeError("secret at /srv/app/service/x.py")

    app.include_router(boom)
    transport = httpx2.ASGITransport(app=app, raise_app_exceptions=False)
    async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
        r = await c.get("/v1/boom")
    assert r.status_code == 500
    assert r.headers["connection"] == "close"
    doc = r.json()
    assert "correlation id" in doc["detail"] and "/srv/" not in r.text and "secret" not in r.text


#: Peak RSS growth allowed to the server process for a 41 MB JSON body of 2e6 samples (the
#: samples themselves are 16 MB as float64). It was ~750 MB (a Python float per sample in
#: several copies), then ~200-240 MB (the body and pydantic's list); streamed: ~55-75 MB.
RSS_BOUND = 100e6


def _rss(pid: int, key: str) -> int:
    with open(f"/proc/{pid}/status") as fh:
        return next(int(x.split()[1]) for x in fh if x.startswith(key)) * 1024


def _peak_growth(pid: int, send) -> tuple[float, object]:  # noqa: ANN001
    """Peak RSS of ``pid`` over its RSS before ``send()`` (the peak is reset first where the
    kernel allows it: /proc/PID/clear_refs)."""
    try:
        with open(f"/proc/{pid}/clear_refs", "w") as fh:
            fh.write("5")
        before = _rss(pid, "VmRSS")
    except OSError:  # no reset: growth over the peak so far (a lower bound of the growth)
        before = _rss(pid, "VmHWM")
    result = send()
    return _rss(pid, "VmHWM") - before, result


@pytest.mark.slow
def test_a_40_mb_json_body_costs_bounded_memory(tmp_path) -> None:  # noqa: ANN001
    """A real uvicorn: a 41 MB JSON signal (POST /v1/signals) and the same inline detection
    (POST /v1/detections) each grow the server's peak RSS by less than RSS_BOUND; the stored
    samples are bit-exact."""
    import hashlib
    import json

    import httpx2
    import numpy as np
    from _svc_helpers import start_server

    server = start_server(
        f"sqlite:///{tmp_path / 'm.db'}", tmp_path, extra_env={"SNAPWARN_WARM_POOL": "false"}
    )
    try:
        w = np.random.default_rng(0).standard_normal(2_000_000)
        body = json.dumps({"dt": 0.001, "w": w.tolist()}).encode()
        small = json.dumps({"dt": 0.001, "w": w[:100].tolist()}).encode()
        grew = {}
        for path in ("/v1/signals", "/v1/detections"):
            def post(content: bytes, path: str = path) -> httpx2.Response:
                return httpx2.post(server.url + path, content=content, timeout=300,
                                   headers={"content-type": "application/json"})  # fmt: skip

            assert post(small).status_code in (200, 201)  # imports, pool started
            grew[path], r = _peak_growth(server.proc.pid, lambda post=post: post(body))
            assert r.status_code in (200, 201), r.text[:300]
            if path == "/v1/signals":
                meta = r.json()
                assert meta["n"] == w.size
                assert meta["sha256"] == hashlib.sha256(w.astype("<f8").tobytes()).hexdigest()
    finally:
        server.stop()
    for path, g in grew.items():
        assert g < RSS_BOUND, f"{path}: peak RSS grew {g / 1e6:.0f} MB for {len(body) / 1e6:.0f} MB"


async def test_oversized_body_is_413_and_closes_the_connection(tmp_path) -> None:  # noqa: ANN001
    import httpx2

    from service.api import create_app
    from service.api.settings import Settings

    app = create_app(
        Settings(db_url=f"sqlite:///{tmp_path / 'b.db'}", warm_pool=False, run_jobs=False,
                 executor="thread", max_body_bytes=4096)  # fmt: skip
    )
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
            r = await c.post("/v1/signals", json={"dt": 0.1, "w": [0.5] * 5000})
    assert r.status_code == 413 and r.headers["connection"] == "close"
    assert r.json()["errors"][0]["field"] == "body"


async def test_too_many_samples_are_refused_before_parsing(tmp_path) -> None:  # noqa: ANN001
    import httpx2

    from service.api import create_app
    from service.api.settings import Settings

    app = create_app(
        Settings(db_url=f"sqlite:///{tmp_path / 's.db'}", warm_pool=False, run_jobs=False,
                 executor="thread", max_samples=1000)  # fmt: skip
    )
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
            big = await c.post("/v1/signals", json={"dt": 0.1, "w": [0.5] * 200_000})
            ok = await c.post("/v1/signals", json={"dt": 0.1, "w": [0.5] * 1000})
            over = await c.post("/v1/signals", json={"dt": 0.1, "w": [0.5] * 1001})
    assert big.status_code == 413 and big.json()["errors"][0]["field"] == "w"
    assert ok.status_code == 201, ok.text
    assert over.status_code == 413, over.text  # the exact count, after parsing
