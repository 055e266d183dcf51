"""Jobs, detections, simulations and sweeps in-process (ASGI) on SQLite and PostgreSQL."""

from __future__ import annotations

import asyncio
import json

import numpy as np
import pytest
from _svc_helpers import require_numerics, test_settings
from _svc_signals import ringdown

from service.api import create_app

pytestmark = pytest.mark.anyio
PROBLEM = "application/problem+json"


async def _job_until_done(client, job_id: str, timeout: float = 60.0) -> dict:  # noqa: ANN001
    seen = []
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        r = await client.get(f"/v1/jobs/{job_id}")
        assert r.status_code == 200, r.text
        doc = r.json()
        seen.append((doc["status"], doc["progress"]["fraction"]))
        if doc["status"] in ("succeeded", "failed"):
            doc["_seen"] = seen
            return doc
        await asyncio.sleep(0.05)
    raise AssertionError(f"job {job_id} not done in {timeout} s: {seen[-5:]}")


async def test_a_job_runs_with_progress(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    store = app.state.snapwarn.store
    row = store.create_job("diagnostic-sleep", {"seconds": 1.0, "steps": 5, "echo": "hi"})
    app.state.snapwarn.runner.wake()
    doc = await _job_until_done(client, row.id)
    assert doc["status"] == "succeeded", doc
    assert doc["result"]["echo"] == "hi" and doc["attempts"] == 1
    assert doc["progress"] == {"fraction": 1.0, "message": "done"}
    fractions = [f for s, f in doc["_seen"] if s == "running"]
    assert any(0 < f < 1 for f in fractions), doc["_seen"]  # progress was visible meanwhile
    assert doc["started_at"] and doc["finished_at"] and doc["error"] is None


async def test_a_failing_job_says_why(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    row = app.state.snapwarn.store.create_job("diagnostic-sleep", {"fail": True})
    app.state.snapwarn.runner.wake()
    doc = await _job_until_done(client, row.id)
    assert doc["status"] == "failed" and doc["result"] is None
    assert doc["error"]["title"] == "Invalid input" and "asked to fail" in doc["error"]["detail"]


async def test_unknown_job(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.get("/v1/jobs/nope")
    assert r.status_code == 404 and r.headers["content-type"] == PROBLEM


async def test_healthz(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.get("/healthz")
    assert r.status_code == 200
    doc = r.json()
    assert doc["status"] == "ok" and doc["database"] == "ok" and doc["workers"] >= 1


# --- detections ------------------------------------------------------------------------------
async def test_detection_validation_needs_no_numerics(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    cases = [
        ({}, "w"),
        ({"signal_id": "x", "w": [1, 2]}, "signal_id"),
        ({"w": [1, float("nan")] * 20, "dt": 0.1}, "w[1]"),
        ({"w": [1, 2, 3], "t": [0, 1]}, "t"),
        ({"w": [1, 2, 3]}, "dt"),
    ]
    for doc, field in cases:
        r = await client.post(
            "/v1/detections",
            content=json.dumps(doc).encode(),
            headers={"content-type": "application/json"},
        )
        assert r.status_code == 422, (doc, r.text)
        assert r.json()["errors"][0]["field"] == field
    r = await client.post("/v1/detections", json={"signal_id": "missing"})
    assert r.status_code == 404


async def test_detection_inline_and_stored(asgi) -> None:  # noqa: ANN001
    require_numerics("service.analysis.detect", "detect")
    from service.analysis.detect import detect

    _, client = asgi
    t, w = ringdown(4000, dt=0.01)
    from service import convert

    expected = convert.detection(detect(w, dt=0.01)).model_dump(mode="json")
    r = await client.post("/v1/detections", json={"dt": 0.01, "w": w.tolist()})
    assert r.status_code == 200, r.text
    doc = r.json()
    assert doc == expected  # the same document as `snapwarn detect --json`
    assert doc["fundamental"]["omega"] == pytest.approx(2 * np.pi * 1.3, rel=1e-4)
    sid = (await client.post("/v1/signals", json={"t": t.tolist(), "w": w.tolist()})).json()["id"]
    r = await client.post("/v1/detections", json={"signal_id": sid})
    assert r.status_code == 200
    assert r.json()["fundamental"]["omega"] == pytest.approx(doc["fundamental"]["omega"], rel=1e-9)
    r = await client.post(
        "/v1/detections", json={"dt": 0.01, "w": w.tolist(), "method": "nonsense"}
    )
    assert r.status_code == 422 and r.json()["errors"][0]["field"] == "method", r.text


# --- simulations -----------------------------------------------------------------------------
async def test_simulation_validation(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    for doc, field in [
        ({"mu": 1.0, "probe": 2.0}, "probe"),
        ({"actuation": "sideways"}, "actuation"),
        ({"model": "magic"}, "model"),
        ({"dt": -1.0}, "dt"),
        ({"mu": 1, "colour": 3}, "colour"),
    ]:
        r = await client.post("/v1/simulations", json=doc)
        assert r.status_code == 422, (doc, r.text)
        assert r.json()["errors"][0]["field"] == field, r.json()


async def test_simulation_runs(asgi) -> None:  # noqa: ANN001
    require_numerics("sim", "simulate")
    _, client = asgi
    r = await client.post(
        "/v1/simulations", json={"mu": 0.5, "model": "euler-beam", "snr_db": 30, "seed": 1}
    )
    assert r.status_code == 201, r.text
    sig = r.json()["signal"]
    assert sig["source"] == "simulation" and sig["control"]["value"] == 0.5
    assert sig["metadata"]["scene"]["mu"] == 0.5
    r = await client.post(
        "/v1/simulations", json={"mu": 0.5, "model": "euler-beam", "background": True}
    )
    assert r.status_code == 202, r.text
    doc = await _job_until_done(client, r.json()["job"]["id"], timeout=120)
    assert doc["status"] == "succeeded", doc
    r = await client.get(f"/v1/signals/{doc['result']['signal_id']}")
    assert r.status_code == 200


# --- sweeps ----------------------------------------------------------------------------------
async def test_sweep_validation(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    no_control = (await client.post("/v1/signals", json={"dt": 1, "w": [1, 2, 3]})).json()["id"]
    cases = [
        ({}, "measurements"),
        ({"measurements": [{"signal_id": no_control}]}, "measurements"),
        (  # fewer signals than the pipeline needs: refused at the door, not by a failed job
            {
                "measurements": [
                    {"signal_id": no_control, "control_value": 1},
                    {"signal_id": no_control, "control_value": 2},
                ]
            },
            "measurements",
        ),
        (
            {
                "measurements": [
                    {"signal_id": "nope", "control_value": 1},
                    {"signal_id": no_control, "control_value": 2},
                    {"signal_id": no_control, "control_value": 3},
                ]
            },
            "measurements[0].signal_id",
        ),
        (
            {
                "measurements": [
                    {"signal_id": no_control, "control_value": 1},
                    {"signal_id": no_control},
                    {"signal_id": no_control, "control_value": 3},
                ]
            },
            "measurements[1].control_value",
        ),
        (
            {
                "measurements": [
                    {"signal_id": no_control, "control_value": 1},
                    {"signal_id": no_control, "control_value": 2},
                    {"signal_id": no_control, "control_value": 1.0},
                ]
            },
            "measurements",  # 2 distinct values: records sharing one are averaged into a point
        ),
        ({"simulate": {"actuation": "sideways"}}, "simulate.actuation"),
        ({"simulate": {"max_measurements": 1}}, "simulate.max_measurements"),
        ({"simulate": {}, "measurements": [{"signal_id": no_control}]}, "measurements"),
    ]
    for doc, field in cases:
        r = await client.post("/v1/sweeps", json=doc)
        assert r.status_code == 422, (doc, r.text)
        assert r.json()["errors"][0]["field"] == field, r.json()
    r = await client.get("/v1/sweeps/nope")
    assert r.status_code == 404
    r = await client.get("/v1/sweeps/nope/plot.png")
    assert r.status_code == 404


async def test_sweep_plot_before_success_is_409(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    store = app.state.snapwarn.store
    sweep, job = store.create_sweep(
        "diagnostic-sleep", {"simulate": {}}, {"seconds": 30, "steps": 300}, "slow"
    )
    r = await client.get(f"/v1/sweeps/{sweep.id}/plot.svg")
    assert r.status_code == 409 and r.json()["errors"][0]["field"] == "status"
    store.fail_job(job.id, None, {"title": "cancelled by the test"})


async def test_sweep_document_and_plot_from_stored_result(asgi) -> None:  # noqa: ANN001
    """The sweep resource and its charts only show the numbers the result holds."""
    app, client = asgi
    store = app.state.snapwarn.store
    sweep, job = store.create_sweep("diagnostic-sleep", {"simulate": {}}, {"seconds": 0}, "charted")
    claimed = None
    for _ in range(400):  # the runner may claim it first; then wait for it to finish
        row = store.get_job(job.id)
        if row.status == "succeeded":
            break
        await asyncio.sleep(0.05)
    store_row = store.get_job(job.id)
    assert store_row.status == "succeeded", claimed
    ms = [{"mu": m, "omega": (2 - m) ** 0.5, "sigma2": -(2 - m)} for m in (0.5, 1.0, 1.5)]
    doc = {  # a sweep document (service.schemas.SweepResult) as the pipeline stores it
        "measurements": ms,
        "prediction": {"mu_star": 2.0, "mu_star_interval": [1.98, 2.02], "a": 0.5,
                       "classification": {"transition": "saddle-node", "a": 0.25}},
        "alarm": [{"level": "watch", "mu": 1.5, "t_ratio": 3.5}],
        "stopped": "done",
    }  # fmt: skip
    with store.session() as s:
        from service.api.storage import JobRow

        s.get(JobRow, job.id).result = doc
    r = await client.get(f"/v1/sweeps/{sweep.id}")
    assert r.status_code == 200
    got = r.json()
    assert got["status"] == "succeeded" and got["prediction"]["mu_star"] == 2.0
    assert got["classification"]["transition"] == "saddle-node"
    assert got["alarm"]["level"] == "watch" and got["result"]["measurements"][2]["mu"] == 1.5
    png = await client.get(f"/v1/sweeps/{sweep.id}/plot.png")
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
    svg = await client.get(f"/v1/sweeps/{sweep.id}/plot.svg")
    assert svg.status_code == 200 and svg.headers["content-type"] == "image/svg+xml"
    assert b"<svg" in svg.content[:1000]


# --- limits (a small app of its own) ---------------------------------------------------------
async def test_limits_answer_413(tmp_path) -> None:  # noqa: ANN001
    import httpx2

    app = create_app(
        test_settings(
            f"sqlite:///{tmp_path / 'small.db'}",
            max_body_bytes=4096,
            max_samples=100,
            max_sweep_signals=2,
            executor="thread",
            run_jobs=False,
            warm_pool=False,
        )
    )
    async with app.router.lifespan_context(app):
        async with httpx2.AsyncClient(
            transport=httpx2.ASGITransport(app=app), base_url="http://small"
        ) as c:
            r = await c.post("/v1/signals", json={"dt": 1, "w": [0.5] * 101})
            assert r.status_code == 413, r.text
            assert r.json()["errors"][0]["field"] == "w"
            assert "SNAPWARN_MAX_SAMPLES" in r.json()["detail"]
            r = await c.post("/v1/signals", json={"dt": 1, "w": [0.123456789] * 1000})
            assert r.status_code == 413 and r.headers["content-type"] == PROBLEM
            assert r.json()["errors"][0]["field"] == "body"

            async def chunks():  # no Content-Length: counted while streaming
                for _ in range(10):
                    yield b" " * 1000

            r = await c.post(
                "/v1/signals", content=chunks(), headers={"content-type": "application/json"}
            )
            assert r.status_code == 413, r.text
            r = await c.post("/v1/signals", files={"file": ("a.csv", b"t,w\n" + b"0,1\n" * 2000)})
            assert r.status_code == 413
            r = await c.post("/v1/detections", json={"dt": 1, "w": [0.5] * 101})
            assert r.status_code == 413
            ids = [
                (
                    await c.post(
                        "/v1/signals", json={"dt": 1, "w": [1, 2], "control": {"value": k}}
                    )
                ).json()["id"]
                for k in range(3)
            ]
            r = await c.post("/v1/sweeps", json={"measurements": [{"signal_id": i} for i in ids]})
            assert r.status_code == 413 and r.json()["errors"][0]["field"] == "measurements"


async def test_api_key(tmp_path) -> None:  # noqa: ANN001
    import httpx2

    app = create_app(
        test_settings(
            f"sqlite:///{tmp_path / 'key.db'}",
            api_key="s3cret",
            executor="thread",
            run_jobs=False,
            warm_pool=False,
        )
    )
    async with app.router.lifespan_context(app):
        async with httpx2.AsyncClient(
            transport=httpx2.ASGITransport(app=app), base_url="http://key"
        ) as c:
            assert (await c.get("/healthz")).status_code == 200
            r = await c.get("/v1/jobs/x")
            assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
            r = await c.get("/v1/jobs/x", headers={"authorization": "Bearer s3cret"})
            assert r.status_code == 404


async def test_lists_of_signals_and_jobs(asgi) -> None:  # noqa: ANN001
    app, client = asgi
    store = app.state.snapwarn.store
    made = []
    for k in range(3):
        r = await client.post("/v1/signals", json={"dt": 1, "w": [k, k + 1], "name": f"l{k}"})
        made.append(r.json()["id"])
    r = await client.get("/v1/signals", params={"limit": 2})
    assert r.status_code == 200
    page = r.json()
    assert page["limit"] == 2 and page["offset"] == 0 and page["total"] >= 3
    assert [s["id"] for s in page["items"]] == made[::-1][:2]  # newest first
    r = await client.get("/v1/signals", params={"limit": 0})
    assert r.status_code == 422 and r.json()["errors"][0]["field"] == "limit"
    job = store.create_job("diagnostic-sleep", {"fail": True})
    app.state.snapwarn.runner.wake()
    await _job_until_done(client, job.id)
    r = await client.get("/v1/jobs", params={"status": "failed", "kind": "diagnostic-sleep"})
    assert r.status_code == 200
    items = r.json()["items"]
    assert job.id in [j["id"] for j in items] and all(j["status"] == "failed" for j in items)
    r = await client.get("/v1/jobs", params={"status": "sleeping"})
    assert r.status_code == 422 and r.json()["errors"][0]["field"] == "status"
