"""End to end against a real server (uvicorn on loopback, SQLite file): upload CSVs of
simulated impulse responses, detect one, run a sweep job to its prediction, chart it -- through
the SDK, and the same through raw HTTP."""

from __future__ import annotations

import io
import math
import time

import httpx2
import numpy as np
import pytest
from _svc_helpers import require_numerics
from _svc_signals import csv_bytes

from service.client import Client

MUS = (0.0, 0.4, 0.8, 1.1, 1.3, 1.45, 1.55, 1.62)


@pytest.fixture(scope="module")
def recorded() -> list[tuple[float, bytes]]:
    """CSV files of simulated records at increasing mu (what a lab would upload)."""
    require_numerics("sim", "simulate")
    from sim import simulate
    from sim.scene import Scene

    out = []
    for k, mu in enumerate(MUS):
        sig = simulate(Scene(actuation="asymmetric", mu=mu, snr_db=50, seed=k), model="euler-beam")
        out.append((mu, csv_bytes(np.asarray(sig.t), np.asarray(sig.w), header="time,w")))
    return out


def test_sdk_end_to_end(live_server, recorded, tmp_path, capsys) -> None:  # noqa: ANN001
    require_numerics("service.analysis.pipeline", "sweep_from_signals")
    with Client(live_server.url, timeout=120) as c:
        ids = []
        for k, (mu, data) in enumerate(recorded):
            path = tmp_path / f"run{k}.csv"
            path.write_bytes(data)
            meta = c.upload_file(path, control_name="mu", control_value=mu)
            assert meta.source == "csv" and meta.control.value == mu
            ids.append(meta.id)
        doc = c.detect(ids[0])
        assert doc.fundamental is not None and doc.fundamental.sigma2 < 0
        assert doc.static_level is not None
        sweep = c.create_sweep(ids, name="lab sweep")  # control values stored with the signals
        assert sweep.status in ("queued", "running", "succeeded")
        done = c.wait(sweep, progress=True, timeout=240)
        assert "100%" in capsys.readouterr().err
        assert done.status == "succeeded", done.job.error
        assert len(done.measurements) == len(MUS)
        assert [m.mu for m in done.measurements] == list(MUS)
        p = done.prediction
        assert p is not None and math.isfinite(p.mu_star) and p.mu_star > MUS[-1]
        lo, hi = p.mu_star_interval
        assert lo <= p.mu_star <= hi
        assert done.alarm is not None and done.alarm.mu == MUS[-1]
        png = c.sweep_plot(done.id)
        svg = c.sweep_plot(done.id, format="svg")
        assert png[:4] == b"\x89PNG" and b"<svg" in svg[:2000]
        assert c.get_sweep(done.id) == done  # persisted as shown


def test_simulated_sweep_job(live_server) -> None:  # noqa: ANN001
    require_numerics("service.analysis.pipeline", "warn")
    with Client(live_server.url, timeout=120) as c:
        sweep = c.create_sweep(
            simulate={"actuation": "asymmetric", "max_measurements": 6, "seed": 3}
        )
        done = c.wait(sweep, progress=False, timeout=300)
        assert done.status == "succeeded", done.job.error
        assert len(done.result.measurements) == len(done.measurements) <= 6
        assert done.job.progress.fraction == 1.0
        if done.prediction is not None and done.prediction.mu_star is not None:
            assert done.prediction.mu_star > done.measurements[-1].mu


def test_raw_http_end_to_end(live_server, recorded) -> None:  # noqa: ANN001
    require_numerics("service.analysis.pipeline", "sweep_from_signals")
    base = live_server.url
    with httpx2.Client(base_url=base, timeout=120) as h:
        ids = []
        for k, (mu, data) in enumerate(recorded):
            r = h.post(
                "/v1/signals",
                files={"file": (f"r{k}.csv", data, "text/csv")},
                data={"control_value": str(mu)},
            )
            assert r.status_code == 201, r.text
            assert r.headers["location"] == f"/v1/signals/{r.json()['id']}"
            ids.append(r.json()["id"])
        # the stored samples are those of the file
        r = h.get(f"/v1/signals/{ids[1]}/data", params={"format": "npy"})
        a = np.load(io.BytesIO(r.content))
        sent = np.loadtxt(io.BytesIO(recorded[1][1]), delimiter=",", skiprows=1)
        assert a.tobytes() == sent.tobytes()
        r = h.post("/v1/detections", json={"signal_id": ids[0]})
        assert r.status_code == 200 and r.json()["fundamental"]["sigma2"] < 0
        r = h.post(
            "/v1/sweeps",
            json={
                "measurements": [
                    {"signal_id": i, "control_value": mu} for i, (mu, _) in zip(ids, recorded)
                ]
            },
        )
        assert r.status_code == 202, r.text
        sid = r.json()["id"]
        assert r.headers["location"] == f"/v1/sweeps/{sid}"
        end = time.monotonic() + 240
        while (j := h.get(f"/v1/jobs/{sid}").json())["status"] not in ("succeeded", "failed"):
            assert 0.0 <= j["progress"]["fraction"] <= 1.0
            assert time.monotonic() < end, j
            time.sleep(0.2)
        assert j["status"] == "succeeded", j["error"]
        doc = h.get(f"/v1/sweeps/{sid}").json()
        assert doc["prediction"]["mu_star"] > MUS[-1] and doc["classification"] is not None
        r = h.get(f"/v1/sweeps/{sid}/plot.png")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        # a bad request in the middle leaves everything stored as it was
        before = h.get(f"/v1/sweeps/{sid}").json()
        r = h.post(
            "/v1/sweeps",
            json={"measurements": [{"signal_id": i} for i in (ids[0], "gone", ids[1])]},
        )
        assert (
            r.status_code == 422 and r.json()["errors"][0]["field"] == "measurements[1].signal_id"
        )
        assert h.get(f"/v1/sweeps/{sid}").json() == before
