"""Live sweeps over HTTP against a real uvicorn: records, flags, concurrency, events, close.

The records are closed-form damped oscillations (``_records``): the detections and the
prediction have exact references.
"""

from __future__ import annotations

import threading

import anyio
import httpx2
import pytest
from _records import DT, MU_STAR, record, sigma2_of

from service.analysis.classify import MIN_T_RATIO
from service.client import AsyncClient, Client, InvalidInput
from service.client.errors import ApiError


@pytest.fixture(scope="module")
def client(server) -> Client:  # noqa: ANN001
    with Client(server.url, timeout=120.0) as c:
        yield c


def test_create_add_and_close_is_an_ordinary_sweep(client: Client, server) -> None:  # noqa: ANN001
    live = client.live_sweep("bench strip", control="angle", unit="deg", step=0.3)
    assert live.sweep.status == "open"
    assert live.sweep.request["control"] == {"name": "angle", "unit": "deg"}
    # a lab that always measures at the advised value, until the slowdown names the transition
    updates, mu = [], 0.0
    while len(updates) < 20:
        t, w = record(mu)
        u = live.add(t=t, w=w, control=mu)
        updates.append(u)
        # the record's detection against the closed form
        assert u.detection.fundamental.sigma2 == pytest.approx(sigma2_of(mu), rel=1e-6)
        assert u.measurement.mu == mu
        assert not u.record_flags
        if u.alarm.t_ratio >= MIN_T_RATIO:  # the classifier names no type before
            break
        mu = u.next_control
    controls = [u.control for u in updates]
    assert [u.seq for u in updates] == list(range(1, len(updates) + 1))
    assert controls[:5] == pytest.approx([0.0, 0.3, 0.6, 0.9, 1.2])  # the step, then bounds
    assert updates[1].prediction is None  # fewer than three records
    # an interval wider than the controls travelled is little evidence: its point estimate (or
    # the sigma^4 bound once the slowdown shows) bounds the step, capped by the lab's step; its
    # lower end 4 steps ahead still raises watch (never critical on a wide interval)
    assert updates[2].alarm.level == "watch" and "never critical" in updates[2].alarm.reason
    assert all(u.next_bound_source in ("interval", "sigma4") for u in updates[2:5])
    last = updates[-1]
    assert last.alarm.t_ratio >= MIN_T_RATIO and len(updates) < 20
    assert last.transition == "saddle-node"
    assert last.probabilities["saddle-node"] > 0.99
    lo, hi = last.mu_star_interval
    assert lo <= MU_STAR <= hi
    assert abs(last.mu_star - MU_STAR) < 1e-6
    # every advised value stayed below its bound, hence below mu*
    assert max(controls) < MU_STAR
    assert controls[-1] < last.next_control < MU_STAR
    assert last.next_bound is None or last.next_control < last.next_bound
    # the open sweep is a sweep
    got = client.get_sweep(live.id)
    assert got.status == "open"
    assert httpx2.get(f"{server.url}/sweeps/{live.id}", timeout=120).status_code == 200  # its page
    closed = live.close()
    assert closed.status == "succeeded"
    assert closed.result is not None
    assert len(closed.result.measurements) == len(updates)
    assert closed.result.prediction.mu_star == pytest.approx(last.mu_star, abs=1e-12)
    assert closed.result.stopped == "closed"
    # closing again answers the same sweep; adding is refused
    assert live.close().status == "succeeded"
    t, w = record(1.4)
    with pytest.raises(ApiError) as err:
        live.add(t=t, w=w, control=1.4)
    assert err.value.status == 409
    page = live.records()
    assert page.total == len(updates) and page.status == "closed"
    assert [u.seq for u in page.items] == [u.seq for u in updates]
    # a closed live sweep is an ordinary sweep: chart, page, listing
    r = httpx2.get(f"{server.url}/v1/sweeps/{live.id}/plot.png", timeout=120)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png"
    r = httpx2.get(f"{server.url}/sweeps/{live.id}", timeout=120)
    assert r.status_code == 200 and "bench strip" in r.text
    r = httpx2.get(f"{server.url}/v1/sweeps", params={"limit": 100})
    assert live.id in [x["id"] for x in r.json()["items"]]


