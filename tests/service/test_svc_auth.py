"""API keys and ownership: hashed keys, 401s, another owner's resources are 404, admins see
all, revocation, keys required beyond loopback, CORS closed unless configured."""

from __future__ import annotations

from collections.abc import AsyncIterator

import httpx2
import pytest

from service.api import create_app
from service.api.auth import Caller, is_loopback, keys_required
from service.api.settings import Settings
from service.api.storage import ApiKeyRow, Store

pytestmark = pytest.mark.anyio
W = [0.0, 1.0, 0.5, -0.3, 0.1, 0.0, -0.05, 0.02]


@pytest.fixture
async def keyed(tmp_path) -> AsyncIterator[tuple[object, httpx2.AsyncClient, dict]]:  # noqa: ANN001
    """An app that requires keys, with keys of alice, bob and an admin."""
    settings = Settings(
        db_url=f"sqlite:///{tmp_path / 'k.db'}",
        auth="on",
        executor="thread",
        warm_pool=False,
        run_jobs=False,
        api_key=None,
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        store = app.state.snapwarn.store
        keys = {
            "alice": store.create_key("alice")[0],
            "bob": store.create_key("bob")[0],
            "root": store.create_key("root", admin=True)[0],
        }
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
            yield app, c, {k: {"authorization": f"Bearer {v}"} for k, v in keys.items()}


async def test_keys_are_stored_hashed_and_checked(keyed) -> None:  # noqa: ANN001
    app, c, h = keyed
    store: Store = app.state.snapwarn.store
    secret = h["alice"]["authorization"].split()[1]
    with store.session() as s:
        digests = [r.digest for r in s.query(ApiKeyRow).all()]
    assert all(secret not in d and len(d) == 64 for d in digests)
    assert (await c.get("/v1/signals")).status_code == 401
    r = await c.get("/v1/signals", headers={"authorization": "Bearer " + secret[:-1] + "x"})
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    assert (await c.get("/v1/signals", headers={"x-api-key": secret})).status_code == 200
    assert (await c.get("/healthz")).status_code == 200  # liveness needs no key


async def test_owners_see_only_their_own(keyed) -> None:  # noqa: ANN001
    app, c, h = keyed
    r = await c.post("/v1/signals", json={"dt": 0.1, "w": W}, headers=h["alice"])
    assert r.status_code == 201
    sid = r.json()["id"]
    store: Store = app.state.snapwarn.store
    assert store.get_signal_meta(sid).owner == "alice"
    for path in (f"/v1/signals/{sid}", f"/v1/signals/{sid}/data"):
        assert (await c.get(path, headers=h["bob"])).status_code == 404
        assert (await c.get(path, headers=h["alice"])).status_code == 200
        assert (await c.get(path, headers=h["root"])).status_code == 200
    assert (await c.get("/v1/signals", headers=h["bob"])).json()["total"] == 0
    assert (await c.get("/v1/signals", headers=h["root"])).json()["total"] >= 1
    r = await c.post("/v1/detections", json={"signal_id": sid}, headers=h["bob"])
    assert r.status_code == 404
    assert (await c.delete(f"/v1/signals/{sid}", headers=h["bob"])).status_code == 404
    # jobs and sweeps too
    job = store.create_job("diagnostic-sleep", {"seconds": 0}, owner="alice")
    sweep, _ = store.create_sweep("diagnostic-sleep", {}, {"seconds": 0}, "s", owner="alice")
    for path in (f"/v1/jobs/{job.id}", f"/v1/sweeps/{sweep.id}"):
        assert (await c.get(path, headers=h["bob"])).status_code == 404
        assert (await c.get(path, headers=h["alice"])).status_code == 200
    assert (await c.post(f"/v1/jobs/{job.id}/cancel", headers=h["bob"])).status_code == 404
    assert (await c.get("/v1/jobs", headers=h["bob"])).json()["total"] == 0
    assert (await c.get("/v1/sweeps", headers=h["bob"])).json()["total"] == 0
    mine = (await c.get("/v1/sweeps", headers=h["alice"])).json()
    assert [s["id"] for s in mine["items"]] == [sweep.id]
    r = await c.post(f"/v1/jobs/{job.id}/cancel", headers=h["alice"])
    assert r.status_code == 200 and r.json()["status"] == "cancelled"
    assert r.json()["error"]["reason"] == "cancelled"
    assert (await c.post(f"/v1/jobs/{job.id}/cancel", headers=h["alice"])).status_code == 200
    assert (await c.delete(f"/v1/signals/{sid}", headers=h["alice"])).status_code == 204


async def test_a_revoked_key_stops_working(keyed) -> None:  # noqa: ANN001
    app, c, h = keyed
    store: Store = app.state.snapwarn.store
    key, info = store.create_key("carol")
    hk = {"authorization": f"Bearer {key}"}
    assert (await c.get("/v1/signals", headers=hk)).status_code == 200
    assert store.revoke_key(info.id)
    app.state.snapwarn.extra.get("key_cache", {}).clear()  # else within 2 s
    assert (await c.get("/v1/signals", headers=hk)).status_code == 401
    assert not store.revoke_key(info.id)


async def test_sweeps_page_newest_first(keyed) -> None:  # noqa: ANN001
    app, c, h = keyed
    store: Store = app.state.snapwarn.store
    ids = [store.create_sweep("diagnostic-sleep", {}, {}, f"s{k}", owner="bob")[0].id
           for k in range(3)]  # fmt: skip
    page = (await c.get("/v1/sweeps", params={"limit": 2}, headers=h["bob"])).json()
    assert page["total"] == 3 and [s["id"] for s in page["items"]] == ids[::-1][:2]
    page2 = (await c.get("/v1/sweeps", params={"limit": 2, "offset": 2}, headers=h["bob"]))
    assert [s["id"] for s in page2.json()["items"]] == [ids[0]]


def test_keys_required_beyond_loopback() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("10.0.0.5")
    assert not keys_required(Settings(host="127.0.0.1"))
    assert keys_required(Settings(host="0.0.0.0"))
    assert keys_required(Settings(host="192.168.1.4"))
    assert not keys_required(Settings(host="0.0.0.0", auth="off"))  # explicit opt-out only
    assert keys_required(Settings(host="127.0.0.1", auth="on"))
    assert Caller("a", False).sees("a") and not Caller("a", False).sees("b")
    assert Caller("r", True).sees("b") and Caller("r", True).scope is None


async def test_server_beyond_loopback_refuses_keyless_requests(tmp_path) -> None:  # noqa: ANN001
    settings = Settings(
        db_url=f"sqlite:///{tmp_path / 'p.db'}", host="0.0.0.0", executor="thread",
        warm_pool=False, run_jobs=False,
    )  # fmt: skip
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://10.1.2.3") as c:
            assert (await c.get("/v1/jobs")).status_code == 401


async def test_cors_closed_by_default_and_configurable(tmp_path) -> None:  # noqa: ANN001
    pre = {"origin": "https://lab.example", "access-control-request-method": "POST"}
    for origins, allowed in (([], False), (["https://lab.example"], True)):
        settings = Settings(
            db_url=f"sqlite:///{tmp_path / f'c{allowed}.db'}", executor="thread",
            warm_pool=False, run_jobs=False, cors_origins=origins,
        )  # fmt: skip
        app = create_app(settings)
        async with app.router.lifespan_context(app):
            transport = httpx2.ASGITransport(app=app)
            async with httpx2.AsyncClient(transport=transport, base_url="http://127.0.0.1") as c:
                r = await c.options("/v1/signals", headers=pre)
                assert (r.headers.get("access-control-allow-origin") == pre["origin"]) is allowed
                r = await c.post(
                    "/v1/signals", json={"dt": 0.1, "w": W}, headers={"origin": pre["origin"]}
                )
                assert r.status_code == (201 if allowed else 403), r.text
