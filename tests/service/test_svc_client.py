"""The SDK: light to import, and correct against the real app in-process (ASGI) and over a
real uvicorn on loopback."""

from __future__ import annotations

import json
import subprocess
import sys

import httpx2
import numpy as np
import pytest
from _svc_helpers import numerics_has, require_numerics
from _svc_signals import csv_bytes, ringdown

from service.client import (
    AsyncClient,
    Client,
    Conflict,
    InvalidInput,
    JobFailed,
    NotFound,
    NotImplementedOnServer,
    UnsupportedMediaType,
    WaitTimeout,
)


def test_importing_the_sdk_loads_nothing_heavy() -> None:
    code = (
        "import json, sys\n"
        "import service.client\n"
        "from service.client import Client, AsyncClient\n"
        "heavy = ('fastapi', 'starlette', 'numpy', 'scipy', 'numba', 'sqlalchemy', "
        "'matplotlib', 'uvicorn', 'sim')\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in heavy)))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == []


def test_the_check_above_can_fail() -> None:
    code = "import sys, service.api.app; print('numpy' in sys.modules and 'fastapi' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "True"


# --- in-process (ASGI) ------------------------------------------------------------------------
@pytest.mark.anyio
async def test_async_client_in_process(asgi) -> None:  # noqa: ANN001
    app, _ = asgi
    t, w = ringdown(2000)
    async with AsyncClient("http://asgi", transport=httpx2.ASGITransport(app=app)) as c:
        h = await c.health()
        assert h.status == "ok"
        meta = await c.upload_signal(
            w, dt=0.01, unit="s", control={"name": "mu", "value": 0.7}, metadata={"run": 3}
        )
        assert meta.n == 2000 and meta.control.value == 0.7
        tt, ww = await c.signal_data(meta.id)
        assert isinstance(ww, np.ndarray) and ww.tobytes() == w.tobytes()
        assert np.allclose(tt, t)
        t_list, w_list = await c.signal_data(meta.id, as_numpy=False)
        assert w_list == w.tolist()
        with pytest.raises(InvalidInput) as ei:
            await c.upload_signal(np.array([1.0, np.nan, 2.0]), dt=1.0)
        assert ei.value.field == "w[1]" and ei.value.value == "NaN" and ei.value.status == 422
        with pytest.raises(NotFound):
            await c.get_signal("nope")
        await c.delete_signal(meta.id)
        with pytest.raises(NotFound):
            await c.signal_data(meta.id)
        if numerics_has("service.analysis.pipeline", "warn"):
            sw = await c.create_sweep(
                simulate={"actuation": "antisymmetric", "max_measurements": 5, "seed": 1}
            )
            done = await c.wait(sw, progress=False, timeout=120, poll=0.1)
            assert done.id == sw.id and done.status == "succeeded", done.job.error
            assert len(done.measurements) == 5
        else:
            with pytest.raises(NotImplementedOnServer):
                await c.create_sweep(simulate={"actuation": "asymmetric"})


@pytest.mark.anyio
async def test_async_wait_follows_a_job(asgi, capsys) -> None:  # noqa: ANN001
    app, _ = asgi
    store = app.state.snapwarn.store
    ok = store.create_job("diagnostic-sleep", {"seconds": 0.6, "steps": 6})
    bad = store.create_job("diagnostic-sleep", {"fail": True})
    app.state.snapwarn.runner.wake()
    async with AsyncClient("http://asgi", transport=httpx2.ASGITransport(app=app)) as c:
        job = await c.wait(ok.id, progress=True, timeout=60, poll=0.05)
        assert job.status == "succeeded" and job.progress.fraction == 1.0
        err = capsys.readouterr().err
        assert "100%" in err  # the tqdm bar was drawn on stderr
        with pytest.raises(JobFailed) as ei:
            await c.wait(bad.id, progress=False, timeout=60, poll=0.05)
        assert "asked to fail" in str(ei.value)
        slow = store.create_job("diagnostic-sleep", {"seconds": 30, "steps": 300})
        with pytest.raises(WaitTimeout):
            await c.wait(slow.id, progress=False, timeout=0.3, poll=0.05)
        store.fail_job(slow.id, None, {"title": "cancelled by the test"})


# --- over a real uvicorn ----------------------------------------------------------------------
def test_sync_client_over_uvicorn(live_server, tmp_path) -> None:  # noqa: ANN001
    t, w = ringdown(3000, dt=0.005)
    with Client(live_server.url, timeout=30) as c:
        assert c.health().database == "ok"
        path = tmp_path / "lab run.csv"
        path.write_bytes(csv_bytes(t, w))
        meta = c.upload_file(
            path,
            control_name="angle",
            control_value=0.12,
            control_unit="deg",
            metadata={"operator": "ada"},
        )
        assert meta.name == "lab run.csv" and meta.unit == "s" and meta.value_unit == "mm"
        assert meta.metadata["operator"] == "ada" and meta.control.unit == "deg"
        tt, ww = c.signal_data(meta.id)
        assert ww.tobytes() == w.tobytes() and tt.tobytes() == t.tobytes()
        assert c.get_signal(meta.id) == meta
        assert meta.id in [m.id for m in c.list_signals(limit=500).items]
        assert c.list_jobs(status="failed", limit=5).limit == 5
        csv = c.download_signal(meta.id, format="csv").decode()
        assert csv.splitlines()[0] == "t [s],w [mm]"
        png = c.signal_plot(meta.id)
        assert png[:4] == b"\x89PNG"
        with pytest.raises(UnsupportedMediaType):
            c.upload_file(b"whatever", filename="x.doc")
        with pytest.raises(InvalidInput) as ei:
            c.upload_signal([0.0, 1.0, 2.0], t=[0.0, 2.0, 1.0])
        assert ei.value.field == "t[2]"
        with pytest.raises(NotFound):
            c.get_sweep("nope")
        with pytest.raises(NotFound):
            c.sweep_plot("nope", format="svg")
        if numerics_has("service.analysis.detect", "detect"):
            doc = c.detect(meta.id)
            assert doc.fundamental.omega == pytest.approx(2 * np.pi * 1.3, rel=1e-3)
            inline = c.detect(w=w, dt=0.005)
            assert inline.fundamental == doc.fundamental
        with pytest.raises(Conflict if False else NotFound):
            c.get_job("nope")


def test_sync_client_simulation(live_server) -> None:  # noqa: ANN001
    require_numerics("sim", "simulate")
    with Client(live_server.url, timeout=120) as c:
        res = c.simulate(mu=0.3, model="euler-beam", actuation="symmetric", snr_db=40, seed=2)
        assert res.signal is not None and res.job is None
        t, w = c.signal_data(res.signal.id)
        assert t.size == w.size == res.signal.n
        bg = c.simulate(mu=0.3, model="euler-beam", background=True)
        job = c.wait(bg, progress=False, timeout=120)
        assert job.status == "succeeded"
        assert c.get_signal(job.result["signal_id"]).n > 0