def test_flags_out_of_order_repeated_and_past_the_safe_value(client: Client) -> None:
    live = client.live_sweep("flags", step=0.2)
    t, w = record(0.0)
    live.add(t=t, w=w, control=0.0)
    t, w = record(0.5)
    u = live.add(t=t, w=w, control=0.5)  # advised 0.2
    assert [f.code for f in u.record_flags] == ["past_safe_value"]
    t, w = record(0.25)
    u = live.add(t=t, w=w, control=0.25)
    assert "out_of_order" in [f.code for f in u.record_flags]
    assert u.used_in_fit and u.n_used == 3
    t, w = record(0.5)
    u = live.add(t=t, w=w, control=0.5)
    assert "repeated_control" in [f.code for f in u.record_flags]
    assert u.used_in_fit and u.n_used == 4  # averaged with the first record at 0.5
    # the record list keeps the arrival order
    assert [x.control for x in live.records().items] == [0.0, 0.5, 0.25, 0.5]
    live.close()


def test_stored_signal_and_multipart_file(client: Client, tmp_path) -> None:  # noqa: ANN001
    live = client.live_sweep("doors", control="load", unit="N", step=0.3)
    t, w = record(0.0)
    sig = client.upload_signal(w, dt=DT, unit="s",
                               control={"name": "load", "value": 0.0, "unit": "N"})  # fmt: skip
    u1 = live.add(signal_id=sig.id, control=None)
    assert u1.control == 0.0 and u1.signal_id == sig.id
    # a lab file: CSV with a header and rounded timestamps, time in milliseconds
    t, w = record(0.3)
    path = tmp_path / "run_0.3.csv"
    lines = ["time [ms],w"] + [f"{1e3 * a:.6g},{b:.9g}" for a, b in zip(t, w)]
    path.write_text("\n".join(lines) + "\n")
    u2 = live.add(path, control=0.3)
    assert u2.seq == 2
    # the same eigenvalue in the sweep's unit (1/s^2, its first record's): the ms file converted
    assert u2.detection.fundamental.sigma2 == pytest.approx(sigma2_of(0.3), rel=1e-4)
    stored = client.get_signal(u2.signal_id)
    assert stored.control.value == 0.3 and stored.control.unit == "N"
    # a record without a time unit in a sweep in seconds: refused, naming the field
    t, w = record(0.6)
    with pytest.raises(InvalidInput) as err:
        live.add(t=t, w=w, control=0.6)
    assert err.value.field == "unit"
    live.close()


def test_bad_input_names_the_field(client: Client, server) -> None:  # noqa: ANN001
    live = client.live_sweep("bad", step=0.1)
    t, w = record(0.0)
    with pytest.raises(InvalidInput) as err:
        live.add(t=t, w=w)
    assert err.value.problem.errors[0].field == "control"
    with pytest.raises(InvalidInput) as err:
        live.add(t=t, w=w, control=float("nan"))
    assert err.value.problem.errors[0].field == "control"
    r = httpx2.post(f"{server.url}/v1/sweeps/{live.id}/records", content=b"x",
                    headers={"content-type": "text/plain"})  # fmt: skip
    assert r.status_code == 415
    r = httpx2.post(f"{server.url}/v1/sweeps/nope/records", json={"control": 0, "w": [0, 1]})
    assert r.status_code == 404
    r = httpx2.post(f"{server.url}/v1/sweeps",
                    json={"mode": "live", "live": {"margin": -1}})  # fmt: skip
    assert r.status_code == 422
    r = httpx2.post(f"{server.url}/v1/sweeps", json={"mode": "live", "simulate": {}})
    assert r.status_code == 422
    live.close()


def test_large_inline_record_is_streamed_and_booleans_refused(client: Client, server) -> None:  # noqa: ANN001
    """A record of 80,000 samples (a ~1.6 MB JSON body, above the 1 MiB streaming threshold) is
    read as a stream and detected as in process; booleans are not samples (a 422 naming the
    item), in a small body as in a streamed one."""
    import json

    import numpy as np

    from service.analysis.detect import detect

    live = client.live_sweep("long record", step=0.3)
    t, w = record(0.0, n=80_000)
    body = json.dumps({"control": 0.0, "w": w.tolist(), "dt": DT}).encode()
    assert len(body) > 1 << 20
    r = httpx2.post(f"{server.url}/v1/sweeps/{live.id}/records", content=body,
                    headers={"content-type": "application/json"}, timeout=120.0)  # fmt: skip
    assert r.status_code == 201, r.text
    ref = detect(w, dt=DT)
    got = r.json()["detection"]["fundamental"]["sigma2"]
    assert got == pytest.approx(ref.fundamental.sigma2, rel=1e-12)
    for n in (10, 80_000):
        doc = {"control": 0.3, "w": [0.0] * n, "dt": DT}
        doc["w"][3] = True
        r = httpx2.post(f"{server.url}/v1/sweeps/{live.id}/records", json=doc, timeout=120.0)
        assert r.status_code == 422, r.text
        assert r.json()["errors"][0]["field"] == "w[3]"
    assert np.isfinite(got)
    live.close()


