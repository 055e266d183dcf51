"""POST /v1/atlases (a job on an embedded LocalCluster) and the SDK, against the CLI and the
plain loop: one atlas through every door gives the same cells; bad specs answer 4xx naming the
field; the database keeps each cell once."""

from __future__ import annotations

import json
import subprocess

import httpx2
import pytest
from _atlas_helpers import REPO, SNAPWARN, env_one_thread

from service import convert
from service.api import Settings, create_app
from service.api.storage import Store
from service.api.storage.atlases import DbCellSink, create_atlas
from service.atlas import parse_spec, run_atlas
from service.client import AsyncClient, InvalidInput, NotFound, PayloadTooLarge

BEAM = {"kind": "bifurcation", "name": "beam", "fixed": {"model": "euler-beam"},
        "grid": {"actuation": ["asymmetric", "symmetric", "antisymmetric"]}}


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture
async def app(tmp_path, monkeypatch):  # noqa: ANN001, ANN201
    monkeypatch.setenv("SNAPWARN_ATLAS_WORKERS", "1")
    monkeypatch.delenv("SNAPWARN_DASK_SCHEDULER", raising=False)
    settings = Settings(db_url=f"sqlite:///{tmp_path / 'api.db'}", executor="thread",
                        warm_pool=False, analysis_workers=1, job_workers=1, job_poll_s=0.05,
                        job_heartbeat_s=0.3, api_key=None)  # fmt: skip
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        yield app


@pytest.mark.anyio
async def test_api_sdk_cli_and_loop_give_the_same_cells(app, tmp_path, monkeypatch) -> None:  # noqa: ANN001
    async with AsyncClient("http://asgi", transport=httpx2.ASGITransport(app=app)) as c:
        atlas = await c.create_atlas(BEAM)
        assert atlas.status == "queued" and atlas.cells_total == 3 and atlas.kind == "bifurcation"
        done = await c.wait_atlas(atlas, progress=False, timeout=240, poll=0.1)
        assert done.status == "succeeded", done.job.error
        assert done.cells_done == 3 and done.summary.ok == 3
        assert done.summary.engine.startswith("dask tcp://127.0.0.1")
        page = await c.atlas_cells(atlas.id)
        assert page.total == 3 and [r.index for r in page.items] == [0, 1, 2]
        listed = await c.list_atlases()
        assert atlas.id in [a.id for a in listed.items]
        csv = (await c.atlas_heatmap(atlas.id, metric="type", x="actuation", y="model",
                                     format="csv")).decode()  # fmt: skip
        assert csv.splitlines()[:2] == [
            "model \\ actuation,asymmetric,symmetric,antisymmetric",
            "euler-beam,saddle-node,subcritical-pitchfork,supercritical-pitchfork"]
        png = await c.atlas_heatmap(atlas.id, x="actuation", y="model")
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        # errors name the field and the value
        bad = {**BEAM, "grid": {"actuation": ["asymmetric", "sideways"]}}
        with pytest.raises(InvalidInput) as info:
            await c.create_atlas(bad)
        assert info.value.field == "spec.grid.actuation[1]" and info.value.value == "sideways"
        with pytest.raises(InvalidInput) as info:
            await c.create_atlas({"kind": "sweep", "cells": [{"manifest": "m.csv"}]})
        assert info.value.field == "spec.kind"
        monkeypatch.setenv("SNAPWARN_MAX_ATLAS_CELLS", "2")
        with pytest.raises(PayloadTooLarge) as info:
            await c.create_atlas(BEAM)
        assert info.value.field == "spec" and info.value.value == 3
        with pytest.raises(NotFound):
            await c.get_atlas("0" * 32)
    api = {r.key: r.results for r in page.items}
    loop = {r.key: r.results for r in run_atlas(parse_spec(BEAM), serial=True).rows}
    spec = tmp_path / "beam.json"
    spec.write_text(json.dumps(BEAM))
    r = subprocess.run([*SNAPWARN, "atlas", str(spec), "--serial", "--json", "--no-progress"],
                       capture_output=True, text=True, cwd=REPO, env=env_one_thread(),
                       timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    cli = {c["key"]: c["results"] for c in json.loads(r.stdout)["cells"]}
    assert api.keys() == loop.keys() == cli.keys()
    for k in api:  # the Euler beam's mu* is a closed-form root: the same to the last bits
        assert api[k]["mu_star"] == pytest.approx(loop[k]["mu_star"], rel=1e-13)
        assert cli[k]["mu_star"] == pytest.approx(loop[k]["mu_star"], rel=1e-13)
        assert api[k]["transition"] == loop[k]["transition"] == cli[k]["transition"]


def test_db_sink_keeps_each_cell_once_and_resumes(tmp_path) -> None:  # noqa: ANN001
    store = Store(f"sqlite:///{tmp_path / 'db.sqlite'}")
    store.migrate()
    spec = parse_spec(BEAM)
    atlas, _ = create_atlas(store, name="beam", kind=spec.kind, spec=spec.to_dict(),
                            params={"spec": spec.to_dict()}, cells_total=3)  # fmt: skip
    first = run_atlas(spec, serial=True, sink=DbCellSink(store, atlas.id))
    sink = DbCellSink(store, atlas.id)
    assert sink.put(first.rows[0]) is False  # the unique (atlas_id, key) refuses a duplicate
    again = run_atlas(spec, serial=True, sink=sink)
    assert again.summary.resumed == 3 and again.summary.engine.startswith("none")
    rows = [convert.atlas_cell(r) for r in again.rows]
    assert rows == [convert.atlas_cell(r) for r in first.rows]


@pytest.mark.slow  # ~60 s on a loaded machine: a real server, its process pool, a cluster
def test_a_real_server_runs_an_atlas_job_in_its_process_pool(tmp_path) -> None:  # noqa: ANN001
    """Jobs run in daemonic pool processes, which may not fork multiprocessing children: the
    engine then starts the scheduler and workers as subprocesses."""
    import os
    import signal
    import time

    from _atlas_helpers import free_port

    from service.client import Client

    port = free_port()
    env = env_one_thread()
    env.update({"SNAPWARN_ATLAS_WORKERS": "2", "SNAPWARN_WARM_POOL": "false"})
    log = open(tmp_path / "serve.log", "wb")  # noqa: SIM115
    server = subprocess.Popen([*SNAPWARN, "serve", "--port", str(port), "--db",
                               f"sqlite:///{tmp_path / 'db.sqlite'}"], env=env, cwd=tmp_path,
                              stdout=log, stderr=subprocess.STDOUT)  # fmt: skip
    try:
        url = f"http://127.0.0.1:{port}"
        end = time.monotonic() + 120
        while True:
            try:
                if httpx2.get(url + "/healthz", timeout=2).status_code == 200:
                    break
            except httpx2.HTTPError:
                pass
            assert server.poll() is None and time.monotonic() < end, (tmp_path / "serve.log"
                                                                      ).read_text()
            time.sleep(0.3)
        with Client(url, timeout=60) as c:
            atlas = c.create_atlas(BEAM)
            done = c.wait_atlas(atlas, progress=False, timeout=400, poll=0.5)
            assert done.status == "succeeded", done.job.error
            assert done.summary.ok == 3 and len(done.summary.workers) >= 1
            assert all(w.startswith("tcp://127.0.0.1:") for w in done.summary.workers)
    finally:
        os.kill(server.pid, signal.SIGTERM)
        server.wait(30)
        log.close()
