"""Limits that hold under concurrency and for every job kind.

The audit: the per-owner queue limit of 16 let 20 of 40 concurrent jobs through (a count, then
an insert); atlases got an 86,700 s limit whatever ``SNAPWARN_JOB_TIME_LIMIT_S`` said.
"""

from __future__ import annotations

import threading

import pytest

from service.api.problems import ApiProblem
from service.api.storage import Store


@pytest.mark.parametrize("kind", ["job", "sweep", "atlas"])
def test_40_concurrent_queueings_let_at_most_16_through(new_db, kind) -> None:  # noqa: ANN001
    """40 threads queue at once for one owner against a limit of 16 (no runner takes them):
    exactly 16 are queued, the others are 429s."""
    from service.api.storage import atlases

    store = Store(new_db(f"queue_{kind}"))
    store.migrate()
    barrier = threading.Barrier(40)
    out: list[int] = []

    def one() -> None:
        barrier.wait()
        try:
            if kind == "job":
                store.create_job("diagnostic-sleep", {"seconds": 1}, owner="o", max_active=16)
            elif kind == "sweep":
                store.create_sweep("sweep-signals", {}, {}, None, owner="o", max_active=16)
            else:
                atlases.create_atlas(store, name=None, kind="bifurcation", spec={}, params={},
                                     cells_total=1, owner="o", max_active=16)  # fmt: skip
            out.append(201)
        except ApiProblem as exc:
            out.append(exc.status)

    threads = [threading.Thread(target=one) for _ in range(40)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    try:
        assert sorted(set(out)) == [201, 429] and out.count(201) == 16, out
        assert store.count_active_jobs("o") == 16
        assert store.count_active_jobs("other") == 0
    finally:
        store.dispose()


@pytest.mark.anyio
async def test_an_atlas_job_is_under_the_job_time_limit(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    settings = app.state.snapwarn.settings
    old, settings.job_time_limit_s = settings.job_time_limit_s, 120.0
    spec = {"kind": "bifurcation", "fixed": {"model": "normal-form"},
            "grid": {"actuation": ["asymmetric"]}, "timeout_s": 86_400}  # fmt: skip
    try:
        r = await client.post("/v1/atlases", json={"spec": spec})
    finally:
        settings.job_time_limit_s = old
    assert r.status_code == 202, r.text
    job = app.state.snapwarn.store.get_job(r.json()["id"])
    assert job.time_limit_s <= 120.0, job.time_limit_s
    assert job.params["spec"]["timeout_s"] < 120.0


def test_event_streams_are_capped_per_caller() -> None:
    """The 17th open event stream of one caller is a 429 (another caller is not affected);
    the streams' database reads are one watcher's per sweep, not one per stream."""
    from service.api import live_events

    live_events._open["key-a"] = live_events.MAX_STREAMS_PER_CALLER
    try:
        with pytest.raises(ApiProblem) as exc:
            live_events.event_stream(None, None, "s", 0, None, 10.0, "key-a")  # type: ignore[arg-type]
        assert exc.value.status == 429 and exc.value.headers["Retry-After"]
        live_events.event_stream(None, None, "s", 0, None, 10.0, "key-b")  # type: ignore[arg-type]
    finally:
        live_events._open.pop("key-a", None)


@pytest.mark.parametrize("length", [1000, 200_000])  # read whole / streamed to the route
def test_a_trickling_body_is_dropped_with_408(tmp_path, length) -> None:  # noqa: ANN001
    """A client that stops sending its body holds its connection no longer than the setting:
    a 408 and the connection closed (300 such connections stayed open for 90 s)."""
    import socket
    import time

    from _svc_helpers import start_server

    server = start_server(f"sqlite:///{tmp_path / 't.db'}", tmp_path,
                          extra_env={"SNAPWARN_WARM_POOL": "false",
                                     "SNAPWARN_BODY_READ_TIMEOUT_S": "1"})  # fmt: skip
    try:
        host, port = server.url.removeprefix("http://").split(":")
        with socket.create_connection((host, int(port)), timeout=20) as s:
            head = (b"POST /v1/signals HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: "
                    b"application/json\r\nContent-Length: %d\r\n\r\n" % length)  # fmt: skip
            s.sendall(head + b'{"dt": 0.1, ')
            t0 = time.monotonic()
            got = b""
            while True:
                chunk = s.recv(65536)
                if not chunk:
                    break
                got += chunk
            took = time.monotonic() - t0
        assert got.startswith(b"HTTP/1.1 408"), got[:200]
        assert took < 15, took
    finally:
        server.stop()