def test_two_clients_at_once_lose_nothing(server) -> None:  # noqa: ANN001
    """Two clients add four records each to one sweep at the same time: eight records, seq
    1..8, each answer computed on exactly the records before it, each client's order kept."""
    with Client(server.url, timeout=120.0) as c:
        live = c.live_sweep("race", step=0.1)
    answers: dict[str, list] = {"a": [], "b": []}
    plan = {"a": [0.0, 0.2, 0.4, 0.6], "b": [0.1, 0.3, 0.5, 0.7]}
    barrier = threading.Barrier(2)

    def lab(name: str) -> None:
        with Client(server.url, timeout=120.0) as c:
            mine = c.live_sweep(sweep_id=live.id)
            barrier.wait()
            for mu in plan[name]:
                t, w = record(mu, n=2000)
                answers[name].append(mine.add(t=t, w=w, control=mu))

    threads = [threading.Thread(target=lab, args=(k,)) for k in plan]
    for th in threads:
        th.start()
    for th in threads:
        th.join(300)
    assert all(len(v) == 4 for v in answers.values())
    with Client(server.url, timeout=120.0) as c:
        page = c.live_sweep(sweep_id=live.id).records()
    assert [u.seq for u in page.items] == list(range(1, 9))
    assert sorted(u.control for u in page.items) == sorted(plan["a"] + plan["b"])
    for name, ups in answers.items():
        seqs = [u.seq for u in ups]
        assert seqs == sorted(seqs)  # a client's records keep its order
        assert [u.control for u in ups] == plan[name]
    for u in page.items:
        assert u.n_records == u.seq  # computed on exactly the records before it
    with Client(server.url, timeout=120.0) as c:
        c.live_sweep(sweep_id=live.id).close()


def test_events_in_order_across_processes_and_resume(server, server_factory, live_db) -> None:  # noqa: ANN001
    """Records go to one uvicorn, the stream is read from another on the same database."""
    other = server_factory(live_db, workers=1)
    with Client(server.url, timeout=120.0) as writer, Client(other.url, timeout=120.0) as reader:
        live = writer.live_sweep("stream", step=0.3)
        follow = reader.live_sweep(sweep_id=live.id)
        got: list = []

        def listen() -> None:
            for ev in follow.events():
                got.append(ev)

        th = threading.Thread(target=listen)
        th.start()
        controls = [0.0, 0.3, 0.6]
        for mu in controls:
            t, w = record(mu, n=2000)
            live.add(t=t, w=w, control=mu)
        live.close()
        th.join(60)
        assert not th.is_alive()
        assert [e.event for e in got] == ["update", "update", "update", "closed"]
        assert [e.id for e in got] == [1, 2, 3, 4]
        assert [e.update.control for e in got[:3]] == controls
        assert got[-1].data["status"] == "closed"
        # resume after the second event: the rest, nothing repeated
        rest = list(follow.events(after=2))
        assert [e.id for e in rest] == [3, 4]
        # the raw stream: media type and event ids
        with httpx2.stream("GET", f"{other.url}/v1/sweeps/{live.id}/events",
                           headers={"Last-Event-ID": "1"}) as r:  # fmt: skip
            assert r.headers["content-type"].startswith("text/event-stream")
            ids = [ln for ln in r.iter_lines() if ln.startswith("id:")]
        assert ids == ["id: 2", "id: 3", "id: 4"]

    async def follow_async() -> list:
        async with AsyncClient(other.url, timeout=120.0) as ac:
            s = await ac.live_sweep(sweep_id=live.id)
            return [ev async for ev in s.events()]

    evs = anyio.run(follow_async)
    assert [e.id for e in evs] == [1, 2, 3, 4]


