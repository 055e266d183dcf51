"""The hot path's door (``service.api.hotpath``) answers as the route does.

Two real apps on one SQLite file, one with the hot path and one without (``hot_path=False``:
every request through FastAPI's route), each with its own analysis worker; every kind of
answer of ``POST /v1/detections`` is compared byte for byte: a detection (dt or t), each kind
of bad body, a limit, a stored signal, an unknown one, a missing key, a replayed
``Idempotency-Key``. The hot path's counter shows which requests it answered itself.
"""

from __future__ import annotations

import json
from collections.abc import AsyncIterator
from contextlib import AsyncExitStack, asynccontextmanager
from pathlib import Path

import httpx2
import numpy as np
import pytest
from _svc_helpers import test_settings

from service.api import create_app

pytestmark = pytest.mark.anyio

_T = np.arange(2000) * 1e-3
_W = (np.exp(-0.4 * _T) * np.sin(2 * np.pi * 7.0 * _T)).tolist()


@asynccontextmanager
async def _apps(tmp: Path, **kw: object) -> AsyncIterator[tuple[httpx2.AsyncClient, ...]]:
    """Clients of the app with and without the hot path (same settings ``kw``, same file)."""
    url = f"sqlite:///{tmp / 'hot.db'}"
    async with AsyncExitStack() as stack:
        out = []
        for hot in (True, False):
            app = create_app(test_settings(url, run_jobs=False, hot_path=hot, **kw))
            await stack.enter_async_context(app.router.lifespan_context(app))
            client = httpx2.AsyncClient(
                transport=httpx2.ASGITransport(app=app), base_url="http://asgi"
            )
            await stack.enter_async_context(client)
            client.app = app  # type: ignore[attr-defined]
            out.append(client)
        yield tuple(out)


def _served(client: httpx2.AsyncClient) -> int:
    return client.app.state.snapwarn.extra.get("hot_path_answers", 0)  # type: ignore[attr-defined]


async def _same(hot: httpx2.AsyncClient, cold: httpx2.AsyncClient, **kw: object) -> httpx2.Response:
    a = await hot.post("/v1/detections", **kw)
    b = await cold.post("/v1/detections", **kw)
    assert (a.status_code, a.headers["content-type"]) == (b.status_code, b.headers["content-type"])
    assert a.content == b.content, (a.text[:400], b.text[:400])
    return a


BAD = {
    "malformed JSON": b'{"w": [1.0, 2.0',
    "a text sample": json.dumps({"w": [0.0, "x", 1.0], "dt": 0.1}).encode(),
    "a boolean sample": json.dumps({"w": [0.0, True, 1.0], "dt": 0.1}).encode(),
    "NaN token": b'{"w": [0.0, NaN, 1.0], "dt": 0.1}',
    "no samples": json.dumps({"dt": 0.1}).encode(),
    "negative dt": json.dumps({"w": _W[:50], "dt": -0.1}).encode(),
    "dt and t": json.dumps({"w": _W[:3], "dt": 0.1, "t": [0, 0.1, 0.2]}).encode(),
    "unknown method": json.dumps({"w": _W[:50], "dt": 0.1, "method": "magic"}).encode(),
    "too few samples": json.dumps({"w": [1.0], "dt": 0.1}).encode(),
}


async def test_answers_equal_the_routes(tmp_path: Path) -> None:
    async with _apps(tmp_path) as (hot, cold):
        r = await _same(hot, cold, json={"w": _W, "dt": 1e-3})
        assert r.status_code == 200 and abs(r.json()["fundamental"]["omega"] - 2 * np.pi * 7) < 0.1
        await _same(hot, cold, json={"w": _W, "t": _T.tolist()})
        r = await _same(hot, cold, json={"w": [1.0] * 200, "dt": 0.1})  # flagged, no mode
        assert r.json()["modes"] == [] and r.json()["flags"]
        assert _served(hot) == 3 and _served(cold) == 0
        for label, body in BAD.items():
            r = await _same(
                hot, cold, content=body, headers={"content-type": "application/json"}
            )
            assert r.status_code in (413, 422), (label, r.status_code, r.text)
            assert r.headers["content-type"].startswith("application/problem+json"), label
        assert _served(hot) == 3  # errors are answered by the app's handlers
        # a stored signal: the route reads it (the same signal for both apps: one file)
        sid = (await hot.post("/v1/signals", json={"w": _W, "dt": 1e-3})).json()["id"]
        r = await _same(hot, cold, json={"signal_id": sid})
        assert r.status_code == 200
        r = await _same(hot, cold, json={"signal_id": "nope"})
        assert r.status_code == 404
        assert _served(hot) == 3


async def test_limits_and_keys_apply_as_on_the_route(tmp_path: Path) -> None:
    async with _apps(tmp_path, max_samples=1000, auth="on", api_key="k" * 32) as (hot, cold):
        r = await _same(hot, cold, json={"w": _W, "dt": 1e-3})
        assert r.status_code == 401
        key = {"authorization": "Bearer " + "k" * 32}
        r = await _same(hot, cold, json={"w": _W, "dt": 1e-3}, headers=key)
        assert r.status_code == 413 and "1000" in r.text
        r = await _same(hot, cold, json={"w": _W[:900], "dt": 1e-3}, headers=key)
        assert r.status_code == 200
        assert _served(hot) == 1


async def test_a_retried_request_is_replayed(tmp_path: Path) -> None:
    async with _apps(tmp_path) as (hot, _):
        h = {"idempotency-key": "one"}
        a = await hot.post("/v1/detections", json={"w": _W, "dt": 1e-3}, headers=h)
        b = await hot.post("/v1/detections", json={"w": _W, "dt": 1e-3}, headers=h)
        # the replay is the stored document re-encoded (the same numbers, Python's repr)
        assert a.status_code == b.status_code == 200 and a.json() == b.json()
        assert b.headers.get("idempotent-replayed") == "true"
        assert _served(hot) == 1  # the retry was answered by the idempotency middleware
