"""Start-up readiness: the analysis workers load (or compile) their kernels before the app is
ready; /healthz says when; an analysis request meanwhile waits, then gets 503 + Retry-After
(never a 4xx: a server that is not ready is not the client's error)."""

from __future__ import annotations

import asyncio
import time

import pytest
from _svc_signals import ringdown

import service.api.state as state_mod

pytestmark = pytest.mark.anyio
PROBLEM = "application/problem+json"


async def _until_ready(app, timeout: float = 600.0) -> None:  # noqa: ANN001
    t0 = time.monotonic()
    while not app.state.snapwarn.kernels_ready:
        assert time.monotonic() - t0 < timeout, "the start-up warm-up did not end"
        await asyncio.sleep(0.1)


async def test_warm_up_ends_ready_and_healthz_says_so(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    await _until_ready(app)
    doc = (await client.get("/healthz")).json()
    assert doc["ready"] is True and doc["numerics"].get("detect") is True


async def test_not_ready_is_503_with_retry_after_then_served(asgi, monkeypatch) -> None:  # noqa: ANN001
    app, client = asgi
    await _until_ready(app)
    st = app.state.snapwarn
    _, w = ringdown(2000, dt=0.01)
    body = {"dt": 0.01, "w": w.tolist()}
    monkeypatch.setattr(state_mod, "WARM_WAIT_S", 0.2)
    st.kernels_ready = False
    try:
        h = await client.get("/healthz")
        assert h.status_code == 200 and h.json()["ready"] is False  # alive, not ready
        r = await client.post("/v1/detections", json=body)
        assert r.status_code == 503, r.text
        assert r.headers["content-type"] == PROBLEM
        assert int(r.headers["retry-after"]) > 0
        assert r.json()["type"].endswith("warming-up")
        # a request that arrives during the warm-up is served once it ends (within the wait)
        monkeypatch.setattr(state_mod, "WARM_WAIT_S", 30.0)
        asyncio.get_running_loop().call_later(0.3, setattr, st, "kernels_ready", True)
        r = await client.post("/v1/detections", json=body)
        assert r.status_code == 200, r.text
    finally:
        st.kernels_ready = True