def test_owners_stay_apart(server, live_db) -> None:  # noqa: ANN001
    """A live sweep of one key's owner is 404 for another owner, on every live route."""
    from service.api.storage import Store

    store = Store(live_db)
    alice, _ = store.create_key("alice")
    bob, _ = store.create_key("bob")
    store.dispose()
    with Client(server.url, api_key=alice, timeout=120.0) as a, \
            Client(server.url, api_key=bob, timeout=120.0) as b:  # fmt: skip
        live = a.live_sweep("alice's", step=0.1)
        t, w = record(0.0, n=2000)
        live.add(t=t, w=w, control=0.0)
        for method, path in (("GET", "records"), ("POST", "close"), ("GET", "events"),
                             ("GET", "records/1")):  # fmt: skip
            r = b._http.request(method, f"/v1/sweeps/{live.id}/{path}")
            assert r.status_code == 404, (method, path, r.status_code)
        r = b._http.post(f"/v1/sweeps/{live.id}/records", json={"control": 0.1, "w": [1.0]})
        assert r.status_code == 404
        assert live.records().total == 1  # alice still sees hers
        live.close()


def test_writers_in_two_processes_see_each_others_records(  # noqa: ANN201
    server, server_factory, live_db  # noqa: ANN001
):
    """Each process keeps the records it has seen; one written by the other process in
    between is read before the next update (every answer computed on all records before)."""
    other = server_factory(live_db, workers=1)
    with Client(server.url, timeout=120.0) as a, Client(other.url, timeout=120.0) as b:
        live_a = a.live_sweep("two processes", step=0.3)
        live_b = b.live_sweep(sweep_id=live_a.id)
        ups = []
        for k, mu in enumerate([0.0, 0.3, 0.6, 0.9, 1.2]):
            t, w = record(mu, n=2000)
            ups.append((live_a if k % 2 == 0 else live_b).add(t=t, w=w, control=mu))
        assert [u.seq for u in ups] == [1, 2, 3, 4, 5]
        assert [u.n_used for u in ups] == [1, 2, 3, 4, 5]
        # the same answer as one process computing the whole sweep from the stored records
        from service.analysis import live as numerics

        recs, ref = [], None
        for mu in [0.0, 0.3, 0.6, 0.9, 1.2]:
            _, w = record(mu, n=2000)
            ref = numerics.update(recs, w, dt=DT, control=mu, plan=numerics.LivePlan(step=0.3))
            recs.append(ref.record)
        assert ups[-1].mu_star == ref.prediction.mu_star
        assert ups[-1].next_control == ref.next_control
        live_a.close()


def test_server_timing_splits_the_update(server) -> None:  # noqa: ANN001
    with Client(server.url, timeout=120.0) as c:
        live = c.live_sweep("timing", step=0.3)
        t, w = record(0.0, n=2000)
        r = c._http.post(f"/v1/sweeps/{live.id}/records",
                         json={"t": t.tolist(), "w": w.tolist(), "control": 0.0})  # fmt: skip
        assert r.status_code == 201, r.text
        parts = {p.split(";")[0].strip(): p for p in r.headers["server-timing"].split(",")}
        for name in ("state", "read", "detect", "classify_predict", "policy", "serialise",
                     "pool", "store", "app"):  # fmt: skip
            assert name in parts, (name, r.headers["server-timing"])
        assert 'desc="cpu ' in parts["detect"]
        app = float(parts["app"].split("dur=")[1])
        assert 0 < r.json()["server_ms"] <= app
        live.close()


def test_budget_spent_finishes_with_the_last_updates_prediction(client: Client) -> None:
    live = client.live_sweep("budget", step=0.3, budget=5)
    ups = []
    for mu in [0.0, 0.3, 0.6, 0.9, 1.2]:
        t, w = record(mu, n=2000)
        ups.append(live.add(t=t, w=w, control=mu))
    assert [u.finished for u in ups] == [False] * 4 + [True]
    done = live.get()
    assert done.status == "succeeded" and done.result.stopped == "budget"
    assert done.result.prediction.mu_star == ups[-1].mu_star
    assert done.result.prediction.mu_star_interval == ups[-1].mu_star_interval
    assert len(done.result.measurements) == 5
    t, w = record(1.3, n=2000)
    with pytest.raises(ApiError) as err:
        live.add(t=t, w=w, control=1.3)
    assert err.value.status == 409
