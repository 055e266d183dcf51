"""One snap through every door: sim, CLI --json, REST (POST /v1/snaps) and the SDK agree."""

from __future__ import annotations

import json

import pytest
from fastapi import FastAPI

from service.api.auth import Caller, get_caller
from service.api.routers import snaps
from service.cli import main
from service.client import Client
from sim.scene import Scene
from sim.snap import snap


@pytest.fixture()
def app() -> FastAPI:
    app = FastAPI()
    app.include_router(snaps.router)
    app.dependency_overrides[get_caller] = lambda: Caller(owner="local", admin=True)
    return app


def test_snap_is_the_same_through_every_door(app: FastAPI, capsys) -> None:
    ref = snap(Scene(actuation="antisymmetric"), "normal-form", 1e-3)
    assert main(["snap", "--model", "normal-form", "--actuation", "antisymmetric",
                 "--dmu", "1e-3", "--json"]) == 0  # fmt: skip
    cli = json.loads(capsys.readouterr().out)
    from fastapi.testclient import TestClient

    with TestClient(app) as tc:
        r = tc.post("/v1/snaps", json={"model": "normal-form", "actuation": "antisymmetric",
                                       "dmu": 1e-3})  # fmt: skip
        assert r.status_code == 200
        api = r.json()
        bad = tc.post("/v1/snaps", json={"model": "normal-form", "dmu": -1.0})
        assert bad.status_code == 422
        with Client("http://testserver", transport=tc._transport) as c:  # type: ignore[attr-defined]
            sdk = c.snap(model="normal-form", actuation="antisymmetric", dmu=1e-3)
    for doc in (cli, api):
        assert doc["snap_time"] == pytest.approx(ref.snap_time, rel=1e-12)
        assert (doc["from_branch"], doc["to_branch"]) == ("S_B", "U_A")
        assert doc["samples"] == ref.t.size
    assert sdk.snap_time == pytest.approx(ref.snap_time, rel=1e-12)
