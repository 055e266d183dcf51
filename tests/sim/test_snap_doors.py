"""One snap through every door: sim, CLI --json, REST (POST /v1/snaps, at once or as a job)
and the SDK agree."""

from __future__ import annotations

import json
import time

import pytest

from service.api import create_app
from service.api.settings import Settings
from service.cli import main
from service.client import Client
from sim.scene import Scene
from sim.snap import snap


@pytest.fixture()
def client(tmp_path):
    from fastapi.testclient import TestClient

    settings = Settings(db_url=f"sqlite:///{tmp_path / 'snaps.db'}", analysis_workers=1,
                        job_workers=1, job_poll_s=0.05, api_key=None)  # fmt: skip
    with TestClient(create_app(settings)) as tc:
        yield tc


@pytest.mark.slow  # starts the app with its process pools
def test_snap_is_the_same_through_every_door(client, capsys) -> None:
    ref = snap(Scene(actuation="antisymmetric"), "normal-form", 1e-3)
    assert main(["snap", "--model", "normal-form", "--actuation", "antisymmetric",
                 "--dmu", "1e-3", "--json"]) == 0  # fmt: skip
    cli = json.loads(capsys.readouterr().out)
    r = client.post("/v1/snaps", json={"model": "normal-form", "actuation": "antisymmetric",
                                       "dmu": 1e-3})  # fmt: skip
    assert r.status_code == 200
    api = r.json()["snap"]
    assert client.post("/v1/snaps", json={"model": "normal-form", "dmu": -1.0}).status_code == 422
    bad = client.post("/v1/snaps", json={"model": "euler-beam", "dmu": 1e-6})
    assert bad.status_code == 422 and "dmu" in bad.text
    with Client("http://testserver", transport=client._transport) as c:
        sdk = c.snap(model="normal-form", actuation="antisymmetric", dmu=1e-3).snap
    for doc in (cli, api):
        assert doc["snap_time"] == pytest.approx(ref.snap_time, rel=1e-12)
        assert (doc["from_branch"], doc["to_branch"]) == ("S_B", "U_A")
        assert doc["samples"] == ref.t.size
    assert sdk.snap_time == pytest.approx(ref.snap_time, rel=1e-12)


@pytest.mark.slow
def test_nonlinear_snap_is_a_job_whose_result_is_the_snap(client) -> None:
    r = client.post("/v1/snaps", json={"model": "euler-beam", "actuation": "asymmetric",
                                       "dmu": 1e-2, "duration": 2.0})  # fmt: skip
    assert r.status_code == 202 and r.headers["location"].startswith("/v1/jobs/")
    for _ in range(600):
        job = client.get(r.headers["location"]).json()
        if job["status"] in ("succeeded", "failed", "cancelled"):
            break
        time.sleep(0.1)
    assert job["status"] == "succeeded", job
    ref = snap(Scene(actuation="asymmetric"), "euler-beam", 1e-2, duration=2.0)
    assert job["result"]["snap_time"] == pytest.approx(ref.snap_time, rel=1e-9)
