"""Idempotency keys survive a crash: a key whose request a kill -9 interrupted is recovered.

The audit: in 10 of 14 rounds every retry answered 409 for ever (the key stayed "running"), and
in 4 of them the signal had been saved. Now the key is claimed under a lease, the signal and the
key's resource commit in one transaction, and a retry after the lease replays the signal (work
committed) or runs again (it did not): each round ends with exactly one signal, reachable
through the key.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time

import httpx2
import numpy as np
import pytest
from _svc_helpers import start_server

ROUNDS = int(os.environ.get("SNAPWARN_TEST_KILL_ROUNDS", "4"))


def _post(url: str, body: bytes, key: str) -> httpx2.Response:
    return httpx2.post(url + "/v1/signals", content=body, timeout=60,
                       headers={"content-type": "application/json",
                                "idempotency-key": key})  # fmt: skip


def _retry(url: str, body: bytes, key: str) -> httpx2.Response:
    """The retry a client makes: again while 409 (after its Retry-After), at most 60 s."""
    deadline = time.monotonic() + 60
    while True:
        r = _post(url, body, key)
        if r.status_code != 409 or time.monotonic() > deadline:
            return r
        assert "retry-after" in r.headers, r.text
        time.sleep(min(5.0, float(r.headers["retry-after"])))


@pytest.mark.slow
def test_kill_9_mid_request_ends_in_one_signal_through_the_key(tmp_path) -> None:  # noqa: ANN001
    db = f"sqlite:///{tmp_path / 'k.db'}"
    env = {"SNAPWARN_WARM_POOL": "false", "SNAPWARN_IDEMPOTENCY_LEASE_S": "1"}
    rng = np.random.default_rng(30)
    w = rng.standard_normal(300_000)  # ~6 MB of JSON: the request takes long enough to cut
    server = start_server(db, tmp_path, extra_env=env)
    try:
        for i in range(ROUNDS):
            name = f"round-{i}"
            body = json.dumps({"dt": 0.001, "w": w.tolist(), "name": name}).encode()
            key = f"crash-{i}"
            delay = float(rng.uniform(0.0, 0.4))
            killer = threading.Timer(delay, server.proc.send_signal, (signal.SIGKILL,))
            killer.start()
            try:
                first = _post(server.url, body, key)
                status = first.status_code
            except httpx2.HTTPError:
                status = None  # the connection died with the server
            killer.join()
            server.proc.wait(10)
            server = start_server(db, tmp_path, extra_env=env)
            r = _retry(server.url, body, key)
            assert r.status_code == 201, (i, status, r.status_code, r.text[:300])
            again = _post(server.url, body, key)
            assert again.status_code == 201 and again.headers["idempotent-replayed"] == "true"
            assert again.json()["id"] == r.json()["id"]
            listed = httpx2.get(server.url + "/v1/signals?limit=500", timeout=30).json()
            mine = [s["id"] for s in listed["items"] if s["name"] == name]
            assert mine == [r.json()["id"]], (i, delay, status, mine)
    finally:
        server.stop()


@pytest.mark.anyio
async def test_a_dead_key_without_work_is_taken_over_and_one_with_work_replayed(asgi) -> None:  # noqa: ANN001
    """The two recoveries, made by hand: a pending key past its lease with no resource runs
    again (not 409); one whose work committed answers that work (not 409, no duplicate)."""
    from datetime import timedelta

    from service.api.storage.models import utcnow

    app, client = asgi
    store = app.state.snapwarn.store
    body = {"dt": 0.1, "w": [0.0, 1.0, 0.5], "name": "dead-key"}
    owner = "local"
    assert store.claim_idempotent(owner, "dead-1", "t1", 0.01)
    time.sleep(0.05)
    r = await client.post("/v1/signals", json=body, headers={"idempotency-key": "dead-1"})
    assert r.status_code == 201, r.text
    row = store.get_idempotent(owner, "dead-1")  # the work named in its own transaction
    assert row.resource == f"/v1/signals/{r.json()['id']}" and row.status == 201
    # a key that committed its work (a signal bound to it) and died before its answer
    done = await client.post("/v1/signals", json=body)
    assert store.claim_idempotent(owner, "dead-2", "t2", 30.0)
    with store.session() as s:
        from sqlalchemy import update

        from service.api.storage.models import IdempotencyRow

        s.execute(update(IdempotencyRow).where(IdempotencyRow.key == "dead-2").values(
            resource=f"/v1/signals/{done.json()['id']}", resource_status=201,
            lease_until=utcnow() + timedelta(seconds=30)))  # fmt: skip
    r = await client.post("/v1/signals", json=body, headers={"idempotency-key": "dead-2"})
    assert r.status_code == 201 and r.json()["id"] == done.json()["id"], r.text
    assert r.headers["idempotent-replayed"] == "true"
    # a live claim (its lease held) is a 409 that says when to retry
    assert store.claim_idempotent(owner, "live-3", "t3", 30.0)
    r = await client.post("/v1/signals", json=body, headers={"idempotency-key": "live-3"})
    assert r.status_code == 409 and 1 <= int(r.headers["retry-after"]) <= 30
